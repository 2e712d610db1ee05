"""Reports assembled from the outputs of the sub-commands.

* :func:`write_report_html` / :func:`build_report`: the self-contained HTML
  report of ``bayes-rcsa report`` (Jinja2 template, figures embedded);
* :func:`build_answer` / :func:`answer_html` / :func:`answer_markdown`: the
  summary block that heads the report, the demo's landing page and
  ``summary.md`` (:mod:`.answer`);
* :func:`write_demo_index`: the demo's landing page and ``summary.md``.
"""

from .answer import answer_html, answer_markdown, build_answer
from .html_report import build_report, write_report_html
from .index_html import demo_index_html, write_demo_index

__all__ = ["build_report", "write_report_html", "build_answer", "answer_html", "answer_markdown", "demo_index_html",
           "write_demo_index"]
