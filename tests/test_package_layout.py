"""The package's layout reads as its data flow: a short top level, and
imports that point one way (no two parts of snn_fg import each other, at the
top level or between the parts of one package), read from the source."""

import ast
from collections import defaultdict
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "snn_fg"
#: most modules and packages at the top of snn_fg/ besides its __init__
TOP_LEVEL_MOST = 16


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(path: Path) -> set[str]:
    """Every snn_fg name ``path`` imports, anywhere in it (inside functions too),
    as a dotted name (``from . import x`` in package p: ``p.x``)."""
    here = module_name(path).split(".")
    package = here if path.name == "__init__.py" else here[:-1]
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            base = package[: len(package) - node.level + 1] if node.level else []
            module = ".".join(base + ([node.module] if node.module else []))
            names |= {f"{module}.{a.name}" for a in node.names}
        elif isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
    return {n for n in names if n.startswith("snn_fg.")}


def unit(name: str, depth: int) -> str | None:
    """The part of snn_fg at ``depth`` (1: top level) that ``name`` lies in, if it is one."""
    parts = name.split(".")
    if len(parts) <= depth:
        return None
    where = PACKAGE.parent.joinpath(*parts[: depth + 1])
    return ".".join(parts[: depth + 1]) if where.is_dir() or where.with_suffix(".py").is_file() else None


def import_graph(depth: int) -> dict[str, set[str]]:
    """Part -> the other parts (of the same package) it imports."""
    graph = defaultdict(set)
    for path in PACKAGE.rglob("*.py"):
        source = unit(module_name(path), depth)
        for name in imported(path):
            target = unit(name, depth)
            if source and target and source != target and source.rsplit(".", 1)[0] == target.rsplit(".", 1)[0]:
                graph[source].add(target)
    return graph


def circles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The groups of parts that import each other (strongly connected, more than one)."""
    reach = {v: set() for v in graph}
    for v in graph:
        todo = list(graph[v])
        while todo:
            w = todo.pop()
            if w not in reach[v]:
                reach[v].add(w)
                todo.extend(graph.get(w, ()))
    groups = {frozenset({v} | {w for w in reach[v] if v in reach.get(w, ())}) for v in graph}
    return [set(g) for g in groups if len(g) > 1]


def test_the_top_level_is_short():
    # a package is a folder with modules in it (a folder left holding only __pycache__ after a move is not)
    top = sorted(
        p.name
        for p in PACKAGE.iterdir()
        if p.name != "__init__.py" and (p.suffix == ".py" or (p.is_dir() and any(p.glob("*.py"))))
    )
    assert 10 <= len(top) <= TOP_LEVEL_MOST, top


@pytest.mark.parametrize("depth", [1, 2], ids=["top level", "within a package"])
def test_imports_point_one_way(depth):
    graph = import_graph(depth)
    assert len(graph) > (8 if depth == 1 else 5)  # (the imports were read)
    assert circles(graph) == []


def test_a_circle_is_found():
    assert circles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [{"a", "b", "c"}]
