"""The layering of docs/architecture.md holds: no module imports a component its table forbids,
a folder is one component, no two modules import each other in a circle, no module is long.

Every import counts (top level, inside functions, under TYPE_CHECKING). The tables are read from
the page, so the page is the one place the rule lives. ``python tests/test_architecture.py``
prints the graph between components as the code has it.
"""

from __future__ import annotations

import ast
import re
from collections import defaultdict
from functools import cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
PAGE = ROOT / "docs" / "architecture.md"
PACKAGE = "toaster"
MAX_LINES = 600  # a module over this is cut by concern
MAX_TOP = 9  # modules at the package top: the base and the front door


def _table(heading: str) -> list[list[str]]:
    """The cells of the first table under ``## heading`` (header and rule rows skipped)."""
    text = PAGE.read_text(encoding="utf-8")
    section = text.split(f"\n## {heading}\n", 1)[1].split("\n## ", 1)[0]
    rows = [
        line.strip().strip("|").split("|") for line in section.splitlines() if line.startswith("|")
    ]
    return [[cell.strip() for cell in row] for row in rows[2:]]


def _names(cell: str) -> list[str]:
    return re.findall(r"`([\w.]+)`", cell)


@cache
def components() -> tuple[dict[str, str], dict[str, set[str]]]:
    """(module name in the table -> component, component -> components it may import,
    transitively, itself included)."""
    owner: dict[str, str] = {}
    direct: dict[str, set[str]] = {}
    for name, modules, may, *_ in _table("Components"):
        for module in _names(modules):
            assert module not in owner, f"{module} is in two rows of architecture.md"
            owner[module] = name
        direct[name] = {c.strip() for c in may.split(",") if c.strip() not in ("", "—")}
    for name, targets in direct.items():
        unknown = targets - direct.keys()
        assert not unknown, f"architecture.md: {name} may import unknown components {unknown}"
    closure: dict[str, set[str]] = {}

    def reach(name: str, path: tuple[str, ...] = ()) -> set[str]:
        assert name not in path, f"architecture.md: components import in a cycle {(*path, name)}"
        if name not in closure:
            closure[name] = {name}.union(*(reach(t, (*path, name)) for t in direct[name]))
        return closure[name]

    for name in direct:
        reach(name)
    return owner, closure


def exceptions() -> set[tuple[str, str]]:
    return {(_names(a)[0], _names(b)[0]) for a, b, *_ in _table("Exceptions")}


def component_of(module: str) -> str | None:
    """The row whose module name is the longest prefix of ``module`` (``toaster`` only itself)."""
    owner, _ = components()
    for candidate in sorted(owner, key=len, reverse=True):
        if module == candidate or (candidate != PACKAGE and module.startswith(candidate + ".")):
            return owner[candidate]
    return None


def modules() -> dict[str, Path]:
    """Every module of the package, by dotted name."""
    found = {}
    for path in sorted((SRC / PACKAGE).rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts.pop()
        found[".".join(parts)] = path
    return found


def imports(module: str, path: Path, known: set[str]) -> list[tuple[str, int]]:
    """(imported toaster module, line) for every import statement anywhere in the module.
    ``from a import b`` imports ``a.b`` when that is a module, else ``a``."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parent = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join([*parent, *([node.module] if node.module else [])])
            targets = [
                f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names
            ]
        else:
            continue
        found += [(t, node.lineno) for t in targets if t == PACKAGE or t.startswith(PACKAGE + ".")]
    return found


@cache
def edges() -> list[tuple[str, str, str]]:
    """(importer, imported, where) for every import between two toaster modules."""
    found = modules()
    known = set(found)
    return [
        (module, target, f"{path.relative_to(ROOT)}:{line}")
        for module, path in found.items()
        for target, line in imports(module, path, known)
        if target != module
    ]


def test_every_module_is_in_a_component() -> None:
    missing = [m for m in modules() if component_of(m) is None]
    assert not missing, (
        f"modules in no row of docs/architecture.md: {missing} "
        "(add each to the component it belongs to)"
    )


def test_each_folder_is_one_row() -> None:
    """A row names at most one folder, whole, and every folder has its row: the tree is the
    table."""
    owner, _ = components()
    top = SRC / PACKAGE
    folders = {f"{PACKAGE}.{p.parent.name}" for p in top.glob("*/__init__.py")}
    rows: dict[str, list[str]] = defaultdict(list)
    for module, name in owner.items():
        rows[name].append(module)
    for name, named in rows.items():
        inner = [m for m in named if m != PACKAGE and not (top / f"{m.split('.')[-1]}.py").exists()]
        assert len(inner) <= 1 and all(m in folders for m in inner), (
            f"architecture.md: row {name} names {inner}: a row is one folder of src/toaster"
        )
    missing = folders - set(owner)
    assert not missing, f"folders with no row of their own in architecture.md: {sorted(missing)}"


def cycles() -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), over every import."""
    graph: dict[str, set[str]] = defaultdict(set)
    for importer, imported, _ in edges():
        graph[importer].add(imported)
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(graph[node]):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(modules()):
        if node not in index:
            visit(node)
    return found


def test_no_import_cycle() -> None:
    found = cycles()
    assert not found, f"modules that import each other in a circle: {found}"


def test_no_module_over_600_lines() -> None:
    long = {
        name: n
        for name, path in modules().items()
        if (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    }
    assert not long, f"modules over {MAX_LINES} lines (cut each by concern): {long}"


def test_few_modules_at_the_package_top() -> None:
    top = sorted(p.name for p in (SRC / PACKAGE).glob("*.py"))
    assert len(top) <= MAX_TOP, f"{len(top)} modules at the package top (at most {MAX_TOP}): {top}"


def test_no_forbidden_import() -> None:
    _, closure = components()
    allowed = exceptions()
    bad = []
    for importer, imported, where in edges():
        a, b = component_of(importer), component_of(imported)
        if a and b and b not in closure[a] and (importer, imported) not in allowed:
            bad.append(f"{where}: {importer} ({a}) imports {imported} ({b})")
    assert not bad, (
        "imports that docs/architecture.md forbids:\n"
        + "\n".join(bad)
        + "\n(move the code to the right layer, or add the import to the page's"
        " Exceptions table with the reason)"
    )


def test_every_exception_still_occurs() -> None:
    actual = {(a, b) for a, b, _ in edges()}
    stale = exceptions() - actual
    assert not stale, f"docs/architecture.md lists exceptions no module has: {stale}"


def test_exceptions_are_forbidden_imports() -> None:
    _, closure = components()
    for importer, imported in exceptions():
        a, b = component_of(importer), component_of(imported)
        assert a and b and b not in closure[a], (
            f"{importer} -> {imported} is allowed by the components: not an exception"
        )


@pytest.mark.parametrize(
    ("importer", "imported"),
    [
        ("toaster.db.writer.store", "toaster.queries"),  # the store knows no layer above it
        ("toaster.queries.facts", "toaster.beliefs.api"),
        ("toaster.world.state", "toaster.db"),
        ("toaster.beliefs.api", "toaster"),  # nothing inside uses the front door
        ("toaster.node.live_node", "toaster.queries"),
        ("toaster.app.session", "toaster.ros1"),
        ("toaster.node.live_node", "toaster.app"),
        (
            "toaster.migrations.frozen_triggers",
            "toaster.rules",
        ),  # old revisions import no live rule
        ("toaster.world.rosmsg", "toaster.producers"),
    ],
)
def test_the_table_forbids(importer: str, imported: str) -> None:
    """The rule reads as the page says (a page whose table allowed everything would pass)."""
    _, closure = components()
    assert component_of(imported) not in closure[component_of(importer) or ""]


def test_imports_inside_functions_and_relative_ones_are_seen(tmp_path: Path) -> None:
    module = tmp_path / "__init__.py"
    module.write_text(
        "from . import model\n"
        "def f():\n    from toaster.db import store\n    import toaster.cli\n"
        "if True:\n    from .. import queries, connect\n"
    )
    known = {"toaster.beliefs.model", "toaster.db.store", "toaster.queries"}
    found = {t for t, _ in imports("toaster.beliefs", module, known)}
    assert found == {*known, "toaster.cli", "toaster"}


if __name__ == "__main__":
    graph: dict[tuple[str, str], list[str]] = defaultdict(list)
    for importer, imported, where in edges():
        a, b = component_of(importer) or importer, component_of(imported) or imported
        if a != b:
            graph[a, b].append(f"{where} {importer} -> {imported}")
    for (a, b), wheres in sorted(graph.items()):
        print(f"{a} -> {b}: {len(wheres)} imports, e.g. {wheres[0]}")
