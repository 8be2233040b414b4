"""The package's layout (docs/architecture.md): imports run from a later pipeline stage to an
earlier one only, no module imports itself back through others, the top level is the
pipeline, and modules and functions stay small. Imports inside functions count too."""
from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parent.parent / "hoibench"

#: the stages in import order: a module may import its own stage and earlier ones
STAGES = ("core", "bodies", "representations", "datasets", "text", "metrics", "tracks", "evaluator", "scoring",
          "audit", "baselines", "publish", "challenge", "commands")
#: modules at the top of the package: the version and entry points (cli, the command modules it
#: dispatches to, the demo), above every stage
TOP_MODULES = {"hoibench", "hoibench.cli", "hoibench.demo", "hoibench.commands"} | {
    f"hoibench.commands.{p.stem}" for p in (PACKAGE / "commands").glob("*.py") if p.stem != "__init__"}
MAX_MODULE_LINES = 800
#: imports the checks let pass for now, each in a file rewritten elsewhere: (importer, imported) -> where and why
MAX_FUNCTION_LINES = 125


def _modules(package: Path = PACKAGE) -> dict[str, Path]:
    out = {}
    for path in package.rglob("*.py"):
        parts = list(path.relative_to(package.parent).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


#: a ``"module:attr"`` reference (``load_object``, registries, entry points): absolute, or
#: relative to the package of the module holding it when it starts with dots
_REFERENCE = re.compile(r"(\.*)((?:[A-Za-z_]\w*)(?:\.[A-Za-z_]\w*)*)?:[A-Za-z_]\w*")
#: calls that import the module their first argument names
_IMPORT_CALLS = ("import_module", "__import__")


def _absolute(target: str, package: list[str]) -> str | None:
    """``target`` with its leading dots resolved against ``package`` (None when it climbs out)."""
    level = len(target) - len(target.lstrip("."))
    if not level:
        return target
    if level > len(package):
        return None
    rest = target[level:]
    return ".".join(package[:len(package) - level + 1] + ([rest] if rest else []))


def _constants(tree: ast.Module) -> dict[str, str]:
    """Module-level ``NAME = "string"`` assignments (read in f-string references)."""
    out = {}
    for node in tree.body:
        if isinstance(node, ast.Assign) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            out.update({t.id: node.value.value for t in node.targets if isinstance(t, ast.Name)})
    return out


def _literal(node: ast.AST | None, constants: dict[str, str]) -> str | None:
    """The string ``node`` spells: a literal, a module-level string constant, or an f-string of
    those (None for anything computed at run time)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return node.value
    if isinstance(node, ast.Name):
        return constants.get(node.id)
    if isinstance(node, ast.JoinedStr):
        parts = [_literal(v.value if isinstance(v, ast.FormattedValue) and v.format_spec is None and
                          v.conversion == -1 else v, constants) for v in node.values]
        return None if None in parts else "".join(parts)
    return None


def _call_target(node: ast.Call, name: str, package: list[str], constants: dict[str, str]) -> str | None:
    """The module an ``import_module(name, package)`` / ``__import__(name, ..., level)`` call
    with a literal name imports (None when the name is computed)."""
    func = node.func
    called = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else None
    if called not in _IMPORT_CALLS or not node.args:
        return None
    target = _literal(node.args[0], constants)
    if target is None:
        return None
    keywords = {k.arg: k.value for k in node.keywords}
    if called == "__import__":
        level = node.args[4] if len(node.args) > 4 else keywords.get("level")
        dots = level.value if isinstance(level, ast.Constant) and isinstance(level.value, int) else 0
        return _absolute("." * dots + target, package)
    anchor = node.args[1] if len(node.args) > 1 else keywords.get("package")
    if not target.startswith("."):
        return target
    if isinstance(anchor, ast.Name) and anchor.id == "__package__":
        return _absolute(target, package)
    if isinstance(anchor, ast.Name) and anchor.id == "__name__":
        return _absolute(target, name.split("."))
    anchor_name = _literal(anchor, constants)
    return _absolute(target, anchor_name.split(".")) if anchor_name else None


def _imports(name: str, path: Path, modules: dict[str, Path], strings: bool = True) -> set[str]:
    """The package modules ``name`` imports, anywhere in its body: ``import`` statements,
    ``import_module`` / ``__import__`` calls with a literal name, and (``strings``)
    ``"module:attr"`` strings (absolute, or relative with leading dots) that name a package
    module: a registry's lazy reference, imported when the entry is used."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    tree = ast.parse(path.read_text())
    constants = _constants(tree)
    found = set()
    for node in ast.walk(tree):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = ".".join(package[:len(package) - node.level + 1] + ([node.module] if node.module else []))
            else:
                base = node.module or ""
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in modules else base for a in node.names]
        elif isinstance(node, ast.Call):
            targets = [_call_target(node, name, package, constants)]
        elif strings and isinstance(node, (ast.Constant, ast.JoinedStr)):
            text = _literal(node, constants)
            match = _REFERENCE.fullmatch(text) if text else None
            if match and match.group(2) is not None:
                targets = [_absolute(text.partition(":")[0], package)]
            elif match and match.group(1):            # ".:attr": the package itself
                targets = [_absolute(match.group(1), package)]
        for t in targets:
            if t is None:
                continue
            while t not in modules and "." in t:
                t = t.rsplit(".", 1)[0]
            if t in modules and t != name:
                found.add(t)
    return found


def _graph(package: Path = PACKAGE, strings: bool = True) -> dict[str, set[str]]:
    """Module -> the package modules it imports (with ``strings``: its lazy ``module:attr``
    references too)."""
    modules = _modules(package)
    return {name: _imports(name, path, modules, strings) for name, path in modules.items()}


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
    """Over what runs: import statements and importlib calls. A ``module:attr`` reference is
    resolved when its registry entry is used, never while a module imports, so a registry
    may name the modules that register themselves in it (the stage order still holds for
    references: :func:`test_imports_run_from_later_stages_to_earlier_ones`)."""
    assert _cycles(_graph(strings=False)) == []


def _wrong_way(graph: dict[str, set[str]]) -> list[str]:
    """``importer -> imported`` for every import of a later stage by an earlier one."""
    wrong = []
    for name, deps in sorted(graph.items()):
        for dep in sorted(deps):
            if dep == "hoibench":          # the package root: its version only
                continue
            if _stage(dep) > _stage(name):
                wrong.append(f"{name} -> {dep}")
    return wrong


def test_imports_run_from_later_stages_to_earlier_ones():
    assert _wrong_way(_graph()) == []


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


def _write(root: Path, files: dict[str, str]) -> Path:
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text)
    return root / "hoibench"


def test_the_checks_see_importlib_calls_and_module_attr_references(tmp_path):
    package = _write(tmp_path, {
        "hoibench/__init__.py": "",
        "hoibench/core/__init__.py": "",
        "hoibench/core/a.py": "import importlib\n\ndef f():\n    return importlib.import_module('.b', __package__)\n",
        "hoibench/core/b.py": "def g():\n    return __import__('hoibench.core.a')\n",
        "hoibench/core/c.py": "from importlib import import_module\n\ndef h(name):\n    return import_module(name)\n",
        "hoibench/core/d.py": "import importlib\nM = importlib.import_module('..metrics.m', package='hoibench.core')\n",
        "hoibench/metrics/__init__.py": "from .m import X\nREG = {'x': 'hoibench.evaluator.e:load'}\n",
        "hoibench/metrics/m.py": "X = 1\n",
        "hoibench/evaluator/__init__.py": "",
        "hoibench/evaluator/e.py": "_M = 'hoibench.metrics.m'\nREF = f'{_M}:X'\nNOTE = 'hand:left'\n",
        "hoibench/evaluator/f.py": "import importlib\nE = importlib.import_module('.e', __name__.rpartition('.')[0])\n",
    })
    graph = _graph(package)
    assert graph["hoibench.core.a"] == {"hoibench.core.b"} and graph["hoibench.core.b"] == {"hoibench.core.a"}
    assert graph["hoibench.core.c"] == set()                           # a computed name is not seen
    assert graph["hoibench.core.d"] == {"hoibench.metrics.m"}
    assert graph["hoibench.evaluator.e"] == {"hoibench.metrics.m"}       # f-string of a module constant
    assert graph["hoibench.evaluator.f"] == set()                      # a computed package is not seen
    assert _cycles(graph) == [["hoibench.core.a", "hoibench.core.b"]]
    assert _wrong_way(graph) == ["hoibench.core.d -> hoibench.metrics.m",
                                 "hoibench.metrics -> hoibench.evaluator.e"]
    assert _cycles(_graph(package, strings=False)) == [["hoibench.core.a", "hoibench.core.b"]]   # importlib runs
    lazy = _write(tmp_path / "lazy", {"hoibench/__init__.py": "", "hoibench/core/__init__.py": "",
                                      "hoibench/core/reg.py": "ENTRIES = {'x': 'hoibench.core.impl:X'}\n",
                                      "hoibench/core/impl.py": "from .reg import ENTRIES\nX = 1\n"})
    assert _cycles(_graph(lazy)) != [] and _cycles(_graph(lazy, strings=False)) == []


def test_old_import_paths_are_gone():
    import importlib
    for old in ("hoibench.store", "hoibench.multibody.metrics"):
        with pytest.raises(ModuleNotFoundError, match=old.rsplit(".", 1)[0]):
            importlib.import_module(old)
