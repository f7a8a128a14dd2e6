"""The batched pieces of the 3D mortar coupling and the sparse two-body combination.

The polygon clip runs over all candidate facet pairs at once in fixed vertex slots;
these tests hold it to exact intersections, to the symmetry of the intersection, and
the assembled operator to identities that hold exactly on flat unstructured meshes.
"""
import dataclasses
from types import SimpleNamespace

import numpy as np
import pytest
import scipy.sparse as sp

from qsma.reduction.two_bodies import combine
from qsma.model import Body, Clamp, Interface, Material, Mesh, Model
from qsma.model.coupling import (_pieces_3d, _shoelace, clip_polygons,
                                 mortar_operator)
from qsma.mesh.generate import structured_mesh
from qsma.mesh.facets import facet_normals

STEEL = Material(200e9, 0.3, 7800.0)


def _rotated_square(angle, half=1.0, centre=(0.0, 0.0)):
    a = angle + np.pi / 4 + np.arange(4) * np.pi / 2
    return np.asarray(centre) + half * np.sqrt(2) * np.stack([np.cos(a), np.sin(a)], 1)


def _padded(polys):
    """Polygons of 3 or 4 vertices in 4 slots, with their counts."""
    out = np.zeros((len(polys), 4, 2))
    for k, p in enumerate(polys):
        out[k, :len(p)] = p
    return out, np.array([len(p) for p in polys])


SQUARE = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])

# (subject, clipper, exact area, exact vertex count or None)
EXACT = [
    # a square and the same square turned by 45 degrees: the regular octagon of
    # inradius 1, area 8 tan(pi / 8)
    (_rotated_square(np.pi / 4), _rotated_square(0.0), 8 * np.tan(np.pi / 8), 8),
    # a triangle inside a quad: the triangle itself
    (np.array([[0.2, 0.1], [0.9, 0.3], [0.4, 0.8]]), SQUARE, 0.5 * abs(
        0.7 * 0.7 - 0.2 * 0.2), 3),
    # a quad against a triangle whose legs lie on two of its edges: the triangle
    (SQUARE, np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]]), 0.5, None),
    # offset squares: a 0.5 x 0.75 rectangle
    (SQUARE + [0.5, 0.25], SQUARE, 0.375, 4),
    # squares touching along an edge: nothing of positive area
    (SQUARE + [1.0, 0.0], SQUARE, 0.0, None),
    # squares touching at a corner
    (SQUARE + [1.0, 1.0], SQUARE, 0.0, None),
    # disjoint
    (SQUARE + [2.5, 0.0], SQUARE, 0.0, 0),
]


def test_batched_clip_gives_the_exact_intersections():
    """All the cases of one clipper size in one call: areas to round-off, and the
    vertex count where it is unambiguous (touching cases may keep repeated points)."""
    for k_clip in (3, 4):
        cases = [c for c in EXACT if len(c[1]) == k_clip]
        subject, n_subject = _padded([c[0] for c in cases])
        poly, count = clip_polygons(subject, np.stack([c[1] for c in cases]), n_subject)
        area = _shoelace(poly, count)
        for k, (_, _, exact, n_exact) in enumerate(cases):
            assert area[k] == pytest.approx(exact, rel=1e-14, abs=1e-15), (k_clip, k)
            if n_exact is not None:
                assert count[k] == n_exact, (k_clip, k)


def _random_convex(rng, n, k):
    """``n`` random counter-clockwise triangles (k = 3) or convex quads (k = 4)."""
    angles = np.sort(rng.uniform(0, 2 * np.pi, (n, k)), axis=1)
    radius = rng.uniform(0.5, 1.5, (n, 1))
    centre = rng.uniform(-0.8, 0.8, (n, 1, 2))
    return centre + radius[..., None] * np.stack([np.cos(angles), np.sin(angles)], -1)


@pytest.mark.parametrize("k_subject, k_clipper", [(3, 3), (3, 4), (4, 3), (4, 4)])
def test_batched_clip_is_symmetric_and_inside_both(k_subject, k_clipper):
    """area(A clipped by B) = area(B clipped by A), and every vertex of the result lies
    in both polygons, over 400 random pairs in one call (some disjoint, some nested)."""
    rng = np.random.default_rng(7 + 10 * k_subject + k_clipper)
    A = _random_convex(rng, 400, k_subject)
    B = _random_convex(rng, 400, k_clipper)
    pa, ca = clip_polygons(A, B)
    pb, cb = clip_polygons(B, A)
    area_ab, area_ba = _shoelace(pa, ca), _shoelace(pb, cb)
    np.testing.assert_allclose(area_ab, area_ba, rtol=0, atol=1e-13)
    assert (ca <= k_subject + k_clipper).all()
    assert (area_ab > 1e-3).sum() > 100 and (ca == 0).sum() > 5      # both kinds occur
    for poly, count, outer in ((pa, ca, A), (pa, ca, B)):
        for i in range(outer.shape[1]):
            a, b = outer[:, i], outer[:, (i + 1) % outer.shape[1]]
            e = (b - a)[:, None]
            side = e[..., 0] * (poly[..., 1] - a[:, None, 1]) - \
                e[..., 1] * (poly[..., 0] - a[:, None, 0])
            used = np.arange(poly.shape[1])[None, :] < count[:, None]
            assert (side[used] >= -1e-13).all()
    assert (area_ab <= np.minimum(_shoelace(A), _shoelace(B)) + 1e-13).all()


def _square_facets(x0, z0, h, y=0.0, up=True):
    """One square facet [x0, x0 + h] x [z0, z0 + h] in the plane y, normal +-y."""
    p = np.array([[x0, y, z0], [x0 + h, y, z0], [x0 + h, y, z0 + h], [x0, y, z0 + h]])
    n = np.array([[0.0, h * h if up else -h * h, 0.0]])
    return p, np.array([[0, 1, 2, 3]]), n


def test_pieces_below_the_area_threshold_and_same_way_facets_are_left_out():
    """One slave square (normal +y) against three master squares: one overlapping it by
    a sliver of 1e-14 of its area (below the 1e-12 threshold: no piece), one by 1e-10
    (a piece of that area), one covering it with a normal pointing the same way (no
    piece; the slave facet reported as facing a same-way normal)."""
    xs, sf, ns = _square_facets(0.0, 0.0, 1.0, up=True)
    parts = [_square_facets(1.0 - 1e-14, 0.0, 1.0, up=False),
             _square_facets(-1.0 + 1e-10, 0.0, 1.0, up=False)]
    xm = np.concatenate([p for p, _, _ in parts])
    mf = np.array([[0, 1, 2, 3], [4, 5, 6, 7]])
    nm = np.concatenate([n for _, _, n in parts])
    pieces, same_way = _pieces_3d(xs, sf, ns, xm, mf, nm)
    assert pieces.master.tolist() == [1] and len(same_way) == 0
    assert pieces.weight.sum() == pytest.approx(1e-10, rel=1e-5)
    # the same master squares turned to face the same way as the slave
    pieces, same_way = _pieces_3d(xs, sf, ns, xm, mf, -nm)
    assert len(pieces.facet) == 0 and same_way.tolist() == [0]


# ---------------------------------------------------------------- whole operator
def _jittered_plate(n, y0, lower, seed, tetra):
    """A plate [0, 1] x [y0, y0 + 0.2] x [0, 1] with ``n`` cells along x and z; the
    nodes of the interface face moved in its plane (it stays flat), so its facets are
    general quads (or triangles of a Kuhn split: ``tetra``)."""
    ax = [np.linspace(0, 1, n + 1), np.linspace(y0, y0 + 0.2, 3), np.linspace(0, 1, n + 1)]
    m = structured_mesh(*ax)
    p = m.points.copy()
    rng = np.random.default_rng(seed)
    inner = np.all((p[:, [0, 2]] > 1e-9) & (p[:, [0, 2]] < 1 - 1e-9), axis=1)
    shift = rng.uniform(-0.3, 0.3, (inner.sum(), 2)) / n
    p[np.ix_(inner, [0, 2])] += shift
    cells = m.cells
    kind = m.cell_type
    if tetra:
        split = [(0, 1, 2, 6), (0, 2, 3, 6), (0, 3, 7, 6), (0, 7, 4, 6), (0, 4, 5, 6),
                 (0, 5, 1, 6)]
        cells = np.concatenate([cells[:, list(t)] for t in split])
        q = p[cells]
        vol = np.einsum("ij,ij->i", np.cross(q[:, 1] - q[:, 0], q[:, 2] - q[:, 0]),
                        q[:, 3] - q[:, 0])
        cells[vol < 0] = cells[vol < 0][:, [0, 2, 1, 3]]
        kind = "tetra"
    face = y0 + (0.0 if lower else 0.2)
    mesh = Mesh(p, cells, kind)
    return mesh, mesh.boundary_facets_where(lambda q: np.abs(q[:, 1] - face) < 1e-9)


def _consistent_areas(mesh, facets):
    """``int N_k dA`` of each node of flat linear facets (triangles: a third of the
    area; quads: from the 2 x 2 Gauss rule of the bilinear map)."""
    out = np.zeros(mesh.n_nodes)
    if facets.shape[1] == 3:
        a = np.linalg.norm(facet_normals(mesh, facets), axis=1)
        np.add.at(out, facets.ravel(), np.repeat(a / 3, 3))
        return out
    g = np.array([-1, 1]) / np.sqrt(3)
    x = mesh.points[facets][:, :, [0, 2]]
    for a in g:
        for b in g:
            N = 0.25 * np.array([(1 - a) * (1 - b), (1 + a) * (1 - b), (1 + a) * (1 + b),
                                 (1 - a) * (1 + b)])
            dNa = 0.25 * np.array([-(1 - b), 1 - b, 1 + b, -(1 + b)])
            dNb = 0.25 * np.array([-(1 - a), -(1 + a), 1 + a, 1 - a])
            J = np.stack([dNa @ x, dNb @ x], axis=1)
            det = np.abs(np.linalg.det(J))
            np.add.at(out, facets.ravel(), (det[:, None] * N[None, :]).ravel())
    return out


@pytest.mark.parametrize("slave_tetra, master_tetra", [(True, True), (True, False),
                                                       (False, True), (False, False)])
def test_mortar_identities_on_jittered_nonmatching_surfaces(slave_tetra, master_tetra):
    """Flat, unstructured, non-matching: rows of P sum to one, P reproduces the
    in-plane coordinates (linear fields), ``D_i = int N_i`` of the slave facets,
    ``P^T D`` the master's ``int N_k`` (the contact patch test), zero gap.

    The last two are exact for triangles (polynomial integrands on the pieces); on a
    general quad ``N`` is rational in the physical coordinates and the 4 x 4 collapsed
    rule leaves up to 1.3e-5 at this distortion (measured; nodes moved by up to 0.3 of
    the element size), asserted at 1e-4."""
    ms, fs = _jittered_plate(7, 0.2, True, 1, slave_tetra)      # slave: lower face of top
    mm, fm = _jittered_plate(5, 0.0, False, 2, master_tetra)    # master: upper of bottom
    op = mortar_operator(ms, fs, mm, fm)
    P = op.P
    np.testing.assert_allclose(P.sum(axis=1).A1, 1.0, rtol=0, atol=1e-13)
    xs, xm = ms.points[op.slave_nodes], mm.points[op.master_nodes]
    np.testing.assert_allclose(P @ xm[:, [0, 2]], xs[:, [0, 2]], rtol=0, atol=1e-14)
    tol = lambda tetra: 1e-12 if tetra else 1e-4
    np.testing.assert_allclose(op.area, _consistent_areas(ms, fs)[op.slave_nodes],
                               rtol=tol(slave_tetra))
    np.testing.assert_allclose(P.T @ op.area, _consistent_areas(mm, fm)[op.master_nodes],
                               rtol=tol(master_tetra))
    assert op.area.sum() == pytest.approx(1.0, rel=1e-13)
    assert np.abs(op.gap).max() < 1e-14
    np.testing.assert_allclose(op.normals, np.tile([0.0, -1.0, 0.0], (len(xs), 1)),
                               atol=1e-14)
    assert list(op.slave_nodes) == list(op.slave_nodes[np.lexsort(xs.T[::-1])])


# ---------------------------------------------------------------- combination
def _spd(rng, n):
    A = rng.standard_normal((n, n))
    S = A @ A.T + n * np.eye(n)
    return 0.5 * (S + S.T)                    # exactly symmetric, as condense_body's


def test_sparse_combination_equals_the_dense_formula_and_woodbury():
    """``combine`` with a sparse ``P``: ``S = Kc_m + P^T Kc_s P`` and
    ``K = Kc_s - Kc_s P S^-1 P^T Kc_s = (Kc_s^-1 + P Kc_m^-1 P^T)^-1``."""
    rng = np.random.default_rng(3)
    ns, nm = 18, 12
    Ks, Km = _spd(rng, ns), _spd(rng, nm)
    P = sp.random(ns, nm, density=0.2, random_state=4, format="csr")
    K, S_cho = combine(SimpleNamespace(Kc=Ks), SimpleNamespace(Kc=Km), P)
    Pd = P.toarray()
    S = Km + Pd.T @ Ks @ Pd
    dense = Ks - Ks @ Pd @ np.linalg.solve(S, Pd.T @ Ks)
    np.testing.assert_allclose(K, dense, rtol=0, atol=1e-12 * np.abs(dense).max())
    wood = np.linalg.inv(np.linalg.inv(Ks) + Pd @ np.linalg.inv(Km) @ Pd.T)
    np.testing.assert_allclose(K, wood, rtol=0, atol=1e-11 * np.abs(wood).max())
    c, lower = S_cho
    U = np.tril(c) if lower else np.triu(c)
    np.testing.assert_allclose(U @ U.T if lower else U.T @ U, S, rtol=1e-13,
                               atol=1e-13 * np.abs(S).max())
    assert np.array_equal(K, K.T)


def test_reduced_model_keeps_the_projection_sparse():
    from qsma.reduction.two_bodies import reduce_two_bodies
    from qsma.fe import assemble_body
    ms, fs = _jittered_plate(4, 0.2, True, 1, False)
    mm, fm = _jittered_plate(3, 0.0, False, 2, True)
    ms = ms.with_sets(node_sets={"top": np.flatnonzero(ms.points[:, 1] > 0.4 - 1e-9)},
                      facet_sets={"lower": fs})
    mm = mm.with_sets(node_sets={"base": np.flatnonzero(mm.points[:, 1] < 1e-9)},
                      facet_sets={"upper": fm})
    model = Model((Body("bottom", mm, STEEL, clamps=(Clamp("base"),)),
                   Body("top", ms, STEEL, clamps=(Clamp("top"),))),
                  Interface("bottom", "upper", "top", "lower", coupling="mortar",
                            slave="top"))
    from qsma.model import make_pairing
    pairing = make_pairing(model)
    rm = reduce_two_bodies(*(assemble_body(b) for b in model.bodies), pairing)
    assert sp.issparse(rm.P) and rm.P.nnz < 0.5 * np.prod(rm.P.shape)
    # the relative-displacement stiffness is the Woodbury form of the two bodies
    Ks, Km, Pd = np.asarray(rm.bodies[1].Kc), np.asarray(rm.bodies[0].Kc), rm.P.toarray()
    wood = np.linalg.inv(np.linalg.inv(Ks) + Pd @ np.linalg.inv(Km) @ Pd.T)
    np.testing.assert_allclose(rm.K, wood, rtol=0, atol=1e-8 * np.abs(wood).max())


# ---------------------------------------------------------------- refusals in 3D
def _block_3d(y0, n, clamped):
    """A block [0, 1] x [y0, y0 + 0.25] x [0, 1], ``n`` cells along x and z; facet
    sets 'lower' and 'upper'; clamped on its lower face if ``clamped``."""
    m = structured_mesh(np.linspace(0, 1, n + 1), np.linspace(y0, y0 + 0.25, 3),
                        np.linspace(0, 1, n + 1))
    y = m.points[:, 1]
    m = m.with_sets(node_sets={"base": np.flatnonzero(np.abs(y - y0) < 1e-9)},
                    facet_sets={"lower": m.boundary_facets_where(
                                    lambda p: np.abs(p[:, 1] - y0) < 1e-9),
                                "upper": m.boundary_facets_where(
                                    lambda p: np.abs(p[:, 1] - y0 - 0.25) < 1e-9)})
    return m, (Clamp("base"),) if clamped else ()


def _two_blocks(top_y0, top_set):
    from qsma.model import make_pairing
    mb, cb = _block_3d(0.0, 4, True)
    mt, ct = _block_3d(top_y0, 3, False)
    model = Model((Body("bottom", mb, STEEL, clamps=cb), Body("top", mt, STEEL, clamps=ct)),
                  Interface("bottom", "upper", "top", top_set, coupling="mortar"))
    return lambda: make_pairing(model)


@pytest.mark.parametrize("top_y0, top_set, match", [
    (0.0, "upper", r"body 'bottom' set 'upper' / body 'top' set 'upper'.*point the "
                   r"same way.*Fix"),
    (0.25 - 0.125, "lower", r"0\.50 of the local element size(.|\n)*Fix: move the bodies"),
    (0.25 + 0.2, "lower", r"2\.000e-01 m apart at \[[0-9.]+, 0\.25, [0-9.]+\], 0\.80 of "
                           r"the local element size; initial gaps up to 0\.5 of an element"
                           r"(.|\n)*do not face each other(.|\n)*Fix: check that the sets"),
])
def test_3d_refusals_name_the_problem(top_y0, top_set, match):
    """Facing facets with same-way normals, surfaces sunk half an element into each
    other, surfaces 0.8 of an element apart (0.6 of the other side's, tried as slave
    too; reported at a point of the first slave surface: the first of the worst gap,
    here uniform; 0.3 of an element is an initial gap, tests/test_initial_gaps.py)."""
    from qsma.errors import InputError
    with pytest.raises(InputError, match=match):
        _two_blocks(top_y0, top_set)()


def test_a_gap_that_is_not_finite_is_refused_by_name():
    """A degenerate facet can make a gap NaN; the check names it instead of crashing on
    ``ratio.max()`` being NaN."""
    from qsma.errors import InputError
    from qsma.model.mortar_checks import check_gap
    x = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    with pytest.raises(InputError, match=r"not finite at \[1.0, 0.0, 0.0\]"):
        check_gap(np.array([0.0, np.nan]), x, np.ones(2), ("a", "s", "b", "t"))
