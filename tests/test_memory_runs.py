"""Repeated runs in one process keep nothing of the runs before them.

A program that runs several models in turn (a script, a notebook, a benchmark) must
not grow by the meshes, element data, matrices and factorisations of earlier runs
once their results are dropped. The per-mesh caches of qsma.fe held the last eight
meshes of the process and their element data, whatever run they came from
(docs/performance.md, "Memory of repeated runs in one process").
"""
import gc
import weakref

import numpy as np
import pytest

import qsma
from qsma.analysis import prepare, run_prepared
from qsma.reduction.condensation import CondensedBody
from qsma.examples import sandwich_2d
from qsma.fe import AssembledBody
from qsma.fe.batched import cell_quadrature, mesh_pattern
from qsma.fe.cache import per_mesh
from qsma.fe.elements import fe_space
from qsma.reduction.schur import EESolver
from qsma.model import Mesh

#: The objects of a run that hold its large arrays: meshes (and through the caches,
#: their element data), assembled bodies (K, M), condensed bodies (dense Kc, K_EC)
#: and the K_EE factorisations.
HEAVY = (Mesh, AssembledBody, CondensedBody, EESolver)
LEVELS = qsma.Levels.log("tip", 1e-6, 1e-3, 6)


def _live(types):
    """ids of the live objects of ``types`` known to the garbage collector."""
    gc.collect()
    return {id(o): type(o).__name__ for o in gc.get_objects() if isinstance(o, types)}


def _new_live(before, types=HEAVY):
    now = _live(types)
    return sorted(name for i, name in now.items() if i not in before)


def test_dropped_run_leaves_no_mesh_matrix_or_factor_alive():
    before = _live(HEAVY)
    model = sandwich_2d(1)
    mesh = weakref.ref(model.bodies[0].mesh)
    res = qsma.run(model, levels=LEVELS)
    assert res.success
    assert res.reduced.bodies[0].Kc.shape[0] > 0        # the result holds its own model
    solver = weakref.ref(res.reduced.bodies[0].solve_EE)
    del model, res
    assert _new_live(before) == []
    assert mesh() is None and solver() is None


def test_dropped_run_is_freed_without_the_cycle_collector():
    """The large objects of a run are freed as soon as the result goes, by reference
    counting alone: none of them sits in a reference cycle that would keep it until
    the next full collection of the cyclic garbage collector (which a program may
    not see for many runs)."""
    model = sandwich_2d(1)
    res = qsma.run(model, levels=LEVELS)
    refs = [weakref.ref(o) for o in (model.bodies[0].mesh, model.bodies[1].mesh,
                                     res.reduced, *res.reduced.bodies,
                                     res.reduced.bodies[0].solve_EE, res)]
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        del model, res
        assert [r() is None for r in refs] == [True] * len(refs)
    finally:
        if was_enabled:
            gc.enable()


def test_second_run_does_not_retain_the_first():
    """Two runs one after the other: after the second, only its objects are alive."""
    before = _live(HEAVY)
    first = qsma.run(sandwich_2d(1), levels=LEVELS)
    first_mesh = weakref.ref(first.model.bodies[0].mesh)
    first_kc = weakref.ref(first.reduced.bodies[0])
    f0 = first.f0_hz
    del first
    second = qsma.run(sandwich_2d(1), levels=LEVELS)
    assert first_mesh() is None and first_kc() is None
    assert second.f0_hz == pytest.approx(f0, rel=1e-12)    # same model, same answer
    alive = _new_live(before)
    assert alive.count("CondensedBody") == 2 and alive.count("AssembledBody") == 0
    del second
    assert _new_live(before) == []


def test_prepared_study_state_is_released():
    """A study's shared preparation (assembly, condensation, cached preload and tied
    modes) goes with the last reference to it."""
    before = _live(HEAVY)
    prep = prepare(sandwich_2d(1))
    res = run_prepared(prep.with_mu(0.3), levels=LEVELS)
    assert res.success and len(prep.cache) >= 2         # preload and mode cached
    del prep, res
    assert _new_live(before) == []


def test_fe_caches_follow_their_mesh():
    """The element space, quadrature data and block pattern of a mesh are built once
    while the mesh lives and dropped with it."""
    mesh = sandwich_2d(1).bodies[0].mesh
    assert fe_space(mesh) is fe_space(mesh)
    assert cell_quadrature(mesh) is cell_quadrature(mesh)
    pattern = mesh_pattern(mesh)
    assert pattern is mesh_pattern(mesh)
    data = weakref.ref(pattern)
    n = mesh_pattern.cache_size()
    del mesh, pattern
    gc.collect()
    assert data() is None and mesh_pattern.cache_size() <= n - 1


def test_per_mesh_cache_keys_on_identity_and_arguments():
    calls = []

    @per_mesh
    def area(mesh, scale):
        calls.append(scale)
        return np.full(3, scale)

    a, b = sandwich_2d(1).bodies[0].mesh, sandwich_2d(1).bodies[0].mesh
    assert area(a, 2.0) is area(a, 2.0) and len(calls) == 1
    area(a, 3.0)
    area(b, 2.0)                       # an equal but distinct mesh: its own entry
    assert calls == [2.0, 3.0, 2.0] and area.cache_size() == 2
    area.cache_clear()
    assert area.cache_size() == 0


def test_sweep_case_frees_reference_cycles_of_large_interfaces():
    """The collection a sweep worker runs after a case (``_free_cycles``): from
    ``FREE_CYCLES_FROM`` contact unknowns on it frees cyclic garbage at once, below it
    leaves it to the automatic collector. Shown on a synthetic reference cycle; that a
    sweep case's contact problems form such cycles (their cached zone elimination) is
    the reason for the call, not asserted here."""
    from qsma.study.runners import FREE_CYCLES_FROM, _free_cycles

    class Node:
        pass

    def cycle():
        a, b = Node(), Node()
        a.other, b.other, a.data = b, a, np.zeros(1000)
        return weakref.ref(a)

    was_enabled = gc.isenabled()
    gc.disable()
    try:
        small, large = cycle(), cycle()
        _free_cycles(FREE_CYCLES_FROM - 1)
        assert small() is not None                  # left to the automatic collector
        _free_cycles(FREE_CYCLES_FROM)
        assert small() is None and large() is None
    finally:
        if was_enabled:
            gc.enable()


def test_contact_zones_of_a_dropped_run_are_freed_without_the_cycle_collector():
    """The contact zones (their Cholesky factors of the interface) are cached on the
    contact problem and refer back to it; a run that owns the problem releases the
    cache, so the eliminations go with the run by reference counting alone.
    sandwich-2d eliminates its open pairs (several eliminations per run)."""
    from qsma.contact.zone import Elimination

    def eliminations():
        return {id(o) for o in gc.get_objects() if isinstance(o, Elimination)}

    gc.collect()
    before = eliminations()
    was_enabled = gc.isenabled()
    gc.disable()
    try:
        res = qsma.run(sandwich_2d(1), levels=LEVELS)
        assert res.success
        del res
        assert eliminations() - before == set()
    finally:
        if was_enabled:
            gc.enable()
