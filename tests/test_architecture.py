"""The package structure against the layer table of DESIGN.md.

DESIGN.md's fenced ``layers`` block lists the packages and top-level modules of
src/flightid, one layer per line, lowest first. Every ``import`` / ``from … import`` in
src/flightid is read with ``ast`` — at module level, inside functions and under
``if TYPE_CHECKING`` — and the tests check that

(a) every package and top-level module appears in exactly one layer;
(b) no import goes from a lower layer to a higher one (TYPE_CHECKING imports included: an
    annotation naming a higher layer's type is a dependency on it all the same);
(c) the module import graph has no cycle (Tarjan's strongly connected components), lazy
    imports included; imports under ``if TYPE_CHECKING`` are left out here, since they never
    run and so cannot form a circle at import or call time;
(d) no function has a cyclomatic complexity above 25 (radon; skipped without it).

Each failure names the offending import as file:line.
"""

from __future__ import annotations

import ast
import re
import sys
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "flightid"
DESIGN = ROOT / "DESIGN.md"
FACADE = "flightid/__init__"  # the layer table's name for src/flightid/__init__.py
MAX_COMPLEXITY = 25


# ------------------------------------------------------------------------ the layer table


def layer_table(text: str) -> list[tuple[int, list[list[str]]]]:
    """The ``layers`` block of DESIGN.md: [(layer number, [[names], [names], …])], the inner
    lists in order from below (``a → b, c``: [[a], [b, c]]); parenthesised remarks are
    dropped, except ``(later: …)``, whose names are reserved in that layer."""
    block = re.search(r"^```layers\n(.*?)^```", text, re.M | re.S)
    assert block, f"{DESIGN}: no fenced block marked ```layers"
    layers = []
    for line in block.group(1).splitlines():
        match = re.fullmatch(r"\s*L(\d+)\s+(.*)", line)
        if not match:
            continue
        body = match.group(2)
        later = re.findall(r"\(later:([^)]*)\)", body)
        body = re.sub(r"\([^)]*\)", "", body)
        tiers = [[n.strip() for n in tier.split(",") if n.strip()] for tier in body.split("→")]
        for names in later:
            tiers[-1] += [n.strip() for n in names.split(",") if n.strip()]
        layers.append((int(match.group(1)), tiers))
    return layers


def ranks() -> dict[str, tuple[int, int]]:
    """name → (layer, tier within the layer)."""
    out: dict[str, tuple[int, int]] = {}
    for layer, tiers in layer_table(DESIGN.read_text(encoding="utf-8")):
        for tier, names in enumerate(tiers):
            for name in names:
                out.setdefault(name, (layer, tier))
    return out


def units() -> list[str]:
    """The packages and top-level modules of src/flightid, as the layer table names them."""
    names = [FACADE]
    for path in sorted(PACKAGE.iterdir()):
        if path.is_dir() and any(path.glob("*.py")):
            names.append(path.name)
        elif path.suffix == ".py" and path.name != "__init__.py":
            names.append(path.stem)
    return names


def unit_of(module: str) -> str:
    """The package or top-level module a dotted module name belongs to."""
    parts = module.split(".")
    return FACADE if len(parts) == 1 else parts[1]


# ------------------------------------------------------------------------------- imports


@dataclass(frozen=True)
class Import:
    source: str  # importing module, dotted
    target: str  # imported module of flightid, dotted
    path: Path
    line: int
    type_checking: bool

    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"


def modules() -> dict[str, tuple[Path, bool]]:
    """Dotted module name → (file, is a package's __init__)."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
        is_package = parts[-1] == "__init__"
        if is_package:
            parts = parts[:-1]
        out[".".join(parts)] = (path, is_package)
    return out


def _type_checking_nodes(tree: ast.AST) -> set[int]:
    """ids of the nodes inside ``if TYPE_CHECKING:`` bodies."""
    inside = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            for statement in node.body:
                inside.update(id(n) for n in ast.walk(statement))
    return inside


def _targets(node: ast.AST, module: str, is_package: bool, known: dict) -> list[str]:
    """The flightid modules an import statement imports (``from m import x`` imports the
    module m.x where it is one, else m)."""
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    else:
        base = module if is_package else module.rpartition(".")[0]
        for _ in range(node.level - 1):
            base = base.rpartition(".")[0]
        parent = (base + "." + node.module if node.module else base) if node.level else node.module
        names = [
            f"{parent}.{alias.name}" if f"{parent}.{alias.name}" in known else parent
            for alias in node.names
        ]
    out = []
    for name in names:
        if name != "flightid" and not name.startswith("flightid."):
            continue
        while name not in known and "." in name:
            name = name.rpartition(".")[0]
        out.append(name)
    return out


def imports() -> list[Import]:
    """Every import of a flightid module in src/flightid, once per statement and target."""
    known = modules()
    found: dict[Import, None] = {}
    for module, (path, is_package) in known.items():
        tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
        guarded = _type_checking_nodes(tree)
        for node in ast.walk(tree):
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                for target in _targets(node, module, is_package, known):
                    found[Import(module, target, path, node.lineno, id(node) in guarded)] = None
    return list(found)


def strongly_connected(graph: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's strongly connected components with more than one node (or a self-loop)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components = []
    counter = [0]
    sys.setrecursionlimit(max(sys.getrecursionlimit(), 10 * len(graph) + 1000))

    def visit(v: str) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in graph.get(v, ()):
                components.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return components


# --------------------------------------------------------------------------------- tests


def test_the_layer_table_parses_as_written():
    table = layer_table(DESIGN.read_text(encoding="utf-8"))
    assert [layer for layer, _ in table] == list(range(13))
    names = dict(table)
    assert names[1] == [["data"], ["logs", "examples"]]
    assert names[8] == [["compat", "design", "export", "globalmodel"]]
    assert names[12] == [["cli", "paper", FACADE]]


def test_every_package_is_in_exactly_one_layer():
    table = layer_table(DESIGN.read_text(encoding="utf-8"))
    listed = [name for _, tiers in table for names in tiers for name in names]
    twice = sorted({name for name in listed if listed.count(name) > 1})
    assert not twice, f"DESIGN.md names these in more than one layer: {twice}"
    missing = [name for name in units() if name not in listed]
    assert not missing, f"packages or modules of src/flightid in no layer of DESIGN.md: {missing}"


def test_no_import_goes_up_a_layer():
    rank = ranks()
    upward = []
    for found in imports():
        source, target = unit_of(found.source), unit_of(found.target)
        if source == target or source not in rank or target not in rank:
            continue
        if rank[target] > rank[source]:
            guard = " (under TYPE_CHECKING)" if found.type_checking else ""
            upward.append(
                f"{found.where()}: {found.source} (L{rank[source][0]} {source}) imports "
                f"{found.target} (L{rank[target][0]} {target}){guard}"
            )
    assert not upward, f"{len(upward)} imports go up a layer:\n" + "\n".join(upward)


def _cycles(key, culprit=lambda source, target: True) -> list[str]:
    """The cycles of the import graph over ``key(module)`` nodes, each with its edges for
    which ``culprit(source node, target node)`` holds."""
    graph: dict[str, set[str]] = defaultdict(set)
    edges: dict[tuple[str, str], list[Import]] = defaultdict(list)
    for found in imports():
        source, target = key(found.source), key(found.target)
        if found.type_checking or source == target:
            continue
        graph[source].add(target)
        edges[(source, target)].append(found)
    messages = []
    for component in strongly_connected(graph):
        members = set(component)
        lines = [
            f"  {e.where()}: {e.source} → {e.target}"
            for (a, b), found in sorted(edges.items())
            if a in members and b in members and culprit(a, b)
            for e in found
        ]
        messages.append(f"cycle {' ↔ '.join(component)}:\n" + "\n".join(lines))
    return messages


def test_the_module_import_graph_has_no_cycle():
    cycles = _cycles(lambda module: module)
    assert not cycles, f"{len(cycles)} import cycles between modules:\n" + "\n".join(cycles)


def test_the_package_import_graph_has_no_cycle():
    """Peers of one layer may import one another, but not in a circle; each cycle lists its
    imports that do not go down a layer (those that do are not to blame)."""
    rank = ranks()
    cycles = _cycles(unit_of, lambda a, b: rank.get(b, (99, 0)) >= rank.get(a, (99, 0)))
    assert not cycles, f"{len(cycles)} import cycles between packages:\n" + "\n".join(cycles)


def test_the_checks_see_lazy_imports_and_cycles(tmp_path):
    """The reader finds an import inside a function, and Tarjan finds a three-cycle."""
    tree = ast.parse("def f():\n    from flightid.simulation import simulate\n")
    node = tree.body[0].body[0]
    known = {"flightid.simulation": None, "flightid.model.check": None}
    assert _targets(node, "flightid.model.check", False, known) == ["flightid.simulation"]
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert strongly_connected(graph) == [["a", "b", "c"]]
    assert strongly_connected({"a": {"b"}, "b": set()}) == []


# ---------------------------------------------------------------------------- complexity


def _blocks(block):
    """A radon block and the functions nested in it (methods, closures)."""
    yield block
    for inner in [*getattr(block, "methods", ()), *getattr(block, "closures", ())]:
        yield from _blocks(inner)


def test_no_function_is_more_complex_than_25():
    complexity = pytest.importorskip("radon.complexity")
    above = []
    for path in sorted(PACKAGE.rglob("*.py")):
        for top in complexity.cc_visit(path.read_text(encoding="utf-8")):
            for block in _blocks(top):
                if type(block).__name__ == "Class":
                    continue
                if block.complexity > MAX_COMPLEXITY:
                    name = getattr(block, "fullname", block.name)
                    above.append(
                        f"{path.relative_to(ROOT)}:{block.lineno}: {name} {block.complexity}"
                    )
    assert not above, f"functions above complexity {MAX_COMPLEXITY}:\n" + "\n".join(above)
