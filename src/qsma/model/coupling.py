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
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from ..errors import InputError

#: Gauss-Legendre points per direction: 4 points integrate degree 7 on a segment and,
#: collapsed onto a triangle (Duffy), total degree 6 exactly; the integrands of a flat
#: interface (products of two bilinear functions on affine pieces) have degree <= 4.
GAUSS_POINTS = 4

#: A slave node counts as covered when the master covers every slave facet around it
#: to all but this fraction of the facet's area: six orders above double round-off of
#: the clipped areas, far below any intended overhang (half an element is 0.5).
COVERAGE_TOL = 1e-6

#: Largest gap or overlap between the two surfaces, as a fraction of the local slave
#: element size, accepted as "touching": a chord of length h on a radius R deviates
#: from the arc by h^2 / (8 R), below 0.1 h for any mesh with h < 0.8 R. Farther apart
#: the surfaces are not in contact (or overlap): refused, never snapped.
GAP_FRACTION = 0.1


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
        undeformed surfaces (positive apart); within :data:`GAP_FRACTION` of the element
        size, it is reported and treated as zero (touching surfaces)
    """

    slave_nodes: np.ndarray
    master_nodes: np.ndarray
    P: sp.csr_matrix
    area: np.ndarray
    normals: np.ndarray
    gap: np.ndarray


def mortar_operator(slave_mesh, slave_facets, master_mesh, master_facets,
                    names=("slave", "set", "master", "set")) -> MortarOperator:
    """Build :class:`MortarOperator` for ``slave_facets`` against ``master_facets``.

    ``names`` = (slave body, slave set, master body, master set), for messages.

    Raises
    ------
    InputError
        When part of the slave surface projects onto no master facet, when the facing
        facets have normals pointing the same way (a set on the wrong face), or when the
        surfaces are farther apart or overlap more than :data:`GAP_FRACTION` of an element,
        and for quadratic facets (the projection is built for linear ones).
    """
    from .mesh import FACET_CORNERS
    for mesh, facets, body, name in ((slave_mesh, slave_facets, names[0], names[1]),
                                     (master_mesh, master_facets, names[2], names[3])):
        if facets.shape[1] != FACET_CORNERS[mesh.facet_type]:
            raise InputError(
                f"interface body {names[0]!r} set {names[1]!r} / body {names[2]!r} set "
                f"{names[3]!r}: the mortar coupling is built for linear facets, and body "
                f"{body!r} set {name!r} has {mesh.facet_type} facets ({mesh.cell_type} "
                f"cells). Fix: mesh the two sides with coincident nodes (node-to-node "
                f"coupling handles quadratic cells) or use linear cells at the interface")
    xs, xm = slave_mesh.points, master_mesh.points
    dim = xs.shape[1]
    ns = _outward(slave_mesh, slave_facets)
    nm = _outward(master_mesh, master_facets)
    same_way = set()          # slave facets facing a master facet with a same-way normal
    build = _pieces_2d if dim == 2 else _pieces_3d
    pieces = build(xs, slave_facets, ns, xm, master_facets, nm, same_way)
    return _assemble(xs, slave_facets, ns, xm, master_facets, pieces, names, same_way)


def _outward(mesh, facets):
    from .interface import facet_normals
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


# ---------------------------------------------------------------- shape functions
def _shape(kind, r):
    """Shape functions at local coordinates ``r`` (n, k): line ``xi in [0, 1]``,
    triangle ``(r, s)`` barycentric, quad ``(xi, eta) in [-1, 1]^2`` (cyclic nodes)."""
    if kind == 2:
        return np.stack([1.0 - r[:, 0], r[:, 0]], axis=1)
    if kind == 3:
        return np.stack([1.0 - r[:, 0] - r[:, 1], r[:, 0], r[:, 1]], axis=1)
    a, b = r[:, 0], r[:, 1]
    return 0.25 * np.stack([(1 - a) * (1 - b), (1 + a) * (1 - b), (1 + a) * (1 + b),
                            (1 - a) * (1 + b)], axis=1)


def _inverse_map(polys, q):
    """Local coordinates of the points ``q`` (n, 2), point i in the planar facet
    ``polys[i]`` (n, k, 2): barycentric for triangles, Newton on the bilinear map for
    quads (exact in one step for parallelograms)."""
    if polys.shape[1] == 3:
        A = np.stack([polys[:, 1] - polys[:, 0], polys[:, 2] - polys[:, 0]], axis=2)
        return np.linalg.solve(A, (q - polys[:, 0])[:, :, None])[:, :, 0]
    r = np.zeros((len(q), 2))
    scale = np.abs(polys).max()
    for _ in range(30):
        a, b = r[:, 0], r[:, 1]
        dNa = 0.25 * np.stack([-(1 - b), 1 - b, 1 + b, -(1 + b)], axis=1)
        dNb = 0.25 * np.stack([-(1 - a), -(1 + a), 1 + a, 1 - a], axis=1)
        J = np.stack([np.einsum("nk,nkd->nd", dNa, polys),
                      np.einsum("nk,nkd->nd", dNb, polys)], axis=2)     # dx/d(a, b)
        res = q - np.einsum("nk,nkd->nd", _shape(4, r), polys)
        if np.abs(res).max() <= 1e-15 * scale:
            break
        r += np.linalg.solve(J, res[:, :, None])[:, :, 0]
    return r


# ---------------------------------------------------------------- 2D pieces
def _pieces_2d(xs, sf, ns, xm, mf, nm, same_way):
    """Integration points of each slave segment: (slave facet, master facet, xi, eta, w)."""
    gx, gw = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    gx, gw = 0.5 * (gx + 1.0), 0.5 * gw
    mnorm = _nodal_normals(len(xm), mf, nm)
    hm = _facet_size(xm, mf)
    tree = cKDTree(xm[mf].mean(axis=1))
    out = []
    for e, (a, b) in enumerate(sf):
        x0, x1 = xs[a], xs[b]
        edge = x1 - x0
        length = np.linalg.norm(edge)
        reach = 0.5 * length + 0.5 * hm.max() + GAP_FRACTION * length
        for f in tree.query_ball_point(0.5 * (x0 + x1), reach):
            if ns[e] @ nm[f] >= 0:
                same_way.add(e)
                continue
            ka, kb = mf[f]
            xi = [_cross_line(x0, edge, xm[k], mnorm[k]) for k in (ka, kb)]
            if None in xi:
                continue
            lo, hi = max(min(xi), 0.0), min(max(xi), 1.0)
            if hi - lo <= 1e-12:
                continue
            xg = lo + (hi - lo) * gx
            eta = _along_normal(x0 + xg[:, None] * edge, xm[ka], xm[kb], mnorm[ka], mnorm[kb])
            out.append((e, f, xg[:, None], eta[:, None], (hi - lo) * gw * length))
    return out


def _cross_line(x0, edge, y, n):
    """Parameter ``xi`` where the line ``y + t n`` crosses the line ``x0 + xi edge``."""
    A = np.column_stack([edge, -n])
    if abs(np.linalg.det(A)) < 1e-12 * np.linalg.norm(edge):
        return None
    return float(np.linalg.solve(A, y - x0)[0])


def _along_normal(x, y0, y1, n0, n1):
    """``eta`` with ``x - y(eta)`` parallel to ``n(eta)``, ``y``, ``n`` linear in eta:
    the root of ``cross(a - eta b, n0 + eta c) = 0`` (quadratic) nearest the chord's."""
    cr = lambda u, v: u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    a, b, c = x - y0, y1 - y0, n1 - n0
    c0, c1 = cr(a, n0), cr(a, c) - cr(b, n0)
    c2 = np.broadcast_to(-cr(b, c), c0.shape)
    guess = (a @ b) / (b @ b)
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


# ---------------------------------------------------------------- 3D pieces
def _plane_basis(n):
    ref = np.array([0.0, 0.0, 1.0]) if abs(n[0]) > 0.9 else np.array([1.0, 0.0, 0.0])
    t1 = ref - (ref @ n) * n
    t1 /= np.linalg.norm(t1)
    return np.stack([t1, np.cross(n, t1)])


def _clip(subject, clipper):
    """Sutherland-Hodgman: the part of polygon ``subject`` inside the convex
    counter-clockwise polygon ``clipper`` (both (k, 2))."""
    out = list(subject)
    for i in range(len(clipper)):
        a, b = clipper[i], clipper[(i + 1) % len(clipper)]
        edge = b - a
        side = lambda p: edge[0] * (p[1] - a[1]) - edge[1] * (p[0] - a[0])
        src, out = out, []
        for j in range(len(src)):
            p, q = src[j], src[(j + 1) % len(src)]
            sp_, sq = side(p), side(q)
            if sp_ >= 0:
                out.append(p)
            if (sp_ >= 0) != (sq >= 0):
                out.append(p + (q - p) * (sp_ / (sp_ - sq)))
        if not out:
            return np.zeros((0, 2))
    return np.array(out)


def _ccw(poly):
    """Signed area of a polygon (k, 2), positive when counter-clockwise (shoelace)."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(x[:-1] @ y[1:] - x[1:] @ y[:-1] + x[-1] * y[0] - x[0] * y[-1])


def _triangle_rule():
    """Collapsed (Duffy) Gauss rule on the reference triangle: points (r, s), weights
    summing to 1/2."""
    g, w = np.polynomial.legendre.leggauss(GAUSS_POINTS)
    g, w = 0.5 * (g + 1.0), 0.5 * w
    u, v = np.meshgrid(g, g, indexing="ij")
    wu, wv = np.meshgrid(w, w, indexing="ij")
    r, s = u.ravel(), ((1 - u) * v).ravel()
    return np.stack([r, s], axis=1), (wu * wv * (1 - u)).ravel()


def _pieces_3d(xs, sf, ns, xm, mf, nm, same_way):
    rule, rw = _triangle_rule()
    hm = _facet_size(xm, mf)
    hs = _facet_size(xs, sf)
    tree = cKDTree(xm[mf].mean(axis=1))
    out = []
    for e, face in enumerate(sf):
        n = ns[e] / np.linalg.norm(ns[e])
        c = xs[face].mean(axis=0)
        B = _plane_basis(n)
        spoly = (xs[face] - c) @ B.T
        if _ccw(spoly) < 0:
            spoly, face_order = spoly[::-1], face[::-1]
        else:
            face_order = face
        reach = hs[e] + hm.max() + GAP_FRACTION * hs[e]
        lo, hi = spoly.min(axis=0), spoly.max(axis=0)
        for f in tree.query_ball_point(c, reach):
            if n @ nm[f] >= 0:
                same_way.add(e)
                continue
            mpoly = (xm[mf[f]] - c) @ B.T
            if (mpoly.max(axis=0) <= lo).any() or (mpoly.min(axis=0) >= hi).any():
                continue                                   # bounding boxes apart
            morder = mf[f]
            if _ccw(mpoly) < 0:
                mpoly, morder = mpoly[::-1], morder[::-1]
            piece = _clip(mpoly, spoly)
            if len(piece) < 3 or _ccw(piece) <= 1e-12 * _ccw(spoly):
                continue
            q, w = [], []
            for k in range(1, len(piece) - 1):
                tri = piece[[0, k, k + 1]]
                area2 = 2.0 * _ccw(tri)
                if area2 <= 0:
                    continue
                q.append(tri[0] + rule @ np.stack([tri[1] - tri[0], tri[2] - tri[0]]))
                w.append(rw * area2)
            q, w = np.concatenate(q), np.concatenate(w)
            out.append([e, f, (spoly, q), (mpoly, q), w, face_order, morder])
    for side in (2, 3):                       # local coordinates, batched over pieces
        for k in (3, 4):
            sel = [p for p in out if len(p[side][0]) == k]
            if not sel:
                continue
            polys = np.concatenate([np.broadcast_to(p[side][0], (len(p[side][1]), k, 2))
                                    for p in sel])
            r = _inverse_map(polys, np.concatenate([p[side][1] for p in sel]))
            ends = np.cumsum([len(p[side][1]) for p in sel])[:-1]
            for p, rr in zip(sel, np.split(r, ends)):
                p[side] = rr
    return [tuple(p) for p in out]


# ---------------------------------------------------------------- assembly
def _assemble(xs, sf, ns, xm, mf, pieces, names, same_way):
    """Dual basis per slave facet, then ``D``, ``M`` and the weighted gap."""
    sbody, sset, mbody, mset = names
    dim = xs.shape[1]
    by_facet = {}
    for piece in pieces:
        by_facet.setdefault(piece[0], []).append(piece)
    snodes = np.unique(sf)
    mnodes_all = np.unique(mf)
    # covered fraction of each slave facet (the clipped pieces' area over the facet's,
    # exact for planar polygons), and of each node: the least of its facets
    covered = np.zeros(len(sf))
    for piece in pieces:
        covered[piece[0]] += piece[4].sum()
    covered /= np.linalg.norm(ns, axis=1)
    node_cover = np.full(len(xs), np.inf)
    np.minimum.at(node_cover, sf.ravel(), np.repeat(covered, sf.shape[1]))
    hs = _facet_size(xs, sf)
    facets = []                        # per slave facet: nodes, pieces, N_s, N_m, weights
    D = np.zeros(len(xs))
    for e, plist in by_facet.items():
        sfn = plist[0][5] if dim == 3 else sf[e]
        Ns = [_shape(len(sfn), p[2]) for p in plist]
        Nm = [_shape(len(p[6]) if dim == 3 else 2, p[3]) for p in plist]
        W = [p[4] for p in plist]
        Me = sum((N * w[:, None]).T @ N for N, w in zip(Ns, W))
        D[sfn] += Me.sum(axis=1)                 # D_e = diag(int N_i) = row sums of M_e
        facets.append((e, sfn, plist, Ns, Nm, W, Me))
    _check_coverage(xs, snodes, node_cover, names, np.unique(sf[sorted(same_way)]))
    weighted_gap = np.zeros(len(xs))
    rows, cols, vals = [], [], []
    worst = (0.0, None)
    for e, sfn, plist, Ns, Nm, W, Me in facets:
        # dual basis psi = A N with A = D_e M_e^-1 (M_e symmetric: A^T = M_e^-1 D_e)
        A = np.linalg.solve(Me, np.diag(Me.sum(axis=1))).T
        normal = ns[e] / np.linalg.norm(ns[e])
        for p, N, Nmk, w in zip(plist, Ns, Nm, W):
            mnodes = p[6] if dim == 3 else mf[p[1]]
            psi = N @ A.T
            xg_s = N @ xs[sfn]
            gap = (Nmk @ xm[mnodes] - xg_s) @ normal
            k = int(np.argmax(np.abs(gap)))
            if abs(gap[k]) / hs[e] > worst[0]:
                worst = (abs(gap[k]) / hs[e], (gap[k], xg_s[k]))
            np.add.at(weighted_gap, sfn, psi.T @ (w * gap))
            rows.append(np.repeat(sfn, len(mnodes)))
            cols.append(np.tile(mnodes, len(sfn)))
            vals.append(((psi * w[:, None]).T @ Nmk).ravel())
    if worst[0] > GAP_FRACTION:
        g, x = worst[1]
        what = "apart" if g > 0 else "overlap (interpenetrate)"
        raise InputError(
            f"interface body {sbody!r} set {sset!r} / body {mbody!r} set {mset!r}: the two "
            f"surfaces are {abs(g):.3e} m {what} at {np.round(x, 12).tolist()}, "
            f"{worst[0]:.2f} of the local element size (at most {GAP_FRACTION} is taken "
            f"as touching). Fix: move the bodies so that the interface surfaces touch in "
            f"the undeformed configuration, or check that the sets name the facing "
            f"surfaces.")
    order = snodes[np.lexsort(xs[snodes].T[::-1])]
    M = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(len(xs), len(xm))).tocsr()
    M = M[order]
    used = np.flatnonzero(np.abs(M).sum(axis=0).A1 > 0)
    mnodes = np.intersect1d(mnodes_all, used)
    P = sp.diags(1.0 / D[order]) @ M[:, mnodes]
    P.eliminate_zeros()
    nrm = _nodal_normals(len(xs), sf, ns)[order]
    return MortarOperator(order, mnodes, P.tocsr(), D[order], nrm,
                          weighted_gap[order] / D[order])


def _check_coverage(xs, snodes, node_cover, names, same_way_nodes):
    sbody, sset, mbody, mset = names
    frac = node_cover[snodes]
    bad = snodes[frac < 1.0 - COVERAGE_TOL]
    if len(bad) == 0:
        return
    if np.isin(bad, same_way_nodes).all():
        raise InputError(
            f"interface body {sbody!r} set {sset!r} / body {mbody!r} set {mset!r}: the "
            f"outward normals of the two surfaces point the same way where they meet "
            f"({len(bad)} slave node(s), e.g. node {bad[0]} at "
            f"{np.round(xs[bad[0]], 12).tolist()}), so they cannot be in contact (inverted "
            f"or mis-assigned surface). Fix: name the facet set on the face of each body "
            f"that touches the other body (outward normals opposed).")
    nowhere = snodes[frac <= COVERAGE_TOL]
    lines = [f"  node {k} at {np.round(xs[k], 12).tolist()}: an adjacent facet is "
             f"{100 * node_cover[k]:.1f} % covered" for k in bad[:8]]
    more = f"\n  ... and {len(bad) - 8} more" if len(bad) > 8 else ""
    head = ("projects nowhere onto" if len(nowhere) == len(snodes)
            else "is not covered by")
    raise InputError(
        f"interface body {sbody!r} set {sset!r} (slave) {head} body {mbody!r} set "
        f"{mset!r} (master): {len(bad)} of {len(snodes)} slave node(s) lie (partly) "
        f"outside the master surface, or face a master facet whose normal points the same "
        f"way:\n" + "\n".join(lines) + more +
        "\nFix: make the slave the side that lies within the other (Interface(slave=...)), "
        "restrict both facet sets to the overlap of the two surfaces, and check that the "
        "sets name facing surfaces (outward normals opposed).")
