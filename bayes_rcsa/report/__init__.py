"""Reports assembled from the outputs of the sub-commands (HTML pages linking figures and tables)."""

from .index_html import demo_index_html, write_demo_index

__all__ = ["demo_index_html", "write_demo_index"]
