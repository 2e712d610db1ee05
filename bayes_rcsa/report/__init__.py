"""Reports assembled from the outputs of the sub-commands.

* :func:`write_report_html` / :func:`build_report`: the self-contained HTML
  report of ``bayes-rcsa report`` (Jinja2 template, figures embedded);
* :func:`write_demo_index`: the demo's landing page.
"""

from .html_report import build_report, write_report_html
from .index_html import demo_index_html, write_demo_index

__all__ = ["build_report", "write_report_html", "demo_index_html", "write_demo_index"]
