"""The room map: import layers of the packages, no cycles, no private names across packages (docs/architecture.md)."""

from __future__ import annotations

import ast
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "bayes_rcsa"

#: Layer of every top-level part of the package; a module may import from its own or a lower layer only.
LAYERS = {
    "errors": 0, "registry": 0, "messages": 0, "stats": 0, "units": 0, "vocabulary": 0, "threads": 0, "caching": 0,
    "model": 1,
    "io": 2, "synthetic": 2, "spindle": 2,
    "params": 3, "store": 3,
    "inference": 4,
    "posterior": 5, "stability": 5, "discrepancy": 5, "design": 5,
    "report": 6, "batch": 6, "cuts": 6, "library": 6,
    "workflows": 7,
    "cli": 8, "__main__": 9,
}


def _part(parts: tuple[str, ...]) -> str:
    """Top-level part (subpackage or module) of ``bayes_rcsa.<part>...``."""
    return parts[1] if len(parts) > 1 else "<root>"


def _imports():
    """(importing part, imported part, imported module, names, file) for every import of the package's modules."""
    out = []
    for f in sorted(PACKAGE.rglob("*.py")):
        rel = f.relative_to(ROOT).with_suffix("").parts
        is_init = rel[-1] == "__init__"
        mod = rel[:-1] if is_init else rel
        me = _part(mod) if len(mod) > 1 else "<root>"
        for node in ast.walk(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = list(mod if is_init else mod[:-1])
                    base = base[: len(base) - (node.level - 1)]
                    target = tuple(base + (node.module.split(".") if node.module else []))
                else:
                    target = tuple((node.module or "").split("."))
                names = [a.name for a in node.names]
            elif isinstance(node, ast.Import):
                for a in node.names:
                    t = tuple(a.name.split("."))
                    if t[0] == "bayes_rcsa":
                        out.append((me, _part(t), t, [], f))
                continue
            else:
                continue
            if target and target[0] == "bayes_rcsa":
                out.append((me, _part(target), target, names, f))
    return out


def test_inference_does_not_import_posterior_in_a_fresh_interpreter():
    code = ("import sys, bayes_rcsa.inference; assert 'bayes_rcsa.posterior' not in sys.modules, 'posterior'; "
            "import bayes_rcsa.posterior; assert 'bayes_rcsa.stability' not in sys.modules, 'stability'")
    res = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]


def test_the_command_line_parser_imports_no_numerical_library():
    """Building ``bayes-rcsa``'s parser (every start of the command: ``--help``, a refused argument) registers every
    sub-command; a module imported only for a default shown in a help text made each start take 1.2-1.6 s instead of
    0.3 s (the library command imported stage 2's sampler, numba and scipy.optimize for its ``--max-steps``)."""
    heavy = ("numba", "scipy", "matplotlib", "emcee", "arviz", "h5py", "xarray", "dask", "pyuff", "corner")
    code = ("import sys; from bayes_rcsa.cli.main import build_parser; build_parser(); "
            f"print(sorted({{m.split('.')[0] for m in sys.modules}} & set({heavy!r})))")
    res = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    assert res.stdout.strip() == "[]", res.stdout
    from bayes_rcsa.library.defaults import STAGE2_MAX_STEPS
    from bayes_rcsa.library.stage2 import Stage2Settings

    assert Stage2Settings().max_steps == STAGE2_MAX_STEPS


def test_no_import_cycle_between_packages_and_layers_respected():
    edges = defaultdict(set)
    wrong = []
    for me, other, target, _, f in _imports():
        if other == me or me == "<root>" or other == "<root>":
            continue
        edges[me].add(other)
        if other == "data":
            continue
        if me in LAYERS and other in LAYERS and LAYERS[other] > LAYERS[me]:
            wrong.append(f"{f.relative_to(ROOT)} ({me}) imports {'.'.join(target)} ({other}, a higher layer)")
    assert not wrong, "\n".join(wrong)
    # no cycle of any length between parts (depth-first search)
    state: dict[str, int] = {}

    def visit(node, path):
        state[node] = 1
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == 1:
                pytest.fail(f"import cycle: {' -> '.join(path[path.index(nxt):] + [nxt])}")
            if nxt not in state:
                visit(nxt, path + [nxt])
        state[node] = 2

    for node in sorted(edges):
        if node not in state:
            visit(node, [node])
    assert set(edges) - set(LAYERS) <= {"<root>"}, f"parts without a layer: {set(edges) - set(LAYERS)}"


def test_no_private_names_imported_from_another_package():
    bad = []
    for me, other, target, names, f in _imports():
        if other == me or other in ("<root>",):
            continue
        private_module = [p for p in target[2:] if p.startswith("_") and p != "__init__"]
        private_names = [n for n in names if n.startswith("_")]
        if private_module or private_names:
            bad.append(f"{f.relative_to(ROOT)} imports {'.'.join(target)} {private_names or ''}")
    assert not bad, "\n".join(bad)


# ----------------------------------------------------------------------------------------------------------------
# The command line is a thin shell over bayes_rcsa.workflows (issue #41)

CLI = PACKAGE / "cli"
#: modules of cli/ that are not sub-commands (shared parsing, the program itself)
CLI_SHARED = {"__init__", "_common", "_arguments", "main"}
#: what a sub-command may import outside ``register`` (which may also import constants and registries for its help)
CLI_ALLOWED = {("workflows",), ("errors",), ("messages",), ("cli", "_common"), ("cli", "_arguments")}
#: lines of code (no docstring, comments or blank lines) of a sub-command's ``run``
RUN_BUDGET = 40


def _command_modules():
    return sorted(f for f in CLI.glob("*.py") if f.stem not in CLI_SHARED)


def _absolute(f: Path, node: ast.ImportFrom) -> tuple[str, ...]:
    base = list(f.relative_to(ROOT).with_suffix("").parts[:-1])
    if node.level:
        base = base[: len(base) - (node.level - 1)]
        return tuple(base + (node.module.split(".") if node.module else []))
    return tuple((node.module or "").split("."))


def _code_lines(func: ast.FunctionDef, source: list[str]) -> int:
    body = func.body
    if body and isinstance(body[0], ast.Expr) and isinstance(getattr(body[0], "value", None), ast.Constant):
        body = body[1:]  # the docstring
    if not body:
        return 0
    lines = source[body[0].lineno - 1: func.end_lineno]
    return sum(1 for ln in lines if ln.strip() and not ln.strip().startswith("#"))


def test_no_command_module_imports_another_command():
    commands = {f.stem for f in _command_modules()}
    bad = []
    for f in _command_modules():
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.ImportFrom):
                target = _absolute(f, node)
                names = [a.name for a in node.names]
                hit = ({target[2]} if target[:2] == ("bayes_rcsa", "cli") and len(target) > 2 else set()) | (
                    set(names) if target == ("bayes_rcsa", "cli") else set())
                if hit & commands - {f.stem}:
                    bad.append(f"{f.name} imports cli.{sorted(hit & commands)}")
    assert not bad, "\n".join(bad)


def test_every_command_run_only_parses_calls_a_workflow_and_prints():
    """Outside ``register``, a sub-command imports only the workflows, errors and the shared parsing modules, and its
    ``run`` fits the budget: the job (checks of values, domain objects, files) lives in ``bayes_rcsa.workflows``."""
    bad = []
    for f in _command_modules():
        text = f.read_text()
        tree = ast.parse(text)
        source = text.splitlines()
        register = next((n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "register"), None)
        inside_register = set(map(id, ast.walk(register))) if register is not None else set()
        for node in ast.walk(tree):
            if id(node) in inside_register or not isinstance(node, (ast.Import, ast.ImportFrom)):
                continue
            if isinstance(node, ast.Import):
                mods = [tuple(a.name.split(".")) for a in node.names]
            else:
                mods = [_absolute(f, node)]
            for m in mods:
                if m[0] != "bayes_rcsa":
                    continue
                if not any(m[1:1 + len(a)] == a for a in CLI_ALLOWED):
                    bad.append(f"{f.name}:{node.lineno} imports {'.'.join(m)}")
        run = next((n for n in tree.body if isinstance(n, ast.FunctionDef) and n.name == "run"), None)
        if run is None:
            bad.append(f"{f.name}: no run()")
        elif _code_lines(run, source) > RUN_BUDGET:
            bad.append(f"{f.name}: run() has {_code_lines(run, source)} lines of code (budget {RUN_BUDGET})")
    assert not bad, "\n".join(bad)


def test_every_workflow_is_public_from_the_top_level_and_returns_a_result():
    import inspect

    import bayes_rcsa
    from bayes_rcsa import workflows
    from bayes_rcsa.workflows.result import Result

    for name in workflows.EXPORTS:
        if name == "Result":
            continue
        obj = getattr(bayes_rcsa, name)
        assert obj is getattr(workflows, name), name
        if inspect.isclass(obj):
            assert issubclass(obj, Result), name
            for method in ("to_dict", "save", "load", "headline", "summary_line"):
                assert getattr(obj, method) is not getattr(Result, method), f"{name}.{method} is not implemented"
        else:
            ret = inspect.signature(obj).return_annotation
            ret = getattr(workflows, ret) if isinstance(ret, str) else ret
            assert inspect.isclass(ret) and issubclass(ret, Result), f"{name} returns {ret!r}, not a Result"
