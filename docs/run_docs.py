#!/usr/bin/env python3
"""Run every shell block of README.md and docs/*.md, in order, in a fresh folder per page.

    python3 docs/run_docs.py                      # every page (what .ci/run does after the test suite)
    python3 docs/run_docs.py docs/spindle.md      # some pages
    python3 docs/run_docs.py --list               # the blocks that would run, and the skipped ones

Which fenced blocks are run (the rule the pages are written to):

* a block fenced ```bash, ```sh, ```shell or ```console is a shell block.  In a ```console block only the
  lines that start with ``$ `` are commands (the rest is the output they print, not checked);
* a block with a plain fence (no language) is a shell block when its first line that is neither blank nor a
  ``#`` comment starts with ``bayes-rcsa``, ``python3`` or ``$ ``; anything else in a plain fence (a CSV
  header, a folder listing) is text;
* a synopsis with placeholders (``SETUP``, ``DIR``, ``[--option]``, ``a|b``) is fenced ```text and never run;
* ``<!-- docs: skip REASON -->`` on the line before a shell block skips it; the reason is required and is
  printed (used only for commands that install the package or run the test suite, which .ci/run does itself);
* ``<!-- expect: PATH [PATH ...] -->`` after a block (blank lines between are allowed) lists files or folders,
  relative to the folder the block ends in, that must exist once the block has run: the files the text says
  are written.

Each page runs in a new temporary folder with ``bash -e -o pipefail``, block after block; the working
directory carries over from one block to the next, as in one terminal (a block may ``cd``), the shell's
variables do not.  ``bayes-rcsa`` and ``python3`` run this checkout's package
(``python3 -m bayes_rcsa`` with the repository root first on ``PYTHONPATH``), whatever is installed.  A page
that needs files starts with ``bayes-rcsa example --out .`` (the bundled campaign, the bench, the artifact
tests and a library manifest), written in the page.

Exit status 0 when every block ran and every expected file exists; 1 otherwise, after one line naming the
page, the block (number and line) and the command that failed, with the end of its output.  Standard library
only.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
#: Pages written by docs/gen_reference.py: synopses of --help, never run
GENERATED = ("api.md", "architecture.md", "cli-reference.md")
SHELL_LANGUAGES = ("bash", "sh", "shell", "console")
#: First words that make a plain fence a shell block
COMMAND_WORDS = ("bayes-rcsa", "python3", "$ ")
_FENCE = re.compile(r"^(\s*)(```+|~~~+)\s*([\w+-]*)")
_SKIP = re.compile(r"^\s*<!--\s*docs:\s*skip\b\s*(.*?)\s*-->\s*$")
_EXPECT = re.compile(r"^\s*<!--\s*expect:\s*(.*?)\s*-->\s*$")


@dataclass
class Block:
    """One fenced block of a page.

    Attributes
    ----------
    page : Path
    number : int, 1-based among the page's shell blocks (0 for a block that is not a shell block)
    line : int, 1-based line of the opening fence
    language : str, the fence's info string ("" for a plain fence)
    text : str, the block's lines
    shell : bool, whether it is run
    skip : str or None, the reason of a ``<!-- docs: skip REASON -->`` marker
    expect : list of str, paths of ``<!-- expect: ... -->`` markers after the block
    """

    page: Path
    number: int
    line: int
    language: str
    text: str
    shell: bool
    skip: str | None = None
    expect: list[str] = field(default_factory=list)

    @property
    def where(self) -> str:
        return f"{_name(self.page)}: block {self.number} (line {self.line})"

    def script(self) -> str:
        """The commands of the block as a bash script (a console block: its ``$`` lines only)."""
        lines = self.text.splitlines()
        if self.language == "console" or any(ln.startswith("$ ") for ln in lines):
            lines = [ln[2:] for ln in lines if ln.startswith("$ ")]
        return "\n".join(lines) + "\n"


def _name(page: Path) -> str:
    try:
        return str(page.resolve().relative_to(ROOT))
    except ValueError:
        return str(page)


def is_shell(language: str, text: str) -> bool:
    """The rule of the module docstring: which fenced blocks are shell blocks."""
    if language in SHELL_LANGUAGES:
        return True
    if language:
        return False
    for ln in text.splitlines():
        s = ln.strip()
        if s and not s.startswith("#"):
            return s.startswith(COMMAND_WORDS)
    return False


def extract_blocks(page, text: str | None = None) -> list[Block]:
    """Every fenced block of ``page`` (read from disk unless ``text`` is given), with its markers.

    Raises
    ------
    ValueError
        A fence that is never closed, a skip marker without a reason or not followed by a shell block.
    """
    page = Path(page)
    lines = (page.read_text(encoding="utf-8") if text is None else text).splitlines()
    blocks: list[Block] = []
    pending_skip: tuple[int, str] | None = None
    after_block = False  # only blank lines and markers since the last block's closing fence
    number = 0
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            s, e = _SKIP.match(lines[i]), _EXPECT.match(lines[i])
            if s:
                if not s.group(1):
                    raise ValueError(f"{_name(page)}:{i + 1}: <!-- docs: skip --> needs a reason")
                pending_skip = (i + 1, s.group(1))
            elif e:
                if not (after_block and blocks[-1].shell):
                    raise ValueError(f"{_name(page)}:{i + 1}: <!-- expect: --> must follow a shell block")
                blocks[-1].expect.extend(e.group(1).split())
            elif lines[i].strip():
                after_block = False
            i += 1
            continue
        indent, fence, language = m.group(1), m.group(2), m.group(3).lower()
        start = i
        body = []
        i += 1
        while i < len(lines) and not lines[i].strip().startswith(fence):
            body.append(lines[i][len(indent):] if lines[i].startswith(indent) else lines[i])
            i += 1
        if i == len(lines):
            raise ValueError(f"{_name(page)}:{start + 1}: the fence is never closed")
        i += 1
        text_ = "\n".join(body)
        shell = is_shell(language, text_)
        if shell:
            number += 1
        skip = None
        if pending_skip is not None:
            if not shell:
                raise ValueError(f"{_name(page)}:{pending_skip[0]}: <!-- docs: skip --> is not followed by a shell "
                                 "block")
            skip = pending_skip[1]
            pending_skip = None
        blocks.append(Block(page, number if shell else 0, start + 1, language, text_, shell, skip))
        after_block = True
    if pending_skip is not None:
        raise ValueError(f"{_name(page)}:{pending_skip[0]}: <!-- docs: skip --> is not followed by a shell block")
    return blocks


def pages(root: Path = ROOT) -> list[Path]:
    """README.md and docs/*.md without the generated pages."""
    return [root / "README.md"] + sorted(p for p in (root / "docs").glob("*.md") if p.name not in GENERATED)


def _shims(folder: Path) -> dict:
    """The environment of a page: ``bayes-rcsa`` and ``python3`` run this checkout's package."""
    folder.mkdir(parents=True, exist_ok=True)
    tool = folder / "bayes-rcsa"
    tool.write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} -m bayes_rcsa "$@"\n', encoding="utf-8")
    py = folder / "python3"
    py.write_text(f'#!/bin/sh\nexec {shlex.quote(sys.executable)} "$@"\n', encoding="utf-8")
    for f in (tool, py):
        f.chmod(0o755)
    env = dict(os.environ)
    env["PATH"] = f"{folder}{os.pathsep}{env.get('PATH', '')}"
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT)] + [p for p in env.get("PYTHONPATH", "").split(os.pathsep) if p])
    env.pop("BAYES_RCSA_QUICK", None)  # the pages say their own settings
    return env


#: Printed before each block's script: on failure, the command bash was running (one line)
_PROLOGUE = ("set -e -o pipefail\n"
             "trap 'echo \"docs-runner-failed-command: $BASH_COMMAND\" >&2' ERR\n")


@dataclass
class Outcome:
    page: Path
    ok: bool
    lines: list[str]
    seconds: float


def _run_block(script: str, cwd: Path, env: dict, timeout: float | None) -> subprocess.CompletedProcess:
    """``bash -c script`` in its own process group, so that a timeout or an interrupt also ends its commands."""
    proc = subprocess.Popen(["bash", "-c", script], cwd=cwd, env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        out, err = proc.communicate(timeout=timeout)
    except BaseException:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGTERM)
        proc.communicate()
        raise
    return subprocess.CompletedProcess(proc.args, proc.returncode, out, err)


def run_page(page: Path, work: Path, timeout: float | None = None, echo=None) -> Outcome:
    """Run the shell blocks of ``page`` in the new folder ``work``; the outcome with one line per block."""
    t0 = time.perf_counter()
    lines: list[str] = []
    try:
        blocks = [b for b in extract_blocks(page) if b.shell]
    except ValueError as exc:
        return Outcome(page, False, [f"FAILED {exc}"], 0.0)
    here = work / "page"
    here.mkdir(parents=True)
    env = _shims(work / "bin")
    state = work / "cwd"
    for b in blocks:
        if b.skip is not None:
            lines.append(f"{b.where}: skipped ({b.skip})")
            continue
        t = time.perf_counter()
        # the working directory carries over to the next block, as in one terminal (a block may `cd`)
        prologue = _PROLOGUE + "trap 'pwd > \"$DOCS_RUNNER_CWD\"' EXIT\n"
        try:
            proc = _run_block(prologue + b.script(), here, {**env, "DOCS_RUNNER_CWD": str(state)}, timeout)
        except subprocess.TimeoutExpired:
            lines.append(f"FAILED {b.where}: did not finish within {timeout:g} s")
            return Outcome(page, False, lines, time.perf_counter() - t0)
        took = time.perf_counter() - t
        if proc.returncode != 0:
            failed = [ln for ln in proc.stderr.splitlines() if ln.startswith("docs-runner-failed-command: ")]
            command = " ".join(failed[-1].split()[1:]) if failed else b.script().strip().splitlines()[0]
            tail = [ln for ln in proc.stderr.splitlines() if not ln.startswith("docs-runner-failed-command: ")][-5:]
            lines.append(f"FAILED {b.where}: `{command}` exited with status {proc.returncode}")
            lines.extend(f"    {ln}" for ln in tail)
            return Outcome(page, False, lines, time.perf_counter() - t0)
        if state.is_file():
            here = Path(state.read_text(encoding="utf-8").strip() or here)
        missing = [p for p in b.expect if not (here / p).exists()]
        if missing:
            lines.append(f"FAILED {b.where}: ran, but did not write {', '.join(missing)} (<!-- expect: --> marker)")
            return Outcome(page, False, lines, time.perf_counter() - t0)
        lines.append(f"{b.where}: ok ({took:.0f} s" + (f"; wrote {', '.join(b.expect)})" if b.expect else ")"))
        if echo:
            echo(lines[-1])
    return Outcome(page, True, lines, time.perf_counter() - t0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="docs/run_docs.py", description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("pages", nargs="*", type=Path, help="pages to run (default: README.md and docs/*.md)")
    ap.add_argument("--list", action="store_true", help="print the shell blocks and their markers; run nothing")
    ap.add_argument("--jobs", type=int, default=1, metavar="N", help="pages run at the same time (default 1)")
    ap.add_argument("--timeout", type=float, default=900.0, metavar="S", help="limit per block in s (default 900)")
    ap.add_argument("--keep", action="store_true", help="keep the pages' folders (printed) for inspection")
    args = ap.parse_args(argv)
    chosen = [p.resolve() for p in args.pages] or pages()
    if args.list:
        status = 0
        for page in chosen:
            try:
                blocks = [b for b in extract_blocks(page) if b.shell]
            except ValueError as exc:
                print(f"FAILED {exc}")
                status = 1
                continue
            for b in blocks:
                mark = f" [skip: {b.skip}]" if b.skip else ""
                expect = f" [expect: {' '.join(b.expect)}]" if b.expect else ""
                print(f"{b.where}{mark}{expect}")
                print("    " + b.script().strip().replace("\n", "\n    "))
        return status
    runnable = [p for p in chosen if any(b.shell for b in _safe_blocks(p))] + [
        p for p in chosen if _broken(p)]
    base = Path(tempfile.mkdtemp(prefix="bayes-rcsa-docs-"))
    t0 = time.perf_counter()
    try:
        def one(item):
            i, page = item
            return run_page(page, base / f"{i:02d}-{page.stem}", args.timeout)

        with ThreadPoolExecutor(max(1, args.jobs)) as pool:
            outcomes = []
            for out in pool.map(one, enumerate(runnable)):
                outcomes.append(out)
                print(f"{_name(out.page)}: {'ok' if out.ok else 'FAILED'} ({out.seconds:.0f} s)", flush=True)
                for ln in out.lines:
                    print(f"  {ln}", flush=True)
    finally:
        if args.keep:
            print(f"docs/run_docs.py: the pages' folders are in {base}")
        else:
            shutil.rmtree(base, ignore_errors=True)
    failed = [o for o in outcomes if not o.ok]
    total = time.perf_counter() - t0
    if failed:
        for o in failed:
            first = next(ln for ln in o.lines if ln.startswith("FAILED"))
            print(f"docs/run_docs.py: {first}", file=sys.stderr)
        return 1
    print(f"docs/run_docs.py: {len(outcomes)} page(s) ran as written in {total:.0f} s")
    return 0


def _safe_blocks(page: Path) -> list[Block]:
    try:
        return extract_blocks(page)
    except ValueError:
        return []


def _broken(page: Path) -> bool:
    try:
        extract_blocks(page)
    except ValueError:
        return True
    return False


if __name__ == "__main__":
    sys.exit(main())
