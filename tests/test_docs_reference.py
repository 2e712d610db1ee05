"""The generated reference pages (docs/cli-reference.md, docs/api.md, docs/architecture.md) are current.

All three are regenerated in memory by docs/gen_reference.py and compared with the committed files;
a changed help text or docstring fails here until ``python3 docs/gen_reference.py`` is run.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parent.parent / "docs"


def _generator():
    spec = importlib.util.spec_from_file_location("gen_reference", DOCS / "gen_reference.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("page", ["cli-reference.md", "api.md", "architecture.md"])
def test_generated_reference_page_is_current(page):
    gen = _generator()
    fresh = gen.PAGES[page]()
    committed = (DOCS / page).read_text(encoding="utf-8")
    assert committed == fresh, f"docs/{page} is out of date: regenerate it with `{gen.COMMAND}` and commit it"


def test_cli_reference_covers_every_sub_command_and_the_undocumented_options():
    import argparse

    from bayes_rcsa.cli.main import build_parser

    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    text = (DOCS / "cli-reference.md").read_text(encoding="utf-8")
    assert len(sub.choices) >= 10
    for name in sub.choices:
        assert f"## bayes-rcsa {name}\n" in text, name
    # options that were missing from every page before the reference existed
    for option in ("--artifact", "--spindle-uncertainty", "--checkpoint-interval"):
        assert option in text, option


def test_api_reference_lists_every_public_name():
    import importlib

    gen = _generator()
    text = (DOCS / "api.md").read_text(encoding="utf-8")
    for pkg in gen.API_PACKAGES:
        for name in importlib.import_module(pkg).__all__:
            assert f"| `{name}` |" in text, (pkg, name)


def test_architecture_page_describes_every_layer_part_and_api_page_starts_with_the_top_level_api():
    gen = _generator()
    arch = gen._layer_table()
    text = (DOCS / "architecture.md").read_text(encoding="utf-8")
    for part, layer in arch.LAYERS.items():
        assert f"### {part}\n\nLayer {layer}.  " in text, part
        # a description of its own, not only a heading
        assert len(gen._description(part)) >= 40, f"bayes_rcsa.{part} needs a docstring that describes it"
    api = (DOCS / "api.md").read_text(encoding="utf-8")
    top = api.index("## The top-level API: `import bayes_rcsa`")
    assert top < api.index("# The packages")
    for name in ("identify", "predict", "lobes", "check_model", "design_test", "build_library", "update", "make_report"):
        assert f"| `{name}` |" in api[top:api.index("# The packages")], name
