"""The scanner of human outputs (stderr, Markdown, HTML) for the unit policy and the vocabulary.

Used by tests/test_human_outputs.py and, on the demo's outputs (made once, there), by tests/test_demo.py:
``offences(text, identifiers)`` lists what a person should not read: an internal identifier (``k_xf``,
``spindle_error``, ``zoa``, ``systematic_relative_residual``; the list comes from the registries), a length in
metres, a float with an exponent (``5.321e-05``), a Python list or tuple of numbers, a ``None``/``nan``
placeholder or a bare "none" item.
"""

from __future__ import annotations

import html as html_lib
import re


def identifiers(parameter_names=()) -> set[str]:
    """The internal names no human output may show: the parameters of a model, every registered term, stability
    method and model-check criterion (from the registries and the vocabulary's tables, not a hand list)."""
    from bayes_rcsa import vocabulary
    from bayes_rcsa.params.terms import TERMS
    from bayes_rcsa.stability.methods import STABILITY_METHODS

    names = set(parameter_names) | set(TERMS.names()) | set(STABILITY_METHODS.names()) | set(vocabulary.identifiers())
    return {n for n in names if n}


def visible_text(page: str) -> str:
    """What a browser shows of an HTML page: no style, script, tags, attributes or embedded images."""
    page = re.sub(r"(?is)<(style|script)\b.*?</\1>", " ", page)
    page = re.sub(r"(?s)<!--.*?-->", " ", page)
    page = re.sub(r"(?s)<[^>]+>", " ", page)
    return html_lib.unescape(page)


def markdown_text(md: str) -> str:
    """The words of a Markdown page without link targets and code spans (paths and commands)."""
    md = re.sub(r"\]\([^)]*\)", "]", md)
    return re.sub(r"`[^`]*`", " ", md)


def _paths_removed(text: str) -> str:
    """``text`` without file paths and file names (``/tmp/x/lobes.json``, ``p_stable.npz``): those are names of
    files, not words."""
    text = re.sub(r"(?<!\w)(?:[\w.-]*/)+[\w.-]*", " ", text)
    return re.sub(r"\b[\w-]+\.(?:json|npz|nc|csv|png|html|md|toml|h5|uff|unv|txt)\b", " ", text)


_CHECKS = (
    ("float with an exponent", re.compile(r"\b\d+(?:\.\d+)?e[-+]?\d+\b", re.I)),
    ("length in metres", re.compile(r"\b\d+(?:\.\d+)?(?:×10[⁰¹²³⁴⁵⁶⁷⁸⁹⁻]+)?\s?m\b(?![/·²³])")),
    ("Python list of numbers", re.compile(r"\[\s*-?\d+(?:\.\d+)?(?:e[-+]?\d+)?\s*,\s*-?\d")),
    ("Python list of strings", re.compile(r"\[\s*'[^']*'\s*[,\]]")),
    ("Python tuple of numbers", re.compile(r"\(\s*-?\d+\.\d+\s*,\s*-?\d+\.\d+\s*\)")),
    ("placeholder", re.compile(r"\bNone\b|\bnan\b|\bNaN\b")),
    ("bare 'none' item", re.compile(r"(?m)^\s*(?:[-*•]\s*)?none\s*$")),
    ("doubled word", re.compile(r"\b(tool|holder|mm|Hz|rpm)\s+\1\b")),
)


def offences(text: str, names) -> list[str]:
    """What a person should not read in ``text`` (plain text: stderr, or the result of :func:`visible_text` /
    :func:`markdown_text`), one line each with its context."""
    text = _paths_removed(text)
    found = []
    for what, rx in _CHECKS:
        for m in rx.finditer(text):
            found.append(f"{what}: {text[max(m.start() - 40, 0):m.end() + 30]!r}")
    for name in sorted(names):
        for m in re.finditer(rf"(?<![\w-]){re.escape(name)}(?![\w-])", text):
            found.append(f"identifier {name}: {text[max(m.start() - 40, 0):m.end() + 30]!r}")
    return found
