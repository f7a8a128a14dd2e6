r"""Multifrontal Cholesky on a nested-dissection tree: the ``"multifrontal"`` Schur backend.

For the SPD ``K`` and interface DOFs ``C`` (``E`` the rest, sorted) this computes

.. math:: K_c = K_{CC} - K_{CE} K_{EE}^{-1} K_{EC}, \qquad x = K_{EE}^{-1} b

with one Cholesky factorisation ``K_EE = L L^T`` done front by front with dense
BLAS-3 (LAPACK ``dpotrf``, BLAS ``dtrsm``, ``dgemm``, ``dsyrk``):

1. **Separator tree.** The node graph of ``K_EE`` (supervariables: the DOFs of one
   mesh node) is cut in two by METIS (``pymetis.part_graph``); a minimum vertex
   cover of the cut edges is a vertex separator ``S``. Both sides
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
:func:`qsma.reduction.schur.schur_complement` turns into an
:class:`~qsma.errors.InputError`; otherwise the ratio is ``min_i L_ii^2 / (K_EE)_ii``.
"""
from __future__ import annotations

from dataclasses import dataclass
import time

import numpy as np
import scipy.sparse as sp
from scipy.linalg import blas, lapack

from ..._infra.dense import mirror_triangle
from ..._infra.threads import one_blas_thread
from .ordering import node_graph
from .registry import PIVOT_RATIO_MIN, SchurParts, register_backend

#: Most graph vertices (mesh nodes) in a leaf of the separator tree. A leaf is one
#: dense front: larger leaves mean fewer fronts (less Python work per factorisation
#: and solve) but more dense arithmetic. One body of sandwich-3d refine 1 (one BLAS
#: thread, single runs on a loaded machine): 16, 32, 64, 128 nodes gave 1.23, 1.07,
#: 0.82, 0.74 s; refine 2: 32, 64, 128 gave 6.05e7, 6.45e7, 7.51e7 factor entries and
#: times within the noise of the machine (docs/schur.md).
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


def separator_tree(G, leaf_nodes: int | None = None) -> SeparatorTree:
    r"""Nested dissection of the graph ``G`` (symmetric CSR adjacency, no diagonal)
    into a tree of fronts by recursive METIS bisection.

    A bisection ``P_0 \cup P_1`` from ``pymetis.part_graph(2, ...)`` is turned into a
    vertex separator ``S``: a minimum vertex cover of the cut edges
    (:func:`minimum_cover`). The front of a tree node eliminates ``S``;
    its children are the trees of ``P_0 \setminus S`` and ``P_1 \setminus S``, which no
    edge joins. Sets of at most ``leaf_nodes`` vertices, without edges to cut or that
    METIS does not split, are leaves.

    Returns
    -------
    SeparatorTree with the fronts in postorder (children before their parent).
    """
    G = sp.csr_matrix(G)
    leaf_nodes = LEAF_NODES if leaf_nodes is None else leaf_nodes
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
    part = np.asarray(pymetis.part_graph(2, pymetis.CSRAdjacency(sub.indptr, sub.indices))
                      .vertex_part, dtype=np.int8)
    rows = np.repeat(np.arange(n), np.diff(sub.indptr))
    cut = (part[rows] == 0) & (part[sub.indices] == 1)
    sep = minimum_cover(rows[cut], sub.indices[cut])
    keep = np.ones(n, dtype=bool)
    keep[sep] = False
    a = np.flatnonzero(keep & (part == 0))
    b = np.flatnonzero(keep & (part == 1))
    if max(len(a), len(b)) == n:
        return None
    return a, b, sep


def minimum_cover(left, right) -> np.ndarray:
    r"""Smallest set of vertices that touches every edge ``left[i] - right[i]`` of a
    bipartite graph (the two lists name disjoint vertex sets): a vertex separator
    from the cut edges of a bisection.

    By Koenig's theorem its size is that of a maximum matching ``M``
    (``scipy.sparse.csgraph.maximum_bipartite_matching``). With ``Z`` the vertices
    reachable from the unmatched left vertices by alternating paths (any edge from
    left to right, a matched edge from right to left), the cover is
    ``(L \setminus Z) \cup (R \cap Z)``.
    """
    from scipy.sparse.csgraph import breadth_first_order, maximum_bipartite_matching
    if len(left) == 0:
        return np.zeros(0, dtype=np.int64)
    L, li = np.unique(left, return_inverse=True)
    R, ri = np.unique(right, return_inverse=True)
    nL, nR = len(L), len(R)
    edges = sp.csr_matrix((np.ones(len(li)), (li, ri)), shape=(nL, nR))
    match = maximum_bipartite_matching(edges, perm_type="column")   # left -> right
    matched = match >= 0
    # directed graph on [source, L, R]: source -> unmatched left, left -> right,
    # right -> its matched left
    src = np.concatenate([np.zeros(int(np.sum(~matched)), dtype=np.int64),
                          1 + li, 1 + nL + match[matched]])
    dst = np.concatenate([1 + np.flatnonzero(~matched), 1 + nL + ri,
                          1 + np.flatnonzero(matched)])
    graph = sp.csr_matrix((np.ones(len(src)), (src, dst)), shape=(1 + nL + nR,) * 2)
    reached = np.zeros(1 + nL + nR, dtype=bool)
    reached[breadth_first_order(graph, 0, directed=True, return_predecessors=False)] = True
    cover = np.concatenate([L[~reached[1:1 + nL]], R[reached[1 + nL:]]])
    return np.sort(cover)


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
    interface : per front, the interface DOFs its update couples, as sorted numbers
        of the interface order
    interface_order : the interface order: ``interface_order[i]`` is the position in
        the caller's C of interface DOF number ``i``. The DOFs are numbered by the
        last front that couples them (postorder), so that those of a subtree form
        one run of numbers, apart from the few that later fronts also couple: the
        extend-add and the C x C update then work mostly on slices.
    """

    perm: np.ndarray
    start: np.ndarray
    parent: np.ndarray
    boundary: tuple
    interface: tuple
    interface_order: np.ndarray

    @property
    def n_fronts(self) -> int:
        return len(self.parent)

    def factor_entries(self) -> int:
        """Entries of ``L`` held by the solver: ``L_11`` (lower) and ``L_21,B``."""
        nV = np.diff(self.start)
        nB = np.array([len(b) for b in self.boundary])
        return int(np.sum(nV * (nV + 1) // 2 + nV * nB))


def front_structure(K_EE, K_CE, leaf_nodes: int | None = None) -> FrontStructure:
    """Separator tree and front sets of the sparse ``K_EE`` with interface coupling
    ``K_CE`` (|C| x n_E), on the node graph of ``K_EE``
    (:func:`qsma.reduction.schur.ordering.node_graph`)."""
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
    last = np.full(GC.shape[1], -1, dtype=np.int64)      # last front coupling a C DOF
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
        own = np.concatenate([GC.indices[GC.indptr[g]:GC.indptr[g + 1]] for g in mine]
                             + [np.zeros(0, dtype=np.int64)])
        last[own] = t
        interface.append(np.unique(np.concatenate(
            [own] + [interface[c] for c in children[t]])))
    order = np.argsort(last, kind="stable")
    number = np.empty(len(order), dtype=np.int64)
    number[order] = np.arange(len(order))
    interface = tuple(np.sort(number[c]) for c in interface)
    return FrontStructure(perm, start.astype(np.int64), tree.parent, tuple(boundary),
                          interface, order)


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
        then ``L^T x = y`` in reverse order (``x_V = L_11^{-T}(y_V - L_21^T x_B)``).

        The right-hand sides are the columns of Fortran blocks passed to BLAS
        ``dtrsm`` and ``dgemm`` as their ``n`` dimension, as in SuperLU's solves: the
        OpenBLAS kernels treat such columns in pairs, so a solve of columns split at
        even offsets (:func:`qsma.reduction.schur.superlu.solved_by_columns`) has the bits of the
        whole one."""
        s = self.structure
        one = b.ndim == 1
        y = np.asfortranarray(b.reshape(len(b), -1)[s.perm], dtype=float)
        fronts = np.flatnonzero(np.diff(s.start) > 0)    # (a separator may be empty)
        for t in fronts:
            yV = self._front_solve(y, t, trans=0)
            if len(s.boundary[t]):
                yB = np.asfortranarray(y[s.boundary[t]])
                y[s.boundary[t]] = blas.dgemm(-1.0, self.L21[t], yV, beta=1.0, c=yB,
                                              overwrite_c=1)
        for t in fronts[::-1]:
            if len(s.boundary[t]):
                a, e = s.start[t], s.start[t + 1]
                yV = np.asfortranarray(y[a:e])
                y[a:e] = blas.dgemm(-1.0, self.L21[t], np.asfortranarray(y[s.boundary[t]]),
                                    trans_a=1, beta=1.0, c=yV, overwrite_c=1)
            self._front_solve(y, t, trans=1)
        x = np.empty_like(y)
        x[s.perm] = y
        return x[:, 0] if one else x

    def _front_solve(self, y, t, trans):
        """``y_V = L_11^{-1} y_V`` (``trans = 0``) or ``L_11^{-T} y_V`` (1) in place
        for the rows ``V`` of front ``t``; returns the new ``y_V`` (Fortran)."""
        a, e = self.structure.start[t], self.structure.start[t + 1]
        yV = blas.dtrsm(1.0, self.L11[t], np.asfortranarray(y[a:e]), lower=1,
                        trans_a=trans, overwrite_b=1)
        y[a:e] = yV
        return yV


def multifrontal_schur(K_EE, K_CE, structure: FrontStructure):
    r"""Factorise ``K_EE`` on the fronts of ``structure`` and condense onto C.

    Returns
    -------
    (factor, G, ratio, seconds) : the :class:`MultifrontalFactor` (``None`` if
        ``K_EE`` is not positive definite), ``G = -K_CE K_EE^{-1} K_EC`` (dense,
        |C| x |C|, caller's C order, symmetric), ``min_i L_ii^2 / (K_EE)_ii``
        (``-inf`` when ``dpotrf`` meets a non-positive pivot) and the seconds spent
        on the C x C updates (included in the factorisation's time).
    """
    s = structure
    A = sp.csc_matrix(K_EE)[s.perm][:, s.perm].tocsc()
    A.sort_indices()
    B = sp.csc_matrix(sp.csr_matrix(K_CE)[s.interface_order][:, s.perm])
    B.sort_indices()
    diag = A.diagonal()
    nC = K_CE.shape[0]
    out = np.zeros((nC, nC), order="F")
    n_children = np.bincount(s.parent[s.parent >= 0], minlength=s.n_fronts)
    L11, L21, updates = [], [], []        # updates: a stack, children on top
    ratio = np.inf
    clock = [0.0]                          # seconds of the C x C updates
    for t in range(s.n_fronts):
        front = _assembled_front(A, B, s, t)
        for child in updates[len(updates) - n_children[t]:]:
            _extend_add(front, child, s, t)
        del updates[len(updates) - n_children[t]:]
        L, LB, update, ratio_t = _partial_cholesky(*front, s, t, out, diag, clock)
        del front
        if L is None:
            return None, out, -np.inf, clock[0]
        ratio = min(ratio, ratio_t)
        updates.append(update)
        L11.append(L)
        L21.append(LB)
    G = _reordered(mirror_triangle(out.T, "lower"), s.interface_order)
    return MultifrontalFactor(s, tuple(L11), tuple(L21)), G, ratio, clock[0]


def _reordered(G, order, rows_per_block=512):
    """``H`` with ``H[order[i], order[j]] = G[i, j]`` (a new C-ordered array; ``G``
    square, C-ordered), by blocks of rows (no second temporary of full size)."""
    rank = np.empty(len(order), dtype=np.int64)
    rank[order] = np.arange(len(order))
    if np.array_equal(rank, np.arange(len(rank))):
        return G
    H = np.empty_like(G)
    for i in range(0, len(rank), rows_per_block):
        H[i:i + rows_per_block] = G[rank[i:i + rows_per_block]][:, rank]
    return H


def _assembled_front(A, B, s, t):
    """The front of ``t`` with ``K``'s entries in its columns ``V``: ``F11`` (V x V),
    ``FB`` (rows ``B``, columns ``[V, B]``) and ``FC`` (rows ``C``, columns
    ``[V, B]``), Fortran arrays; the ``B`` columns are zero."""
    a, e = s.start[t], s.start[t + 1]
    nV, bnd, itf = e - a, s.boundary[t], s.interface[t]
    F11 = np.zeros((nV, nV), order="F")
    FB = np.zeros((len(bnd), nV + len(bnd)), order="F")
    FC = np.zeros((len(itf), nV + len(bnd)), order="F")
    lo, hi = A.indptr[a], A.indptr[e]
    rows, vals = A.indices[lo:hi], A.data[lo:hi]
    cols = np.repeat(np.arange(nV), np.diff(A.indptr[a:e + 1]))
    inside = (rows >= a) & (rows < e)
    F11[rows[inside] - a, cols[inside]] = vals[inside]
    above = rows >= e
    FB[np.searchsorted(bnd, rows[above]), cols[above]] = vals[above]
    lo, hi = B.indptr[a], B.indptr[e]
    cols = np.repeat(np.arange(nV), np.diff(B.indptr[a:e + 1]))
    FC[np.searchsorted(itf, B.indices[lo:hi]), cols] = B.data[lo:hi]
    return F11, FB, FC


def _partial_cholesky(F11, FB, FC, s, t, out, diag, clock):
    r"""Eliminate the DOFs ``V`` of front ``t``:

    .. math:: F_{11} = L_{11} L_{11}^T, \quad L_{B} = F_{BV} L_{11}^{-T}, \quad
              L_{C} = F_{CV} L_{11}^{-T}, \quad
              U_{BB} = F_{BB} - L_B L_B^T, \quad U_{CB} = F_{CB} - L_C L_B^T,

    and ``out[C, C] -= L_C L_C^T`` (upper triangle). ``U_BB`` is valid in its lower
    triangle only (``dsyrk``), which is all its ancestors read. Returns ``(L11, L_B,
    (U_BB, U_CB, B, C) or None, ratio)``, ``L11 = None`` if ``F11`` is not positive
    definite."""
    a, e = s.start[t], s.start[t + 1]
    nV, nB = e - a, len(s.boundary[t])
    L, info = lapack.dpotrf(F11, lower=1, clean=1, overwrite_a=1)
    if info != 0:
        return None, None, None, -np.inf
    ratio = float(np.min(np.diag(L) ** 2 / diag[a:e])) if nV else np.inf
    LB, UB = FB[:, :nV], FB[:, nV:]               # column blocks: Fortran-contiguous
    LC, UC = FC[:, :nV], FC[:, nV:]
    if nV and nB:
        LB = blas.dtrsm(1.0, L, LB, side=1, lower=1, trans_a=1, overwrite_b=1)
        UB = blas.dsyrk(-1.0, LB, beta=1.0, c=UB, lower=1, overwrite_c=1)
    if nV and len(LC):
        LC = blas.dtrsm(1.0, L, LC, side=1, lower=1, trans_a=1, overwrite_b=1)
        if nB:
            UC = blas.dgemm(-1.0, LC, LB, trans_b=1, beta=1.0, c=UC, overwrite_c=1)
        t0 = time.perf_counter()
        _interface_update(out, LC, s.interface[t])
        clock[0] += time.perf_counter() - t0
    update = None
    if nB:
        update = (np.array(UB, order="F"), np.array(UC, order="F"), s.boundary[t],
                  s.interface[t])
    return L, np.array(LB, order="F"), update, ratio


def _extend_add(front, child, s, t):
    """Add a child's update (``U_BB``: rows and columns ``B_c``, lower triangle;
    ``U_CB``: rows ``C_c``, columns ``B_c``) to the front of ``t``. ``B_c`` is sorted
    and the positions of ``t``'s own DOFs precede all its ancestors', so the first
    ``k`` entries of ``B_c`` are ``t``'s."""
    if child is None:
        return
    F11, FB, FC = front
    UB, UC, bc, cc = child
    a, e = s.start[t], s.start[t + 1]
    k = int(np.searchsorted(bc, e))
    own = bc[:k] - a
    up = np.searchsorted(s.boundary[t], bc[k:])
    cols = np.concatenate([own, (e - a) + up])
    _add_block(F11, own, own, UB[:k, :k])
    _add_block(FB, up, cols, UB[k:])
    _add_block(FC, np.searchsorted(s.interface[t], cc), cols, UC)


#: Shortest run of consecutive rows that :func:`_add_block` adds through a slice.
RUN_ROWS = 16


def _add_block(F, rows, cols, X):
    """``F[ix_(rows, cols)] += X`` (``rows`` and ``cols`` increasing). Runs of at
    least :data:`RUN_ROWS` consecutive rows are added through slices; the other rows
    are gathered, added to and put back. numpy's 2-D fancy indexing costs ~40 ns an
    entry, a slice ~5 ns."""
    if len(rows) == 0 or len(cols) == 0:
        return
    if cols[-1] - cols[0] == len(cols) - 1:
        cols = slice(cols[0], cols[-1] + 1)
    breaks = np.flatnonzero(np.diff(rows) != 1) + 1
    first = np.concatenate([[0], breaks])
    end = np.concatenate([breaks, [len(rows)]])
    long = end - first >= RUN_ROWS
    for i, j in zip(first[long], end[long]):
        F[rows[i]:rows[i] + (j - i), cols] += X[i:j]
    if long.all():
        return
    rest = np.repeat(~long, end - first)
    r = rows[rest]
    if isinstance(cols, slice) or 2 * len(cols) < F.shape[1]:
        F[np.ix_(r, np.arange(F.shape[1])[cols])] += X[rest]
    else:
        block = F[r]
        block[:, cols] += X[rest]
        F[r] = block


def _interface_update(out, LC, itf):
    """``out[itf, itf] -= LC LC^T`` on the upper triangle (``itf`` sorted)."""
    if len(itf) == out.shape[0]:
        blas.dsyrk(-1.0, LC, beta=1.0, c=out, overwrite_c=1, lower=0)
    else:
        _add_block(out, itf, itf, blas.dsyrk(-1.0, LC, lower=0))


def schur_parts(K, C, E):
    """The ``"multifrontal"`` backend on the canonical CSR ``K``: ``(Kc, factor,
    ratio, timings)``, ``Kc`` in the order of ``C`` (not yet symmetrised: its two
    triangles are equal by construction), ``factor`` a :class:`MultifrontalFactor` or
    ``None`` when ``K_EE`` is not positive definite (then ``ratio = -inf``)."""
    t0 = time.perf_counter()
    K_EE = K[E][:, E].tocsr()
    K_CE = K[C][:, E].tocsr()
    structure = front_structure(K_EE, K_CE)
    t1 = time.perf_counter()
    factor, G, ratio, update = multifrontal_schur(K_EE, K_CE, structure)
    t2 = time.perf_counter()
    if factor is not None:
        K_CC = K[C][:, C].tocoo()
        G[K_CC.row, K_CC.col] += K_CC.data
    t3 = time.perf_counter()
    return G, factor, ratio, {"ordering": t1 - t0, "factorization": t2 - t1 - update,
                              "schur": t3 - t2 + update}


@register_backend("multifrontal", requires="pymetis")
def _schur_multifrontal(K, C, E) -> SchurParts:
    r"""Dense-front Cholesky ``K_EE = L L^T`` on a nested-dissection tree of the node
    graph (this module); the interface rows are carried in every front and never
    eliminated, so their updates sum to ``K_CE K_EE^{-1} K_EC``. The factor (one
    triangle) is the solver, called on all the columns at once with one BLAS thread:
    its loop over the fronts holds the GIL between the BLAS calls, so the column blocks
    of :func:`~qsma.reduction.schur.superlu.solved_by_columns` on two threads wait for
    each other (12 columns, quiet machine: 40 ms in one call against 98 ms on two threads for
    the 3d-1 block, 352 against 784 ms for 3d-2;
    ``python benchmarks/bench_schur.py --solve-split --cases 3d-1 3d-2``), and one
    BLAS thread keeps the bits of a solve independent of the machine's thread count."""
    Kc, factor, ratio, timings = schur_parts(K, C, E)
    if factor is None or not ratio > PIVOT_RATIO_MIN:
        return SchurParts(Kc, None, ratio, timings)

    def solve(b):
        with one_blas_thread():
            return factor.solve(b)
    return SchurParts(Kc, solve, ratio, timings)
