"""The shape of the code: no module over 500 lines, no import cycle between rhi modules, docs/design.md true.

The import graph is read with `ast` from the source (nothing is imported): an edge A → B for every
``import rhi.B`` / ``from rhi.B import x`` / ``from rhi import B`` in A, at module level *and* inside
functions (a deferred import still ties the modules together; hiding an edge in a function does not
break a cycle). ``if TYPE_CHECKING:`` imports never run, but a cycle through them still ties the modules'
types together: the graph with them has no cycle either.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src"
MAX_LINES = 500


def modules() -> dict[str, Path]:
    """{dotted name: path} of every module in src/rhi (packages by their ``__init__``)."""
    out = {}
    for p in sorted((SRC / "rhi").rglob("*.py")):
        parts = p.relative_to(SRC).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = p
    return out


def _type_checking_block(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def _imports(tree: ast.AST, name: str, is_package: bool, known: set[str], *, type_checking: bool = False) -> set[str]:
    """The rhi modules imported anywhere in `tree` (module `name`), resolved to the longest known module.

    ``if TYPE_CHECKING:`` imports count only with `type_checking`.
    """
    found: set[str] = set()
    skip: set[int] = set()
    for node in ast.walk(tree):
        if not type_checking and _type_checking_block(node):
            skip.update(id(n) for n in ast.walk(node))
    for node in ast.walk(tree):
        if id(node) in skip:
            continue
        targets: list[str] = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = name.split(".") if is_package else name.split(".")[:-1]
                pkg = pkg[: len(pkg) - (node.level - 1)]
                base = ".".join([*pkg, base] if base else pkg)
            # `from pkg import sub` depends on the submodule; `from mod import name` on the module
            targets = [f"{base}.{a.name}" if f"{base}.{a.name}" in known else base for a in node.names]
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name and t.startswith("rhi"):
                found.add(t)
    return found


def import_graph(*, type_checking: bool = False) -> dict[str, set[str]]:
    """{module: rhi modules it imports}, package ``__init__`` re-exports included; ``TYPE_CHECKING`` ones too if asked."""
    mods = modules()
    known = set(mods)
    graph = {}
    for name, path in mods.items():
        graph[name] = _imports(ast.parse(path.read_text()), name, path.name == "__init__.py", known,
                               type_checking=type_checking)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan), each sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
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


def _package_edges(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """The graph without edges from a package ``__init__`` to its own submodules (re-exports, not cycles)."""
    return {a: {b for b in bs if not b.startswith(a + ".")} for a, bs in graph.items()}


def test_no_module_over_500_lines() -> None:
    long = {name: n for name, p in modules().items() if (n := len(p.read_text().splitlines())) > MAX_LINES}
    assert not long, f"modules over {MAX_LINES} lines (split them by concept): {long}"


def test_no_import_cycle() -> None:
    found = cycles(_package_edges(import_graph()))
    assert not found, f"import cycles between rhi modules: {found}"


def test_no_import_cycle_through_type_checking_imports() -> None:
    """Types do not go round in circles either: a module typed against a higher one uses a protocol instead."""
    found = cycles(_package_edges(import_graph(type_checking=True)))
    assert not found, f"import cycles between rhi modules through TYPE_CHECKING imports: {found}"


def test_the_cycle_check_finds_a_cycle() -> None:
    """The checker itself: a planted cycle and a relative import are found (else the test above cannot fail)."""
    known = {"rhi.a", "rhi.b", "rhi.c", "rhi"}
    a = _imports(ast.parse("def f():\n    from rhi.b import x\n"), "rhi.a", False, known)
    b = _imports(ast.parse("from . import c\n"), "rhi.b", False, known)
    c = _imports(ast.parse("import rhi.a\nfrom typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import rhi.b\n"),
                 "rhi.c", False, known)
    assert (a, b, c) == ({"rhi.b"}, {"rhi.c"}, {"rhi.a"})
    assert cycles({"rhi.a": a, "rhi.b": b, "rhi.c": c}) == [["rhi.a", "rhi.b", "rhi.c"]]
    typed = _imports(ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import rhi.b\n"), "rhi.c", False,
                     known, type_checking=True)
    assert typed == {"rhi.b"} and cycles({"rhi.b": {"rhi.c"}, "rhi.c": typed}) == [["rhi.b", "rhi.c"]]


def test_design_names_every_module() -> None:
    """docs/design.md describes every module (by its dotted name) and no module that no longer exists."""
    text = (ROOT / "docs" / "design.md").read_text()
    mods = set(modules())
    missing = sorted(m for m in mods if f"`{m}`" not in text)
    assert not missing, f"modules missing from docs/design.md: {missing}"
    named = set(re.findall(r"`(rhi(?:\.\w+)*)`", text))
    stale = sorted(m for m in named if m not in mods and not any(m.startswith(k + ".") for k in mods))
    assert not stale, f"docs/design.md names modules that do not exist: {stale}"


#: the layers of docs/design.md, bottom to top; modules directly under rhi (errors, jit, thesis, ...)
#: are the foundations below them all, the ``rhi.cli*`` modules the top.
LAYERS = ("devices", "metrics", "control", "sim", "runtime", "viz", "analysis", "design", "study", "experiments", "plots",
          "report", "cli")
#: edges upwards that are known and accepted (the package's re-exports, entry points, a helper of the top).
UPWARD_OK = {("rhi", "rhi.devices"), ("rhi", "rhi.metrics"), ("rhi.__main__", "rhi.cli"),
             ("rhi.devices.measures", "rhi.metrics.summary"), ("rhi.viz.cli", "rhi.cli_device"),
             ("rhi.viz.cli", "rhi.cli_args")}


def layer(module: str) -> int:
    """Position of `module`'s layer in `LAYERS` (-1: a foundation module directly under rhi)."""
    parts = module.split(".")
    if len(parts) < 2:
        return -1
    if parts[1].startswith("cli"):
        return LAYERS.index("cli")
    return LAYERS.index(parts[1]) if parts[1] in LAYERS else -1


def test_layers_import_downwards_only() -> None:
    """A lower layer never imports a higher one (docs/design.md), e.g. rhi.study never imports rhi.experiments."""
    up = sorted((a, b) for a, bs in import_graph().items() for b in bs
                if layer(b) > layer(a) and (a, b) not in UPWARD_OK)
    assert not up, f"imports from a lower layer into a higher one: {up}"
    assert layer("rhi.study.live") < layer("rhi.experiments.participants") < layer("rhi.cli_study")
    assert layer("rhi.analysis.stats") < layer("rhi.study.results") and layer("rhi.runtime.loop") < layer("rhi.study")
