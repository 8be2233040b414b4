"""The package's layout (docs/architecture.md): imports run from a later pipeline stage to an
earlier one only, no module imports itself back through others, the top level is the
pipeline, and modules and functions stay small. Imports inside functions count too."""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "hoibench"

#: the stages in import order: a module may import its own stage and earlier ones
STAGES = ("core", "bodies", "representations", "datasets", "text", "metrics", "tracks", "evaluator", "scoring",
          "baselines", "publish", "challenge")
#: modules at the top of the package: the version and entry points, above every stage
TOP_MODULES = {"hoibench", "hoibench.cli", "hoibench.demo"}
MAX_MODULE_LINES = 850
MAX_FUNCTION_LINES = 125


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def _imports(name: str, path: Path, modules: dict[str, Path]) -> set[str]:
    """The package modules ``name`` imports, anywhere in its body."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package[:len(package) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        for t in targets:
            while t not in modules and "." in t:
                t = t.rsplit(".", 1)[0]
            if t in modules and t != name:
                found.add(t)
    return found


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    return {name: _imports(name, path, modules) for name, path in modules.items()}


def _stage(name: str) -> int:
    parts = name.split(".")
    if name in TOP_MODULES:
        return len(STAGES)
    if len(parts) < 2 or parts[1] not in STAGES:
        raise AssertionError(f"{name}: not in a stage folder (stages: {', '.join(STAGES)})")
    return STAGES.index(parts[1])


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circles():
    assert _cycles(_graph()) == []


def test_imports_run_from_later_stages_to_earlier_ones():
    wrong = []
    for name, deps in sorted(_graph().items()):
        for dep in sorted(deps):
            if dep == "hoibench":          # the package root: its version only
                continue
            if _stage(dep) > _stage(name):
                wrong.append(f"{name} -> {dep}")
    assert wrong == []


def test_the_checks_see_a_wrong_way_import_and_a_circle(tmp_path):
    graph = {"hoibench.core.io": {"hoibench.scoring.submission"}, "hoibench.scoring.submission": {"hoibench.core.io"}}
    assert _cycles(graph) == [["hoibench.core.io", "hoibench.scoring.submission"]]
    assert _stage("hoibench.scoring.submission") > _stage("hoibench.core.io")
    src = tmp_path / "m.py"
    src.write_text("def f():\n    from ..scoring import submission\n")
    assert _imports("hoibench.core.m", src, {"hoibench.core.m": src, "hoibench.scoring.submission": src,
                                             "hoibench.scoring": src}) == {"hoibench.scoring.submission"}


def test_the_top_level_is_the_pipeline():
    entries = sorted(p.name for p in PACKAGE.iterdir() if not p.name.startswith((".", "__pycache__")))
    folders = [e for e in entries if (PACKAGE / e).is_dir()]
    files = [e for e in entries if (PACKAGE / e).is_file()]
    assert sorted(folders) == sorted(STAGES)
    assert files == ["__init__.py", "cli.py", "demo.py", "py.typed"]


@pytest.mark.parametrize("limit", [MAX_MODULE_LINES])
def test_modules_and_functions_stay_small(limit):
    long_modules, long_functions = [], []
    for name, path in sorted(_modules().items()):
        text = path.read_text()
        if text.count("\n") > limit:
            long_modules.append(f"{name}: {text.count(chr(10))} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long_functions.append(f"{name}.{node.name}: {n} lines")
    assert long_modules == [] and long_functions == []


def test_old_import_paths_forward_with_a_deprecation_warning():
    import importlib
    import sys
    for old in ("hoibench.store", "hoibench.multibody.metrics"):
        sys.modules.pop(old, None)
    with pytest.warns(DeprecationWarning, match="hoibench.datasets.store"):
        old_store = importlib.import_module("hoibench.store")
    from hoibench.datasets.store import Store
    assert old_store.Store is Store
    with pytest.warns(DeprecationWarning, match="hoibench.metrics.multibody"):
        from hoibench.multibody.metrics import CSR
    from hoibench.metrics.multibody import CSR as new_csr
    assert CSR is new_csr
