"""Interface nodes held by clamps (docs/theory.md, "Clamped interface nodes").

A symmetry plane that cuts the contact face clamps the normal displacement of the
plane on both bodies, interface nodes included. The cut model must give the same
answer as the whole one: the same contact state on the kept half (pressures,
tangential tractions, slip), the same tied modes and the same backbone. These tests
compare the two, node-to-node and mortar, in 2D and 3D, and check what is refused.
"""
import numpy as np
import pytest

import qsma
from qsma.contact import ContactProblem, residual, solve
from qsma.errors import InputError
from qsma.fe import assemble_body
from qsma.mesh.generate import structured_mesh
from qsma.model import Body, Clamp, Interface, Material, Model, Pressure, Probe, make_pairing
from qsma.reduction.two_bodies import reduce_two_bodies

from helpers import needs_ccx

# two dissimilar materials: the Poisson mismatch drives tangential tractions and slip
# under a purely normal load (Goodman's problem), so friction acts at the interface
SOFT = Material(70e9, 0.34, 2700.0)
HARD = Material(210e9, 0.28, 7800.0)
R, MU = 0.05, 0.2                  # cylinder / sphere radius of the gap, friction
W = H = 0.012                      # half width and height of the blocks [m]
P_TOP = 40e6                       # pressure on the top face [Pa]
EPS = 1e-12


def _axis(n, half, mirrored):
    """``n`` cells on [0, half] graded towards 0, or mirrored onto [-half, half]."""
    x = half * (np.linspace(0.0, 1.0, n + 1) ** 1.5)
    return np.concatenate([-x[:0:-1], x]) if mirrored else x


def _bent(model, radius):
    """``model`` with every point moved by ``(1 - |y| / H) x^2 / (2 radius)`` along y:
    the contact face y = 0 becomes the parabola of a cylinder of that radius (both
    sides alike, nodes still matching), the far faces stay flat."""
    def moved(mesh):
        q = mesh.points.copy()
        q[:, 1] += (1 - np.abs(q[:, 1]) / H) * q[:, 0] ** 2 / (2 * radius)
        return type(mesh)(**{**mesh.__dict__, "points": q})
    return Model(tuple(Body(b.name, moved(b.mesh), b.material, b.clamps, b.pressures)
                       for b in model.bodies), model.interface, mu=model.mu)


def _blocks_2d(half, n_top):
    """The 2D cylinder-on-block model: bottom (HARD) clamped at y = -H, top (SOFT)
    held in x at y = H, pressure on y = H, gap x^2 / 2R; ``half``: x >= 0 only with
    the symmetry clamp u_x = 0 at x = 0 on both bodies. ``n_top`` cells of the top
    block across the half width (24 like the bottom: node-to-node, else mortar)."""
    ys = H * np.linspace(0.0, 1.0, 11) ** 1.4
    bodies = []
    for name, n, y, mat in (("bottom", 24, -ys[::-1], HARD), ("top", n_top, ys, SOFT)):
        m = structured_mesh(_axis(n, W, not half), y)
        far = -H if name == "bottom" else H
        p = m.points
        m = m.with_sets(
            node_sets={"far": np.flatnonzero(np.abs(p[:, 1] - far) < EPS),
                       "sym": np.flatnonzero(np.abs(p[:, 0]) < EPS)},
            facet_sets={"contact": m.boundary_facets_where(lambda q: np.abs(q[:, 1]) < EPS),
                        "load": m.boundary_facets_where(
                            lambda q, f=far: np.abs(q[:, 1] - f) < EPS)})
        clamps = (Clamp("far"),) if name == "bottom" else (Clamp("far", (0,)),)
        if half:
            clamps += (Clamp("sym", (0,)),)
        pressures = (Pressure("load", P_TOP),) if name == "top" else ()
        bodies.append(Body(name, m, mat, clamps, pressures))
    return Model(tuple(bodies), Interface("bottom", "contact", "top", "contact"), mu=MU)


def _preload(model, curvature):
    """The contact state of the preload: ``(pairing, reduced, result, problem, lam_w)``,
    its residual checked."""
    p = make_pairing(model)
    A = [assemble_body(b) for b in model.bodies]
    rm = reduce_two_bodies(A[0], A[1], p)
    gap = curvature(p.x) / (2 * R)
    prob = ContactProblem(rm.K, model.mu, dim=model.dim, gap0=gap)
    lw = rm.welded_contact_force([1.0])
    res = solve(prob, lw)
    assert res.success
    assert residual(prob, lw, res.d, res.lam) <= 1e-9
    return p, rm, res, prob, lw


def _matched(p_full, p_half):
    """Per contact point of the half model, the contact point of the whole one at the
    same place."""
    d = np.linalg.norm(p_full.x[None, :, :] - p_half.x[:, None, :], axis=2)
    k = d.argmin(axis=1)
    assert d[np.arange(len(k)), k].max() < 1e-9 * W
    return k


def _compare(full, half, mirror_axes, rtol=1e-6):
    """The half (or quarter) model's state equals the whole one's on the kept part:
    tractions (force over the point's area: a point on a symmetry plane has its share of
    the area), relative displacements and pair states."""
    (pf, rf, sf, _, _), (ph, rh, sh, probh, lwh) = full, half
    k = _matched(pf, ph)
    tf = sf.lam[k] / pf.area[k][:, None]
    th = sh.lam / ph.area[:, None]
    scale = np.abs(tf).max()
    assert np.abs(th - tf).max() < rtol * scale
    assert np.abs(sh.d - sf.d[k]).max() < rtol * np.abs(sf.d).max()
    assert np.array_equal(sh.status, sf.status[k])
    # on a symmetry plane x_c = 0 the tangential component along c is fixed: zero
    # relative displacement and zero traction (the whole model's by symmetry)
    for c in mirror_axes:
        on = np.abs(ph.x[:, c]) < EPS
        axis = np.abs(ph.frames[on][:, :, c]).argmax(axis=1)   # local axis along c
        assert np.abs(sh.d[on, axis]).max() <= 1e-12 * np.abs(sh.d).max()
        assert np.abs(sh.lam[on, axis]).max() <= 1e-12 * np.abs(sh.lam).max()
        assert np.abs(sf.lam[k][on, axis]).max() < 1e-6 * scale
    return sf


@pytest.mark.parametrize("n_top", [24, 17], ids=["node", "mortar"])
def test_half_model_equals_the_whole_in_2d(n_top):
    """2D cylinder pressed on a block of another material, whole against half (x >= 0,
    u_x = 0 at x = 0 on both bodies): pressures, tractions, slip and pair states equal to
    1e-6 (round-off and the solver's tolerance), node-to-node and mortar."""
    curv = lambda x: x[:, 0] ** 2
    full = _preload(_blocks_2d(False, n_top), curv)
    half = _preload(_blocks_2d(True, n_top), curv)
    assert half[0].coupling == ("node" if n_top == 24 else "mortar")
    sf = _compare(full, half, [0])
    # the test means something: the contact is partial and friction acts (slip and
    # stick both present under the mismatch of the two materials)
    assert 0 < np.sum(sf.status == 2) and np.sum(sf.status == 1) > 0 \
        and np.sum(sf.status == 0) > 0


@pytest.mark.parametrize("n_top", [24, 17], ids=["node", "mortar"])
def test_half_model_of_a_curved_face_equals_the_whole(n_top):
    """The contact face meshed curved (a parabola, both sides alike): the half model's
    normal at the point on the symmetry plane, averaged from the facets of one side,
    would lean out of the plane and make the symmetry clamp oblique to the contact frame;
    it is taken in the plane (the whole model's normal there), and the half model
    equals the whole one: node-to-node to 1e-6 as on a flat face, mortar to 1e-5
    (measured 2.7e-6 of the largest traction, at the point on the plane: the mortar
    projection there is built with the master's normals averaged on one side of the
    plane, whose lean, about a facet's turn, enters to second order)."""
    flat = lambda x: 0.0 * x[:, 0]
    full = _preload(_bent(_blocks_2d(False, n_top), 0.02), flat)
    half = _preload(_bent(_blocks_2d(True, n_top), 0.02), flat)
    on = np.abs(half[0].x[:, 0]) < EPS
    assert np.abs(half[0].frames[on][:, -1, 0]).max() == 0.0     # normal in the plane
    _compare(full, half, [0], rtol=1e-6 if n_top == 24 else 1e-5)


def _blocks_3d(mirror_axes, n_top, n_bottom=8):
    """The 3D sphere-on-block model (as :func:`_blocks_2d`, gap (x^2 + y^2) / 2R),
    the whole one, or cut by the symmetry planes x_c = 0 for c in ``mirror_axes``
    (u_c = 0 there on both bodies)."""
    zs = H * np.linspace(0.0, 1.0, 7) ** 1.4
    bodies = []
    for name, n, z, mat in (("bottom", n_bottom, -zs[::-1], HARD), ("top", n_top, zs, SOFT)):
        m = structured_mesh(_axis(n, W, 0 not in mirror_axes),
                            _axis(n, W, 1 not in mirror_axes), z)
        far = -H if name == "bottom" else H
        p = m.points
        sets = {"far": np.flatnonzero(np.abs(p[:, 2] - far) < EPS)}
        sets.update({f"sym{c}": np.flatnonzero(np.abs(p[:, c]) < EPS) for c in mirror_axes})
        m = m.with_sets(
            node_sets=sets,
            facet_sets={"contact": m.boundary_facets_where(lambda q: np.abs(q[:, 2]) < EPS),
                        "load": m.boundary_facets_where(
                            lambda q, f=far: np.abs(q[:, 2] - f) < EPS)})
        clamps = (Clamp("far"),) if name == "bottom" else (Clamp("far", (0, 1)),)
        clamps += tuple(Clamp(f"sym{c}", (c,)) for c in mirror_axes)
        pressures = (Pressure("load", P_TOP),) if name == "top" else ()
        bodies.append(Body(name, m, mat, clamps, pressures))
    return Model(tuple(bodies), Interface("bottom", "contact", "top", "contact"), mu=MU)


@pytest.fixture(scope="module")
def whole_3d():
    curv = lambda x: x[:, 0] ** 2 + x[:, 1] ** 2
    return {n: _preload(_blocks_3d((), n), curv) for n in (8, 7)}


@pytest.mark.parametrize("n_top", [8, 7], ids=["node", "mortar"])
@pytest.mark.parametrize("mirror_axes", [(1,), (0, 1)], ids=["half", "quarter"])
def test_cut_model_equals_the_whole_in_3d(whole_3d, mirror_axes, n_top):
    """3D sphere pressed on a block of another material: the half model (y >= 0) and
    the quarter model (x, y >= 0; the point on the axis fixed in both tangential
    directions, friction free only along the normal) give the whole model's tractions,
    slip and pair states on the kept part to 1e-6, node-to-node and mortar."""
    curv = lambda x: x[:, 0] ** 2 + x[:, 1] ** 2
    cut = _preload(_blocks_3d(mirror_axes, n_top), curv)
    assert cut[0].coupling == ("node" if n_top == 8 else "mortar")
    sf = _compare(whole_3d[n_top], cut, mirror_axes)
    assert np.sum(sf.status == 0) > 4           # a contact zone, stuck in its centre
    if n_top == 8:                              # and slipping at its edge
        assert np.sum(sf.status == 1) > 0


def _beams(half, n_top=40):
    """Two steel beams of length 2 L stacked, clamped at x = +-L, pressed together by
    pressures on the middle of their outer faces, in contact over |x| <= L / 2 (a
    flat interface): the first bending mode is symmetric about x = 0. ``half``: x >= 0
    with u_x = 0 at x = 0 on both beams. ``n_top`` cells of the top beam over L (40 like
    the bottom: node-to-node, else mortar)."""
    L, h, b = 0.2, 0.01, 0.01
    steel = Material(200e9, 0.3, 7800.0)
    bodies = []
    for name, n, y0 in (("bottom", 40, -h), ("top", n_top, 0.0)):
        x = np.linspace(0.0, L, n + 1)
        m = structured_mesh(x if half else np.concatenate([-x[:0:-1], x]),
                            np.linspace(y0, y0 + h, 5))
        p = m.points
        outer = y0 if name == "bottom" else y0 + h
        m = m.with_sets(
            node_sets={"ends": np.flatnonzero(np.abs(np.abs(p[:, 0]) - L) < EPS),
                       "sym": np.flatnonzero(np.abs(p[:, 0]) < EPS),
                       "mid": np.flatnonzero((np.abs(p[:, 0]) < EPS)
                                             & (np.abs(p[:, 1] - outer) < EPS))},
            facet_sets={"contact": m.boundary_facets_where(
                lambda q: (np.abs(q[:, 1]) < EPS) & (np.abs(q[:, 0]) <= L / 2 + EPS)),
                "bolt": m.boundary_facets_where(
                    lambda q, o=outer: (np.abs(q[:, 1] - o) < EPS)
                    & (np.abs(q[:, 0]) <= b + EPS))})
        clamps = (Clamp("ends"),) + ((Clamp("sym", (0,)),) if half else ())
        bodies.append(Body(name, m, steel, clamps, (Pressure("bolt", 20e6),)))
    return Model(tuple(bodies), Interface("bottom", "contact", "top", "contact"),
                 tip=Probe((("top", "mid"),), (0.0, 1.0)), mu=0.3)


@pytest.mark.parametrize("n_top", [40, 33], ids=["node", "mortar"])
def test_half_model_run_equals_the_whole(n_top):
    """``qsma.run`` end to end on the symmetric beams, whole against half: the preload,
    the tied frequency and the backbone (frequency and damping per level, from
    microslip to macroslip) agree to the solvers' tolerance."""
    levels = qsma.Levels("tip", (1e-6, 1e-5, 3e-5, 1e-4))
    whole = qsma.run(_beams(False, n_top), levels=levels, refine_levels=False)
    half = qsma.run(_beams(True, n_top), levels=levels, refine_levels=False)
    assert whole.success and half.success
    assert abs(half.f0_hz - whole.f0_hz) < 1e-6 * whole.f0_hz
    assert np.allclose(half.f_hz, whole.f_hz, rtol=1e-6, atol=0)
    assert np.allclose(half.zeta, whole.zeta, rtol=1e-4, atol=1e-6 * whole.zeta.max())
    assert whole.zeta[-1] > 1e-3                  # the joint dissipates at the top level


def _on_foundation(mu, clamp_top_face_instead=False):
    """The top block of :func:`_blocks_2d` (SOFT, pressure on y = H) on a bottom block
    clamped at every node (a rigid foundation); ``clamp_top_face_instead``: the top
    block alone, its contact face clamped (bonded to the foundation)."""
    model = _blocks_2d(False, 24)
    bottom, top = model.bodies
    sets = dict(top.mesh.node_sets, face=np.flatnonzero(np.abs(top.mesh.points[:, 1]) < EPS))
    top = Body("top", top.mesh.with_sets(node_sets=sets), SOFT,
               (Clamp("face"),) if clamp_top_face_instead else (), top.pressures)
    if clamp_top_face_instead:
        return top
    m = bottom.mesh.with_sets(node_sets={"all": np.arange(bottom.mesh.n_nodes)})
    bottom = Body("bottom", m, HARD, (Clamp("all"),))
    return Model((bottom, top), Interface("bottom", "contact", "top", "contact"), mu=mu)


def test_block_on_a_clamped_foundation_frictionless_is_uniaxial():
    """Clamped on one side only: the foundation is clamped at every node, so the top
    block's displacement is the relative one. Frictionless, the block under a uniform
    pressure is in uniaxial stress (bilinear cells represent it exactly): every contact
    force is the pressure times the point's area, the tangential ones zero."""
    model = _on_foundation(0.0)
    p, rm, res, _, _ = _preload(model, lambda x: 0.0 * x[:, 0])
    assert len(rm.bodies[0].C) == 0                 # nothing of the foundation is free
    assert np.all(res.status != 2)                  # every pair closed
    assert np.allclose(res.lam[:, 1], P_TOP * p.area, rtol=1e-6, atol=0)
    assert np.abs(res.lam[:, 0]).max() < 1e-6 * P_TOP * p.area.max()


def test_block_stuck_on_a_clamped_foundation_is_the_block_clamped_there():
    """With friction high enough for every pair to stick, the block on the clamped
    foundation is the block alone with its contact face clamped: the same
    displacement field (a direct sparse solve of that one body) to 1e-6."""
    import scipy.sparse.linalg as spla
    model = _on_foundation(5.0)
    p, rm, res, _, _ = _preload(model, lambda x: 0.0 * x[:, 0])
    assert np.all(res.status == 0)
    u = rm.recover(res.d, [1.0])[1]
    a = assemble_body(_on_foundation(0.0, clamp_top_face_instead=True))
    K = a.K.tocsr()[a.free][:, a.free]
    ref = np.zeros(a.n_dofs)
    ref[a.free] = spla.spsolve(K.tocsc(), a.loads["preload"][a.free])
    assert np.abs(u - ref).max() < 1e-6 * np.abs(ref).max()


def _edge_clamped(components):
    """The half model of :func:`_blocks_2d` with both bodies also clamped at the
    interface's edge node (x = W, y = 0) in ``components`` (None: every one)."""
    model = _blocks_2d(True, 24)
    bodies = []
    for b in model.bodies:
        edge = np.flatnonzero((np.abs(b.mesh.points[:, 0] - W) < EPS)
                              & (np.abs(b.mesh.points[:, 1]) < EPS))
        m = b.mesh.with_sets(node_sets=dict(b.mesh.node_sets, edge=edge))
        bodies.append(Body(b.name, m, b.material, b.clamps + (Clamp("edge", components),),
                           b.pressures))
    return Model(tuple(bodies), model.interface, mu=MU)


def test_normal_clamped_on_both_sides_is_refused():
    """A contact point whose normal both bodies' clamps hold can neither open nor close,
    and its pressure is a share of the clamps' reaction that nothing determines: the
    reduction refuses it, naming the point and the way out."""
    model = _edge_clamped(components=(1,))
    A = [assemble_body(b) for b in model.bodies]
    with pytest.raises(InputError, match=r"contact point\(s\) \[24\] .* clamped along the "
                       r"contact normal on both sides.*release the normal clamp of one side"):
        reduce_two_bodies(A[0], A[1], make_pairing(model))


def test_point_clamped_in_every_direction_on_both_sides_is_inert(monkeypatch):
    """The point of the test above clamped in both directions on both sides: it can
    neither open nor slip whatever its pressure, so it is kept with d = lam = 0, and
    the rest of the contact state does not depend on the stiffness the reduction gives
    it (scaled by 1e3: the same state to round-off)."""
    import qsma.reduction.multibody as multibody
    model = _edge_clamped(components=None)
    curvature = lambda x: x[:, 0] ** 2
    _, _, res, _, _ = _preload(model, curvature)
    np.testing.assert_array_equal(res.d.reshape(-1, 2)[24], 0.0)
    np.testing.assert_array_equal(res.lam.reshape(-1, 2)[24], 0.0)
    assert res.lam.reshape(-1, 2)[:, 1].max() > 0
    plain = multibody.decoupled

    def stiffer(K, fixed):
        K = plain(K, fixed)
        K[fixed, fixed] *= 1e3
        return K
    monkeypatch.setattr(multibody, "decoupled", stiffer)
    _, _, scaled, _, _ = _preload(model, curvature)
    np.testing.assert_allclose(scaled.d, res.d, rtol=0, atol=1e-12 * np.abs(res.d).max())
    np.testing.assert_allclose(scaled.lam, res.lam, rtol=0,
                               atol=1e-9 * np.abs(res.lam).max())


def test_clamp_oblique_to_the_contact_frame_on_both_sides_is_refused():
    """The half model of :func:`_blocks_2d` turned by 30 degrees: the symmetry clamp
    u_x = 0 (global x) now holds a combination of the normal and tangential relative
    displacement at the point on the plane, on which the contact law cannot act."""
    model = _blocks_2d(True, 24)
    c, s = np.cos(np.pi / 6), np.sin(np.pi / 6)
    turn = np.array([[c, -s], [s, c]])
    bodies = tuple(Body(b.name, type(b.mesh)(**{**b.mesh.__dict__,
                                                 "points": b.mesh.points @ turn.T}),
                        b.material, b.clamps, b.pressures) for b in model.bodies)
    model = Model(bodies, model.interface, mu=MU)
    A = [assemble_body(b) for b in model.bodies]
    with pytest.raises(InputError, match=r"the clamps hold a combination of the relative "
                       r"displacements of contact points \[0\]"):
        reduce_two_bodies(A[0], A[1], make_pairing(model))


def test_interface_node_pinned_on_one_side():
    """sandwich-2d with one interface node of the top beam pinned (both components, the
    bottom beam's partner free): the run goes through, and at that pair the relative
    displacement is the bottom node's displacement with its sign turned, the pinned node
    staying at zero, for the preload and at every level."""
    import dataclasses
    from qsma.examples import sandwich_2d
    m = sandwich_2d(1)
    top = m.bodies[1]
    node = int(top.mesh.nodes("interface")[3])
    mesh = top.mesh.with_sets(node_sets={"pin": [node]})
    top = dataclasses.replace(top, mesh=mesh, clamps=(Clamp("clamp"), Clamp("pin")))
    model = dataclasses.replace(m, bodies=(m.bodies[0], top))
    res = qsma.run(model, levels=qsma.Levels("tip", (1e-6, 1e-5)), refine_levels=False)
    assert res.success
    p = res.pairing
    i = int(np.flatnonzero(p.nodes2 == node)[0])
    a = np.zeros(len(res.reduced.patterns))
    a[res.reduced.patterns.index("preload")] = 1.0
    u1, u2 = res.reduced.recover(res.preload.d, a)
    assert np.all(u2[2 * node:2 * node + 2] == 0.0)
    partner = p.nodes1[i]
    d_i = res.preload.d.reshape(-1, 2)[i]
    assert np.allclose(d_i, -p.frames[i] @ u1[2 * partner:2 * partner + 2],
                       rtol=1e-9, atol=1e-12 * np.abs(res.preload.d).max())


@needs_ccx
def test_calculix_agrees_on_the_half_model(tmp_path):
    """The half beams (:func:`_beams`, symmetry clamps on the interface of both bodies)
    written as a CalculiX deck (``qsma export --calculix``) and run by ccx, which
    models the clamped contact nodes itself: its tied frequency equals qsma's to the 7
    digits it prints, its preload contact forces equal qsma's to the penalty
    (benchmarks/bench_export_calculix.py; measured with ccx 2.20: 4.3e-6 of the largest
    force, the sums to 1.3e-8; the whole model: 3.8e-6)."""
    from helpers import load_benchmark
    r = load_benchmark("bench_export_calculix").compare(_beams(True), tmp_path)
    assert r["f0_tied"] == pytest.approx(r["f0_qsma"], rel=1e-6)
    assert r["closed_ccx"] == r["closed_qsma"]
    assert r["max_diff"] < 5e-5
    assert r["total_ccx"] == pytest.approx(r["total_qsma"], rel=1e-6)


def test_hertz_on_a_quarter_model():
    """Hertz on the quarter model (x, y >= 0, symmetry clamps on both bodies): a sphere
    of radius R on a block of the same material, E* = E / (2 (1 - nu^2)); the contact
    radius a = (3 P R / (4 E*))^(1/3) for the whole load P = 4 x the quarter's contact
    resultant, which equals the load on the quarter's top face. Measured: 1.5 % on
    16 cells per half width (the FE radius is the middle of the edge interval; 6.0 %
    on 12 cells)."""
    same = Material(70e9, 0.3, 2700.0)
    model = _blocks_3d((0, 1), 16, 16)
    model = Model(tuple(Body(b.name, b.mesh, same, b.clamps, b.pressures)
                        for b in model.bodies), model.interface, mu=MU)
    p, rm, res, _, _ = _preload(model, lambda x: x[:, 0] ** 2 + x[:, 1] ** 2)
    quarter = res.lam[:, -1].sum()
    # the top block is held by the joint only: the regularising spring along its
    # rigid motion (docs/theory.md section 10) takes 1.5e-6 of the load here
    assert quarter == pytest.approx(P_TOP * W ** 2, rel=1e-5)
    Estar = same.E / (2 * (1 - same.nu ** 2))
    a_th = (3 * 4 * quarter * R / (4 * Estar)) ** (1 / 3)
    r = np.linalg.norm(p.x[:, :2], axis=1)
    closed = res.status != 2
    edge_in = r[closed].max()
    edge_out = r[~closed][r[~closed] > edge_in].min()
    a_fe = 0.5 * (edge_in + edge_out)
    assert abs(a_fe - a_th) < 0.04 * a_th


def test_prescribed_displacement_on_an_interface_node_is_refused():
    """A clamp that moves an interface node (a displacement other than zero) would give
    the relative displacement a prescribed part that the contact problem, written over
    the unclamped DOFs, does not see: refused, naming the body, the nodes and the fix."""
    model = _blocks_2d(True, 24)
    top = model.bodies[1]
    edge = np.flatnonzero((np.abs(top.mesh.points[:, 0] - W) < EPS)
                          & (np.abs(top.mesh.points[:, 1]) < EPS))
    mesh = top.mesh.with_sets(node_sets=dict(top.mesh.node_sets, edge=edge))
    top = Body("top", mesh, top.material, top.clamps
               + (Clamp("edge", (0,), displacement=(1e-6,)),), top.pressures)
    model = Model((model.bodies[0], top), model.interface, mu=MU)
    A = [assemble_body(b) for b in model.bodies]
    with pytest.raises(InputError, match=r"body 'top': interface node\(s\) \[\d+(, \d+)*\] "
                       r"have a prescribed displacement other than zero"):
        reduce_two_bodies(A[0], A[1], make_pairing(model))


def test_partly_tied_modes_by_the_full_solve_equal_the_substructured_ones():
    """Tied modes with an interface law rigid in one local direction and compliant in
    the other (a spring k normal to the face, the tangent tied): the factorised tied
    stiffness (which a clamped interface's reduced model leaves to it) eliminates the
    tied components by constraints and gives the frequencies the condensed two-body
    solve gives, to 1e-8 (sandwich-2d)."""
    from qsma.examples import sandwich_2d
    from qsma.modal import linear_modes
    m = sandwich_2d(1)
    p = make_pairing(m)
    A = [assemble_body(b) for b in m.bodies]
    rm = reduce_two_bodies(A[0], A[1], p)
    springs = np.column_stack([np.full(p.n_pairs, np.inf), np.full(p.n_pairs, 1e12) * p.area])
    tied = np.ones(p.n_pairs, bool)
    sub = linear_modes(m, A, p, tied=tied, n_modes=4, reduced=rm, springs=springs)
    full = linear_modes(m, A, p, tied=tied, n_modes=4, reduced=None, springs=springs)
    assert np.allclose(full.omega, sub.omega, rtol=1e-8, atol=0)
    free = linear_modes(m, A, p, tied=~tied, n_modes=4)
    assert sub.omega[0] > 1.01 * free.omega[0]        # the springs matter
