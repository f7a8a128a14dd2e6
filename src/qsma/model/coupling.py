r"""Dual mortar coupling of two independently meshed interface surfaces.

The contact unknowns live at the nodes of one side, the *slave* (non-mortar)
side; the other side, the *master* (mortar) side, enters only through the
projection operator ``P`` built here once. With ``N_i`` the slave shape
functions, ``N_k^m`` the master ones and ``psi_i`` the dual basis on the slave
surface (biorthogonal: ``int psi_i N_j = delta_ij D_i``, Wohlmuth 2000)::

    D_i  = int_{Gamma_s} N_i dA              (tributary area of slave node i)
    M_ik = int_{Gamma_s} psi_i N_k^m dA      (slave point mapped onto the master)
    P    = D^-1 M                            (n_slave x n_master)

``(P u_m)_i`` is the master displacement seen by slave node ``i``. Because ``D``
is diagonal, the weighted gap ``D_i (P u_m - u_s)_i`` and the nodal contact force
``lam_i = D_i z_i`` (``z_i`` the traction coefficient) obey the contact law node
by node, so the condensed contact problem keeps its per-node form. Two exactness
properties follow from the construction (``tests/test_nonmatching.py`` asserts
both):

* every row of ``P`` sums to one, and ``P`` reproduces fields that are linear
  over the surface (flat, affine facets): ``int psi_i u = D_i u_i``;
* a uniform traction ``z_i = t`` gives the consistent nodal forces of both sides,
  ``lam_i = t int N_i`` and ``(P^T lam)_k = t int N_k^m``: the contact patch test.

Geometry. 2D (line facets): a slave point is mapped onto the master along the
continuous master normal field (nodal normals interpolated linearly), so curved
surfaces meshed differently are handled; the pieces of a slave segment that map
into one master segment end where the normal line of a master node crosses it.
3D (triangle and quadrilateral facets): each master facet is projected onto the
plane of the slave facet along the slave facet normal and clipped against it
(Sutherland-Hodgman), as in the segment-based integration of Puso and Laursen
(2004); the pieces are triangulated and integrated with collapsed Gauss rules.
The pieces (2D and 3D) and the assembly are computed for all facet pairs at once
(numpy arrays; the clipped polygons in fixed vertex slots, :func:`clip_polygons`),
not pair by pair (a Gmsh lap joint of 800 slave nodes: 0.3-0.5 s).

Quadratic facets (line3, triangle6, quad8, quad9; docs/theory.md section 9). The
pieces are found on each facet's corners (its chord or flat polygon) and the
quadratic shape functions are evaluated at the pieces' points in the facet's own
reference coordinates; exact for straight / flat facets with their midside nodes at
the edge midpoints, the chord approximation (relative area error of order
``(h / R)^2``) for curved ones. The corner functions of triangle6 and quad8 facets
integrate to zero or less, so ``D`` would be singular: the dual basis is built on
the slave functions mixed with their neighbours (:mod:`qsma.model.dual_basis`),
``N~_c = N_c + a sum_m N_m`` over the midside nodes ``m`` next to corner ``c`` and
``N~_m = (1 - 2a) N_m`` (Popp, Wohlmuth, Gee and Wall 2012), whose integrals are
positive. The contact unknowns then belong to the coefficients ``u~`` of the slave
displacement in the mixed functions, ``u_s = B u~`` (``B = T^T``,
:class:`qsma.model.dual_basis.SlaveBasis`), so ``(P u_m)_i`` is what ``u~_i`` is tied to; the three
properties above hold for ``u~`` (on straight / flat facets ``u~ = u`` for every
linear field), and the consistent slave forces of a uniform traction are
``B^-T lam = t int N_i``.
"""
from __future__ import annotations

from dataclasses import dataclass
from itertools import chain

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..errors import InputError
from ..mesh.celltypes import TYPES
from ..mesh.facets import facet_normals
from .dual_basis import (SlaveBasis, dual_basis, facet_values, mixing_matrix, shape_values,
                         slave_basis, weak_shares)
from .mortar_checks import (COVERAGE_TOL, GAP_APART_FRACTION, MIN_FACET_COVER,
                            check_coverage, check_gap, refuse_partly_covered)

#: Gauss-Legendre points per direction: 4 points integrate degree 7 on a segment and,
#: collapsed onto a triangle (Duffy), total degree 6 exactly; the integrands of a flat
#: interface (products of two bilinear functions on affine pieces) have degree <= 4.
GAUSS_POINTS = 4


@dataclass(frozen=True, eq=False)
class MortarOperator:
    """The projection of a master surface onto the nodes of a slave surface.

    Attributes
    ----------
    slave_nodes, master_nodes : node indices (slave in lexicographic coordinate order;
        master nodes that no slave point sees are left out)
    P : (n_slave, n_master) sparse, ``P = D^-1 M``
    area : (n_slave,) ``D_i = int N_i dA`` (length per unit depth in 2D)
    normals : (n_slave,) unit outward normals of the slave surface at its nodes
    gap : (n_slave,) weighted normal gap ``D_i^-1 int psi_i (x_m - x_s).n_s dA`` of the
        undeformed surfaces (positive apart), the initial gap of the contact problem;
        at most :data:`GAP_APART_FRACTION` of the element size apart and
        :data:`qsma.model.mortar_checks.GAP_FRACTION` overlapping
    slave_area : area of the slave facet set (length per unit depth in 2D)
    unmatched_area : the part of it that faces no master facet (left out of the
        coupling: holes, curved or offset edges of two discretisations)
    basis : :class:`qsma.model.dual_basis.SlaveBasis` of mixed quadratic slave facets, or
        None (the contact unknowns are the nodal values)
    """

    slave_nodes: np.ndarray
    master_nodes: np.ndarray
    P: sp.csr_matrix
    area: np.ndarray
    normals: np.ndarray
    gap: np.ndarray
    slave_area: float = 0.0
    unmatched_area: float = 0.0
    basis: SlaveBasis | None = None

    @property
    def unmatched_fraction(self) -> float:
        return self.unmatched_area / self.slave_area if self.slave_area else 0.0

    @property
    def fully_covered(self) -> bool:
        return self.unmatched_fraction <= COVERAGE_TOL


def mortar_operator(slave_mesh, slave_facets, master_mesh, master_facets,
                    names=("slave", "set", "master", "set")) -> MortarOperator:
    """Build :class:`MortarOperator` for ``slave_facets`` against ``master_facets``.

    ``names`` = (slave body, slave set, master body, master set), for messages.

    Partial coverage is the normal case at holes and at curved or offset edges of two
    discretisations: the integrals run over the overlap of the two surfaces only (the
    clipped pieces), the dual basis of each slave facet is built on its covered part
    (biorthogonal there, so the rows of ``P`` still sum to one), the slave nodes that
    face no master facet are left out, and the area left uncovered is reported
    (``unmatched_area``); facets covered on less than :data:`MIN_FACET_COVER` of their
    area are left out whole.

    Raises
    ------
    InputError
        When no part of the slave surface projects onto the master, when the facing
        facets have normals pointing the same way (a set on the wrong face), or when the
        surfaces are farther apart than :data:`GAP_APART_FRACTION` or overlap more than
        :data:`qsma.model.mortar_checks.GAP_FRACTION` of an element,
        and for facet rows that are not the mesh's facets (corners only, say).
    """
    kinds = [_facet_kind(mesh, facets, body, name, names) for mesh, facets, body, name
             in ((slave_mesh, slave_facets, names[0], names[1]),
                 (master_mesh, master_facets, names[2], names[3]))]
    xs, xm = slave_mesh.points, master_mesh.points
    dim = xs.shape[1]
    ns = _outward(slave_mesh, slave_facets)
    nm = _outward(master_mesh, master_facets)
    build = _pieces_2d if dim == 2 else _pieces_3d
    # the pieces on the facets' corners; same_way: slave facets facing a master facet
    # whose normal points the same way
    sc, mc = (f[:, :TYPES[k].corners] for f, k in zip((slave_facets, master_facets), kinds))
    pieces, same_way = build(xs, sc, ns, xm, mc, nm)
    return _assemble(xs, (slave_facets, kinds[0]), ns, xm, (master_facets, kinds[1]),
                     pieces, names, same_way)


def _facet_kind(mesh, facets, body, name, names):
    """The facet type of ``facets`` (rows of every node of the mesh's facet type)."""
    kind = mesh.facet_type
    if facets.shape[1] != TYPES[kind].n_nodes:
        raise InputError(
            f"interface body {names[0]!r} set {names[1]!r} / body {names[2]!r} set "
            f"{names[3]!r}: body {body!r} set {name!r} has facets of {facets.shape[1]} "
            f"nodes, its {mesh.cell_type} cells have {kind} facets of "
            f"{TYPES[kind].n_nodes}. Fix: give the facet set as facets of the body's own "
            f"cells (every node of each face)")
    return kind


def _outward(mesh, facets):
    return facet_normals(mesh, facets)


def _nodal_normals(n_points, facets, weighted):
    """Unit nodal normals: facet normals weighted by area, averaged at the nodes."""
    acc = np.zeros((n_points, weighted.shape[1]))
    nv = facets.shape[1]
    np.add.at(acc, facets.ravel(), np.repeat(weighted / nv, nv, axis=0))
    norm = np.linalg.norm(acc, axis=1, keepdims=True)
    return np.divide(acc, norm, out=np.zeros_like(acc), where=norm > 0)


def _facet_size(x, facets):
    """Longest edge of each facet."""
    p = x[facets]
    return np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2).max(axis=1)


def _inverse_map(polys, q):
    """Local coordinates of the points ``q`` (n, 2), point i in the planar facet
    ``polys[i]`` (n, k, 2): barycentric for triangles, Newton on the bilinear map for
    quads (exact in one step for parallelograms)."""
    if polys.shape[1] == 3:
        A = np.stack([polys[:, 1] - polys[:, 0], polys[:, 2] - polys[:, 0]], axis=2)
        return _solve_2x2(A, q - polys[:, 0])
    r = np.zeros((len(q), 2))
    scale = np.abs(polys).max()
    for _ in range(30):
        a, b = r[:, 0], r[:, 1]
        dNa = 0.25 * np.stack([-(1 - b), 1 - b, 1 + b, -(1 + b)], axis=1)
        dNb = 0.25 * np.stack([-(1 - a), -(1 + a), 1 + a, 1 - a], axis=1)
        J = np.stack([np.einsum("nk,nkd->nd", dNa, polys),
                      np.einsum("nk,nkd->nd", dNb, polys)], axis=2)     # dx/d(a, b)
        res = q - np.einsum("nk,nkd->nd", shape_values(4, r), polys)
        if np.abs(res).max() <= 1e-15 * scale:
            break
        r += _solve_2x2(J, res)
    return r


def _solve_2x2(A, b):
    """``x`` with ``A[i] x[i] = b[i]`` for (n, 2, 2) ``A``, by Cramer's rule."""
    det = A[:, 0, 0] * A[:, 1, 1] - A[:, 0, 1] * A[:, 1, 0]
    return np.stack([A[:, 1, 1] * b[:, 0] - A[:, 0, 1] * b[:, 1],
                     A[:, 0, 0] * b[:, 1] - A[:, 1, 0] * b[:, 0]], axis=1) / det[:, None]


# ---------------------------------------------------------------- 2D pieces
def _pieces_2d(xs, sf, ns, xm, mf, nm):
    """Integration points of each slave segment against the master segments it faces,
    batched over all candidate pairs: ``(_Pieces, same_way)``. A piece spans the
    parameters ``xi`` of the slave segment between the crossings of the normal lines
    of the master segment's two nodes, clipped to [0, 1]."""
    gx, gw = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    gx, gw = 0.5 * (gx + 1.0), 0.5 * gw
    mnorm = _nodal_normals(len(xm), mf, nm)
    hm = _facet_size(xm, mf)
    x0 = xs[sf[:, 0]]
    edge = xs[sf[:, 1]] - x0
    length = np.linalg.norm(edge, axis=1)
    e, f = _candidates(cKDTree(xm[mf].mean(axis=1)), x0 + 0.5 * edge,
                       0.5 * length + 0.5 * hm.max() + GAP_APART_FRACTION * length)
    opposed = np.einsum("ij,ij->i", ns[e], nm[f]) < 0
    same_way = np.unique(e[~opposed])
    e, f = e[opposed], f[opposed]
    ka, kb = mf[f, 0], mf[f, 1]
    xi_a, ok_a = _cross_line(x0[e], edge[e], xm[ka], mnorm[ka])
    xi_b, ok_b = _cross_line(x0[e], edge[e], xm[kb], mnorm[kb])
    lo = np.maximum(np.minimum(xi_a, xi_b), 0.0)
    hi = np.minimum(np.maximum(xi_a, xi_b), 1.0)
    keep = ok_a & ok_b & (hi - lo > 1e-12)
    e, f, ka, kb, lo, hi = (v[keep] for v in (e, f, ka, kb, lo, hi))
    xg = lo[:, None] + (hi - lo)[:, None] * gx[None, :]              # (pieces, points)
    at = lambda v: np.repeat(v, GAUSS_POINTS, axis=0)
    eta = _along_normal(at(x0[e]) + xg.reshape(-1, 1) * at(edge[e]), at(xm[ka]),
                        at(xm[kb]), at(mnorm[ka]), at(mnorm[kb]))
    w = (hi - lo)[:, None] * gw[None, :] * length[e][:, None]
    return _Pieces(e, f, sf[e], mf[f], np.repeat(np.arange(len(e)), GAUSS_POINTS),
                   xg.reshape(-1, 1), eta.reshape(-1, 1), w.ravel()), same_way


def _cross_line(x0, edge, y, n):
    """Parameters ``xi`` where the lines ``y + t n`` cross the lines ``x0 + xi edge``
    (rows), and whether they do (not parallel to 1e-12 of the edge length)."""
    det = n[:, 0] * edge[:, 1] - edge[:, 0] * n[:, 1]
    ok = np.abs(det) >= 1e-12 * np.linalg.norm(edge, axis=1)
    d = y - x0
    with np.errstate(divide="ignore", invalid="ignore"):
        xi = (n[:, 0] * d[:, 1] - d[:, 0] * n[:, 1]) / det
    return np.where(ok, xi, 0.0), ok


def _along_normal(x, y0, y1, n0, n1):
    """``eta`` with ``x - y(eta)`` parallel to ``n(eta)``, ``y``, ``n`` linear in eta:
    the root of ``cross(a - eta b, n0 + eta c) = 0`` (quadratic) nearest the chord's;
    every argument (m, 2), row by row."""
    cr = lambda u, v: u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    a, b, c = x - y0, y1 - y0, n1 - n0
    c0, c1 = cr(a, n0), cr(a, c) - cr(b, n0)
    c2 = -cr(b, c)
    guess = np.einsum("ij,ij->i", a, b) / np.einsum("ij,ij->i", b, b)
    linear = np.abs(c2) < 1e-14 * (np.abs(c1) + np.abs(c0))
    disc = np.sqrt(np.maximum(c1 ** 2 - 4 * c2 * c0, 0.0))
    q = -0.5 * (c1 + np.copysign(disc, c1))               # stable roots q / c2, c0 / q
    with np.errstate(divide="ignore", invalid="ignore"):
        roots = np.stack([np.where(linear, -c0 / c1, q / c2),
                          np.where(q != 0, c0 / q, np.inf)], axis=1)
    roots = np.where(np.isfinite(roots), roots, np.inf)
    eta = roots[np.arange(len(x)), np.argmin(np.abs(roots - guess[:, None]), axis=1)]
    eta = np.where(np.isfinite(eta), eta, guess)
    return np.clip(eta, 0.0, 1.0)


# ---------------------------------------------------------------- pieces
@dataclass(frozen=True, eq=False)
class _Pieces:
    """Integration points of the pieces (the part of a slave facet that faces one
    master facet): pieces in slave facet order, points in piece order.

    Attributes
    ----------
    facet, master : (n_pieces,) slave and master facet of each piece
    slave_nodes, master_nodes : (n_pieces, k) the two facets' nodes in the order their
        local coordinates refer to (3D: counter-clockwise seen from the master side)
    piece : (n_points,) piece of each point (non-decreasing)
    r_slave, r_master : (n_points, dim - 1) local coordinates of the points in the two
        facets (:func:`qsma.model.dual_basis.shape_values`)
    weight : (n_points,) integration weights (area; length per unit depth in 2D)
    """

    facet: np.ndarray
    master: np.ndarray
    slave_nodes: np.ndarray
    master_nodes: np.ndarray
    piece: np.ndarray
    r_slave: np.ndarray
    r_master: np.ndarray
    weight: np.ndarray


# ---------------------------------------------------------------- 3D pieces
def _plane_bases(n):
    """Orthonormal in-plane axes ``(t1, t2)`` of each unit normal ``n`` (m, 3): (m, 2, 3),
    ``t1`` the projection of z (of x when ``n`` is far from x) and ``t2 = n x t1``."""
    ref = np.where(np.abs(n[:, :1]) > 0.9, [0.0, 0.0, 1.0], [1.0, 0.0, 0.0])
    t1 = ref - np.einsum("ij,ij->i", ref, n)[:, None] * n
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    return np.stack([t1, np.cross(n, t1)], axis=1)


def _shoelace(poly, count=None):
    r"""Signed areas of polygons ``poly`` (m, k, 2), positive when counter-clockwise:
    :math:`A = \tfrac12 \sum_i (x_i y_{i+1} - x_{i+1} y_i)`, over the first
    ``count[j]`` vertices of polygon j (default all ``k``)."""
    if count is None:
        nxt = np.roll(poly, -1, axis=1)
        return 0.5 * (poly[..., 0] * nxt[..., 1] - nxt[..., 0] * poly[..., 1]).sum(axis=1)
    slot = np.arange(poly.shape[1])[None, :]
    nxt = np.where(slot + 1 < count[:, None], slot + 1, 0)
    x, y = poly[..., 0], poly[..., 1]
    terms = x * np.take_along_axis(y, nxt, 1) - np.take_along_axis(x, nxt, 1) * y
    return 0.5 * np.where(slot < count[:, None], terms, 0.0).sum(axis=1)


def clip_polygons(subject, clipper, count=None):
    r"""Sutherland-Hodgman clipping, batched: the part of each polygon ``subject[j]``
    inside the convex counter-clockwise polygon ``clipper[j]``.

    Each clipper edge ``a -> b`` keeps the vertices ``p`` with
    :math:`s(p) = (b - a) \times (p - a) \ge 0` and inserts
    :math:`p + (q - p)\, s(p) / (s(p) - s(q))` where the subject's edge ``p -> q``
    crosses the line. The vertices live in fixed slots, the first ``count[j]`` used;
    the loop runs over the clipper's edges only (a convex subject of ``k`` vertices
    ends with at most ``k`` plus the clipper's count).

    Parameters
    ----------
    subject : (m, k, 2) polygons, vertices in order
    clipper : (m, kc, 2) convex polygons, counter-clockwise
    count : (m,) vertices used in ``subject`` (default ``k``)

    Returns
    -------
    vertices : (m, c, 2) the clipped polygons, in order, unused slots zero
    count : (m,) their numbers of vertices (0 when disjoint)
    """
    poly = np.asarray(subject, dtype=float)
    count = np.full(len(poly), poly.shape[1]) if count is None else np.asarray(count)
    kc = clipper.shape[1]
    for i in range(kc):
        a = clipper[:, i, None, :]
        edge = clipper[:, (i + 1) % kc, None, :] - a
        side = (edge[..., 0] * (poly[..., 1] - a[..., 1])
                - edge[..., 1] * (poly[..., 0] - a[..., 0]))
        poly, count = _clip_step(poly, count, side)
    return poly, count


def _clip_step(poly, count, side):
    """One Sutherland-Hodgman pass of polygons in slots against one line, given the
    ``side`` of each vertex (>= 0 inside): each vertex emits itself if inside, then the
    crossing point if its edge to the next vertex crosses the line."""
    slot = np.arange(poly.shape[1])[None, :]
    used = slot < count[:, None]
    nxt = np.where(slot + 1 < count[:, None], slot + 1, 0)
    inside = side >= 0
    keep = used & inside
    cross = used & (inside != np.take_along_axis(inside, nxt, 1))
    emit = keep.astype(int) + cross
    pos = np.cumsum(emit, axis=1) - emit
    count = emit.sum(axis=1)
    out = np.zeros((len(poly), int(count.max(initial=0)), 2))
    r, j = np.nonzero(keep)
    out[r, pos[r, j]] = poly[r, j]
    r, j = np.nonzero(cross)
    k = nxt[r, j]
    p, q, sp_, sq = poly[r, j], poly[r, k], side[r, j], side[r, k]
    out[r, pos[r, j] + keep[r, j]] = p + (q - p) * (sp_ / (sp_ - sq))[:, None]
    return out, count


def _triangle_rule():
    """Collapsed (Duffy) Gauss rule on the reference triangle: points (r, s), weights
    summing to 1/2."""
    g, w = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    g, w = 0.5 * (g + 1.0), 0.5 * w
    u, v = np.meshgrid(g, g, indexing="ij")
    wu, wv = np.meshgrid(w, w, indexing="ij")
    r, s = u.ravel(), ((1 - u) * v).ravel()
    return np.stack([r, s], axis=1), (wu * wv * (1 - u)).ravel()


def _candidates(tree, centres, reach):
    """``(slave facet, master facet)`` index pairs with the master centre within
    ``reach[e]`` of slave centre ``e``: one multi-point query, in slave facet order."""
    lists = tree.query_ball_point(centres, reach, return_sorted=False)
    n = np.fromiter(map(len, lists), dtype=int, count=len(lists))
    f = np.fromiter(chain.from_iterable(lists), dtype=int, count=int(n.sum()))
    return np.repeat(np.arange(len(centres)), n), f


def _counter_clockwise(poly, nodes):
    """Polygons (m, k, 2) and their node rows reversed where clockwise."""
    cw = _shoelace(poly) < 0
    return (np.where(cw[:, None, None], poly[:, ::-1], poly),
            np.where(cw[:, None], nodes[:, ::-1], nodes))


def _pieces_3d(xs, sf, ns, xm, mf, nm):
    """Each master facet near a slave facet, projected onto the slave facet's plane
    along its normal and clipped against it; the pieces fan-triangulated and
    integrated by the collapsed Gauss rule. Batched over all candidate pairs:
    ``(_Pieces, same_way)``."""
    n = ns / np.linalg.norm(ns, axis=1, keepdims=True)
    c = xs[sf].mean(axis=1)
    B = _plane_bases(n)
    spoly, snodes = _counter_clockwise(np.einsum("fkd,fjd->fkj", xs[sf] - c[:, None], B),
                                       sf)
    hs, hm = _facet_size(xs, sf), _facet_size(xm, mf)
    e, f = _candidates(cKDTree(xm[mf].mean(axis=1)), c,
                       hs + hm.max() + GAP_APART_FRACTION * hs)
    opposed = np.einsum("ij,ij->i", n[e], nm[f]) < 0
    same_way = np.unique(e[~opposed])
    e, f = e[opposed], f[opposed]
    mpoly = np.einsum("pkd,pjd->pkj", xm[mf[f]] - c[e][:, None], B[e])
    lo, hi = spoly.min(axis=1)[e], spoly.max(axis=1)[e]
    near = ~((mpoly.max(axis=1) <= lo).any(axis=1) | (mpoly.min(axis=1) >= hi).any(axis=1))
    e, f = e[near], f[near]
    mpoly, mnodes = _counter_clockwise(mpoly[near], mf[f])
    piece, count = clip_polygons(mpoly, spoly[e])
    big = (count >= 3) & (_shoelace(piece, count) > 1e-12 * _shoelace(spoly)[e])
    e, f, mpoly, mnodes, piece, count = (a[big] for a in (e, f, mpoly, mnodes, piece,
                                                           count))
    which, q, w = _fan_points(piece, count)
    r_s = _inverse_map(spoly[e[which]], q) if len(q) else np.zeros((0, 2))
    r_m = _inverse_map(mpoly[which], q) if len(q) else np.zeros((0, 2))
    return _Pieces(e, f, snodes[e], mnodes, which, r_s, r_m, w), same_way


def _fan_points(piece, count):
    """Points and weights of the collapsed Gauss rule on the fan triangles
    ``(v0, vk, vk+1)`` of each polygon (those of positive area): ``(polygon of each
    point, points (n, 2), weights (n,))``, in polygon, triangle, rule point order."""
    rule, rw = _triangle_rule()
    if piece.shape[1] < 3:                       # no polygon (no pieces at all)
        return np.zeros(0, dtype=int), np.zeros((0, 2)), np.zeros(0)
    v0, v1, v2 = piece[:, :1], piece[:, 1:-1], piece[:, 2:]
    area2 = ((v1[..., 0] - v0[..., 0]) * (v2[..., 1] - v0[..., 1])
             - (v2[..., 0] - v0[..., 0]) * (v1[..., 1] - v0[..., 1]))
    k = np.arange(1, piece.shape[1] - 1)
    poly, tri = np.nonzero((k[None, :] + 1 < count[:, None]) & (area2 > 0))
    t0 = piece[poly, 0]
    d1, d2 = piece[poly, tri + 1] - t0, piece[poly, tri + 2] - t0
    q = t0[:, None] + rule[None, :, :1] * d1[:, None] + rule[None, :, 1:] * d2[:, None]
    w = rw[None, :] * area2[poly, tri][:, None]
    return np.repeat(poly, len(rw)), q.reshape(-1, 2), w.ravel()


# ---------------------------------------------------------------- assembly
def _assemble(xs, slave, ns, xm, master, pieces, names, same_way):
    """Dual basis per slave facet, then ``D``, ``M`` and the weighted gap, batched over
    the facets (stacked dense solves of the small facet mass matrices). ``slave``,
    ``master``: (facet rows, facet type)."""
    (sf, skind), (mf, mkind) = slave, master
    corners = sf[:, :TYPES[skind].corners]
    # covered fraction of each slave facet (the clipped pieces' area over the facet's,
    # exact for planar polygons), and of each node: the least of its facets
    facet_area = np.linalg.norm(ns, axis=1)
    covered = np.bincount(pieces.facet[pieces.piece], weights=pieces.weight,
                          minlength=len(sf)) / facet_area
    node_cover = np.full(len(xs), np.inf)
    np.minimum.at(node_cover, sf.ravel(), np.repeat(covered, sf.shape[1]))
    keep = covered >= MIN_FACET_COVER
    mixing = mixing_matrix(skind)
    if not TYPES[skind].is_linear:
        weak = keep & weak_shares(pieces, sf, skind, mixing, covered * facet_area)
        if weak.all() and weak.any():
            refuse_partly_covered(xs, sf, covered, skind, names)
        keep &= ~weak
    check_coverage(xs, np.unique(sf), node_cover, names, np.unique(sf[same_way]),
                    keep.any())
    pc = pieces if keep.all() else _only_facets(pieces, keep)
    unmatched = max(float(facet_area.sum() - (covered * facet_area)[keep].sum()), 0.0)
    point_facet = pc.facet[pc.piece]
    snodes = np.unique(sf[keep])
    Ns, s_rows = facet_values(skind, sf, pc.facet, pc.slave_nodes, pc.piece, pc.r_slave)
    Nm, m_rows = facet_values(mkind, mf, pc.master, pc.master_nodes, pc.piece,
                               pc.r_master)
    w = pc.weight
    point_nodes = s_rows[pc.piece]
    D, psi = dual_basis(Ns if mixing is None else Ns @ mixing.T, w, point_facet,
                         point_nodes, len(xs))
    # the gap along the slave normal at every point, the worst one against the size
    normal = ns / np.linalg.norm(ns, axis=1, keepdims=True)
    xg_s = np.einsum("pk,pkd->pd", Ns, xs[point_nodes])
    xg_m = np.einsum("pk,pkd->pd", Nm, xm[m_rows[pc.piece]])
    gap = np.einsum("pd,pd->p", xg_m - xg_s, normal[point_facet])
    check_gap(gap, xg_s, _facet_size(xs, corners)[point_facet], names)
    weighted_gap = np.bincount(point_nodes.ravel(), minlength=len(xs),
                               weights=(psi * (w * gap)[:, None]).ravel())
    # M_ik = int psi_i N_k^m per piece: rows the slave facet's nodes, columns the master's
    starts = np.flatnonzero(np.r_[True, np.diff(pc.piece) != 0])
    vals = np.add.reduceat((psi * w[:, None])[:, :, None] * Nm[:, None, :], starts, axis=0)
    rows = np.broadcast_to(s_rows[:, :, None], vals.shape)
    cols = np.broadcast_to(m_rows[:, None, :], vals.shape)
    order = snodes[np.lexsort(xs[snodes].T[::-1])]
    M = sp.coo_matrix((vals.ravel(), (rows.ravel(), cols.ravel())),
                      shape=(len(xs), len(xm))).tocsr()
    M = M[order]
    mnodes = np.flatnonzero(np.abs(M).sum(axis=0).A1 > 0)   # seen by some slave point
    P = sp.diags(1.0 / D[order]) @ M[:, mnodes]
    P.eliminate_zeros()
    nrm = _nodal_normals(len(xs), sf, ns)[order]
    basis = None if mixing is None else slave_basis(sf[keep], skind, order, len(xs))
    return MortarOperator(order, mnodes, P.tocsr(), D[order], nrm,
                          weighted_gap[order] / D[order], float(facet_area.sum()),
                          unmatched, basis)


def _only_facets(pc, keep):
    """The pieces of the slave facets in mask ``keep``, renumbered."""
    kept = keep[pc.facet]
    point = kept[pc.piece]
    number = np.cumsum(kept) - 1
    return _Pieces(pc.facet[kept], pc.master[kept], pc.slave_nodes[kept],
                   pc.master_nodes[kept], number[pc.piece[point]], pc.r_slave[point],
                   pc.r_master[point], pc.weight[point])
