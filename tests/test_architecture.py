"""The layout of the package (docs/architecture.md): every import of src/qsma, those
inside functions included, read from the source; no import cycle, no layer importing
one above it, no module of ours on an old path; old paths forward to the new ones."""
import ast
import importlib
from pathlib import Path
import warnings

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"

#: The layers, lowest first: a module may import its own layer and those below. A module
#: belongs to the layer of the longest name that is it or a package holding it.
LAYERS = (
    ("base", ("qsma.errors", "qsma.version", "qsma._infra", "qsma.units", "qsma.progress")),
    ("mesh", ("qsma.mesh",)),
    ("contact", ("qsma.contact",)),
    ("model", ("qsma.model",)),
    ("fe", ("qsma.fe",)),
    ("reduction", ("qsma.reduction",)),
    ("modal", ("qsma.modal",)),
    ("hysteresis", ("qsma.hysteresis",)),
    ("run", ("qsma.analysis", "qsma.deck")),
    ("output", ("qsma.output",)),
    ("applications", ("qsma.study", "qsma.examples", "qsma.cli", "qsma.__main__", "qsma")),
)


def _modules():
    """Module name -> (path, is a package)."""
    out = {}
    for path in sorted((SRC / "qsma").rglob("*.py")):
        parts = list(path.relative_to(SRC).with_suffix("").parts)
        package = parts[-1] == "__init__"
        out[".".join(parts[:-1] if package else parts)] = (path, package)
    return out


MODULES = _modules()


def _is_forwarding_only(path) -> bool:
    """Whether a module only forwards an old path: its docstring, the import of
    ``forward`` (:mod:`qsma._infra.deprecation`) and the call of it."""
    body = ast.parse(path.read_text()).body
    calls = [n for n in body if isinstance(n, ast.Expr) and isinstance(n.value, ast.Call)]
    rest = [n for n in body if n not in calls and not (
        isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant))
        and not (isinstance(n, ast.ImportFrom) and (n.module or "").endswith("deprecation"))]
    return bool(calls) and not rest and all(getattr(c.value.func, "id", "") == "forward"
                                            for c in calls)


OLD_PATHS = {name for name, (path, _) in MODULES.items() if _is_forwarding_only(path)}


def _imports(name):
    """``(target module, inside a function, line)`` of every qsma import in module
    ``name``: ``from a.b import c`` names the module ``a.b.c`` if there is one, else
    ``a.b``; importing a module runs its packages first, so those not holding ``name``
    count as imported too."""
    path, package = MODULES[name]
    here = name if package else name.rpartition(".")[0]
    found = []

    def visit(node, in_function):
        for child in ast.iter_child_nodes(node):
            inner = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef,
                                                      ast.Lambda))
            if isinstance(child, ast.Import):
                targets = [a.name for a in child.names]
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    base = here.split(".")[:len(here.split(".")) - child.level + 1]
                    module = ".".join(base + ([child.module] if child.module else []))
                else:
                    module = child.module or ""
                targets = [f"{module}.{a.name}" if f"{module}.{a.name}" in MODULES else module
                           for a in child.names]
            else:
                targets = []
            for t in dict.fromkeys(targets):
                if t in MODULES:
                    found.append((t, in_function, child.lineno))
                    parts = t.split(".")
                    for k in range(1, len(parts)):
                        parent = ".".join(parts[:k])
                        if parent in MODULES and not (name + ".").startswith(parent + "."):
                            found.append((parent, in_function, child.lineno))
            visit(child, inner)

    visit(ast.parse(path.read_text()), False)
    return found


def _checked(name) -> bool:
    return name not in OLD_PATHS


GRAPH = {name: [e for e in _imports(name) if _checked(e[0])]
         for name in MODULES if _checked(name)}


def _layer(name) -> int:
    best = None
    for k, (_, prefixes) in enumerate(LAYERS):
        for p in prefixes:
            if name == p or name.startswith(p + "."):
                if best is None or len(p) > best[1]:
                    best = (k, len(p))
    assert best is not None, f"{name} belongs to no layer: add it to LAYERS"
    return best[0]


def test_every_module_has_a_layer():
    for name in GRAPH:
        _layer(name)


def test_no_layer_imports_one_above_it():
    upward = [f"{a} ({LAYERS[_layer(a)][0]}) imports {b} ({LAYERS[_layer(b)][0]}), line "
              f"{line}" for a, edges in GRAPH.items() for b, _, line in edges
              if _layer(b) > _layer(a)]
    assert not upward, "\n".join(upward)


def test_no_import_cycle():
    """Tarjan's strongly connected components of the import graph, functions included."""
    index, low, stack, on, cycles = {}, {}, [], set(), []

    def connect(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w, _, _ in GRAPH[v]:
            if w == v:
                continue
            if w not in index:
                connect(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in GRAPH:
        if v not in index:
            connect(v)
    assert not cycles, cycles


#: Most lines a module of ours may have: past it a module holds more than one concern.
MAX_MODULE_LINES = 600


def test_no_module_is_longer_than_the_limit():
    long = {name: n for name, (path, _) in MODULES.items()
            if (n := len(path.read_text().splitlines())) > MAX_MODULE_LINES}
    assert not long, f"modules over {MAX_MODULE_LINES} lines: {long}; split them"


def _forwarded(module, name) -> bool:
    """Whether ``from module import name`` reaches a name that moved (module is an old
    path, or forwards ``name`` to its new home)."""
    if module in OLD_PATHS:
        return True
    if module not in MODULES or not module.startswith("qsma"):
        return False
    hook = vars(importlib.import_module(module)).get("__getattr__")
    return getattr(hook, "__module__", "") == "qsma._infra.deprecation" \
        and name not in vars(importlib.import_module(module)) \
        and f"{module}.{name}" not in MODULES


def _old_imports(tree):
    """``(line, what)`` of the imports in ``tree`` that use an old path (absolute
    imports; a module of ours is read with its relative imports resolved)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from ((node.lineno, a.name) for a in node.names if a.name in OLD_PATHS)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            yield from ((node.lineno, f"{node.module}.{a.name}") for a in node.names
                        if f"{node.module}.{a.name}" in OLD_PATHS
                        or _forwarded(node.module, a.name))


def _resolved(name, node):
    """The absolute module of a relative ``from`` import in module ``name``."""
    here = name if MODULES[name][1] else name.rpartition(".")[0]
    base = here.split(".")[:len(here.split(".")) - node.level + 1]
    return ".".join(base + ([node.module] if node.module else []))


def test_our_modules_import_the_new_paths():
    """An old path (a module that moved, or a name that did) is for code outside qsma: no
    module of ours imports one."""
    old = []
    for name, (path, _) in MODULES.items():
        if not _checked(name):
            continue
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.level:
                node.module, node.level = _resolved(name, node), 0
        old += [f"{name}:{line} imports {what}" for line, what in _old_imports(tree)]
    assert not old, "\n".join(old)


def test_tests_and_benchmarks_import_the_new_paths():
    here = Path(__file__).resolve()
    old = []
    for path in sorted(here.parent.rglob("*.py")) + sorted(
            (here.parents[1] / "benchmarks").glob("*.py")):
        if path != here:                       # this file imports old paths on purpose
            old += [f"{path.name}:{line} imports {what}"
                    for line, what in _old_imports(ast.parse(path.read_text()))]
    assert not old, "\n".join(old)


def _imported_names(tree):
    """``(line, module)`` of every import in ``tree``, relative imports by their name."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from ((node.lineno, a.name) for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module:
            yield node.lineno, node.module


def test_no_test_module_imports_another():
    """What several test modules share lives in tests/helpers.py: a test module imported
    by another runs its module-level code twice, and renaming one of its tests' private
    builders breaks a module that nobody reads beside it."""
    tests = Path(__file__).resolve().parent
    modules = {p.stem for p in tests.rglob("test_*.py")}
    found = [f"{path.relative_to(tests)}:{line} imports {module}"
             for path in sorted(tests.rglob("*.py"))
             for line, module in _imported_names(ast.parse(path.read_text()))
             if module.rpartition(".")[2] in modules]
    assert not found, "\n".join(found)


def _top_package(name) -> str:
    """``qsma.deck`` for ``qsma.deck.calculix``; ``qsma`` for a module at the top."""
    return ".".join(name.split(".")[:2]) if name.count(".") else name


def _private_imports(name):
    """``(line, module, name)`` of the private names (one leading underscore) that module
    ``name`` imports from a module of another top-level package of qsma."""
    tree = ast.parse(MODULES[name][0].read_text())
    for node in ast.walk(tree):
        if not isinstance(node, ast.ImportFrom):
            continue
        module = _resolved(name, node) if node.level else node.module or ""
        if not module.startswith("qsma") or _top_package(module) == _top_package(name):
            continue
        for a in node.names:
            if a.name.startswith("_") and not a.name.startswith("__"):
                yield node.lineno, module, a.name


#: Private names still imported across packages: the Abaqus lexer's readers in the deck
#: reader, made public together with it (each entry must still be found below, so the
#: list only shrinks).
PRIVATE_IMPORTS_PENDING = {
    ("qsma.deck.reader", "qsma.mesh.io.abaqus.lexer", "_inp_cards"),
    ("qsma.deck.records", "qsma.mesh.io.abaqus.lexer", "_abaqus_float"),
    ("qsma.deck.records", "qsma.mesh.io.abaqus.lexer", "_rows"),
}


def test_no_private_name_is_imported_from_another_package():
    """A name with a leading underscore is its package's own: another package that needs
    it gets a public name where it lives (a private helper may change without notice)."""
    found = {(name, module, what): line for name in GRAPH
             for line, module, what in _private_imports(name)}
    stale = PRIVATE_IMPORTS_PENDING - set(found)
    assert not stale, f"no longer imported, remove from PRIVATE_IMPORTS_PENDING: {stale}"
    private = [f"{a}:{line} imports {b}.{c}" for (a, b, c), line in sorted(found.items())
               if (a, b, c) not in PRIVATE_IMPORTS_PENDING]
    assert not private, "\n".join(private)


@pytest.mark.parametrize("name", ["qsma.mesh", "qsma.contact", "qsma.model", "qsma.fe",
                                  "qsma.reduction.schur", "qsma.reduction.multibody",
                                  "qsma.modal", "qsma.hysteresis", "qsma.analysis.driver",
                                  "qsma.analysis.config",
                                  "qsma.deck",
                                  "qsma.output.files", "qsma.output.report",
                                  "qsma.study", "qsma.cli"])
def test_each_layer_imports_on_its_own(name):
    """Imported first in a fresh interpreter, without a warning: the static graph above
    does not see the import order Python follows (a package's __init__, a forwarded
    name)."""
    import subprocess
    import sys
    run = subprocess.run([sys.executable, "-W", "error", "-c", f"import {name}"],
                         capture_output=True, text=True, env={"PYTHONPATH": str(SRC)})
    assert run.returncode == 0, run.stderr[-2000:]


#: module that moved -> (a name it held, the module that holds it now)
MOVED = {
    "qsma.linalg": ("schur_complement", "qsma.reduction.schur"),
    "qsma.multifrontal": ("front_structure", "qsma.reduction.schur.multifrontal"),
    "qsma.congruence": ("find_congruence", "qsma.reduction.congruence"),
    "qsma.condense": ("reduce_two_bodies", "qsma.reduction.two_bodies"),
    "qsma.rigid": ("free_motions", "qsma.reduction.rigid"),
    "qsma.pretension": ("lock", "qsma.reduction.pretension"),
    "qsma.multibody": ("reduce_model", "qsma.reduction.multibody"),
    "qsma.model.mesh": ("Mesh", "qsma.mesh.mesh"),
    "qsma.model.validate": ("validate_mesh", "qsma.mesh.validate"),
    "qsma.model.generate": ("structured_mesh", "qsma.mesh.generate"),
    "qsma.model.io": ("read_mesh", "qsma.mesh.io"),
    "qsma.model.io.gmsh": ("GMSH_VERSIONS", "qsma.mesh.io.gmsh"),
    "qsma.model.io.abaqus": ("element_face_facets", "qsma.mesh.io.abaqus"),
    "qsma.model.io.common": ("read_regular", "qsma.mesh.io.common"),
    "qsma.model.io.instances": ("placement", "qsma.mesh.io.abaqus.instances"),
    "qsma.model.io.assembly": ("read_assembly", "qsma.mesh.io.assembly"),
    "qsma.model.io.deck": ("read_deck", "qsma.deck"),
    "qsma.model.bolt": ("bolt_vectors", "qsma.fe.bolts"),
    "qsma.model.interface": ("make_pairing", "qsma.model.pairing"),
    "qsma.contact.laws.base": ("InterfaceLaw", "qsma.contact.laws.interface"),
    "qsma.results": ("write_all", "qsma.output.files"),
    "qsma.rundir": ("RunFolder", "qsma.output.folders"),
    "qsma.report": ("write_report", "qsma.output.report"),
    "qsma.plots": ("write_plots", "qsma.output.plots"),
    "qsma._plotworker": ("PlotWorker", "qsma.output.plotworker"),
    "qsma.rom": ("export_rom", "qsma.study.rom"),
    "qsma.masing": ("masing_loop", "qsma.hysteresis.masing"),
    "qsma.config": ("load_config", "qsma.analysis.config"),
    "qsma.levels": ("Levels", "qsma.analysis.levels"),
    "qsma.options": ("RunOptions", "qsma.analysis.options"),
    "qsma.result": ("QSMAResult", "qsma.analysis.result"),
    "qsma._forked": ("ForkedCall", "qsma._infra.forked"),
    "qsma._threads": ("usable_cores", "qsma._infra.threads"),
    "qsma._resources": ("free_memory", "qsma._infra.resources"),
}


@pytest.mark.parametrize("old", sorted(MOVED))
def test_old_paths_forward_with_a_deprecation_warning(old):
    name, new = MOVED[old]
    module = importlib.import_module(old)
    with pytest.warns(DeprecationWarning, match=f"{old}.{name} moved to {new}.{name}"):
        found = getattr(module, name)
    assert found is getattr(importlib.import_module(new), name)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
            getattr(module, "no_such_name")


def test_every_old_path_is_listed():
    assert OLD_PATHS <= set(MOVED), sorted(OLD_PATHS - set(MOVED))


def test_private_names_and_old_tables_forward_too():
    """Code that reached into a moved module, or read the cell tables the records
    replaced, keeps working for one release."""
    with pytest.warns(DeprecationWarning):
        from qsma.linalg import _superlu_trailing_schur, symmetrised
    from qsma._infra.dense import symmetrised as new
    from qsma.reduction.schur.superlu_schur import _superlu_trailing_schur as new_private
    assert symmetrised is new and _superlu_trailing_schur is new_private
    with pytest.warns(DeprecationWarning):
        from qsma.model.mesh import CELL_FACETS, FACET_CORNERS
    from qsma.mesh.celltypes import CELL_TYPES, TYPES
    assert CELL_FACETS["hexahedron"] == list(CELL_TYPES["hexahedron"].facets)
    assert FACET_CORNERS["quad8"] == TYPES["quad8"].corners == 4
    with pytest.warns(DeprecationWarning):
        from qsma.fe.elements import SKFEM_ELEMENTS
    assert SKFEM_ELEMENTS["quad8"][2] == CELL_TYPES["quad8"].skfem[2]
    with pytest.warns(DeprecationWarning, match="qsma.units.level_units moved to "
                                                "qsma.analysis.result.level_units"):
        from qsma.units import level_units
    from qsma.analysis.result import level_units as new_level_units
    assert level_units is new_level_units
    sweep_module = importlib.import_module("qsma.study.sweep")   # qsma.study.sweep: the function
    with pytest.warns(DeprecationWarning, match="qsma.study.sweep.done_path moved to "
                                                "qsma.study.runners.done_path"):
        done_path = sweep_module.done_path
    from qsma.study.runners import done_path as new_done_path
    assert done_path is new_done_path
