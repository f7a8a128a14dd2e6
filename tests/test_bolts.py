"""Bolts: washer couplings, pretension in the preload, locked afterwards (issue 12,
docs/theory.md section 11)."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import qsma
from qsma.analysis import StageClock, prepare
from qsma.errors import InputError
from qsma.examples.bolted import BOLT_2D, lap_2d_bolted
from qsma.model import Bolt
from qsma.fe.bolts import bolt_vectors
from qsma.analysis.options import RunOptions
from qsma.analysis.result import load_factors


def _preload(model):
    p = prepare(model)
    red, _, pre = p.preloaded(RunOptions(), StageClock())
    return p, red, pre


@pytest.mark.parametrize("free", ["all", "top"])
def test_pretension_only_contact_force_balances_the_bolt(free):
    """A bolted two-plate stack held only by its bolt: the contact pressures sum to the
    bolt tension and the shear to zero (equilibrium of the top plate)."""
    _, red, pre = _preload(lap_2d_bolted(1, free=free))
    N0 = BOLT_2D["pretension"]
    assert red.bolt_forces(pre.d, load_factors(red, 0.0)) == pytest.approx([N0], rel=1e-14)
    assert pre.lam[:, -1].sum() == pytest.approx(N0, rel=1e-10)
    assert abs(pre.lam[:, 0].sum()) < 1e-10 * N0


def _width(p, pre):
    x, P = p.pairing.x[:, 0], pre.lam[:, -1]
    xc = (P @ x) / P.sum()
    return np.sqrt((P @ (x - xc) ** 2) / P.sum())


def test_pressure_distribution_converges_with_the_mesh():
    """The RMS half-width of the bolt's pressure distribution on refine 1, 2, 3 against
    refine 4 (measured 3.2306, 3.2047, 3.1999, 3.1982 mm): errors fall by > 3 per
    refinement step and the bolt force is carried to 1e-10 at every mesh."""
    widths = []
    for r in (1, 2, 3, 4):
        p, _, pre = _preload(lap_2d_bolted(r, free="all"))
        assert pre.lam[:, -1].sum() == pytest.approx(BOLT_2D["pretension"], rel=1e-10)
        widths.append(_width(p, pre))
    err = np.abs(np.array(widths[:3]) - widths[3])
    assert err[0] / err[1] > 3 and err[1] / err[2] > 3
    assert err[2] < 1e-3 * widths[3]


@pytest.fixture(scope="module")
def bolted_run():
    return qsma.run(lap_2d_bolted(1, mu=0.1, free="top"),
                    levels=qsma.Levels.log("tip", 1e-6, 1e-3, 6), refine_levels=False)


def test_locked_bolt_force_follows_its_elongation(bolted_run):
    """N = N0 + k (ell - ell_pre), with ell recomputed from the recovered displacement
    fields of both plates (independent of the elimination of the bolt force)."""
    r = bolted_run
    assert r.success, r.message
    red = r.reduced
    model = r.model
    c = bolt_vectors(model, model.bolts[0])
    ell = lambda d, a: sum(cj @ uj for cj, uj in zip(c, red.recover(d, a)))
    a0 = load_factors(red, 0.0)
    ell_pre = ell(r.preload.d, a0)
    for k in (0, len(r.alpha) - 1):
        a = load_factors(red, r.alpha[k])
        d = r.states.d[k]
        N = red.bolt_forces(d, a)[0]
        expected = BOLT_2D["pretension"] + BOLT_2D["stiffness"] * (ell(d, a) - ell_pre)
        assert N == pytest.approx(expected, rel=1e-9)
    assert abs(N - BOLT_2D["pretension"]) > 1e-6 * BOLT_2D["pretension"]   # it changed


def test_locked_bolt_is_in_the_tied_modes(bolted_run):
    """The stuck levels give the tied frequency with the bolt's stiffness (run success:
    no stuck_not_linear flag), and that frequency depends on the bolt stiffness."""
    r = bolted_run
    stuck = r.n_slip == 0
    assert stuck.any() and r.zeta.max() > 1e-5
    np.testing.assert_allclose(r.f_hz[stuck], r.f0_hz, rtol=1e-6)
    m = r.model
    soft = dataclasses.replace(m, bolts=(dataclasses.replace(m.bolts[0], stiffness=1.0),))
    f_soft = qsma.run(soft, levels=qsma.Levels.log("tip", 1e-7, 1e-6, 2),
                      refine_levels=False).f0_hz
    # measured: 148.139755957 Hz with the bolt, 148.139545473 Hz with k = 1 N/m (the
    # tied overlap is far stiffer than the 8 mm shank, so the bolt adds 1.4e-6)
    assert f_soft < r.f0_hz * (1 - 5e-7)


def test_bolt_with_both_ends_on_one_body():
    with pytest.raises(InputError, match="bolt 'b1': both ends are on body 'top'"):
        Bolt("b1", "top", "bolt", "top", "interface", 1e4, 1e9)


@pytest.mark.parametrize("value", [0.0, -1e6])
def test_pretension_of_the_wrong_sign(value):
    with pytest.raises(InputError, match="bolt 'b1': pretension must be > 0"):
        Bolt("b1", "bottom", "bolt", "top", "bolt", value, 1e9)


def test_washer_on_the_inner_face_is_refused():
    """A washer set on the interface side would pull the plates apart."""
    m = lap_2d_bolted(1)
    bad = dataclasses.replace(m.bolts[0], set_a="interface")
    with pytest.raises(InputError, match="bolt 'bolt': the washer face on body 'bottom' "
                                         "faces towards body 'top'"):
        qsma.run(dataclasses.replace(m, bolts=(bad,)))


def test_bolt_naming_an_unknown_body():
    m = lap_2d_bolted(1)
    bad = dataclasses.replace(m.bolts[0], body_b="lid")
    with pytest.raises(InputError, match="bolt 'bolt' names body 'lid'"):
        dataclasses.replace(m, bolts=(bad,))


def test_bolt_pretension_loads_like_the_patch_it_replaces():
    """The washer coupling spreads the pretension as a uniform traction: the bolted
    sandwich-2d has the preload of the pressure-patch sandwich (same nodal loads)."""
    from qsma.examples import sandwich_2d, sandwich_2d_bolted
    _, _, pre_p = _preload(sandwich_2d(1))
    _, _, pre_b = _preload(sandwich_2d_bolted(1))
    scale = np.abs(pre_p.lam).max()
    np.testing.assert_array_equal(pre_b.status, pre_p.status)
    np.testing.assert_allclose(pre_b.lam, pre_p.lam, rtol=0, atol=1e-9 * scale)


def test_preload_scale_scales_the_pretension():
    """A sweep's preload scale multiplies the bolt pretension with the pressures."""
    p = prepare(lap_2d_bolted(1, free="all")).with_preload_scale(2.0)
    red, _, pre = p.preloaded(RunOptions(), StageClock())
    assert p.model.bolts[0].pretension == 2 * BOLT_2D["pretension"]
    assert red.bolt_forces(pre.d, load_factors(red, 0.0))[0] == pytest.approx(
        2 * BOLT_2D["pretension"], rel=1e-14)
    assert pre.lam[:, -1].sum() == pytest.approx(2 * BOLT_2D["pretension"], rel=1e-10)


@pytest.mark.parametrize("free", [("top",), ("bottom", "top")])
def test_mortar_interface_held_only_by_the_bolt(free):
    """Non-matching meshes (dual mortar coupling; 23 top elements against 30 in the
    overlap): the contact pressures still sum to the bolt tension, for the top plate
    free and for the free-free stack (gauge and spring through the projection)."""
    from qsma.examples import lap_2d
    m = lap_2d(1, top_overlap_elements=23)
    bodies = tuple(dataclasses.replace(b, pressures=(),
                                       clamps=() if b.name in free else b.clamps)
                   for b in m.bodies)
    bolt = Bolt("bolt", "bottom", "bolt", "top", "bolt", BOLT_2D["pretension"],
                BOLT_2D["stiffness"])
    p, red, pre = _preload(dataclasses.replace(m, bodies=bodies, bolts=(bolt,)))
    assert p.pairing.coupling == "mortar"
    assert red.ghost is not None and (red.gauge is not None) == (len(free) == 2)
    assert pre.lam[:, -1].sum() == pytest.approx(BOLT_2D["pretension"], rel=1e-10)


def test_interface_friction_is_kept_after_the_bolts_lock():
    """The friction coefficient given on the interface (not the model) governs every
    level after the bolts lock: the run equals the one with the same value on the model
    (to round-off), and differs from the run with the model's other value (a review
    found the locked problem rebuilt with the model's mu)."""
    levels = qsma.Levels.log("tip", 1e-6, 1e-4, 4)
    base = lap_2d_bolted(1, mu=0.1, free="top")
    on_itf = dataclasses.replace(base, interface=dataclasses.replace(base.interface, mu=0.5))
    a = qsma.run(on_itf, levels=levels)
    b = qsma.run(lap_2d_bolted(1, mu=0.5, free="top"), levels=levels)
    c = qsma.run(base, levels=levels)
    assert a.success and b.success and c.success
    assert np.abs(a.zeta - b.zeta).max() < 1e-10
    assert np.abs(a.zeta - c.zeta).max() > 1e-5        # mu 0.1 slips much earlier


# ---------------------------------------------------------------- several interfaces
def _three_plates(bolt_stiffness=1e11):
    """Three steel plates 60 x 3 mm stacked along y (30 x 3 quads each), a bolt from
    the bottom face of the bottom plate to the top face of the top plate through a
    10 mm washer at x = 30 mm on each, pretension 0.5 MN/m; the bottom and top plates
    clamped at x = 0, the middle one at x = 60 mm; the interfaces span x = 4 to 56 mm
    (off the clamped ends)."""
    from qsma.model import Body, Clamp, Interface, Material, Model, Probe
    from qsma.mesh.generate import structured_mesh
    steel = Material(200e9, 0.3, 7850.0)
    eps = 1e-9
    bodies = []
    for k, (name, x_clamp) in enumerate((("bottom", 0.0), ("middle", 0.06), ("top", 0.0))):
        y0, y1 = 0.003 * k, 0.003 * (k + 1)
        mesh = structured_mesh(np.linspace(0, 0.06, 31), np.linspace(y0, y1, 4))
        on = lambda y: (lambda p: np.abs(p[:, 1] - y) < eps)
        washer = lambda y: (lambda p: on(y)(p) & (np.abs(p[:, 0] - 0.03) < 0.005 + eps))
        inner = lambda p: np.abs(p[:, 0] - 0.03) < 0.026 + eps      # off the clamps
        mesh = mesh.with_sets(
            node_sets={"clamp": np.flatnonzero(np.abs(mesh.points[:, 0] - x_clamp) < eps),
                       "mid": np.flatnonzero(np.abs(mesh.points[:, 0] - 0.03) < eps)},
            facet_sets={"lower": mesh.boundary_facets_where(lambda p: on(y0)(p) & inner(p)),
                        "upper": mesh.boundary_facets_where(lambda p: on(y1)(p) & inner(p)),
                        "washer_low": mesh.boundary_facets_where(washer(y0)),
                        "washer_high": mesh.boundary_facets_where(washer(y1))})
        bodies.append(Body(name, mesh, steel, clamps=(Clamp("clamp"),)))
    bolt = Bolt("bolt", "bottom", "washer_low", "top", "washer_high", 5e5, bolt_stiffness)
    return Model(bodies=tuple(bodies),
                 interfaces=(Interface("bottom", "upper", "middle", "lower"),
                             Interface("middle", "upper", "top", "lower")),
                 tip=Probe(sets=(("top", "mid"),), direction=(0.0, 1.0)),
                 bolts=(bolt,), mu=0.2, name="three plates, one bolt")


def test_bolt_on_the_several_interface_path_equals_the_two_body_path():
    """The bolted lap-2d given as a list of one interface goes through the
    several-interface condensation (qsma.reduction.multibody): the same preload and damping
    curve as the two-body path (measured 7.7e-12 of the largest contact force,
    zeta 5e-14, f 4e-13)."""
    m = lap_2d_bolted(1, mu=0.1)
    listed = dataclasses.replace(m, interface=None,
                                 interfaces=(dataclasses.replace(m.interface, mu=None),))
    levels = qsma.Levels.log("tip", 1e-6, 1e-4, 4)
    a = qsma.run(m, levels=levels, refine_levels=False)
    b = qsma.run(listed, levels=levels, refine_levels=False)
    assert a.success and b.success, b.message
    assert type(b.reduced.base).__name__ == "MultiReducedModel"
    scale = np.abs(a.preload.lam).max()
    np.testing.assert_allclose(b.preload.lam, a.preload.lam, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(b.zeta, a.zeta, rtol=0, atol=1e-12)
    np.testing.assert_allclose(b.f_hz, a.f_hz, rtol=1e-11)
    assert a.zeta.max() > 1e-4


def test_bolt_through_three_plates():
    """A bolt through a stack of three plates (two interfaces): the locked bolt force
    follows N0 + k (ell - ell_pre) with ell from the recovered fields of the outer
    plates, and the top plate is in equilibrium at the preload: its contact forces
    (the second interface's pair forces) balance the bolt tension and its clamp
    reaction, computed apart as K u at the clamped DOFs (to 1e-9 of N0)."""
    model = _three_plates()
    r = qsma.run(model, levels=qsma.Levels.log("tip", 1e-7, 1e-5, 3), refine_levels=False)
    assert r.success, r.message
    red, N0, k = r.reduced, 5e5, 1e11
    a0 = load_factors(red, 0.0)
    assert red.bolt_forces(r.preload.d, a0)[0] == pytest.approx(N0, rel=1e-12)
    c = bolt_vectors(model, model.bolts[0])
    ell = lambda d, a: sum(cj @ uj for cj, uj in zip(c, red.recover(d, a)))
    ell_pre = ell(r.preload.d, a0)
    a = load_factors(red, r.alpha[-1])
    N = red.bolt_forces(r.states.d[-1], a)[0]
    assert N == pytest.approx(N0 + k * (ell(r.states.d[-1], a) - ell_pre), rel=1e-9)
    assert abs(N - N0) > 1e-9 * N0                              # it changed
    # equilibrium of the top plate at the preload
    from qsma.fe import assemble_body
    top = model.bodies[2]
    u_top = red.recover(r.preload.d, a0)[2]
    asm = assemble_body(top)
    reaction_y = (asm.K @ u_top)[asm.fixed].reshape(-1, 2)[:, 1].sum()
    rows = r.pairing.rows
    contact_y = r.preload.lam[rows[1]:rows[2], -1].sum()         # normal: into 'top'
    assert contact_y - N0 + reaction_y == pytest.approx(0.0, abs=1e-9 * N0)
    assert abs(reaction_y) > 1e-3 * N0                           # the clamp takes load


# ---------------------------------------------------------------- 3D stack, no CalculiX
def test_stack_preload_satisfies_the_contact_conditions_of_the_full_model():
    """The bolted square stack (refine 1, the CalculiX comparison's model): qsma's
    preload, checked on the full FE model of both plates without condensation. With
    the closed pairs tied (all stick at mu = 0.6) and the open ones free, the
    constrained equilibrium (Lagrange multipliers) gives qsma's pair forces (measured
    3e-13 of the largest); the tied pairs press (normal force > 0, shear within mu
    times it: largest ratio 0.17), the open pairs gape (gap >= 0), and the contact
    forces sum to the pretension 8 kN."""
    import scipy.sparse as sp
    import scipy.sparse.linalg as spla
    from qsma.contact.state import OPEN
    from qsma.examples.bolted import STACK_3D, stack_3d_bolted
    from qsma.fe import assemble_body
    from qsma.fe.bolts import bolt_loads
    model = stack_3d_bolted(1)
    p, _, pre = _preload(model)
    pr = p.pairing
    asm = [assemble_body(b) for b in model.bodies]
    n1, n = asm[0].n_dofs, model.n_dofs
    free = np.setdiff1d(np.arange(n), asm[0].fixed)
    closed = np.flatnonzero(pre.status != OPEN)
    # constraints u_top(i2) - u_bottom(i1) = 0 at the closed pairs, every component
    rows = np.repeat(np.arange(3 * len(closed)), 2)
    cols = np.stack([n1 + 3 * pr.nodes2[closed][:, None] + np.arange(3),
                     3 * pr.nodes1[closed][:, None] + np.arange(3)], axis=-1)
    B = sp.csr_matrix((np.tile([1.0, -1.0], 3 * len(closed)), (rows, cols.ravel())),
                      shape=(3 * len(closed), n))[:, free]
    K = sp.block_diag([a.K for a in asm]).tocsr()[free][:, free]
    F = np.concatenate(bolt_loads(model)[1])[free]
    c = K.diagonal().mean()                            # constraint rows scaled like K
    kkt = sp.bmat([[K, c * B.T], [c * B, None]]).tocsc()
    sol = spla.spsolve(kkt, np.concatenate([F, np.zeros(B.shape[0])]))
    u = np.zeros(n)
    u[free] = sol[:len(free)]
    lam = -c * sol[len(free):].reshape(-1, 3)          # force on the top plate
    # qsma's pair frames are (t1, t2, n) with n = +y here: compare in global axes
    lam_q = np.einsum("pij,pi->pj", pr.frames, pre.lam)
    scale = np.abs(lam).max()
    np.testing.assert_allclose(lam_q[closed], lam, rtol=0, atol=1e-9 * scale)
    assert np.abs(lam_q[pre.status == OPEN]).max() < 1e-9 * scale
    assert lam[:, 1].min() > 0
    assert (np.hypot(lam[:, 0], lam[:, 2]) / lam[:, 1]).max() < STACK_3D["mu"]
    gap = (u[n1:].reshape(-1, 3)[pr.nodes2] - u[:n1].reshape(-1, 3)[pr.nodes1])[:, 1]
    assert gap[pre.status == OPEN].min() >= -1e-9 * np.abs(u).max()
    assert lam[:, 1].sum() == pytest.approx(STACK_3D["pretension"], rel=1e-10)
