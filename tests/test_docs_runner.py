"""The documentation runs as written: docs/run_docs.py, the documented command lines, ``bayes-rcsa example``.

The docs job (``python3 docs/run_docs.py``, run by .ci/run after the suite) executes every shell block; these
tests are the cheap part that belongs in the suite: (a) the runner's extraction and failure report on a small
fake page; (b) every ``bayes-rcsa ...`` command line of README.md and docs/*.md against the real argparse
parser, without running any (a renamed or removed option fails here at once); (c) ``bayes-rcsa example`` writes
the files the pages' commands read, and the batch/library manifest among them is accepted.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import re
import shlex
import sys
from pathlib import Path

import pytest

from bayes_rcsa.cli.main import build_parser, main

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture(scope="module")
def runner():
    spec = importlib.util.spec_from_file_location("run_docs", ROOT / "docs" / "run_docs.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules["run_docs"] = module  # its dataclasses look their module up while the class is made
    spec.loader.exec_module(module)
    return module


# ------------------------------------------------------------------------------------- (a) the runner --
FAKE = """\
# A page

```bash
mkdir out && cd out && echo 1 > made.txt
```
<!-- expect: made.txt -->

```text
bayes-rcsa identify SETUP --out DIR
```

```
# a plain fence whose first command is bayes-rcsa (or python3) is run
python3 -c "open('second.txt', 'w').write('2')"
```

<!-- docs: skip not on this machine -->
```sh
exit 3
```

```console
$ test -f second.txt
not a command: the output of the one above
$ ls missing-file-of-the-page
```
"""


def test_runner_extracts_the_blocks_by_the_documented_rule(runner, tmp_path):
    page = tmp_path / "page.md"
    page.write_text(FAKE, encoding="utf-8")
    blocks = runner.extract_blocks(page)
    assert [(b.language, b.shell, b.number) for b in blocks] == [
        ("bash", True, 1), ("text", False, 0), ("", True, 2), ("sh", True, 3), ("console", True, 4)]
    assert blocks[0].expect == ["made.txt"] and blocks[3].skip == "not on this machine"
    assert blocks[4].script() == "test -f second.txt\nls missing-file-of-the-page\n"  # `$` lines only
    with pytest.raises(ValueError, match="needs a reason"):
        runner.extract_blocks(page, "<!-- docs: skip -->\n```bash\ntrue\n```\n")
    with pytest.raises(ValueError, match="must follow a shell block"):
        runner.extract_blocks(page, "```bash\ntrue\n```\nsome prose\n<!-- expect: x -->\n")


def test_runner_names_the_page_block_and_command_that_failed(runner, tmp_path, capsys):
    page = tmp_path / "page.md"
    page.write_text(FAKE, encoding="utf-8")
    assert runner.main([str(page)]) == 1
    captured = capsys.readouterr()
    out = captured.out
    # the working directory carried over (the python block wrote into out/), the skipped block was not run
    assert "block 1 (line 3): ok" in out and "block 2 (line 12): ok" in out
    assert "block 3 (line 18): skipped (not on this machine)" in out
    assert re.search(r"FAILED .*page\.md: block 4 \(line 22\): `ls missing-file-of-the-page` exited with status 2",
                     captured.err)
    # a block that runs but does not write what its marker promises fails too
    page.write_text("```bash\ntrue\n```\n<!-- expect: never.txt -->\n", encoding="utf-8")
    assert runner.main([str(page)]) == 1
    assert "did not write never.txt" in capsys.readouterr().err


def test_the_pages_follow_the_rule(runner):
    """Every page parses; every page with a runnable bayes-rcsa command starts from files it makes itself."""
    for page in runner.pages():
        blocks = [b for b in runner.extract_blocks(page) if b.shell and b.skip is None]
        scripts = [b.script() for b in blocks]
        uses = [s for s in scripts if re.search(r"^\s*bayes-rcsa (?!example)", s, re.M)]
        if uses:
            first = next(s for s in scripts if "bayes-rcsa" in s)
            assert "bayes-rcsa example --out" in first, f"{page.name}: the first command must write the files"
    # skipped blocks are the install and test-suite commands only
    skipped = [b.script() for p in runner.pages() for b in runner.extract_blocks(p) if b.skip]
    assert skipped and all("pip install" in s for s in skipped)


# ----------------------------------------------------------------------- (b) documented command lines --
def _subparsers():
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return parser, sub.choices


def _commands(script: str) -> list[list[str]]:
    """The ``bayes-rcsa`` command lines of a shell script, as argv lists (continuations joined)."""
    out = []
    for line in script.replace("\\\n", " ").splitlines():
        for part in re.split(r"&&|;|\|\|", line):
            try:
                argv = shlex.split(part, comments=True)
            except ValueError:
                continue
            if argv[:1] == ["bayes-rcsa"]:
                out.append(argv[1:])
            elif argv[:3] == ["python3", "-m", "bayes_rcsa"]:
                out.append(argv[3:])
    return out


def _code_texts(runner, page: Path) -> list[str]:
    """Every piece of code of a page: fenced blocks, indented lines, inline code spans."""
    text = page.read_text(encoding="utf-8")
    texts = [b.text for b in runner.extract_blocks(page)]
    fenced = re.sub(r"^\s*(```|~~~).*?^\s*(```|~~~)", "", text, flags=re.S | re.M)
    texts += re.findall(r"`([^`\n]+)`", fenced)
    # an indented synopsis continues on the following indented lines
    texts += [m.group(0) for m in re.finditer(r"^ {4,}bayes-rcsa .*(?:\n {6,}.*)*", fenced, re.M)]
    return texts


def test_every_documented_command_line_parses(runner):
    """Runnable blocks: the whole line parses; synopses and inline code: the command and every option exist."""
    parser, commands = _subparsers()
    bad, checked = [], 0
    for page in runner.pages():
        for b in runner.extract_blocks(page):
            if not b.shell:
                continue
            for argv in _commands(b.script()):
                checked += 1
                err = io.StringIO()
                try:
                    with contextlib.redirect_stderr(err):
                        parser.parse_args(argv)
                except SystemExit:
                    bad.append(f"{b.where}: bayes-rcsa {' '.join(argv)}: {err.getvalue().strip()}")
        for code in _code_texts(runner, page):
            # a command line: at the start of a line or after && / ; / a prompt; up to the end of the command
            for m in re.finditer(r"(?:^|&&|;|\$)\s*(?:bayes-rcsa|python3 -m bayes_rcsa)\s+([a-z][a-z-]*)"
                                 r"((?:[^`\n&;#\\]|\\\n|\\)*)", code, re.M):
                name, rest = m.group(1), m.group(2)
                if name not in commands:
                    bad.append(f"{page.name}: `bayes-rcsa {name}`: no such command")
                    continue
                known = commands[name]._option_string_actions
                for flag in re.findall(r"(?<![\w-])(--[a-z][a-z0-9-]*[a-z0-9])(?![\w*-])", rest):
                    checked += 1
                    action = known.get(flag)
                    if action is None:
                        bad.append(f"{page.name}: `bayes-rcsa {name} ... {flag}`: no such option")
                    elif action.help == argparse.SUPPRESS:
                        bad.append(f"{page.name}: `bayes-rcsa {name} ... {flag}`: a deprecated name")
    assert checked > 200
    assert not bad, "\n".join(bad)


def test_design_reads_the_old_immersion_name_with_a_deprecation_warning():
    """One name for one quantity (--immersion, as lobes and update); the old design option still parses."""
    parser, commands = _subparsers()
    args = parser.parse_args(["design", "s.toml", "--out", "d", "--radial-immersion", "0.5"])
    assert args.immersion == "0.5" and args.deprecated_names == [("--radial-immersion", "--immersion")]
    assert parser.parse_args(["design", "s.toml", "--out", "d", "--immersion", "0.5"]).immersion == "0.5"
    for name in ("lobes", "update", "design"):
        assert "--immersion" in commands[name]._option_string_actions
    assert "--radial-immersion" not in commands["design"].format_help()


# ------------------------------------------------------------------------------- (c) bayes-rcsa example --
@pytest.fixture(scope="module")
def example_folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("example") / "my-campaign"
    assert main(["example", "--out", str(out)]) == 0
    return out


def test_example_writes_the_files_the_pages_read(runner, example_folder):
    from bayes_rcsa.io.setup import load_setup

    # every .toml a runnable command of the pages reads (a positional argument) is in the folder
    inputs = set()
    for page in runner.pages():
        for b in runner.extract_blocks(page):
            if b.shell and b.skip is None:
                for argv in _commands(b.script()):
                    inputs |= {a for a in argv[1:] if a.endswith(".toml") and not a.startswith("-")}
    produced = {"campaign/setup.toml"}  # written by an earlier block (synthesize --out campaign)
    assert {"setup.toml", "bench.toml", "artifact/artifact.toml", "library.toml"} <= inputs
    for rel in sorted(inputs - produced):
        assert (example_folder / rel).is_file(), rel
    for rel in ("README.txt", "spindle_x.csv", "spindle_y.csv", "tip_x_25mm.csv", "tip_y_40mm.csv", "truth.json",
                "artifact/h11_x.csv", "artifact/h22_y.csv"):
        assert (example_folder / rel).stat().st_size > 0, rel
    readme = (example_folder / "README.txt").read_text(encoding="utf-8")
    for name in ("setup.toml", "bench.toml", "artifact/", "library.toml", "library/"):
        assert name in readme
    assert len(load_setup(example_folder / "setup.toml").measurements) == 8


def test_example_library_manifest_is_accepted_by_batch_and_library(example_folder):
    from bayes_rcsa.batch import load_manifest
    from bayes_rcsa.io.setup import load_setup

    jobs = load_manifest(example_folder / "library.toml")
    assert len(jobs) == 2 and len({j.name for j in jobs}) == 2
    for job in jobs:
        setup = load_setup(job.setup_file)
        # every step runs (lobes couple x and y: both spindle directions); the library pools one holder type
        assert [step for step, _ in job.commands] == ["identify", "predict", "lobes"]
        assert {"x", "y"} <= set(setup.spindle) and setup.holder_type == "ER32" and len(setup.tools) == 1


def test_example_refuses_a_non_empty_folder_in_one_line(example_folder, capsys):
    capsys.readouterr()
    assert main(["example", "--out", str(example_folder)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "exists and is not empty; use --force" in err
