"""The package's layers: no import cycle between its modules, and no import from a lower layer
into a higher one.

Each module's imports are read with :mod:`ast` (nothing is imported): ``import`` and
``from ... import`` statements anywhere in the module, at the top or inside a function (an
import deferred into a function is still a dependency, and a cycle deferred that way is still a
cycle). Imports under ``if TYPE_CHECKING:`` are left out: they are annotations, never run.
An import of a package is an edge to its ``__init__``; ``from pkg import name`` is an edge to
the submodule ``pkg.name`` when there is one, else to ``pkg``.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

import pytest

import fricbench

ROOT = Path(fricbench.__file__).parent
PACKAGE = "fricbench"

# layer -> the layers it must never import
FORBIDDEN = {
    "axis": ("bench", "compensators", "predictors", "sysid"),
    "friction": ("bench", "compensators", "predictors", "sysid"),
    "trajectories": ("bench", "compensators", "predictors", "sysid"),
    "compensators": ("bench",),
    "predictors": ("bench",),
}

def _module_names() -> dict[str, Path]:
    names = {}
    for path in sorted(ROOT.rglob("*.py")):
        parts = path.relative_to(ROOT.parent).with_suffix("").parts
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return names


MODULES = _module_names()


def _is_type_checking(test: ast.expr) -> bool:
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING")


def _import_nodes(body: list[ast.stmt]) -> Iterator[ast.Import | ast.ImportFrom]:
    """Every import statement in ``body``, at any depth, except under ``if TYPE_CHECKING``."""
    for node in body:
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            yield node
            continue
        if isinstance(node, ast.If) and _is_type_checking(node.test):
            yield from _import_nodes(node.orelse)
            continue
        for field in ("body", "orelse", "finalbody", "handlers", "cases"):
            for child in getattr(node, field, None) or ():
                if isinstance(child, ast.stmt):
                    yield from _import_nodes([child])
                elif isinstance(child, (ast.ExceptHandler, ast.match_case)):
                    yield from _import_nodes(child.body)


def _owner(name: str) -> str | None:
    """The module of the package that ``name`` lives in (the longest known prefix)."""
    while name:
        if name in MODULES:
            return name
        name = name.rpartition(".")[0]
    return None


def imports_of(module: str) -> set[str]:
    """The package's modules that ``module`` imports (not counting itself)."""
    path = MODULES[module]
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found: set[str] = set()
    for node in _import_nodes(tree.body):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        else:
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([node.module] if node.module else []))
            else:
                source = node.module or ""
            targets = [f"{source}.{alias.name}" if f"{source}.{alias.name}" in MODULES
                       else source for alias in node.names]
        for target in targets:
            if target.split(".")[0] == PACKAGE and (owner := _owner(target)) not in (None, module):
                found.add(owner)  # type: ignore[arg-type]
    return found


GRAPH = {module: imports_of(module) for module in MODULES}


def cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[frozenset[str]] = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = len(index)
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                if len(component) > 1:
                    found.append(frozenset(component))
    return found


def _layer(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else ""


def test_the_graph_sees_the_imports_it_should() -> None:
    # a top-level import, one deferred into a function, one under TYPE_CHECKING (left out)
    assert "fricbench.axis.sections" in GRAPH["fricbench.axis.linear"]
    assert "fricbench.axis.plant" in GRAPH["fricbench.axis.linear"]
    assert "fricbench.axis.params" not in GRAPH["fricbench.axis.linear"]
    assert "fricbench.compensators.train" in GRAPH["fricbench.compensators.command"]
    assert len(MODULES) > 100


def test_cycles_are_found() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": {"e"}}
    assert cycles(graph) == [frozenset("abc")]


def test_no_import_cycle_inside_the_package() -> None:
    found = [sorted(c) for c in cycles(GRAPH)]
    assert not found, f"import cycles: {found}"


@pytest.mark.parametrize("layer", sorted(FORBIDDEN))
def test_no_upward_import(layer: str) -> None:
    upward = sorted(f"{module} -> {target}" for module, targets in GRAPH.items()
                    if _layer(module) == layer for target in targets
                    if _layer(target) in FORBIDDEN[layer])
    assert not upward, f"{layer}/ imports a layer above it: {upward}"


def test_the_core_modules_import_no_subpackage() -> None:
    # run, units, registry, ...: below every sub-package (the CLI and the package's __init__
    # sit on top of everything)
    core = [m for m, path in MODULES.items() if m.count(".") == 1 and path.name != "__init__.py"
            and m != "fricbench.cli"]
    assert "fricbench.run" in core and "fricbench.units" in core
    upward = sorted(f"{module} -> {target}" for module in core for target in GRAPH[module]
                    if target.count(".") > 1 or MODULES[target].name == "__init__.py")
    assert not upward, f"core modules import a sub-package: {upward}"
