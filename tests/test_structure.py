"""Where compiled code and private names may be used: one jit decorator, no private name across packages.

Read with `ast` from the source, like `tests/test_codebase.py` (nothing is imported):

- a private name (a ``_name`` in a module, or a module whose dotted path has a ``_`` component such as
  ``rhi.control._compiled.step``) is imported only inside the package that holds it — a ``_name`` of
  module ``rhi.a.b``, or a private module ``rhi.a._c...``, from ``rhi.a`` and its subpackages — except
  that compiled code calls compiled code: a module of a ``_compiled`` package may import another layer's
  ``_compiled`` modules (the compiled tick calls the device kernels, the compiled simulation loop calls
  the tick; `tests/test_codebase.py` keeps those edges downwards);
- every compiled function of rhi carries the one decorator `rhi.jit.jit`: no other module makes a Numba
  decorator (``njit``, ``jit``, ``vectorize``, ... from Numba) or decorates with a ``*jit`` of its own.
"""

from __future__ import annotations

import ast
import re

from test_codebase import modules

#: Numba's decorator factories; only `rhi.jit` may use them.
NUMBA_DECORATORS = {"jit", "njit", "generated_jit", "vectorize", "guvectorize", "cfunc", "stencil", "jitclass"}


def _private(part: str) -> bool:
    return part.startswith("_") and not (part.startswith("__") and part.endswith("__"))


def _package(module: str, is_package: bool) -> str:
    return module if is_package else module.rpartition(".")[0]


def _imported(tree: ast.AST, name: str, is_package: bool) -> list[tuple[str, str | None, int]]:
    """(module, imported name or None, line) of every rhi import in `tree`, relative imports resolved."""
    out: list[tuple[str, str | None, int]] = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(a.name, None, node.lineno) for a in node.names if a.name.startswith("rhi")]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = _package(name, is_package).split(".")
                pkg = pkg[: len(pkg) - (node.level - 1)]
                base = ".".join([*pkg, base] if base else pkg)
            if base.startswith("rhi"):
                out += [(base, a.name, node.lineno) for a in node.names]
    return out


def private_imports(tree: ast.AST, name: str, is_package: bool, known: set[str]) -> list[str]:
    """The imports of module `name` that reach a private name of another package (see the module docstring)."""
    here = _package(name, is_package)
    compiled = "_compiled" in name.split(".")
    bad = []
    for module, imported, line in _imported(tree, name, is_package):
        target = f"{module}.{imported}" if imported and f"{module}.{imported}" in known else module
        parts = target.split(".")
        for i, part in enumerate(parts):
            if not _private(part):
                continue
            owner = ".".join(parts[:i])
            inside = here == owner or here.startswith(owner + ".")
            if not inside and not (compiled and part == "_compiled"):
                bad.append(f"{name}:{line} imports {target} (private to {owner})")
            break
        if imported and _private(imported) and target == module:
            owner = _package(module, any(k.startswith(module + ".") for k in known))
            if here != owner and not here.startswith(owner + "."):
                bad.append(f"{name}:{line} imports {imported} from {module} (private to {owner})")
    return bad


def jit_makers(tree: ast.AST) -> list[str]:
    """Numba decorator factories imported or used in `tree`, and decorators named ``*jit`` not from `rhi.jit`."""
    found = []
    ours: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "numba":
            found += [f"from {node.module} import {a.name}" for a in node.names if a.name in NUMBA_DECORATORS]
        elif isinstance(node, ast.ImportFrom) and node.module == "rhi.jit":
            ours |= {a.asname or a.name for a in node.names if a.name == "jit"}
        elif isinstance(node, ast.Attribute) and node.attr in NUMBA_DECORATORS and ast.unparse(node.value) == "numba":
            found.append(ast.unparse(node))
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef):
            for d in node.decorator_list:
                f = d.func if isinstance(d, ast.Call) else d
                label = ast.unparse(f)
                if label.split(".")[-1].lstrip("_").endswith("jit") and label not in ours:
                    found.append(f"@{label} on {node.name}")
    return found


def test_no_private_name_imported_across_packages() -> None:
    mods = modules()
    known = set(mods)
    bad = [b for name, p in mods.items()
           for b in private_imports(ast.parse(p.read_text()), name, p.name == "__init__.py", known)]
    assert not bad, "private names imported from another package (make them public or move the code):\n" + "\n".join(bad)


def test_one_jit_decorator() -> None:
    found = {name: f for name, p in modules().items() if name != "rhi.jit" and (f := jit_makers(ast.parse(p.read_text())))}
    assert not found, f"compiled functions must use rhi.jit.jit, the one decorator: {found}"
    users = [name for name, p in modules().items() if re.search(r"^from rhi\.jit import .*\bjit\b", p.read_text(), re.M)]
    assert {"rhi.devices._compiled.terms", "rhi.control._compiled.step", "rhi.sim._compiled.fast_loop",
            "rhi.design.planar", "rhi.metrics._small"} <= set(users)


def test_the_checks_find_what_they_forbid() -> None:
    """The checkers themselves: planted violations are found and allowed imports pass (else the tests cannot fail)."""
    known = {"rhi", "rhi.sim", "rhi.sim.loop", "rhi.sim._compiled", "rhi.sim._compiled.io", "rhi.control",
             "rhi.control._compiled", "rhi.control._compiled.whole", "rhi.control.tick", "rhi.devices",
             "rhi.devices.terms", "rhi._validate"}
    src = ("from rhi.control._compiled import whole\nfrom rhi.control import _compiled\n"
           "from rhi.devices.terms import _private\nimport rhi.control._compiled.whole\n"
           "from rhi._validate import as_array\nfrom rhi.sim._compiled import io\nfrom rhi.control.tick import KernelTick\n")
    bad = private_imports(ast.parse(src), "rhi.sim.loop", False, known)
    assert len(bad) == 4 and all("rhi.sim.loop:" in b for b in bad), bad
    assert [b.split(":")[1].split()[0] for b in bad] == ["1", "2", "3", "4"]
    # compiled code may call another layer's compiled code, but not its private names
    ok = private_imports(ast.parse("from rhi.control._compiled import whole\n"), "rhi.sim._compiled.io", False, known)
    assert ok == []
    assert private_imports(ast.parse("from rhi.control.tick import _x\n"), "rhi.sim._compiled.io", False, known)
    assert private_imports(ast.parse("from . import _x\n"), "rhi.control.tick", False, known) == []
    jits = jit_makers(ast.parse("from numba import njit\nimport numba\n_j = numba.jit()\n@njit\ndef f(): pass\n"
                                "from rhi.jit import jit\n@jit\ndef g(): pass\n"))
    assert jits == ["from numba import njit", "numba.jit", "@njit on f"], jits
