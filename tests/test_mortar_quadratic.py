"""The dual mortar coupling on quadratic facets (line3, triangle6, quad8, quad9) of two
blocks meshed on different grids, against exact answers: the projection partitions
unity and reproduces linear fields, a welded pressure passes with the consistent nodal
forces of both sides, and an interference gives the uniform contact pressure."""
import dataclasses

import numpy as np
import pytest
from scipy.spatial import cKDTree

from qsma.contact import ContactProblem, solve as contact_solve
from qsma.fe import assemble_body
from qsma.mesh.generate import structured_mesh
from qsma.modal import tie_transform
from qsma.model import Body, Interface, Mesh, Model, Pressure, make_pairing
from qsma.model.dual_basis import MIXING
from qsma.reduction.two_bodies import reduce_two_bodies

from helpers import (BLOCK_H as H, BLOCK_STEEL as STEEL, BLOCK_W as W, HEX_TO_TETS,
                     assert_forced_mortar_is_node_to_node,
                     assert_uniform_interference_pressure, block_sets, jitter_contact_zone,
                     needs_ccx, ring_interface_pressure, shifted_top, welded_body_forces)


def _tetra10(mesh):
    """A hexahedral mesh split into tetrahedra (Kuhn), midside nodes added."""
    tets = np.concatenate([mesh.cells[:, list(t)] for t in HEX_TO_TETS])
    q = mesh.points[tets]
    vol = np.einsum("ij,ij->i", np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]),
                    q[:, 3] - q[:, 0])
    tets[vol < 0] = tets[vol < 0][:, [0, 2, 1, 3]]
    pairs = [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]       # tetra10 edge order
    edges = np.sort(np.stack([tets[:, list(p)] for p in pairs], axis=1), axis=2)
    unique, inverse = np.unique(edges.reshape(-1, 2), axis=0, return_inverse=True)
    mids = len(mesh.points) + inverse.reshape(len(tets), 6)
    points = np.vstack([mesh.points, mesh.points[unique].mean(axis=1)])
    return Mesh(points, np.hstack([tets, mids]), "tetra10")


def _block(y0, n, dim, held, cell_type):
    """A block ``[0, W] x [y0, y0 + H] (x [0, W])`` of ``n`` cells per direction of
    ``cell_type``, sets and clamps as in tests/test_nonmatching.py."""
    ax = [np.linspace(0.0, e, k + 1) for e, k in zip([W, H, W][:dim], n)]
    ax[1] = ax[1] + y0
    if cell_type == "tetra10":
        m = _tetra10(structured_mesh(*ax))
    else:
        m = structured_mesh(*ax, cell_type=cell_type)
    return block_sets(m, y0, dim, held)


def _stack(case, slave, top_held=False, p=0.0):
    (nb, tb), (nt, tt) = case
    dim = len(nb)
    mb, cb = _block(0.0, nb, dim, "bottom", tb)
    mt, ct = _block(H, nt, dim, "top" if top_held else "", tt)
    bottom = Body("bottom", mb, STEEL, clamps=cb)
    top = Body("top", mt, STEEL, clamps=ct, pressures=(Pressure("upper", p),) if p else ())
    return Model((bottom, top), Interface("bottom", "upper", "top", "lower",
                                          coupling="mortar", slave=slave))


# (bottom cells, type), (top cells, type): different grids, mixed kinds
CASES = {
    "quad8": (((5, 2), "quad8"), ((3, 2), "quad8")),
    "quad9-quad8": (((4, 2), "quad9"), ((7, 2), "quad8")),
    "hex20": (((3, 1, 2), "hexahedron20"), ((2, 1, 3), "hexahedron20")),
    "hex27-hex20": (((2, 1, 3), "hexahedron27"), ((3, 1, 2), "hexahedron20")),
    "tet10-hex20": (((2, 1, 2), "tetra10"), ((3, 1, 2), "hexahedron20")),
    "hex8-tet10": (((3, 1, 2), None), ((2, 1, 2), "tetra10")),
}
PARAMS = [(k, s) for k in CASES for s in ("bottom", "top")]


@pytest.mark.parametrize("case, slave", PARAMS)
def test_projection_partitions_unity_and_reproduces_linear_fields(case, slave):
    """Rows of P sum to one, P maps the master coordinates onto the slave's (a linear
    field; on straight / flat facets its mixed coefficients are its nodal values), the
    areas D are positive and add up to the interface, and the gap is zero."""
    m = _stack(CASES[case], slave)
    p = make_pairing(m)
    assert p.coupling == "mortar" and p.slave == (1 if slave == "bottom" else 2)
    smesh, mmesh = m.bodies[p.slave - 1].mesh, m.bodies[2 - p.slave].mesh
    assert (p.slave_basis is not None) == (smesh.facet_type in MIXING)
    N = p.projection
    np.testing.assert_allclose(N.sum(axis=1).A1, 1.0, rtol=0, atol=1e-13)
    np.testing.assert_allclose(N @ mmesh.points[p.master_nodes],
                               smesh.points[p.contact_nodes], rtol=0, atol=1e-14 * W)
    assert p.area.min() > 0
    assert p.area.sum() == pytest.approx(W ** (len(CASES[case][0][0]) - 1), rel=1e-13)
    assert np.abs(p.gap).max() < 1e-14 * W


def _consistent(body, name, pressure):
    """Consistent nodal forces of a pressure on facet set ``name`` of ``body``."""
    b = dataclasses.replace(body, clamps=(), pressures=(Pressure(name, pressure),))
    return assemble_body(b).loads["preload"].reshape(b.mesh.n_nodes, -1)


@pytest.mark.parametrize("case, slave", PARAMS)
def test_welded_pressure_gives_the_consistent_forces_of_both_sides(case, slave):
    """Pressure on top, bottom held, the interface tied by the mortar constraint: the
    stress is uniform, so the force each body gets at its interface nodes is the
    consistent nodal force of the pressure on its own facets (negative at quad8
    corners), and the contact forces of the coefficients ``lam~ = B^T f`` are the
    pressure times D at every contact point, to round-off."""
    pressure = 3e6
    m = _stack(CASES[case], slave, p=pressure)
    pr = make_pairing(m)
    dim = m.dim
    forces = welded_body_forces(m, pr)
    s, mst = pr.slave - 1, 2 - pr.slave
    sets = ("upper", "lower")
    scale = pressure * W ** (dim - 1)
    for k, nodes in ((s, pr.contact_nodes), (mst, pr.master_nodes)):
        expected = _consistent(m.bodies[k], sets[k], pressure)[nodes]
        np.testing.assert_allclose(forces[k][nodes], expected, rtol=0, atol=1e-10 * scale)
    f_s = forces[s][pr.contact_nodes]
    lam = f_s if pr.slave_basis is None else pr.slave_basis.to_nodes.T @ f_s
    sign = -1.0 if s == 0 else 1.0                  # bottom is pushed down, top up
    np.testing.assert_allclose(lam[:, 1] / pr.area, sign * pressure, rtol=1e-9)


@pytest.mark.parametrize("case, slave", PARAMS[::3])
def test_interference_gives_uniform_contact_pressure(case, slave):
    """Both blocks held on their outer faces and pressed together by an interference
    delta, through the condensed mortar problem (the slave condensed on the mixed
    coefficients) and the contact solver: uniform pressure E_u delta / (2 H) at every
    contact point, no shear (tests/test_nonmatching.py, linear facets)."""
    m = _stack(CASES[case], slave, top_held=True)
    dim, delta = m.dim, 1e-6
    pr, rm, res = assert_uniform_interference_pressure(m, delta)
    # the recovered fields: the interference closed at every slave node
    u1, u2 = rm.recover(res.d, [1.0])
    s = pr.slave - 1
    us = (u1, u2)[s].reshape(-1, dim)[pr.contact_nodes, 1]
    np.testing.assert_allclose(np.abs(us), delta / 2, rtol=1e-8)


@pytest.mark.parametrize("case", ["hex20", "tet10-hex20"])
def test_several_body_reduction_agrees_with_the_two_body_one(case):
    """The reduction over several interfaces (the slave's mixed coefficients in the
    relative-displacement operator) gives the two-body problem's K and welded force."""
    from qsma.model.pairing import Coupling
    from qsma.reduction.multibody import reduce_bodies
    m = _stack(CASES[case], "top", top_held=True, p=1e6)
    pr = make_pairing(m)
    assert pr.slave_basis is not None
    A = [assemble_body(b) for b in m.bodies]
    rm = reduce_two_bodies(A[0], A[1], pr)
    mm = reduce_bodies(A, [Coupling(pr, 0, 1)])
    scale = np.abs(rm.K).max()
    np.testing.assert_allclose(mm.K, rm.K, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(mm.W, rm.W, rtol=0, atol=1e-9 * np.abs(rm.W).max())


# ------------------------------------------------------------------ end to end
def test_line3_mortar_on_a_conforming_quad8_mesh_is_node_to_node():
    """sandwich-2d in quad8 cells with the projection forced on its conforming interface:
    line3 facets need no mixing, the projection is the identity and the run gives the
    node-to-node f0, q and zeta (measured: 1e-10, 2e-10, 4e-11 apart)."""
    from qsma.examples import sandwich_2d
    _, _, pairing = assert_forced_mortar_is_node_to_node(sandwich_2d(1, element="quad8"))
    assert pairing.slave_basis is None


def test_quad8_parts_meshed_apart_give_the_conforming_answer():
    """sandwich-2d in quad8 cells, the top beam's contact-zone nodes moved by up to a
    quarter element (tests/test_nonmatching.py): tied frequency within 1e-4 of the
    conforming run (measured 6e-5), damping within 2 % at microslip (levels 30-45,
    measured 1.0 %) and 1 % at gross slip (measured 0.2 %)."""
    import qsma
    from qsma.examples import sandwich_2d
    m = sandwich_2d(1, element="quad8")
    j = shifted_top(dataclasses.replace(
        m, interface=dataclasses.replace(m.interface, coupling="mortar")), jitter_contact_zone)
    conf, res = qsma.run(m), qsma.run(j)
    assert res.success and res.pairing.coupling == "mortar"
    assert res.f0_hz == pytest.approx(conf.f0_hz, rel=1e-4)
    assert np.abs(res.zeta[:10]).max() < 1e-3 * conf.zeta.max()
    np.testing.assert_allclose(res.zeta[30:46], conf.zeta[30:46], rtol=0.02)
    assert res.zeta[-1] == pytest.approx(conf.zeta[-1], rel=0.01)


def test_facet_rows_of_the_wrong_length_are_refused_by_name():
    """Rows of corners only on a quad8 mesh name the set, the facet type and the fix."""
    from qsma.errors import InputError
    from qsma.model.coupling import mortar_operator
    m = _stack(CASES["quad8"], "top")
    top, bottom = m.bodies[1].mesh, m.bodies[0].mesh
    with pytest.raises(InputError, match="set 'lower' has facets of 2 nodes.*line3 facets "
                                         "of 3.*every node of each face"):
        mortar_operator(top, top.facets("lower")[:, :2], bottom, bottom.facets("upper"),
                        names=("top", "lower", "bottom", "upper"))


@pytest.mark.parametrize("case", ["hex20", "tet10-hex20"])
def test_partly_tied_modes_agree_between_the_full_and_the_condensed_solve(case):
    """Half the contact points tied (the others open) on mixed quadratic slave facets:
    the tie transform of the whole assembly (each tied coefficient eliminated, the open
    nodes' DOFs kept) and the condensed tied solve (d = 0 on the tied coefficients)
    give the same frequencies."""
    from qsma.modal.linear import linear_modes
    m = _stack(CASES[case], "top", top_held=True)
    pr = make_pairing(m)
    assert pr.slave_basis is not None
    A = [assemble_body(b) for b in m.bodies]
    rm = reduce_two_bodies(A[0], A[1], pr)
    tied = np.random.default_rng(3).random(pr.n_pairs) < 0.5
    from qsma.modal.substructured import identity_rows
    assert identity_rows(tie_transform(m, A, pr, tied)) is not None   # condensed path
    full = linear_modes(m, A, pr, tied, n_modes=4)
    sub = linear_modes(m, A, pr, tied, n_modes=4, reduced=rm)
    np.testing.assert_allclose(sub.omega, full.omega, rtol=1e-8)
    everywhere = linear_modes(m, A, pr, np.ones(pr.n_pairs, bool), n_modes=4)
    assert (full.omega <= everywhere.omega * (1 + 1e-9)).all()


# ------------------------------------------------------------------ curved facets
def _annulus(r0, r1, nr, nt, ct):
    """Full ring ``r0 <= r <= r1`` of nr x nt quadratic cells ``ct`` (midside nodes on
    the arcs: curved facets), the seam nodes merged."""
    m = structured_mesh(np.linspace(r0, r1, nr + 1), np.linspace(0, 2 * np.pi, nt + 1),
                        cell_type=ct)
    r, t = m.points[:, 0], m.points[:, 1]
    x = np.column_stack([r * np.cos(t), r * np.sin(t)])
    idx = np.flatnonzero(~np.isclose(t, 2 * np.pi))          # t = 2 pi: onto t = 0
    target = idx[cKDTree(x[idx]).query(x)[1]]
    number = np.full(len(x), -1)
    number[idx] = np.arange(len(idx))
    mesh = Mesh(x[idx], number[target[m.cells]], ct)
    on = lambda R: (lambda p: np.abs(np.hypot(p[:, 0], p[:, 1]) - R) < 1e-9 * r1)
    return mesh.with_sets(node_sets={"rim": np.flatnonzero(on(r1)(mesh.points))},
                          facet_sets={"in": mesh.boundary_facets_where(on(r0)),
                                      "out": mesh.boundary_facets_where(on(r1))})


@pytest.mark.parametrize("cell_type", ["quad8", "quad9"])
def test_curved_quadratic_facets_meshed_apart_converge_to_lame(cell_type):
    """Rings of quadratic cells (24 and 17 cells around at refine 1, midside nodes on
    the arc) welded through the mortar projection, integrated on the facets' chords: the
    interface pressure converges to Lame's like h^2 (measured mean error 0.42 %,
    0.106 %, 0.027 % at refine 1, 2, 4; pointwise 1.8 %, 0.43 %, 0.11 %; node-to-node
    on 24 / 24 cells: 0.07 %)."""
    errors = []
    for refine in (1, 2):
        pr, pres, exact = ring_interface_pressure(
            refine, 35, lambda r0, r1, nr, nt: _annulus(r0, r1, nr // 2, nt // 2, cell_type))
        assert pr.coupling == "mortar"
        errors.append((abs(pres.mean() / exact - 1), np.abs(pres / exact - 1).max()))
    assert errors[0][0] < 6e-3 and errors[0][1] < 0.025
    assert errors[1][0] < errors[0][0] / 3.5 and errors[1][1] < errors[0][1] / 3.5


@pytest.mark.parametrize("case", ["hex20", "tet10-hex20"])
def test_slave_held_only_by_the_joint_carries_its_pressure(case):
    """The top block unclamped (held only through the interface, its rigid motions
    expressed in the mixed coefficients through the inverse of the slave's R) and
    pressed by p on its upper face: the contact solver gives the dual traction p at
    every contact point and no shear."""
    pressure = 2e6
    m = _stack(CASES[case], "top", p=pressure)
    pr = make_pairing(m)
    assert pr.slave_basis is not None and pr.slave == 2
    A = [assemble_body(b) for b in m.bodies]
    rm = reduce_two_bodies(A[0], A[1], pr)
    top = rm.bodies[1]
    assert top.rigid is not None and top.R_inv is not None
    # its rigid-motion basis, taken back to nodal values, moves the nodes rigidly
    x = m.bodies[1].mesh.points[pr.contact_nodes]
    Z = np.concatenate([np.tile(np.eye(3), (len(x), 1))] + [
        np.cross(np.eye(3)[k], x).reshape(-1, 1) for k in range(3)], axis=1)
    moved = top.R @ top.rigid
    coef = np.linalg.lstsq(Z, moved, rcond=None)[0]
    assert np.abs(Z @ coef - moved).max() < 1e-10 * np.abs(moved).max()
    res = contact_solve(ContactProblem(rm.K, 0.3, dim=m.dim), rm.welded_contact_force([1.0]))
    assert res.success
    traction = res.lam / pr.area[:, None]
    np.testing.assert_allclose(traction[:, -1], pressure, rtol=1e-7)
    assert np.abs(traction[:, :-1]).max() < 1e-7 * pressure


# ------------------------------------------------------------------ 3D end to end
def _beam(y0, top, n_fine, cell_type, L=0.1, h=0.004, b=0.02, lc=0.03):
    """A cantilever (clamped at x = 0) of one cell through its thickness h, with
    ``n_fine`` cells along the contact zone ``L - lc <= x <= L`` of its inner face and a
    'bolt' facet set on the outer face over the same zone."""
    xs = np.concatenate([np.linspace(0, L - lc, 5)[:-1], np.linspace(L - lc, L, n_fine + 1)])
    mesh = structured_mesh(xs, np.linspace(y0, y0 + h, 2), np.linspace(0, b, 3),
                           cell_type=cell_type)
    eps = 1e-9 * L
    y_if, y_out = (y0, y0 + h) if top else (y0 + h, y0)
    zone = lambda y: (lambda p: (np.abs(p[:, 1] - y) < eps) & (p[:, 0] >= L - lc - eps))
    return mesh.with_sets(
        node_sets={"clamp": np.flatnonzero(np.abs(mesh.points[:, 0]) < eps),
                   "tip": np.flatnonzero(np.abs(mesh.points[:, 0] - L) < eps)},
        facet_sets={"interface": mesh.boundary_facets_where(zone(y_if)),
                    "bolt": mesh.boundary_facets_where(zone(y_out))})


def _lap(n_bottom, n_top, coupling, cell_type="hexahedron20"):
    """Two hexahedron20 cantilevers pressed together over their contact zone by 2 kN
    of pressure on their outer faces, meshed with ``n_bottom`` and ``n_top`` cells
    along it."""
    from qsma.model import Clamp, Material, Probe
    steel = Material(200e9, 0.3, 7800.0)
    p = 2000.0 / (0.03 * 0.02)
    bodies = tuple(Body(name, _beam(y0, top, n, cell_type), steel, clamps=(Clamp("clamp"),),
                        pressures=(Pressure("bolt", p),))
                   for name, y0, top, n in (("bottom", 0.0, False, n_bottom),
                                            ("top", 0.004, True, n_top)))
    return Model(bodies=bodies, interface=Interface("bottom", "interface", "top",
                                                    "interface", coupling=coupling),
                 tip=Probe(sets=(("bottom", "tip"), ("top", "tip")),
                           direction=(0.0, 1.0, 0.0)), mu=0.3)


@pytest.mark.filterwarnings("ignore::qsma.errors.QuadraticFacetWarning")
def test_hexahedron20_cantilevers_meshed_apart_give_the_conforming_answer():
    """Two hexahedron20 cantilevers pressed together (quad8 facets). Conforming, node
    to node: the preload opens the corner pairs (their consistent share of a pressure
    is negative) and the tied f0 is 0.25 % lower; through the mortar coupling on the
    same mesh every contact point closes (positive mixed shares); the resultants of the
    preload (part of it goes to the clamps) agree to 4e-5. Meshed apart (6 and 5 cells
    along the zone), the mortar run gives the conforming mortar run's answer, Masing's
    rules on both (measured): preload resultant 1.6e-6, f0 8.4e-5, the backbone's
    frequency 5.5e-4 and zeta at levels 20 and 30 3.2 % and 0.8 % apart."""
    import qsma
    runs = {k: qsma.run(_lap(6, n, c), dissipation="masing")
            for k, n, c in (("node", 6, "node"), ("mortar", 6, "mortar"),
                            ("apart", 5, "mortar"))}
    assert all(r.success for r in runs.values())
    node, conf, apart = runs["node"], runs["mortar"], runs["apart"]
    assert node.pairing.coupling == "node" and apart.pairing.coupling == "mortar"
    assert conf.pairing.slave_basis is not None
    assert (conf.preload.lam[:, -1] > 0).all() and (apart.preload.lam[:, -1] > 0).all()
    corners = np.isin(node.pairing.nodes1, node.model.bodies[0].mesh.facets(
        "interface")[:, :4])
    assert (node.preload.lam[corners, -1] <= 1e-9 * node.preload.lam[:, -1].max()).all()
    assert node.f0_hz < conf.f0_hz * (1 - 1e-3)
    total = {k: r.preload.lam[:, -1].sum() for k, r in runs.items()}
    assert total["apart"] == pytest.approx(total["mortar"], rel=1e-5)
    assert total["node"] == pytest.approx(total["mortar"], rel=1e-4)
    assert apart.f0_hz == pytest.approx(conf.f0_hz, rel=2e-4)
    np.testing.assert_allclose(apart.f_hz, conf.f_hz, rtol=1e-3)
    np.testing.assert_allclose(apart.zeta[[20, 30]], conf.zeta[[20, 30]], rtol=0.05)


@needs_ccx
@pytest.mark.filterwarnings("ignore::qsma.errors.QuadraticFacetWarning")
def test_calculix_ties_the_coefficients_as_qsma_does(tmp_path):
    """The exported tied deck of the cantilevers meshed apart ties each closed contact
    point's coefficient (``*EQUATION`` over its node and, at a midside node, the two
    corners): CalculiX's tied f0 is qsma's to the 7 digits it prints (measured
    543.3939 against 543.39393), and its preload through its own penalty contact has
    qsma's resultant to 1e-4 (measured 2.1e-5)."""
    from qsma.deck import export_calculix
    from qsma.deck.calculix_output import displacements, eigenfrequencies, run_calculix
    from qsma.analysis.options import RunOptions
    m = _lap(6, 5, "mortar")
    deck = export_calculix(m, tmp_path / "model.inp", options=RunOptions(), tied=True)
    mode, p = deck.mode, deck.mode["pairing"]
    assert p.slave_basis is not None
    f_tied = eigenfrequencies(run_calculix(deck.tied_path))
    assert f_tied[0] == pytest.approx(mode["f0_hz"], rel=1e-6)
    blocks = displacements(run_calculix(deck.path), deck.first_node[-1] - 1)
    u = deck.per_body([b for t, b in blocks if t <= 1 + 1e-9][-1])
    k = p.slave - 1
    a = assemble_body(m.bodies[k])
    f = (a.K @ u[k][:, :3].ravel() - a.loads.get("preload", 0.0)).reshape(-1, 3)
    total_ccx = -np.einsum("ij,ij->i", f[p.contact_nodes], p.normals).sum()
    assert total_ccx == pytest.approx(mode["lam"][:, -1].sum(), rel=1e-4)
