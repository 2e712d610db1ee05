"""Entry point of the ``bayes-rcsa`` command line.

Every sub-command lives in its own module in this package and exposes
``register(subparsers)``, which adds its parser and sets ``func`` to a
callable ``run(args) -> int``.  Errors derived from
:class:`bayes_rcsa.errors.BayesRCSAError` (and unreadable files) are printed
as one line on stderr with exit status 2, without a traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import re
import sys
import warnings

from .. import __version__
from ..errors import BayesRCSAError
from ._common import check_arguments

__all__ = ["main", "build_parser", "COMMANDS"]

# Order of appearance in --help; each name is a module of bayes_rcsa.cli.
COMMANDS = (
    "demo",
    "simulate",
    "synthesize",
    "spindle",
    "identify",
    "predict",
    "identifiability",
    "lobes",
    "discrepancy",
    "design",
    "report",
    "batch",
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


def build_parser() -> argparse.ArgumentParser:
    parser = _OneLineParser(
        prog="bayes-rcsa",
        description="Bayesian receptance coupling for tool-point FRFs, tool-holder contact identification "
        "and chatter stability.",
    )
    parser.add_argument("--version", action="version", version=f"bayes-rcsa {__version__}")
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
    return parser


@contextlib.contextmanager
def _one_line_warnings(command: str):
    """Show every warning as one ``bayes-rcsa CMD: warning: ...`` line (no source line, no file path)."""

    def show(message, category, filename, lineno, file=None, line=None):
        text = " ".join(str(message).split())
        print(f"bayes-rcsa {command}: warning: {text}", file=sys.stderr if file is None else file)

    with warnings.catch_warnings():
        warnings.showwarning = show
        yield


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    with _one_line_warnings(args.command):
        return _run(args)


def _run(args) -> int:
    try:
        check_arguments(args)
        return int(args.func(args) or 0)
    except BayesRCSAError as exc:
        print(f"bayes-rcsa {args.command}: error: {' '.join(str(exc).split())}", file=sys.stderr)
        return 2
    except (FileNotFoundError, IsADirectoryError, NotADirectoryError, FileExistsError, PermissionError) as exc:
        print(f"bayes-rcsa {args.command}: error: {exc.strerror or exc}: {exc.filename}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"bayes-rcsa {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
