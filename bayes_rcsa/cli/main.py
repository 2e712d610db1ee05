"""Entry point of the ``bayes-rcsa`` command line.

Every sub-command lives in its own module in this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a
callable ``run(args)`` returning a :class:`~bayes_rcsa.cli._common.Summary`
(or, for commands not converted yet, an exit status ``int``).  ``main``
prints a Summary the same way for every command: its warnings (and every
warning issued while it ran, which also go into the ``--json`` object) and ONE human
line on stderr (``bayes-rcsa CMD: ...``) and, with ``--json`` (before or
after the command name), ONE JSON object on stdout and nothing else there.
Errors derived from :class:`bayes_rcsa.errors.BayesRCSAError` (and
unreadable files) are printed as one line on stderr with exit status 2,
without a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import importlib
import json
import re
import sys
import textwrap

from .. import __version__
from ..threads import single_threaded_by_default

# before numpy (imported with ._arguments) loads its BLAS: see bayes_rcsa.threads
single_threaded_by_default()

from ..errors import BayesRCSAError, OutputError  # noqa: E402
from ..messages import warning_log  # noqa: E402
from ..vocabulary import in_words  # noqa: E402
from ._arguments import check_lengths_in_metres, join_negative_values  # noqa: E402
from ._common import Summary, check_arguments, command_warnings, merge_warnings  # noqa: E402

__all__ = ["main", "build_parser", "COMMANDS", "HelpFormatter", "HELP_WIDTH"]

#: Columns of every --help text (descriptions, option help, preformatted lists).
HELP_WIDTH = 100

# Order of appearance in --help; each name is a module of bayes_rcsa.cli.
COMMANDS = (
    "demo",
    "example",
    "simulate",
    "synthesize",
    "spindle",
    "identify",
    "predict",
    "identifiability",
    "lobes",
    "update",
    "discrepancy",
    "design",
    "report",
    "batch",
    "library",
)


class _OneLineParser(argparse.ArgumentParser):
    """argparse that reports usage errors on one line (exit status 2).

    Negative numbers in scientific notation (``--kt -790e6``) are taken as
    values, not as unknown options: argparse's own pattern only knows
    ``-790`` and ``-7.9``, and answered "expected one argument".  Whether a
    negative value is meaningful is then said by the option's own check.
    """

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


class HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """One help layout for every command, wrapped to :data:`HELP_WIDTH` columns.

    Descriptions are kept as written where they are preformatted lists (a line
    that starts with spaces, or a blank line between paragraphs), but every
    line is wrapped to the width, continuing with the line's own indentation
    (plus two columns for a ``name   text`` list entry, so the text column
    stays aligned).  A one-paragraph description is filled like argparse's
    default.  Option help is wrapped by argparse itself.
    """

    def __init__(self, prog, indent_increment=2, max_help_position=30, width=None):
        super().__init__(prog, indent_increment, max_help_position, width=HELP_WIDTH if width is None else width)

    def _fill_text(self, text, width, indent):
        text = textwrap.dedent(text).strip("\n")
        if "\n" not in text.strip():
            return textwrap.fill(" ".join(text.split()), width, initial_indent=indent, subsequent_indent=indent)
        out = []
        # consecutive unindented lines are one paragraph of prose: filled as a whole, so that a source line a few
        # characters wider than the help width does not leave one word on a line of its own
        lines, merged = text.splitlines(), []
        for line in lines:
            if merged and line.strip() and not line[:1].isspace() and merged[-1].strip() \
                    and not merged[-1][:1].isspace():
                merged[-1] = merged[-1].rstrip() + " " + line.strip()
            else:
                merged.append(line)
        for line in merged:
            if len(line) + len(indent) <= width or not line.strip():
                out.append(indent + line)
                continue
            lead = len(line) - len(line.lstrip())
            # "  name         text": continue under the text column
            m = re.match(r"^(\s*\S+\s{2,})", line)
            hang = len(m.group(1)) if m and lead > 0 else lead
            out.extend(textwrap.wrap(line.strip(), width, initial_indent=indent + " " * lead,
                                     subsequent_indent=indent + " " * hang))
        return "\n".join(out)


def build_parser() -> argparse.ArgumentParser:
    parser = _OneLineParser(
        prog="bayes-rcsa",
        description="Bayesian receptance coupling for tool-point FRFs, tool-holder contact identification "
        "and chatter stability.",
        formatter_class=HelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"bayes-rcsa {__version__}")
    parser.add_argument("--json", action="store_true", dest="json_global",
                        help="print the closing summary of the command as one JSON object on stdout")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_OneLineParser)
    sub.required = True
    for name in COMMANDS:
        try:
            module = importlib.import_module(f"{__package__}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name == f"{__package__}.{name}":
                continue  # sub-command not part of this build
            raise
        module.register(sub)
    for p in sub.choices.values():
        # the same layout everywhere, whatever formatter_class a command asked for
        p.formatter_class = HelpFormatter
        if "--json" not in p._option_string_actions:
            p.add_argument("--json", action="store_true",
                           help="print the closing summary as one JSON object on stdout (nothing else goes there)")
    return parser


@contextlib.contextmanager
def _one_line_warnings(command: str):
    """Collect every warning as one line (no source line, no file path) for :func:`_report`.

    They are printed as ``bayes-rcsa CMD: warning: ...`` lines when the command
    succeeds and added to its ``--json`` output; after an error only the
    error line is printed (a warning issued on the way to a refusal would
    name a misleading cause).
    """
    with warning_log(echo=False) as buffer:
        yield buffer


#: Set by :func:`_run` when the command failed on the file system (see :func:`_unraisable_as_lines`).
_IO_FAILED: list[bool] = []


@contextlib.contextmanager
def _unraisable_as_lines(command: str):
    """Errors Python cannot raise (a destructor failing, e.g. h5py closing a file on a full disk) as one line each.

    A write that failed on a full or read-only disk leaves file handles whose
    destructors fail again with the same :class:`OSError`; Python would print
    each with a traceback after the one error line.  After a failed command
    (exit status 2) these echoes of the reported failure are dropped;
    anything else is printed as one ``warning:`` line.  Yields a list to which
    the caller appends the exit status.
    """
    seen: list = []
    status: list[int] = []
    previous = sys.unraisablehook, sys.excepthook
    sys.unraisablehook = lambda u: seen.append(u.exc_value)
    # Cython prints a destructor's traceback through sys.excepthook before reporting it as unraisable; nothing
    # else calls the hook while a command runs (its exceptions propagate to _run)
    sys.excepthook = lambda kind, value, tb: seen.append(value)
    try:
        yield status
        if _IO_FAILED:
            # a failed write leaves file handles in reference cycles: their destructors run now, under this hook
            # (only then: a collection costs ~0.1 s in a process holding xarray and arviz)
            gc.collect()
    finally:
        _IO_FAILED.clear()
        sys.unraisablehook, sys.excepthook = previous
    seen = list({id(e): e for e in seen}.values())
    for exc in seen:
        if isinstance(exc, OSError) and status and status[0] == 2:
            continue
        first = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        print(f"bayes-rcsa {command}: warning: ignored error while releasing a resource: {first}", file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(join_negative_values(sys.argv[1:] if argv is None else argv))
    with _one_line_warnings(args.command), _unraisable_as_lines(args.command) as status:
        status.append(_run(args))
    return status[0]


def _run(args) -> int:
    try:
        check_arguments(args)
        check_lengths_in_metres(args)
        result = args.func(args)
        if isinstance(result, Summary):
            return _report(args, result)
        for w in command_warnings():
            print(f"bayes-rcsa {args.command}: warning: {in_words(w)}", file=sys.stderr)
        return int(result or 0)  # a command that prints its own closing lines
    except BayesRCSAError as exc:
        if isinstance(exc, OutputError):
            _IO_FAILED.append(True)
        return _error(args, " ".join(str(exc).split()))
    except OSError as exc:
        _IO_FAILED.append(True)
        # a file or folder the command's own checks did not name (a write site outside io.atomic, a read
        # that failed after the checks): its name and the errno meaning, on one line
        from ..io.atomic import os_error_reason

        where = exc.filename if getattr(exc, "filename", None) is not None else "file system"
        return _error(args, f"{where}: {os_error_reason(exc)}")
    except KeyboardInterrupt:
        print(f"bayes-rcsa {args.command}: interrupted", file=sys.stderr)
        return 130


def _wants_json(args) -> bool:
    return bool(getattr(args, "json", False) or getattr(args, "json_global", False))


def _error(args, message: str) -> int:
    """The one error line on stderr (and, with --json, ``{"command", "error"}`` on stdout); exit status 2."""
    print(f"bayes-rcsa {args.command}: error: {message}", file=sys.stderr)
    if _wants_json(args):
        print(json.dumps({"command": args.command, "error": message}))
    return 2


def _report(args, summary: Summary) -> int:
    """Print ``summary``: warnings and one line on stderr; with --json one JSON object on stdout."""
    # the data-plausibility (and any other) warnings issued on the way, then the command's own
    warns = merge_warnings(command_warnings(), summary.warnings)
    for w in warns:
        print(f"bayes-rcsa {args.command}: warning: {in_words(w)}", file=sys.stderr)
    print(f"bayes-rcsa {args.command}: {' '.join(summary.human.split())}", file=sys.stderr)
    if _wants_json(args):
        data = {"command": args.command, **summary.data, "warnings": warns}
        print(json.dumps(data, default=str, allow_nan=False))
    return summary.status


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
