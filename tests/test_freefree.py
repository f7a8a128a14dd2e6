"""Bodies held only through the joint and free-free assemblies (issue 12,
docs/theory.md section 10)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import scipy.sparse.linalg as spla

import qsma
import qsma.reduction.rigid as rigid
from qsma.errors import InputError
from qsma.examples import lap_2d_cantilever, lap_2d_free
from qsma.fe import assemble_body
from qsma.modal import RIGID_TOL, free_shift, linear_modes, nonrigid_part
from qsma.model import Body, Interface, Material, Model, Pressure, Probe, make_pairing
from qsma.mesh.generate import structured_mesh

STEEL = Material(200e9, 0.3, 7850.0)
L, T = 0.1, 0.005
X = np.linspace(0.0, L, 41)


def _block(name, y0, y1, ny):
    mesh = structured_mesh(X, np.linspace(y0, y1, ny + 1))
    eps = 1e-9 * L
    on = lambda y: (lambda p: np.abs(p[:, 1] - y) < eps)
    mesh = mesh.with_sets(
        node_sets={"tip": np.flatnonzero(np.abs(mesh.points[:, 0] - L) < eps)},
        facet_sets={"low": mesh.boundary_facets_where(on(y0)),
                    "high": mesh.boundary_facets_where(on(y1))})
    return Body(name, mesh, STEEL)


def _stack():
    """Two free blocks 100 x 5 mm stacked along y, matching meshes on y = 5 mm."""
    return Model(bodies=(_block("bottom", 0.0, T, 3), _block("top", T, 2 * T, 3)),
                 interface=Interface("bottom", "high", "top", "low"),
                 tip=Probe(sets=(("top", "tip"),), direction=(0.0, 1.0)))


def test_welded_free_free_assembly_equals_one_body():
    """The tied interface is exact: the welded free-free stack has the frequencies of one
    100 x 10 mm block with the same grid, and its three rigid modes come out at zero."""
    model = _stack()
    A = [assemble_body(b) for b in model.bodies]
    modes = linear_modes(model, A, make_pairing(model), n_modes=5)
    assert modes.n_rigid == 3
    one = assemble_body(_block("one", 0.0, 2 * T, 6))
    K, M = one.K.tocsc(), one.M.tocsc()
    lam = np.sort(spla.eigsh(K, k=8, M=M, sigma=-free_shift(K, M), which="LM")[0])
    f_one = np.sqrt(lam[3:]) / (2 * np.pi)
    np.testing.assert_allclose(modes.f_hz[3:], f_one, rtol=1e-8)
    w1 = modes.omega[3]
    K_all = [a.K for a in A]
    off = model.dof_offsets()
    for j in range(3):
        phi = modes.shapes[:, j]
        assert nonrigid_part(model, A, phi) < RIGID_TOL
        energy = sum(phi[off[k]:off[k + 1]] @ (K_all[k] @ phi[off[k]:off[k + 1]])
                     for k in range(2))                     # phi^T K phi = w^2
        assert abs(energy) < 1e-8 * w1 ** 2


LEVELS = qsma.Levels.log("tip", 1e-7, 1e-5, 5)


@pytest.fixture(scope="module")
def free_run():
    return qsma.run(lap_2d_free(1), levels=LEVELS, refine_levels=False)


def test_free_free_lap_runs_on_the_first_elastic_mode(free_run):
    r = free_run
    assert r.success, r.message
    assert r.modes.n_rigid == 3 and np.all(r.modes.f_hz[:3] == 0.0)
    assert r.f0_hz == pytest.approx(r.modes.f_hz[3], rel=1e-14)     # mode 0: elastic
    info = r.model_info
    assert info["rigid_modes"] == 3 and info["mode_counts"] == "elastic modes"
    assert info["held_by_joint"] == ["bottom", "top"]
    assert info["joint_spring_share_max"] < rigid.SHARE_MAX
    stuck = (r.n_slip == 0)
    assert stuck.any()                       # the stuck levels are the tied structure
    np.testing.assert_allclose(r.f_hz[stuck], r.f0_hz, rtol=1e-6)


def test_free_free_preload_is_self_equilibrated(free_run):
    """The contact force on the top plate balances its bolt load: resultant of
    ``lam`` (normal components) equals the bolt force per unit depth."""
    r = free_run
    P = r.preload.lam[:, -1].sum()
    from qsma.examples.lap import LAP_2D
    force = LAP_2D["p_bolt"] * LAP_2D["w_bolt"]
    assert P == pytest.approx(force, rel=1e-6)
    assert abs(r.preload.lam[:, 0].sum()) < 1e-6 * force


@pytest.fixture(scope="module")
def cantilever_runs():
    out = {}
    for rt in (1e-5, 1e-6, 1e-7, rigid.SUPPORT_RTOL):
        old = rigid.SUPPORT_RTOL
        rigid.SUPPORT_RTOL = rt
        try:
            out[rt] = qsma.run(lap_2d_cantilever(1, mu=0.1), levels=qsma.Levels.log(
                "tip", 1e-5, 1e-3, 5), refine_levels=False)
        finally:
            rigid.SUPPORT_RTOL = old
    return out


def test_cantilever_support_limit(cantilever_runs):
    """The damping curve of the cantilever lap joint (top plate held only by the joint)
    converges as the regularising spring goes to zero: the deviation from the default
    (1e-8) falls in proportion to the spring stiffness."""
    ref = cantilever_runs[rigid.SUPPORT_RTOL]
    assert ref.success, ref.message
    assert ref.model_info["held_by_joint"] == ["top"] and ref.modes.n_rigid == 0
    # measured: max |f / f_ref - 1| = 8.0e-6, 7.9e-7, 7.2e-8 and max |zeta - zeta_ref| =
    # 7.7e-7, 7.6e-8, 6.9e-9 for 1e-5, 1e-6, 1e-7 (zeta up to 1.0e-3)
    dev = [np.max(np.abs(cantilever_runs[rt].zeta - ref.zeta)) for rt in (1e-5, 1e-6, 1e-7)]
    dev_f = [np.max(np.abs(cantilever_runs[rt].f_hz / ref.f_hz - 1))
             for rt in (1e-5, 1e-6, 1e-7)]
    assert ref.zeta.max() > 1e-5                                  # the joint slips
    for devs in (dev_f, dev):
        for a, b in zip(devs, devs[1:]):
            assert 5 < a / b < 20                                 # ~ linear in k
    assert dev[2] < 1e-4 * ref.zeta.max()


def test_gross_slip_ends_the_ramp_keeping_the_levels_before():
    """A top plate held only by friction (mu = 0.02) slides away at large amplitude."""
    lv = qsma.Levels.log("tip", 1e-6, 1.0, 9)
    r = qsma.run(lap_2d_cantilever(1, mu=0.02), levels=lv, refine_levels=False)
    assert not r.success
    assert "gross slip" in r.message and "'top'" in r.message
    assert 0 < len(r.alpha) < 9
    np.testing.assert_allclose(r.alpha, lv.alpha(r.omega0, r.phi_tip)[:len(r.alpha)])
    assert r.model_info["joint_spring_share_max"] <= rigid.SHARE_MAX


def test_unbalanced_load_on_free_free_assembly_is_refused():
    m = lap_2d_free(1)
    top = m.bodies[1]
    bad = dataclasses.replace(top, pressures=(Pressure("bolt", 2 * top.pressures[0].p),))
    with pytest.raises(InputError, match="free-free.*not self-equilibrated"):
        qsma.run(dataclasses.replace(m, bodies=(m.bodies[0], bad)), levels=LEVELS)


def test_body_free_of_every_clamp_and_untied_is_a_rigid_mode():
    """Modes with no pair tied: the free top plate is held by nothing."""
    m = lap_2d_cantilever(1)
    p = make_pairing(m)
    with pytest.raises(InputError, match="rigid-body"):
        linear_modes(m, [assemble_body(b) for b in m.bodies], p,
                     tied=np.zeros(p.n_pairs, bool), n_modes=3)

