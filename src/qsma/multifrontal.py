r"""Multifrontal Cholesky on a nested-dissection tree: the ``"multifrontal"`` Schur backend.

For the SPD ``K`` and interface DOFs ``C`` (``E`` the rest, sorted) this computes

.. math:: K_c = K_{CC} - K_{CE} K_{EE}^{-1} K_{EC}, \qquad x = K_{EE}^{-1} b

with one Cholesky factorisation ``K_EE = L L^T`` done front by front with dense
BLAS-3 (LAPACK ``dpotrf``, BLAS ``dtrsm``, ``dgemm``, ``dsyrk``):

1. **Separator tree.** The node graph of ``K_EE`` (supervariables: the DOFs of one
   mesh node) is cut in two by METIS (``pymetis.part_graph``); the vertices of the
   smaller side that touch the other side form a vertex separator ``S``. Both sides
   without ``S`` are cut again, down to leaves of at most :data:`LEAF_NODES` nodes.
   Every tree node ``t`` (a *front*) eliminates its vertices ``V_t`` (a separator or a
   leaf); no edge joins two sibling subtrees, so the rows that ``V_t`` couples to after
   the elimination of its subtree are ancestors' vertices (``B_t``, the E boundary)
   and interface DOFs (``C_t``).
2. **Symbolic phase** (postorder): ``B_t`` = the ancestors among the neighbours of
   ``V_t`` and among the children's ``B``; ``C_t`` = the interface DOFs coupled to
   ``V_t`` and the children's ``C``.
3. **Numeric phase** (postorder). The front of ``t`` has rows ``[V_t, B_t, C_t]`` and
   columns ``[V_t, B_t]``; it receives the entries of ``K`` in the columns ``V_t``
   and the update matrices of its children (extend-add), then

   .. math:: F_{VV} = L_{11} L_{11}^T, \quad
             L_{21} = F_{\{B,C\} V} L_{11}^{-T}, \quad
             U = F_{\{B,C\} B} - L_{21} L_{21,B}^T, \quad
             K_c[C_t, C_t] \mathrel{-}= L_{21,C} L_{21,C}^T .

   ``U`` goes to the parent; the interface rows are never eliminated, their C x C
   updates go straight into one dense |C| x |C| array (upper triangle, mirrored at
   the end), to which ``K_CC`` is added. Only ``L_11`` and ``L_21,B`` are kept.
4. **Solves** ``L L^T x = b``: forward through the fronts in postorder, backward in
   reverse order, all columns of ``b`` at once.

A ``dpotrf`` that meets a non-positive pivot makes the pivot ratio ``-inf``, which
:func:`qsma.linalg.schur_complement` turns into an :class:`~qsma.errors.InputError`;
otherwise the ratio is ``min_i L_ii^2 / (K_EE)_ii``.
"""
from __future__ import annotations

from dataclasses import dataclass
import time

import numpy as np
import scipy.sparse as sp
from scipy.linalg import blas, lapack

#: Most graph vertices (mesh nodes) in a leaf of the separator tree. A leaf is one
#: dense front: larger leaves mean fewer fronts (less Python work per factorisation
#: and solve) but more dense arithmetic. Measured on sandwich-3d refine 1 and 2
#: (docs/schur.md, section "A multifrontal Cholesky of our own").
LEAF_NODES = 64


@dataclass(frozen=True)
class SeparatorTree:
    """Fronts of a nested dissection of a graph, in postorder.

    Attributes
    ----------
    order : graph vertices in elimination order
    start : front ``t`` eliminates ``order[start[t]:start[t + 1]]``
    parent : parent front of each front (``-1``: a root)
    """

    order: np.ndarray
    start: np.ndarray
    parent: np.ndarray

    @property
    def n_fronts(self) -> int:
        return len(self.parent)

    def front_of(self) -> np.ndarray:
        """Front number of each graph vertex."""
        out = np.empty(len(self.order), dtype=np.int64)
        out[self.order] = np.repeat(np.arange(self.n_fronts), np.diff(self.start))
        return out


def separator_tree(G, leaf_nodes: int = LEAF_NODES) -> SeparatorTree:
    r"""Nested dissection of the graph ``G`` (symmetric CSR adjacency, no diagonal)
    into a tree of fronts by recursive METIS bisection.

    A bisection ``P_0 \cup P_1`` from ``pymetis.part_graph(2, ...)`` is turned into a
    vertex separator ``S``: the vertices of one part with a neighbour in the other
    (the smaller of the two such sets). The front of a tree node eliminates ``S``;
    its children are the trees of ``P_0 \setminus S`` and ``P_1 \setminus S``, which no
    edge joins. Sets of at most ``leaf_nodes`` vertices, without edges to cut or that
    METIS does not split, are leaves.

    Returns
    -------
    SeparatorTree with the fronts in postorder (children before their parent).
    """
    G = sp.csr_matrix(G)
    fronts, parents = [], []
    _build(G, np.arange(G.shape[0]), leaf_nodes, fronts, parents)
    order = np.concatenate(fronts) if fronts else np.zeros(0, dtype=np.int64)
    start = np.concatenate([[0], np.cumsum([len(f) for f in fronts])]).astype(np.int64)
    return SeparatorTree(order.astype(np.int64), start, np.asarray(parents, dtype=np.int64))


def _build(G, vertices, leaf_nodes, fronts, parents):
    """Append the fronts of the subtree of ``vertices`` (postorder); return the index
    of its root front."""
    split = None if len(vertices) <= leaf_nodes else _bisection(G[vertices][:, vertices])
    if split is None:
        fronts.append(vertices)
        parents.append(-1)
        return len(fronts) - 1
    a, b, sep = split
    children = [_build(G, vertices[part], leaf_nodes, fronts, parents)
                for part in (a, b) if len(part)]
    fronts.append(vertices[sep])
    parents.append(-1)
    me = len(fronts) - 1
    for c in children:
        parents[c] = me
    return me


def _bisection(sub):
    """``(part a, part b, separator)`` (local indices) of the graph ``sub``, or
    ``None`` when it is not worth splitting (METIS leaves a part empty)."""
    import pymetis
    n = sub.shape[0]
    if sub.nnz == 0:                       # no edges: two halves, nothing between
        half = n // 2
        return np.arange(half), np.arange(half, n), np.zeros(0, dtype=np.int64)
    part = np.asarray(pymetis.part_graph(2, xadj=sub.indptr, adjncy=sub.indices)
                      .vertex_part, dtype=np.int8)
    rows = np.repeat(np.arange(n), np.diff(sub.indptr))
    cut = part[rows] != part[sub.indices]
    sides = [np.unique(rows[cut & (part[rows] == k)]) for k in (0, 1)]
    sep = min(sides, key=len)
    keep = np.ones(n, dtype=bool)
    keep[sep] = False
    a = np.flatnonzero(keep & (part == 0))
    b = np.flatnonzero(keep & (part == 1))
    if max(len(a), len(b)) == n:
        return None
    return a, b, sep


# ----------------------------------------------------------------------------------
# Symbolic phase

@dataclass(frozen=True)
class FrontStructure:
    """The DOF sets of the fronts of a factorisation of ``K_EE`` (all in postorder).

    Attributes
    ----------
    perm : E-local DOFs in elimination order (position ``i`` of the factor is DOF
        ``perm[i]``)
    start : front ``t`` eliminates positions ``start[t]:start[t + 1]``
    parent : parent front (``-1``: a root)
    boundary : per front, the positions (sorted, all ``>= start[t + 1]``) of the
        ancestors' DOFs its update couples
    interface : per front, the interface DOFs (sorted positions in the caller's C)
        its update couples
    """

    perm: np.ndarray
    start: np.ndarray
    parent: np.ndarray
    boundary: tuple
    interface: tuple

    @property
    def n_fronts(self) -> int:
        return len(self.parent)

    def factor_entries(self) -> int:
        """Entries of ``L`` held by the solver: ``L_11`` (lower) and ``L_21,B``."""
        nV = np.diff(self.start)
        nB = np.array([len(b) for b in self.boundary])
        return int(np.sum(nV * (nV + 1) // 2 + nV * nB))


def front_structure(K_EE, K_CE, leaf_nodes: int = LEAF_NODES) -> FrontStructure:
    """Separator tree and front sets of the sparse ``K_EE`` with interface coupling
    ``K_CE`` (|C| x n_E), on the node graph of ``K_EE``
    (:func:`qsma.linalg.node_graph`)."""
    from .linalg import node_graph
    group, G = node_graph(K_EE)
    tree = separator_tree(G, leaf_nodes)
    n_groups = G.shape[0]
    first = np.searchsorted(group, np.arange(n_groups + 1))  # groups: runs of rows
    size = np.diff(first)
    perm = _expanded(first[tree.order], size[tree.order])
    position = np.empty(n_groups, dtype=np.int64)           # first position of a group
    position[tree.order] = np.concatenate([[0], np.cumsum(size[tree.order])[:-1]])
    start = np.concatenate([[0], np.cumsum(size[tree.order])])[tree.start]
    front = tree.front_of()
    GC = _group_pattern(sp.csc_matrix(K_CE).T.tocsr(), group, n_groups)   # groups x C
    boundary, interface = [], []
    children = [[] for _ in range(tree.n_fronts)]
    for t, p in enumerate(tree.parent):
        if p >= 0:
            children[p].append(t)
    bgroups = [None] * tree.n_fronts
    for t in range(tree.n_fronts):
        mine = tree.order[tree.start[t]:tree.start[t + 1]]
        near = np.unique(np.concatenate(
            [G.indices[G.indptr[g]:G.indptr[g + 1]] for g in mine]
            + [bgroups[c] for c in children[t]] + [np.zeros(0, dtype=np.int64)]))
        near = near[front[near] > t]
        bgroups[t] = near
        for c in children[t]:
            bgroups[c] = None
        near = near[np.argsort(position[near])]
        boundary.append(_expanded(position[near], size[near]))
        interface.append(np.unique(np.concatenate(
            [GC.indices[GC.indptr[g]:GC.indptr[g + 1]] for g in mine]
            + [interface[c] for c in children[t]] + [np.zeros(0, dtype=np.int64)])))
    return FrontStructure(perm, start.astype(np.int64), tree.parent, tuple(boundary),
                          tuple(interface))


def _expanded(first, size) -> np.ndarray:
    """``concatenate([arange(f, f + s) for f, s in zip(first, size)])``."""
    size = np.asarray(size, dtype=np.int64)
    if len(size) == 0:
        return np.zeros(0, dtype=np.int64)
    offset = np.cumsum(size) - size
    return (np.repeat(np.asarray(first, dtype=np.int64) - offset, size)
            + np.arange(int(size.sum()))).astype(np.int64)


def _group_pattern(A, group, n_groups):
    """Pattern of the rows of ``A`` (CSR) summed per group: groups x columns."""
    P = sp.csr_matrix((np.ones(len(group)), (group, np.arange(len(group)))),
                      shape=(n_groups, len(group)))
    pattern = sp.csr_matrix((np.ones(A.nnz), A.indices, A.indptr), shape=A.shape)
    out = (P @ pattern).tocsr()
    out.sort_indices()
    return out


# ----------------------------------------------------------------------------------
# Numeric phase

@dataclass(frozen=True, eq=False)
class MultifrontalFactor:
    """``K_EE = L L^T`` front by front, and its solves.

    Attributes
    ----------
    structure : :class:`FrontStructure`
    L11 : per front, its Cholesky factor (lower triangle of a Fortran array)
    L21 : per front, the rows of ``L`` at its boundary positions (Fortran array)
    """

    structure: FrontStructure
    L11: tuple
    L21: tuple

    def solve(self, b) -> np.ndarray:
        r"""``K_EE^{-1} b`` for ``b`` of shape (n_E,) or (n_E, k): ``L y = b[perm]``
        front by front in postorder (``y_V = L_11^{-1} y_V``, ``y_B -= L_21 y_V``),
        then ``L^T x = y`` in reverse order (``x_V = L_11^{-T}(y_V - L_21^T x_B)``)."""
        s = self.structure
        one = b.ndim == 1
        y = np.ascontiguousarray(b.reshape(len(b), -1)[s.perm], dtype=float)
        start = s.start
        for t in range(s.n_fronts):
            a, e = start[t], start[t + 1]
            yV = y[a:e].T                     # F-contiguous view: trsm in place
            blas.dtrsm(1.0, self.L11[t], yV, side=1, lower=1, trans_a=1, overwrite_b=1)
            if len(s.boundary[t]):
                y[s.boundary[t]] -= self.L21[t] @ y[a:e]
        for t in range(s.n_fronts - 1, -1, -1):
            a, e = start[t], start[t + 1]
            if len(s.boundary[t]):
                y[a:e] -= self.L21[t].T @ y[s.boundary[t]]
            blas.dtrsm(1.0, self.L11[t], y[a:e].T, side=1, lower=1, trans_a=0,
                       overwrite_b=1)
        x = np.empty_like(y)
        x[s.perm] = y
        return x[:, 0] if one else x


def multifrontal_schur(K_EE, K_CE, structure: FrontStructure):
    r"""Factorise ``K_EE`` on the fronts of ``structure`` and condense onto C.

    Returns
    -------
    (factor, G, ratio) : the :class:`MultifrontalFactor` (``None`` if ``K_EE`` is not
        positive definite), ``G = -K_CE K_EE^{-1} K_EC`` (dense, |C| x |C|, caller's C
        order, symmetric) and ``min_i L_ii^2 / (K_EE)_ii`` (``-inf`` when ``dpotrf``
        meets a non-positive pivot).
    """
    s = structure
    A = sp.csc_matrix(K_EE)[s.perm][:, s.perm].tocsc()
    A.sort_indices()
    B = sp.csc_matrix(sp.csr_matrix(K_CE)[:, s.perm])
    B.sort_indices()
    diag = A.diagonal()
    nC = K_CE.shape[0]
    out = np.zeros((nC, nC), order="F")
    n_children = np.bincount(s.parent[s.parent >= 0], minlength=s.n_fronts)
    L11, L21, updates = [], [], []
    ratio = np.inf
    for t in range(s.n_fronts):
        F11, F21, F22 = _assembled_front(A, B, s, t)
        for child in updates[len(updates) - n_children[t]:]:
            _extend_add(F11, F21, F22, child, s, t)
        del updates[len(updates) - n_children[t]:]
        a, e = s.start[t], s.start[t + 1]
        L, info = lapack.dpotrf(F11, lower=1, clean=1, overwrite_a=1)
        if info != 0:
            return None, out, -np.inf
        if e > a:
            ratio = min(ratio, float(np.min(np.diag(L) ** 2 / diag[a:e])))
        nB = len(s.boundary[t])
        if F21.shape[0] and e > a:
            F21 = blas.dtrsm(1.0, L, F21, side=1, lower=1, trans_a=1, overwrite_b=1)
        LB = np.asfortranarray(F21[:nB])
        if nB and e > a:
            F22 = blas.dgemm(-1.0, F21, LB, trans_b=1, beta=1.0, c=F22, overwrite_c=1)
        updates.append((F22, s.boundary[t], s.interface[t]) if nB else None)
        if len(s.interface[t]) and e > a:
            _interface_update(out, np.asfortranarray(F21[nB:]), s.interface[t])
        del F21, F22
        L11.append(L)
        L21.append(LB)
    from .linalg import mirror_triangle
    G = mirror_triangle(out.T, "lower")          # C order, no copy
    return MultifrontalFactor(s, tuple(L11), tuple(L21)), G, ratio


def _assembled_front(A, B, s, t):
    """The front of ``t`` with ``K``'s entries in its columns: ``F11`` (V x V),
    ``F21`` ([B, C] x V) and ``F22`` ([B, C] x B, zero)."""
    a, e = s.start[t], s.start[t + 1]
    nV, bnd, itf = e - a, s.boundary[t], s.interface[t]
    nB = len(bnd)
    F11 = np.zeros((nV, nV), order="F")
    F21 = np.zeros((nB + len(itf), nV), order="F")
    F22 = np.zeros((nB + len(itf), nB), order="F")
    lo, hi = A.indptr[a], A.indptr[e]
    rows, vals = A.indices[lo:hi], A.data[lo:hi]
    cols = np.repeat(np.arange(nV), np.diff(A.indptr[a:e + 1]))
    inside = (rows >= a) & (rows < e)
    F11[rows[inside] - a, cols[inside]] = vals[inside]
    above = rows >= e
    F21[np.searchsorted(bnd, rows[above]), cols[above]] = vals[above]
    lo, hi = B.indptr[a], B.indptr[e]
    cols = np.repeat(np.arange(nV), np.diff(B.indptr[a:e + 1]))
    F21[nB + np.searchsorted(itf, B.indices[lo:hi]), cols] = B.data[lo:hi]
    return F11, F21, F22


def _extend_add(F11, F21, F22, child, s, t):
    """Add a child's update (rows ``[B_c, C_c]``, columns ``B_c``) to the front of
    ``t``. ``B_c`` is sorted and the positions of ``t``'s own DOFs precede all its
    ancestors', so the first ``k`` entries of ``B_c`` are ``t``'s."""
    if child is None:
        return
    U, bc, cc = child
    a, e = s.start[t], s.start[t + 1]
    k = int(np.searchsorted(bc, e))
    own = bc[:k] - a
    rows = np.concatenate([np.searchsorted(s.boundary[t], bc[k:]),
                           len(s.boundary[t]) + np.searchsorted(s.interface[t], cc)])
    F11[np.ix_(own, own)] += U[:k, :k]
    if len(rows):
        F21[np.ix_(rows, own)] += U[k:, :k]
        F22[np.ix_(rows, rows[:len(bc) - k])] += U[k:, k:]


def _interface_update(out, LC, itf):
    """``out[itf, itf] -= LC LC^T`` on the upper triangle (``itf`` sorted)."""
    if len(itf) == out.shape[0]:
        blas.dsyrk(-1.0, LC, beta=1.0, c=out, overwrite_c=1, lower=0)
    else:
        out[np.ix_(itf, itf)] += blas.dsyrk(-1.0, LC, lower=0)


def schur_parts(K, C, E):
    """The ``"multifrontal"`` backend: ``(Kc, solve, ratio, timings)`` for
    :class:`qsma.linalg.SchurParts`."""
    t0 = time.perf_counter()
    KE = K[E]
    K_EE = KE[:, E].tocsr()
    K_CE = K[C][:, E].tocsr()
    structure = front_structure(K_EE, K_CE)
    t1 = time.perf_counter()
    factor, G, ratio = multifrontal_schur(K_EE, K_CE, structure)
    t2 = time.perf_counter()
    if factor is not None:
        K_CC = K[C][:, C].tocoo()
        G[K_CC.row, K_CC.col] += K_CC.data
    t3 = time.perf_counter()
    return G, factor, ratio, {"ordering": t1 - t0, "factorization": t2 - t1,
                              "schur": t3 - t2}
