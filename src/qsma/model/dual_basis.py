r"""The slave side of the dual mortar coupling (:mod:`qsma.model.coupling`): shape
functions of linear and quadratic facets at the pieces' points, the mixing of the
quadratic slave functions whose corner integrals are not positive, and the dual basis
built on them (docs/theory.md section 9).

For triangle6 and quad8 facets the corner functions integrate to zero or less, so the
diagonal ``D_i = int N_i`` of the dual basis would be singular or indefinite. The dual
basis is built instead on mixed functions ``N~ = T N`` (Popp, Wohlmuth, Gee and Wall,
SIAM J. Sci. Comput. 34, 2012), each corner function plus ``a`` times the midside
functions next to it, each midside function times ``1 - 2 a``: they still sum to one,
their integrals are positive, and the slave displacement is the same field written in
them, ``u = sum N_i u_i = sum N~_j u~_j`` with ``u = T^T u~`` (:class:`SlaveBasis`).
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import scipy.sparse as sp

from ..mesh.celltypes import TYPES, reference_nodes

#: Weight ``a`` of each midside function added to its corner functions before the dual
#: basis is built, per slave facet type (absent: no mixing). With ``a = 1/5`` the mixed
#: corner functions integrate to ``2/15`` of a flat triangle6 (``0`` unmixed) and
#: ``1/20`` of a parallelogram quad8 (``-1/12`` unmixed), the midside ones to ``1/5``:
#: positive, so ``D`` is (Popp, Wohlmuth, Gee and Wall, SIAM J. Sci. Comput. 34, 2012).
#: line3 (``1/6``, ``2/3``) and quad9 (``1/36``, ``1/9``, ``4/9``) need none.
MIXING = {"triangle6": 0.2, "quad8": 0.2}

#: A slave quadratic facet covered only in part is left out of the coupling when one
#: of its (mixed) functions integrates over the covered part to less than this
#: fraction of the part's area over its node count: quadratic functions change sign on
#: the facet, so a partial cover can leave ``D`` of a node near zero or negative.
MIN_NODE_SHARE = 1e-2


@dataclass(frozen=True, eq=False)
class SlaveBasis:
    """The change from the nodal values ``u`` of the slave interface nodes (contact
    point order) to the coefficients ``u~`` of the mixed functions that carry the
    contact unknowns: ``u = to_nodes @ u~``, ``u~ = from_nodes @ u`` (both sparse,
    the same for each component). Corner rows are the identity, a midside node ``m``
    between corners ``c1``, ``c2``: ``u_m = (1 - 2a) u~_m + a (u~_c1 + u~_c2)``."""

    to_nodes: sp.csr_matrix
    from_nodes: sp.csr_matrix


def shape_values(kind, r):
    """Shape functions at local coordinates ``r`` (n, k): line ``xi in [0, 1]``,
    triangle ``(r, s)`` barycentric, quad ``(xi, eta) in [-1, 1]^2`` (cyclic nodes)."""
    if kind == 2:
        return np.stack([1.0 - r[:, 0], r[:, 0]], axis=1)
    if kind == 3:
        return np.stack([1.0 - r[:, 0] - r[:, 1], r[:, 0], r[:, 1]], axis=1)
    a, b = r[:, 0], r[:, 1]
    return 0.25 * np.stack([(1 - a) * (1 - b), (1 + a) * (1 - b), (1 + a) * (1 + b),
                            (1 - a) * (1 + b)], axis=1)


@lru_cache(maxsize=None)
def _lagrange_coefficients(kind):
    """``(exponents, C)``: the shape functions of facet type ``kind`` are
    ``N(r) = m(r) @ C`` with ``m`` its monomials at reference coordinates ``r``."""
    exps = np.asarray(TYPES[kind].basis)
    nodes = reference_nodes(kind)
    return exps, np.linalg.inv(np.prod(nodes[:, None, :] ** exps[None], axis=2))


def facet_values(kind, facets, which, corner_rows, piece, r):
    """Shape functions of the facets ``facets[which]`` (type ``kind``, rows in the
    mesh's node order) at the points of the pieces: ``(N (n_points, k), rows
    (n_pieces, k))``. The points' local coordinates ``r`` refer to the pieces' corner
    rows ``corner_rows`` (3D: possibly reversed, to counter-clockwise): their linear
    functions, put back in the facet's corner order, give its reference coordinates."""
    rows = facets[which]
    nc = corner_rows.shape[1]
    at = np.argmax(corner_rows[:, None, :] == rows[:, :nc, None], axis=2)
    L = np.take_along_axis(shape_values(nc, r), at[piece], axis=1)
    if TYPES[kind].is_linear:
        return L, rows
    exps, C = _lagrange_coefficients(kind)
    ref = L @ np.asarray(TYPES[TYPES[kind].linear].reference, dtype=float)
    return np.prod(ref[:, None, :] ** exps[None], axis=2) @ C, rows


def mixing_matrix(kind):
    """``T`` (k, k) with the mixed functions ``N~ = T N`` of one facet of type ``kind``
    (:data:`MIXING`), or None for a type left as it is."""
    a = MIXING.get(kind)
    if a is None:
        return None
    t = TYPES[kind]
    T = np.eye(t.n_nodes)
    for j, ends in enumerate(t.higher_nodes, start=t.corners):
        T[j, j] = 1.0 - 2.0 * a
        T[list(ends), j] = a
    return T


def weak_shares(pieces, sf, kind, mixing, covered_area):
    """Mask of the slave facets on whose covered part a (mixed) shape function
    integrates to at most :data:`MIN_NODE_SHARE` of the part's area over the node count
    (quadratic functions change sign: a partial cover can leave ``D`` of a node near
    zero or negative). Whole facets of the mixed types have positive shares."""
    N, _ = facet_values(kind, sf, pieces.facet, pieces.slave_nodes, pieces.piece,
                        pieces.r_slave)
    if mixing is not None:
        N = N @ mixing.T
    share = np.zeros(sf.shape)
    np.add.at(share, pieces.facet[pieces.piece], N * pieces.weight[:, None])
    return (share <= MIN_NODE_SHARE * covered_area[:, None] / sf.shape[1]).any(axis=1)


def slave_basis(sf, kind, order, n_points) -> SlaveBasis:
    """:class:`SlaveBasis` of the slave facets ``sf`` (type ``kind``, mixed by
    :data:`MIXING`), rows and columns in the contact point ``order``."""
    t, a = TYPES[kind], MIXING[kind]
    pos = np.full(n_points, -1)
    pos[order] = np.arange(len(order))
    mid = np.concatenate([sf[:, j] for j in range(t.corners, t.n_nodes)])
    ends = np.concatenate([sf[:, list(e)] for e in t.higher_nodes])
    mid, first = np.unique(mid, return_index=True)
    m, c = pos[mid], pos[ends[first]]
    corner = pos[np.unique(sf[:, :t.corners])]
    n = len(order)

    def matrix(diagonal, off):
        r = np.concatenate([corner, m, m, m])
        k = np.concatenate([corner, m, c[:, 0], c[:, 1]])
        v = np.concatenate([np.ones(len(corner)), np.full(len(m), diagonal),
                            np.full(2 * len(m), off)])
        return sp.csr_matrix((v, (r, k)), shape=(n, n))

    return SlaveBasis(matrix(1.0 - 2.0 * a, a),
                      matrix(1.0 / (1.0 - 2.0 * a), -a / (1.0 - 2.0 * a)))



def dual_basis(Ns, w, point_facet, point_nodes, n_points):
    r"""``(D, psi)``: the tributary areas ``D_i = int N_i`` (over all nodes) and the
    dual basis at every point, per slave facet ``e`` (the points come sorted by facet)

    .. math:: M_e = \int N N^T, \quad D_e = \mathrm{diag}(M_e \mathbf{1}), \quad
              \psi = A N, \quad A = D_e M_e^{-1}

    so that :math:`\int \psi_i N_j = \delta_{ij} D_i` (``M_e`` symmetric:
    :math:`A^T = M_e^{-1} D_e`, one stacked solve for all facets)."""
    first = np.flatnonzero(np.r_[True, np.diff(point_facet) != 0])
    slot = np.repeat(np.arange(len(first)), np.diff(np.r_[first, len(w)]))
    Me = np.add.reduceat((Ns * w[:, None])[:, :, None] * Ns[:, None, :], first, axis=0)
    rowsum = Me.sum(axis=2)
    D = np.bincount(point_nodes[first].ravel(), weights=rowsum.ravel(), minlength=n_points)
    A = np.linalg.solve(Me, rowsum[:, :, None] * np.eye(Ns.shape[1])).transpose(0, 2, 1)
    return D, np.einsum("pk,pik->pi", Ns, A[slot])
