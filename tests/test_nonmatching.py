"""Non-matching interfaces: the dual mortar coupling against exact answers.

Every mesh here is built on its own grid (``structured_mesh``), so the two sides of
an interface have nodes at different places unless a test says otherwise.
"""
import dataclasses

import numpy as np
import pytest

import qsma
from qsma.reduction.two_bodies import reduce_two_bodies
from qsma.contact import ContactProblem, solve as contact_solve
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.model import Body, Clamp, Interface, Mesh, Model, Pressure, make_pairing
from qsma.mesh.generate import structured_mesh

from helpers import (BLOCK_H as H, BLOCK_STEEL as STEEL, BLOCK_W as W, HEX_TO_TETS,
                     assert_forced_mortar_is_node_to_node,
                     assert_uniform_interference_pressure, block_sets, jitter_contact_zone,
                     ring_interface_pressure, shifted_top, welded_body_forces)


def _axes(n, *extent):
    return [np.linspace(0.0, e, k + 1) for e, k in zip(extent, n)]


def _block(y0, n, dim, held):
    """A block ``[0, W] x [y0, y0 + H] (x [0, W])`` with ``n`` elements per direction.
    ``held``: "bottom" clamps u_y on its lower face and u_x (u_z) on edges of that face
    (no interface node), "top" the same on its upper face, "" nothing."""
    ax = _axes(n, *([W, H, W] if dim == 3 else [W, H]))
    ax[1] = ax[1] + y0
    return block_sets(structured_mesh(*ax), y0, dim, held)


def _stack(n_bottom, n_top, dim, slave=None, top_held=False, p=0.0):
    """Two stacked blocks, interface y = H, pressure ``p`` on the top face."""
    mb, cb = _block(0.0, n_bottom, dim, "bottom")
    mt, ct = _block(H, n_top, dim, "top" if top_held else "")
    bottom = Body("bottom", mb, STEEL, clamps=cb)
    top = Body("top", mt, STEEL, clamps=ct,
               pressures=(Pressure("upper", p),) if p else ())
    return Model((bottom, top), Interface("bottom", "upper", "top", "lower",
                                          coupling="mortar", slave=slave))


RATIOS_2D = [((8, 4), (5, 3)), ((3, 2), (7, 2)), ((10, 3), (10, 5)), ((13, 2), (4, 3))]
RATIOS_3D = [((4, 2, 4), (3, 2, 5)), ((2, 1, 3), (5, 2, 4))]
CASES = [(nb, nt, 2, s) for nb, nt in RATIOS_2D for s in ("bottom", "top")] + \
        [(nb, nt, 3, s) for nb, nt in RATIOS_3D for s in ("bottom", "top")]


@pytest.mark.parametrize("n_bottom, n_top, dim, slave", CASES)
def test_projection_reproduces_linear_fields_and_partitions_unity(n_bottom, n_top, dim, slave):
    m = _stack(n_bottom, n_top, dim, slave)
    p = make_pairing(m)
    assert p.coupling == "mortar" and p.slave == (1 if slave == "bottom" else 2)
    N = p.projection
    slave_mesh = m.bodies[p.slave - 1].mesh
    master_mesh = m.bodies[2 - p.slave].mesh
    np.testing.assert_allclose(N.sum(axis=1).A1, 1.0, rtol=0, atol=1e-13)
    xm = master_mesh.points[p.master_nodes]
    xs = slave_mesh.points[p.contact_nodes]
    np.testing.assert_allclose(N @ xm, xs, rtol=0, atol=1e-14 * W)
    # tributary areas add up to the interface area
    assert p.area.sum() == pytest.approx(W ** (dim - 1), rel=1e-13)
    assert np.abs(p.gap).max() < 1e-14 * W


@pytest.mark.parametrize("n_bottom, n_top, dim, slave", CASES)
def test_patch_test_pressure_passes_a_welded_nonmatching_interface(n_bottom, n_top, dim,
                                                                   slave):
    """Pressure on top, bottom held: with the interface tied by the mortar multipoint
    constraint the stress is uniform, so every slave node carries p x its area and every
    master node the consistent nodal force of p, to round-off."""
    pressure = 3e6
    m = _stack(n_bottom, n_top, dim, slave, p=pressure)
    pr = make_pairing(m)
    forces = welded_body_forces(m, pr)
    s, mst = pr.slave - 1, 2 - pr.slave
    on_slave = forces[s][pr.contact_nodes]
    sign = -1.0 if s == 0 else 1.0                  # bottom is pushed down, top up
    traction = on_slave[:, 1] / pr.area
    np.testing.assert_allclose(traction, sign * pressure, rtol=1e-9)
    assert np.abs(np.delete(on_slave, 1, axis=1)).max() < 1e-9 * pressure * pr.area.max()
    # master side: the consistent nodal force of the same pressure on its own facets
    mb = m.bodies[mst]
    facets = mb.mesh.facets("upper" if mst == 0 else "lower")
    consistent = np.zeros(mb.mesh.n_nodes)
    from qsma.mesh.facets import facet_normals
    a_f = np.linalg.norm(facet_normals(mb.mesh, facets), axis=1)
    np.add.at(consistent, facets.ravel(), np.repeat(a_f / facets.shape[1], facets.shape[1]))
    on_master = forces[mst][pr.master_nodes, 1]
    np.testing.assert_allclose(on_master, -sign * pressure * consistent[pr.master_nodes],
                               rtol=1e-9, atol=1e-9 * pressure * a_f.max())




def _as_tetra(model, k):
    """Body ``k`` split into tetrahedra (triangular interface facets), sets rebuilt."""
    b = model.bodies[k]
    tets = np.concatenate([b.mesh.cells[:, list(t)] for t in HEX_TO_TETS])
    q = b.mesh.points[tets]
    vol = np.einsum("ij,ij->i", np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]),
                    q[:, 3] - q[:, 0])
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    mesh = Mesh(b.mesh.points, tets, "tetra", b.mesh.node_sets)
    y = b.mesh.points[:, 1]
    e = 1e-9 * W
    mesh = mesh.with_sets(facet_sets={
        "lower": mesh.boundary_facets_where(lambda p: np.abs(p[:, 1] - y.min()) < e),
        "upper": mesh.boundary_facets_where(lambda p: np.abs(p[:, 1] - y.max()) < e)})
    bodies = list(model.bodies)
    bodies[k] = dataclasses.replace(b, mesh=mesh)
    return dataclasses.replace(model, bodies=tuple(bodies))


@pytest.mark.parametrize("slave", ["bottom", "top"])
def test_patch_test_triangles_against_quadrilaterals(slave):
    """Tetrahedra (triangular facets) on top of hexahedra (quadrilateral facets), meshed
    on different grids: affine triangles make every integrand polynomial, so the welded
    pressure passes to round-off."""
    pressure = 3e6
    m = _as_tetra(_stack((4, 2, 4), (3, 2, 5), 3, slave, p=pressure), 1)
    pr = make_pairing(m)
    assert m.bodies[1].mesh.facets("lower").shape[1] == 3
    np.testing.assert_allclose(pr.projection.sum(axis=1).A1, 1.0, rtol=0, atol=1e-13)
    f = welded_body_forces(m, pr)[pr.slave - 1][pr.contact_nodes]
    np.testing.assert_allclose(np.abs(f[:, 1]) / pr.area, pressure, rtol=1e-9)


def _distorted(model, k, amp):
    """Body ``k`` with its nodes moved in the x-z plane (faces stay planar): the facets
    of the interface become general (non-parallelogram) quadrilaterals."""
    b = model.bodies[k]
    p = b.mesh.points.copy()
    x, z = p[:, 0] / W, p[:, 2] / W
    p[:, 0] += amp * np.sin(np.pi * x) * np.sin(2 * np.pi * z)
    p[:, 2] += amp * np.sin(2 * np.pi * x) * np.sin(np.pi * z)
    mesh = Mesh(p, b.mesh.cells, b.mesh.cell_type, b.mesh.node_sets, b.mesh.facet_sets)
    bodies = list(model.bodies)
    bodies[k] = dataclasses.replace(b, mesh=mesh)
    return dataclasses.replace(model, bodies=tuple(bodies))


@pytest.mark.parametrize("slave", ["bottom", "top"])
def test_patch_test_with_distorted_quadrilaterals(slave):
    """Non-parallelogram quads on both sides: the projection still partitions unity and
    reproduces linear fields to round-off (biorthogonality holds at the integration
    points), and the welded pressure is uniform to quadrature accuracy: the products of
    bilinear functions are rational in the clipped pieces; the 4 x 4 collapsed Gauss
    rule leaves 3e-9 (measured), asserted at 1e-7."""
    pressure = 3e6
    m = _stack((4, 2, 4), (3, 2, 5), 3, slave, p=pressure)
    m = _distorted(_distorted(m, 1, 0.15 * W / 5), 0, 0.1 * W / 4)
    pr = make_pairing(m)
    xs = m.bodies[pr.slave - 1].mesh.points[pr.contact_nodes]
    xm = m.bodies[2 - pr.slave].mesh.points[pr.master_nodes]
    np.testing.assert_allclose(pr.projection.sum(axis=1).A1, 1.0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(pr.projection @ xm, xs, rtol=0, atol=1e-14 * W)
    f = welded_body_forces(m, pr)[pr.slave - 1][pr.contact_nodes]
    np.testing.assert_allclose(np.abs(f[:, 1]) / pr.area, pressure, rtol=1e-7)


@pytest.mark.parametrize("n_bottom, n_top, dim, slave", CASES[::3])
def test_contact_patch_test_interference_gives_uniform_pressure(n_bottom, n_top, dim, slave):
    """Both blocks held on their outer faces and pressed together by a uniform initial
    interference delta, through the condensed mortar problem and the contact solver:
    uniform pressure E_u delta / (2 H), E_u = E / (1 - nu^2) in plane strain (uniaxial
    stress, free lateral faces), E in 3D; no shear (equal lateral strains)."""
    assert_uniform_interference_pressure(_stack(n_bottom, n_top, dim, slave, top_held=True))


def test_conforming_mortar_gives_the_node_to_node_answer():
    """sandwich-2d with the projection forced on a conforming interface: f0, q and zeta
    of the node-to-node run to 1e-8 (the projection is the identity to round-off)."""
    a, b, _ = assert_forced_mortar_is_node_to_node(sandwich_2d(1))
    assert (b.n_slip == a.n_slip).all() and (b.n_open == a.n_open).all()


# ------------------------------------------------------------------ curved interface
def test_curved_nonmatching_interface_converges_to_lame():
    """A circular interface meshed with 48 and 35 segments (polygons that differ by up to
    1.4 % of an element): mapped along the master normal field, the welded pressure has
    the conforming mesh's accuracy on average (Lame to 0.27 % at refine 1, 0.066 % at
    refine 2, measured; the same as 48 / 48 node-to-node) and a pointwise scatter that
    halves with h (0.41 %, 0.14 %, 0.054 % at refine 1, 2, 4)."""
    pr, conf, exact = ring_interface_pressure(1, 48)
    assert pr.coupling == "node"
    errors = []
    for refine in (1, 2):
        pr, pres, exact = ring_interface_pressure(refine, 35)
        assert pr.coupling == "mortar" and 0 < np.abs(pr.gap).max() < 0.02 * 2 * np.pi * 0.03 / 35
        assert abs(pres.mean() / exact - 1) < 3e-3 / refine ** 2      # O(h^2), as conforming
        errors.append(np.abs(pres / exact - 1).max())
    assert abs(conf.mean() / exact - 1) < 3e-3
    assert errors[0] < 6e-3 and errors[1] < 0.5 * errors[0]


# ------------------------------------------------------------------ never snapped
def test_approximately_matching_nodes_are_refused_not_snapped():
    """Equal node counts a fraction of an element apart: the node coupling refuses and
    points to the mortar coupling; tol cannot be raised to glue them; "auto" couples
    them properly (and a conforming mesh stays node-to-node)."""
    base = sandwich_2d(1)
    m = shifted_top(base, jitter_contact_zone)
    m = dataclasses.replace(m, interface=dataclasses.replace(m.interface, coupling="node"))
    with pytest.raises(InputError, match=r"no partner(.|\n)*never snapped(.|\n)*mortar"):
        make_pairing(m)
    glued = dataclasses.replace(m.interface, tol=3e-4)      # below half the spacing
    with pytest.raises(InputError, match="cannot glue meshes.*mortar"):
        make_pairing(dataclasses.replace(m, interface=glued))
    auto = dataclasses.replace(m, interface=dataclasses.replace(m.interface, coupling="auto"))
    assert make_pairing(auto).coupling == "mortar"
    base_auto = dataclasses.replace(base, interface=dataclasses.replace(base.interface,
                                                                        coupling="auto"))
    assert make_pairing(base_auto).coupling == "node"


def test_bad_coupling_options_are_refused():
    with pytest.raises(InputError, match="coupling must be one of"):
        Interface("a", "s", "b", "t", coupling="segment")
    with pytest.raises(InputError, match="slave must name one of its bodies"):
        Interface("a", "s", "b", "t", coupling="mortar", slave="c")


# ------------------------------------------------------------------ bad input
def test_surface_that_projects_nowhere():
    m = shifted_top(sandwich_2d(1), lambda p: np.full(len(p), 0.3))
    m = dataclasses.replace(m, interface=dataclasses.replace(m.interface, coupling="mortar"))
    with pytest.raises(InputError, match=r"body 'bottom' set 'interface'.*projects nowhere"
                                         r"(.|\n)*Fix:"):
        make_pairing(m)


def test_offset_surfaces_couple_their_overlap_and_report_the_rest():
    """The top beam shifted by 0.3 mm: neither side lies within the other. The overlap
    is coupled (rows of P sum to one, linear fields reproduced, the tributary areas add
    up to the overlap) and the 0.3 mm of the slave that faces nothing is reported, to
    round-off; QSMA runs through it."""
    from qsma.errors import PartialCoverageWarning
    from qsma.model.coupling import mortar_operator
    shift, length = 3e-4, 0.0508                    # sandwich-2d contact zone
    m = shifted_top(sandwich_2d(1), lambda p: np.full(len(p), shift))
    m = dataclasses.replace(m, interface=dataclasses.replace(m.interface, coupling="auto"))
    bottom, top = m.bodies
    op = mortar_operator(bottom.mesh, bottom.mesh.facets("interface"), top.mesh,
                         top.mesh.facets("interface"))
    assert op.slave_area == pytest.approx(length, rel=1e-12)
    assert op.unmatched_area == pytest.approx(shift, rel=1e-9)
    assert op.area.sum() == pytest.approx(length - shift, rel=1e-12)
    np.testing.assert_allclose(op.P.sum(axis=1).A1, 1.0, rtol=0, atol=1e-13)
    xs, xm = bottom.mesh.points[op.slave_nodes], top.mesh.points[op.master_nodes]
    np.testing.assert_allclose(op.P @ xm[:, 0], xs[:, 0], rtol=0, atol=1e-15)
    assert np.all(op.area > 0)              # the end facet is partly covered: kept
    with pytest.warns(PartialCoverageWarning, match=r"0.591 % of the slave surface"):
        res = qsma.run(m, levels=qsma.Levels.log("tip", 1e-5, 1e-3, 3), method="basket")
    assert res.success and res.model_info["coupling"] == "mortar"


def _holed_plate(y0, n, centre, half):
    """A plate [0, W] x [y0, y0 + H] x [0, W] of n x 2 x n hexahedra with a square hole
    through it: the cells whose centres lie within ``half`` of ``centre`` (x and z)
    removed. Returns the mesh (facet sets 'lower', 'upper') and the hole's extent."""
    m = structured_mesh(np.linspace(0, W, n + 1), np.linspace(y0, y0 + H, 3),
                        np.linspace(0, W, n + 1))
    c = m.points[m.cells].mean(axis=1)
    keep = ~((np.abs(c[:, 0] - centre) < half) & (np.abs(c[:, 2] - centre) < half))
    cells = m.cells[keep]
    used = np.unique(cells)
    renumber = np.full(m.n_nodes, -1)
    renumber[used] = np.arange(len(used))
    mesh = Mesh(m.points[used], renumber[cells], "hexahedron")
    e = 1e-9 * W
    mesh = mesh.with_sets(facet_sets={
        "lower": mesh.boundary_facets_where(lambda p: np.abs(p[:, 1] - y0) < e),
        "upper": mesh.boundary_facets_where(lambda p: np.abs(p[:, 1] - y0 - H) < e)})
    hole = c[~keep][:, 0]
    pitch = W / n
    return mesh, (hole.min() - pitch / 2, hole.max() + pitch / 2)


def test_plates_with_holes_meshed_apart_couple_their_overlap():
    """Two plates with a bolt hole each, meshed apart (4 mm and 5.7 mm elements, the holes
    16-24 mm and 17.1-28.6 mm square): neither surface covers the other, whichever is
    the slave. The overlap is coupled exactly (rows of P sum to one, linear fields
    reproduced, sum of D = the overlap's area) and the unmatched area is the part of the
    master's hole over the slave's material, to round-off; the tied modes solve."""
    from qsma.model.coupling import mortar_operator
    from qsma.modal import linear_modes
    mb, hb = _holed_plate(0.0, 10, 0.020, 0.006)
    mt, ht = _holed_plate(H, 7, 0.021, 0.006)
    overlap = max(0.0, min(hb[1], ht[1]) - max(hb[0], ht[0])) ** 2
    for (ms, hs), (mm, hm) in (((mb, hb), (mt, ht)), ((mt, ht), (mb, hb))):
        face = "upper" if ms is mb else "lower"
        op = mortar_operator(ms, ms.facets(face), mm, mm.facets("upper" if mm is mb
                                                                  else "lower"))
        unmatched = (hm[1] - hm[0]) ** 2 - overlap        # master hole over slave material
        assert op.slave_area == pytest.approx(W ** 2 - (hs[1] - hs[0]) ** 2, rel=1e-12)
        assert op.unmatched_area == pytest.approx(unmatched, rel=1e-9)
        assert op.area.sum() == pytest.approx(op.slave_area - unmatched, rel=1e-12)
        np.testing.assert_allclose(op.P.sum(axis=1).A1, 1.0, rtol=0, atol=1e-12)
        xs, xm = ms.points[op.slave_nodes], mm.points[op.master_nodes]
        np.testing.assert_allclose(op.P @ xm[:, [0, 2]], xs[:, [0, 2]], rtol=0,
                                   atol=1e-13 * W)
    _, cb = _block(0.0, (1, 1, 1), 3, "")
    edge = lambda m, y: np.flatnonzero((m.points[:, 0] < 1e-9) & (np.abs(m.points[:, 1] - y) < H))
    bottom = Body("bottom", mb.with_sets(node_sets={"end": edge(mb, 0.0)}), STEEL,
                  clamps=(Clamp("end"),))
    top = Body("top", mt.with_sets(node_sets={"end": np.flatnonzero(
        mt.points[:, 0] > W - 1e-9)}), STEEL, clamps=(Clamp("end"),))
    model = Model((bottom, top), Interface("bottom", "upper", "top", "lower"))
    with pytest.warns(qsma.errors.PartialCoverageWarning):
        pairing = make_pairing(model)
    assert pairing.coupling == "mortar"
    modes = linear_modes(model, [assemble_body(b) for b in model.bodies], pairing,
                         n_modes=2)
    assert np.all(modes.f_hz > 0)


def test_normals_pointing_the_same_way():
    """Both facet sets are upper faces at the same height (the second block inside the
    first): refused with the fix, not coupled."""
    mb, cb = _block(0.0, (4, 2), 2, "bottom")
    mt, ct = _block(0.0, (3, 2), 2, "bottom")
    m = Model((Body("bottom", mb, STEEL, clamps=cb), Body("top", mt, STEEL, clamps=ct)),
              Interface("bottom", "upper", "top", "upper", coupling="mortar"))
    with pytest.raises(InputError, match=r"body 'bottom' set 'upper' / body 'top' set "
                                         r"'upper'.*point the same way.*Fix"):
        make_pairing(m)


def test_overlapping_bodies_are_refused():
    """The top block sunk by half an element into the bottom one."""
    mb, cb = _block(0.0, (4, 2), 2, "bottom")
    mt, ct = _block(H - 0.5 * W / 4, (3, 2), 2, "")
    m = Model((Body("bottom", mb, STEEL, clamps=cb), Body("top", mt, STEEL, clamps=ct)),
              Interface("bottom", "upper", "top", "lower", coupling="mortar"))
    with pytest.raises(InputError, match=r"overlap \(interpenetrate\).*Fix: move the bodies"):
        make_pairing(m)


# ------------------------------------------------------------------ QSMA through mortar
@pytest.fixture(scope="module")
def jittered():
    m = shifted_top(sandwich_2d(1), jitter_contact_zone)
    return dataclasses.replace(m, interface=dataclasses.replace(m.interface,
                                                                coupling="auto"))


def test_every_contact_solver_accepts_the_projected_problem(jittered):
    from qsma.contact import METHODS, residual
    pr = make_pairing(jittered)
    A = [assemble_body(b) for b in jittered.bodies]
    rm = reduce_two_bodies(A[0], A[1], pr)
    prob = ContactProblem(rm.K, jittered.mu, dim=2)
    lam_w = rm.welded_contact_force([1.0])
    ref = None
    for method in sorted(METHODS):
        if method == "nodal_gs":          # the capped baseline (docs/contact.md)
            continue
        res = contact_solve(prob, lam_w, method=method)
        assert res.success, method
        assert residual(prob, lam_w, res.d, res.lam) <= 1e-8
        ref = res.status if ref is None else ref
        assert (res.status == ref).all(), method


def test_qsma_through_a_nonmatching_interface(jittered):
    """QSMA on sandwich-2d whose top beam has its contact-zone nodes moved by up to a
    quarter element: the same physics as the conforming run (f0 within 0.05 %, stuck
    regime exactly linear, zeta >= 0, frequency non-increasing, zeta close)."""
    res, conf = qsma.run(jittered), qsma.run(sandwich_2d(1))
    assert res.success and res.pairing.coupling == "mortar"
    assert res.f0_hz == pytest.approx(conf.f0_hz, rel=5e-4)
    stuck = res.n_slip == 0
    assert stuck[:10].all()
    np.testing.assert_allclose(res.f_hz[stuck], res.f0_hz, rtol=1e-6)
    assert np.abs(res.zeta[stuck]).max() < 1e-8
    assert (res.zeta >= -1e-12).all() and (np.diff(res.f_hz) <= 1e-9 * res.f0_hz).all()
    # microslip levels (30-45) within 5 %, gross slip (last level) within 1 %; the onset
    # of gross slip (levels 46-48) is sensitive to the edge of the closed zone
    np.testing.assert_allclose(res.zeta[30:46], conf.zeta[30:46], rtol=0.05)
    assert res.zeta[-1] == pytest.approx(conf.zeta[-1], rel=0.01)


# ------------------------------------------------------------------ initial gaps
def test_mortar_gap_is_the_initial_gap_of_the_contact_problem():
    """The top plate of sandwich-2d lifted by delta = 1 um (a thousandth of an element):
    the mortar gap is +delta at every contact point (to 1e-9), the contact problem
    starts from it (gap0), the run says so (InterfaceGapWarning), and every pair the
    bolt closes has d_n = -delta (the opening d_n + g0 is zero) while open pairs keep
    d_n + g0 > 0."""
    from qsma.errors import InterfaceGapWarning
    delta = 1e-6
    base = sandwich_2d(1)
    top = base.bodies[1]
    pts = top.mesh.points.copy()
    pts[:, 1] += delta
    mesh = Mesh(pts, top.mesh.cells, top.mesh.cell_type, top.mesh.node_sets,
                top.mesh.facet_sets)
    m = dataclasses.replace(base, bodies=(base.bodies[0], dataclasses.replace(top, mesh=mesh)),
                            interface=dataclasses.replace(base.interface, coupling="mortar"))
    with pytest.warns(InterfaceGapWarning, match="1.000e-06 apart.*initial gaps"):
        res = qsma.run(m, levels=qsma.Levels.log("tip", 1e-6, 1e-5, 3))
    assert res.success
    # the warning is kept with the result (results.json, report.html), once
    assert len(res.warnings) == 1 and "initial gaps" in res.warnings[0]
    from qsma.output.report import run_warnings
    from qsma.output.files import results_dict
    assert results_dict(res)["warnings"] == list(res.warnings)
    assert any("initial gaps" in w for w in run_warnings(res))
    assert np.allclose(res.pairing.gap, delta, rtol=1e-9)
    pre = res.preload
    closed = pre.status != 2
    assert closed.any() and (~closed).any()
    opening = pre.d[:, -1] + delta
    assert np.abs(opening[closed]).max() < 1e-9 * delta
    assert opening[~closed].min() > 0
