r"""Bodies that are congruent up to an orthogonal map share one factorisation.

Two bodies A and B are *congruent* when a node permutation ``p`` and an orthogonal
``Q`` (a rotation, ``det Q = +1``, or a reflection, ``det Q = -1``) and a translation
``c`` carry the nodes of A onto those of B,

.. math:: x^B_{p(i)} = Q\, x^A_i + c ,

and the DOF map :math:`T = P \otimes Q` (``(T u)_{p(i)} = Q u_i``, orthogonal) carries
A's operators onto B's: :math:`K_B = T K_A T^T`, :math:`M_B = T M_A T^T`, A's
clamped DOFs onto B's and A's interface nodes onto B's (as sets). Then every matrix
of B's static condensation is one of A's seen through ``T``: with E and C the
non-interface and interface DOFs of each body,

.. math:: K^B_{EE} = T_E K^A_{EE} T_E^T, \qquad
          (K^B_{EE})^{-1} b = T_E (K^A_{EE})^{-1} T_E^T b, \qquad
          Kc^B_{glob} = T_C\, Kc^A_{glob}\, T_C^T ,

with ``T_E``, ``T_C`` the blocks of ``T`` between the E (C) DOFs of the two bodies.
One factorisation of :math:`K^A_{EE}` serves both bodies (docs/theory.md, section
"Congruent bodies").

The detection (:func:`find_congruence`) proposes ``Q`` from the signed permutations of
the global axes and from the principal axes of the two node clouds (every choice of
signs and order, so that equal principal moments are covered where the axes are
those of the mesh), matches the nodes with a k-d tree to :data:`NODE_RTOL` of the
body size, refines ``Q`` by an orthogonal Procrustes fit on the matched nodes, and
then **verifies** the operators themselves to :data:`OPERATOR_RTOL`: whatever the
element, material, incompatible modes or springs, the map is used only where it
holds for the assembled matrices. Anything that fails leaves the bodies to be
condensed separately (logged at info level, never an error).
"""
from __future__ import annotations

from dataclasses import dataclass
import itertools
import logging

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .._infra.dense import symmetrised
from .schur import ee_rhs

log = logging.getLogger("qsma")

#: Node coordinates match when closer than this fraction of the body's bounding-box
#: diagonal. Operators of bodies whose coordinates differ by more than ~1e-12 fail
#: :data:`OPERATOR_RTOL` anyway; this bound only has to stay well below the node
#: spacing (1e-9 of the body size).
NODE_RTOL = 1e-9
#: ``|T K_A T^T - K_B|_ij <= OPERATOR_RTOL sqrt(|K_B,ii K_B,jj|)`` for every entry (and
#: the same for M): each entry against the diagonal of its own rows, so that a stiff
#: spring or block does not set the scale of the whole check. The round-off of
#: assembling the same body at mirrored or rotated coordinates is 1e-16 .. 1e-13 of
#: it (sandwich-2d and -3d, tests/test_congruence.py), a different material or
#: element 1e-4 and more.
OPERATOR_RTOL = 1e-12
#: Floor of a diagonal entry in :func:`_operator_mismatch`, relative to the largest.
TINY = 1e-300
#: Entries of ``Q`` within this of 0 or +-1 are snapped (a signed permutation stays one
#: exactly, so its DOF map moves single DOFs).
SNAP_TOL = 1e-10
#: Nodes tried first for each candidate ``Q`` before all nodes are matched.
SAMPLE_NODES = 16


@dataclass(frozen=True)
class Congruence:
    r"""``x_B[perm[i]] = Q x_A[i] + c`` for every node ``i`` of body A.

    Attributes
    ----------
    Q : (dim, dim) orthogonal, ``det Q = +-1``
    c : (dim,) translation
    perm : node ``i`` of A is node ``perm[i]`` of B
    mismatch : the largest entry of ``T K_A T^T - K_B`` against the diagonal of its
        rows (:func:`_operator_mismatch`), measured by the verification
    """

    Q: np.ndarray
    c: np.ndarray
    perm: np.ndarray
    mismatch: float = 0.0

    @property
    def dim(self) -> int:
        return self.Q.shape[0]

    @property
    def is_signed_permutation(self) -> bool:
        return bool(np.all((self.Q == 0) | (np.abs(self.Q) == 1)))

    def dof_map(self) -> sp.csr_matrix:
        r"""``T`` (n_B x n_A DOFs) with ``(T u)[dim p(i) + k] = sum_j Q_kj u[dim i + j]``:
        the displacement of A carried onto B (orthogonal, ``T^T T = I``)."""
        d, n = self.dim, len(self.perm)
        rows = d * self.perm[:, None, None] + np.arange(d)[None, :, None]
        cols = d * np.arange(n)[:, None, None] + np.arange(d)[None, None, :]
        shape = (n, d, d)
        T = sp.csr_matrix((np.broadcast_to(self.Q, shape).ravel(),
                           (np.broadcast_to(rows, shape).ravel(),
                            np.broadcast_to(cols, shape).ravel())), shape=(d * n, d * n))
        T.eliminate_zeros()
        return T


def find_congruence(assembled_a, assembled_b, nodes_a, nodes_b) -> Congruence | None:
    r"""The :class:`Congruence` carrying body A onto body B, verified on the assembled
    operators, or None (the reason logged at info level).

    Parameters
    ----------
    assembled_a, assembled_b : :class:`qsma.fe.AssembledBody`
    nodes_a, nodes_b : interface nodes of each body (any order); they must map onto
        each other as sets

    Checks, in order: same dimension and node count; a candidate ``Q`` that matches
    every node to :data:`NODE_RTOL` one to one; the interface nodes map; the clamped
    DOFs map (``T`` sends no clamped DOF of A to a free DOF of B: for a ``Q`` that is
    not a signed permutation only whole-node clamps do); ``T M_A T^T = M_B`` and
    ``T K_A T^T = K_B`` entry by entry to :data:`OPERATOR_RTOL` of their diagonals. Several
    candidates can match the nodes of a symmetric body; the first one that passes
    every check is taken.
    """
    name = f"bodies {assembled_a.body.name!r} and {assembled_b.body.name!r}"
    xa, xb = assembled_a.body.mesh.points, assembled_b.body.mesh.points
    if xa.shape != xb.shape or assembled_a.K.shape != assembled_b.K.shape:
        log.info("%s are condensed separately: different node or DOF counts", name)
        return None
    if len(nodes_a) != len(nodes_b):
        log.info("%s are condensed separately: different interface node counts", name)
        return None
    reasons = []
    for cong in node_maps(xa, xb):
        reason, mismatch = _refusal(assembled_a, assembled_b, nodes_a, nodes_b, cong)
        if reason is None:
            cong = Congruence(cong.Q, cong.c, cong.perm, mismatch)
            log.info("%s are congruent (Q = %s, K mismatch %.1e): one factorisation",
                     name, np.round(cong.Q, 6).tolist(), mismatch)
            return cong
        reasons.append(f"under Q = {np.round(cong.Q, 6).tolist()}, {reason}")
    why = ("; ".join(reasons) if reasons else "no orthogonal map of the nodes")
    log.info("%s are condensed separately: %s", name, why)
    return None


def node_maps(xa, xb):
    """Every distinct :class:`Congruence` (mismatch not yet measured) that carries the
    node cloud ``xa`` onto ``xb`` one to one, to :data:`NODE_RTOL` of the body size."""
    ca, cb = xa.mean(axis=0), xb.mean(axis=0)
    size = float(np.linalg.norm(np.ptp(xa, axis=0)))
    if size == 0.0:
        return
    tol = NODE_RTOL * size
    tree = cKDTree(xb)
    sample = np.linspace(0, len(xa) - 1, min(SAMPLE_NODES, len(xa))).astype(int)
    found = set()
    for Q in candidate_maps(xa - ca, xb - cb):
        if not _matches(tree, (xa[sample] - ca) @ Q.T + cb, tol):
            continue
        d, perm = tree.query((xa - ca) @ Q.T + cb, distance_upper_bound=tol)
        if not np.all(np.isfinite(d)) or len(np.unique(perm)) != len(xa):
            continue
        Q = _procrustes(xa - ca, xb[perm] - cb, Q)
        key = _key(Q)
        if key in found:
            continue
        found.add(key)
        yield Congruence(Q, cb - Q @ ca, perm.astype(np.int64))


def candidate_maps(xa, xb):
    """Candidate ``Q`` for centred clouds ``xa``, ``xb``: the signed permutations of the
    global axes, then ``V_B S V_A^T`` for every signed permutation ``S`` with ``V_A``,
    ``V_B`` the principal axes (eigenvectors of the second moments) of each cloud."""
    dim = xa.shape[1]
    signed = list(signed_permutations(dim))
    yield from signed
    _, Va = np.linalg.eigh(xa.T @ xa)
    _, Vb = np.linalg.eigh(xb.T @ xb)
    for S in signed:
        yield Vb @ S @ Va.T


def signed_permutations(dim):
    """The ``2^dim dim!`` matrices with one entry +-1 per row and column."""
    for perm in itertools.permutations(range(dim)):
        for signs in itertools.product((1.0, -1.0), repeat=dim):
            S = np.zeros((dim, dim))
            S[np.arange(dim), perm] = signs
            yield S


def _matches(tree, points, tol):
    d, _ = tree.query(points, distance_upper_bound=tol)
    return bool(np.all(np.isfinite(d)))


def _procrustes(xa, xb, Q):
    r"""The orthogonal ``Q`` closest to carrying ``xa`` onto ``xb`` (rows matched):
    ``Q = U V^T`` from the SVD ``xb^T xa = U s V^T``; ``Q`` as given when the clouds
    are flat (no unique fit). Entries within :data:`SNAP_TOL` of 0 or +-1 are snapped."""
    U, s, Vt = np.linalg.svd(xb.T @ xa)
    if s.min() > 1e-12 * s.max():
        Q = U @ Vt
    snapped = np.round(Q)
    near = np.abs(Q - snapped) < SNAP_TOL
    if np.all(near):
        return snapped + 0.0                      # -0.0 -> 0.0
    return np.where(near & (snapped == 0), 0.0, Q)


def _key(Q):
    return (np.round(Q, 8) + 0.0).tobytes()


def _refusal(assembled_a, assembled_b, nodes_a, nodes_b, cong):
    """``(reason, mismatch)``: why ``cong`` does not carry body A's condensation onto
    B's (None if it does) and the relative mismatch of the last operator compared."""
    mapped = cong.perm[np.asarray(nodes_a)]
    if not np.array_equal(np.sort(mapped), np.sort(np.asarray(nodes_b))):
        return "the interface nodes do not map onto each other", np.inf
    fixed_a, fixed_b = np.asarray(assembled_a.fixed), np.asarray(assembled_b.fixed)
    T = cong.dof_map()
    if len(fixed_a) != len(fixed_b):
        return "the clamps hold different numbers of DOFs", np.inf
    leak = T[np.asarray(assembled_b.free)][:, fixed_a]
    if leak.nnz and abs(leak).max() > SNAP_TOL:
        return ("the clamped DOFs do not map onto each other"
                + ("" if cong.is_signed_permutation else
                   " (a rotated map carries only whole-node clamps)")), np.inf
    mismatch = np.inf
    for what, A, B in (("mass", assembled_a.M, assembled_b.M),
                       ("stiffness", assembled_a.K, assembled_b.K)):
        mismatch = _operator_mismatch(T, A, B)
        if not mismatch <= OPERATOR_RTOL:
            return (f"the {what} matrices differ under the node map (relative "
                    f"{mismatch:.1e} > {OPERATOR_RTOL:g}: another material, element or "
                    f"mesh)"), mismatch
    return None, mismatch


def _operator_mismatch(T, A, B) -> float:
    r"""``max_ij |(T A T^T - B)_ij| / sqrt(|B_ii| |B_jj|)``: each entry against the
    diagonal of its own rows, so that a stiff part (a grounded spring, a stiff block)
    cannot hide a difference elsewhere; for the positive semi-definite K and M no entry
    of ``B`` exceeds its scale. A zero diagonal (a row of zeros) is compared against
    ``TINY`` times the largest entry."""
    B = sp.csr_matrix(B)
    top = abs(B).max()
    if not top > 0:
        return float("inf")
    d = np.sqrt(np.maximum(np.abs(B.diagonal()), TINY * top))
    D = (T @ sp.csr_matrix(A) @ T.T - B).tocoo()
    if D.nnz == 0:
        return 0.0
    return float(np.max(np.abs(D.data) / (d[D.row] * d[D.col])))


# ----------------------------------------------------------------------------------
# B's condensed stiffness and K_EE solves through A's

@dataclass(frozen=True, eq=False)
class CongruentMatrix:
    r"""The symmetric matrix ``G A G^T`` kept as ``A`` (dense, symmetric, owned by
    the congruent body) and the sparse orthogonal ``G``: no dense copy of its own.

    ``M @ x = G (A (G^T x))`` (vectors or matrices); ``np.asarray(M)`` builds the
    dense matrix (symmetrised), for the few places that need it whole (the two-body
    combination, a block-diagonal stack).
    """

    base: np.ndarray
    G: sp.csr_matrix

    ndim = 2
    dtype = np.dtype(float)

    @property
    def shape(self):
        return (self.G.shape[0], self.G.shape[0])

    @property
    def T(self):                                   # symmetric
        return self

    @property
    def nbytes(self) -> int:
        """Bytes held of its own (``G``; ``A`` belongs to the other body)."""
        return self.G.data.nbytes + self.G.indices.nbytes + self.G.indptr.nbytes

    def __array__(self, dtype=None, copy=None):
        X = self.G @ self.base                     # G A, then G (G A)^T = G A G^T
        dense = symmetrised(np.ascontiguousarray(self.G @ X.T))
        return dense if dtype is None else dense.astype(dtype, copy=False)

    def __matmul__(self, x):
        return self.G @ (self.base @ (self.G.T @ np.asarray(x)))

    def __rmatmul__(self, x):                      # x M = (M x^T)^T, M symmetric
        return (self @ np.asarray(x).T).T

    def __repr__(self):
        return f"CongruentMatrix(shape={self.shape})"


# ----------------------------------------------------------------------------------
# B's K_EE solves through A's factor

@dataclass(frozen=True, eq=False)
class MappedSolver:
    r"""``x = (K^B_{EE})^{-1} b = T_E (K^A_{EE})^{-1} T_E^T b`` through body A's solver.

    Attributes
    ----------
    base : body A's ``K_EE`` solver (:class:`qsma.reduction.schur.EESolver` or any callable
        on (n_E,) / (n_E, k) arrays)
    T_E : sparse (n_E, n_E) orthogonal block of the DOF map between the E DOFs of B
        (rows) and of A (columns), both in their bodies' sorted order
    base_name : the name of body A (the factor's owner)
    """

    base: object
    T_E: sp.csr_matrix
    base_name: str = ""

    @property
    def n(self) -> int:
        return self.T_E.shape[0]

    @property
    def backend(self) -> str:
        return getattr(self.base, "backend", "auto")

    def __call__(self, b) -> np.ndarray:
        b = ee_rhs(b, self.n)
        if b.size == 0:
            return b.copy()
        return self.T_E @ self.base(self.T_E.T @ b)

    def __repr__(self):
        return f"MappedSolver(n={self.n}, base={self.base_name!r})"


def solved_together(solvers, rhs) -> list:
    """``[s(b) for s, b in zip(solvers, rhs)]``, with the right-hand sides of solvers
    that share a factor (:class:`MappedSolver` of the same ``base``, and ``base``
    itself) stacked as columns of one multi-RHS solve. Solvers of their own are called
    as they are (the same bits as calling them one by one)."""
    rhs = [np.asarray(b, dtype=float) for b in rhs]
    roots = [s.base if isinstance(s, MappedSolver) else s for s in solvers]
    out = [None] * len(solvers)
    for root in {id(r): r for r in roots}.values():
        members = [j for j, r in enumerate(roots) if r is root]
        if len(members) == 1:
            j = members[0]
            out[j] = solvers[j](rhs[j])
            continue
        cols = [_as_columns(ee_rhs(rhs[j], solvers[j].n)) for j in members]
        pulled = [c if solvers[j] is root else solvers[j].T_E.T @ c
                  for j, c in zip(members, cols)]
        x = root(np.hstack(pulled))
        start = 0
        for j, c in zip(members, cols):
            xj = x[:, start:start + c.shape[1]]
            start += c.shape[1]
            xj = xj if solvers[j] is root else solvers[j].T_E @ xj
            out[j] = xj.reshape(rhs[j].shape)
    return out


def _as_columns(b):
    return b.reshape(b.shape[0], int(np.prod(b.shape[1:])))
