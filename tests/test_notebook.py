"""The notebook for script users (examples/api_tour.ipynb) runs as a user would run it, on the public API only.

Executed with the Jupyter project's own executor (nbclient) in a fresh kernel with ``BAYES_RCSA_QUICK=1`` (short
chains, fewer draws and speeds; the notebook states the full settings and their run time).
"""

from __future__ import annotations

import ast
import os
from pathlib import Path

import pytest

NOTEBOOK = Path(__file__).resolve().parent.parent / "examples" / "api_tour.ipynb"
ROOT = NOTEBOOK.parent.parent


def _code_cells(nb):
    return [c for c in nb.cells if c.cell_type == "code"]


def test_the_notebook_uses_only_the_public_api():
    nbformat = pytest.importorskip("nbformat")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    for cell in _code_cells(nb):
        for node in ast.walk(ast.parse(cell.source)):
            if isinstance(node, ast.ImportFrom):
                assert not (node.module or "").startswith("bayes_rcsa."), cell.source
            if isinstance(node, ast.Import):
                for a in node.names:
                    assert not a.name.startswith("bayes_rcsa."), cell.source
            # no private names of the package (br._something)
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "br":
                assert not node.attr.startswith("_"), cell.source


@pytest.mark.slow
def test_the_notebook_runs_identify_predict_lobes_discrepancy_in_a_fresh_kernel(tmp_path):
    nbformat = pytest.importorskip("nbformat")
    nbclient = pytest.importorskip("nbclient")
    nb = nbformat.read(NOTEBOOK, as_version=4)
    env_before = os.environ.get("BAYES_RCSA_QUICK")
    os.environ["BAYES_RCSA_QUICK"] = "1"  # the kernel inherits the environment
    try:
        client = nbclient.NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}})
        client.execute()
    finally:
        if env_before is None:
            os.environ.pop("BAYES_RCSA_QUICK", None)
        else:
            os.environ["BAYES_RCSA_QUICK"] = env_before
    outputs = [o for c in _code_cells(nb) for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    import re

    html = "\n".join(o["data"]["text/html"] for o in outputs if "text/html" in o.get("data", {}))
    # the notebook views of the results: printed names and units, no internal identifiers in their tables (the
    # warning lines quote the sampler's convergence reasons as they are in summary.json)
    tables = re.sub(r"<p>Warnings:</p><ul>.*?</ul>", "", html, flags=re.S)
    for text in ("Posterior", "Hz", "rpm", "mm", "Stability lobes"):
        assert text in tables, text
    for internal in ("k_xf", "k_thetaM", "systematic_relative_residual"):
        assert internal not in tables, internal
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    assert len(images) >= 2  # the ArviZ trace plot and the lobes
    text = "\n".join(o.get("text", "") for o in outputs if o.get("output_type") == "stream")
    assert "True" in text  # the saved posterior reads back with the same draws
