"""The package's shape: subpackages that are the pipeline, imports that only run
downwards (counting imports inside functions), no loops, small modules."""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

pytestmark = pytest.mark.once  # the same on both installs: run by `make test` only

PACKAGE = Path(__file__).resolve().parents[1] / "critfric"
# lowest first: a module may import only from its own layer or a lower one
LAYERS = ["_version", "errors", "fem", "guards", "case", "meshing", "solvers", "solve",
          "multiplicity", "stability", "files", "sweep", "plots", "cli", "__main__"]
MAX_LINES = 450
MAX_TOP_MODULES = 6


def _modules() -> dict[str, Path]:
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


MODULES = _modules()


def _imports(name: str, path: Path) -> set[str]:
    """Every critfric module that ``name`` imports, anywhere in its body."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            # `from pkg import module` imports that module
            targets = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in MODULES else mod
                       for a in node.names]
        else:
            continue
        found |= {t for t in targets if t == "critfric" or t.startswith("critfric.")}
    return found


@functools.cache
def import_graph() -> dict[str, set[str]]:
    """module -> the critfric modules it imports (parsed when a test first asks, not when
    the suite is collected)."""
    return {name: _imports(name, path) for name, path in MODULES.items()}


def _stage(module: str) -> str:
    return module.split(".")[1] if module.count(".") else ""


def test_nothing_inside_imports_the_package_root():
    offenders = sorted(n for n, deps in import_graph().items()
                       if n != "critfric" and "critfric" in deps)
    assert offenders == []


@pytest.mark.parametrize("name", sorted(n for n in MODULES if n != "critfric"))
def test_imports_run_downwards(name):
    here = LAYERS.index(_stage(name))
    upward = sorted(d for d in import_graph()[name]
                    if d != "critfric" and LAYERS.index(_stage(d)) > here)
    assert upward == [], f"{name} imports a later stage"


def _cycle(graph: dict[str, set[str]]) -> list[str]:
    state, stack = {}, []

    def visit(node):
        state[node] = 1
        stack.append(node)
        for dep in sorted(graph.get(node, ())):
            if state.get(dep) == 1:
                return stack[stack.index(dep):] + [dep]
            if dep not in state and (found := visit(dep)):
                return found
        state[node] = 2
        stack.pop()
        return []

    for node in sorted(graph):
        if node not in state and (found := visit(node)):
            return found
    return []


def test_no_import_loop_between_modules():
    graph = {n: {d for d in deps if d in MODULES} for n, deps in import_graph().items()}
    assert _cycle(graph) == []


def test_no_import_loop_between_subpackages():
    graph: dict[str, set[str]] = {}
    for name, deps in import_graph().items():
        if name == "critfric":
            continue
        graph.setdefault(_stage(name), set()).update(
            _stage(d) for d in deps if d != "critfric" and _stage(d) != _stage(name))
    assert _cycle(graph) == []


def test_the_package_is_subpackages_with_few_plain_modules():
    top = [p.name for p in PACKAGE.glob("*.py")]
    subpackages = [p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file()]
    assert len(top) <= MAX_TOP_MODULES, top
    assert len(subpackages) >= 5
    assert set(subpackages) | {Path(t).stem for t in top} <= set(LAYERS) | {"__init__",
                                                                            "__main__"}


@pytest.mark.parametrize("name", sorted(MODULES))
def test_modules_read_in_one_sitting(name):
    assert len(MODULES[name].read_text().splitlines()) <= MAX_LINES
