"""The ``"metis_superlu"`` backend (``pymetis``): METIS nested dissection of ``K_EE``
and one SuperLU factorisation of the bordered matrix ``[[K_EE, K_EC], [0, I]]`` in that
order, without pivoting; ``Kc = K_CC - U_EC^T D^-1 U_EC`` by blocked BLAS products, and
the same factor solves with ``K_EE``."""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.linalg import blas as sla_blas

from ..._infra.dense import mirror_triangle
from ..._infra.threads import one_blas_thread
from .ordering import nested_dissection
from .registry import PIVOT_RATIO_MIN, SchurParts, register_backend
from .superlu import _drop_extracted_factors, solved_by_columns
from .superlu_schur import _schur_superlu_partial

#: Columns of ``L_CE`` per dense block of the Schur update in ``"metis_superlu"``.
SCHUR_UPDATE_COLUMNS = 256


@register_backend("metis_superlu", requires="pymetis")
def _schur_metis_superlu(K, C, E) -> SchurParts:
    r"""One SuperLU factorisation gives both ``Kc`` and the solver.

    With ``p`` the METIS ordering of ``K_EE`` (``A = K_EE[p][:, p]``, ``B = K_CE[:, p]``),
    SuperLU factorises, in that order and without pivoting, the block upper triangular

    .. math:: M = \begin{bmatrix} A & B^T \\ 0 & I \end{bmatrix}
              = \begin{bmatrix} L & 0 \\ 0 & I \end{bmatrix}
                \begin{bmatrix} D L^T & U_{EC} \\ 0 & I \end{bmatrix},
              \qquad U_{EC} = L^{-1} B^T,

    so the C columns are never updated by each other (no dense |C| x |C|
    factorisation) and ``Kc = K_CC - U_EC^T D^{-1} U_EC``, summed in dense blocks of
    :data:`SCHUR_UPDATE_COLUMNS` rows of ``U_EC`` over the columns they touch. ``U``
    gives both ``D`` (the pivots) and ``U_EC`` (a column slice; the former
    ``[[A, 0], [B, I]]`` needed ``L_CE``, a row slice of L), and SuperLU's L holds no
    interface rows. scipy's copies of L and U are emptied afterwards
    (:func:`_drop_extracted_factors`).
    ``M [x; y] = [b; 0]`` gives ``y = 0`` and ``x = A^-1 b``: the same factor is the
    solver."""
    t0 = time.perf_counter()
    nE, nC = len(E), len(C)
    K_EE = K[E][:, E]
    p = nested_dissection(K_EE)
    A = K_EE[p][:, p]
    M = sp.bmat([[A, K[E[p]][:, C]], [None, sp.identity(nC)]], format="csc")
    a = A.diagonal()
    del K_EE, A                      # not held next to the factor and scipy's copies
    t1 = time.perf_counter()
    try:
        with one_blas_thread():      # small supernode blocks: see solved_by_columns
            lu = spla.splu(M, permc_spec="NATURAL", diag_pivot_thresh=0.0,
                           options={"SymmetricMode": True})
    except RuntimeError:             # "Factor is exactly singular"
        return SchurParts(np.zeros((nC, nC)), None, -np.inf, {})
    identity = np.arange(nE + nC)
    if not (np.array_equal(lu.perm_r, identity) and np.array_equal(lu.perm_c, identity)):
        return _schur_superlu_partial(K, C, E)   # SuperLU reordered or pivoted
    del M
    U = lu.U.tocsc()
    d = U.diagonal()[:nE]
    ratio = float(np.min(d / a))
    t2 = time.perf_counter()
    if not ratio > PIVOT_RATIO_MIN:
        return SchurParts(np.zeros((nC, nC)), None, ratio, {})
    L_CE = _coupling_transposed(U, nE)             # U_EC^T, CSR: one copy of U_EC
    del U
    _drop_extracted_factors(lu)
    Kc = _low_rank_sum(L_CE, 1.0 / d)             # its CSC conversion, copies gone
    del L_CE
    Kc *= -1.0
    K_CC = K[C][:, C].tocoo()                     # added entry by entry: no dense copy
    Kc[K_CC.row, K_CC.col] += K_CC.data           # (canonical: no repeated entries)
    t3 = time.perf_counter()
    return SchurParts(Kc, _bordered_solver(lu, p, nC), ratio,
                      {"ordering": t1 - t0, "factorization": t2 - t1, "schur": t3 - t2})


def _coupling_transposed(U, nE):
    r"""``U_EC^T`` (CSR, |C| x |E|) from the CSC ``U`` of the bordered factorisation of
    :func:`_schur_metis_superlu`, read from the arrays of U's last |C| columns.

    Those columns hold ``U_EC`` and the unit diagonal of ``U_CC = I`` (nothing updates
    the trailing identity block): one entry of row ``>= nE`` per column, in its own
    column, which is dropped; the CSC arrays of ``U_EC`` that remain are the CSR arrays
    of its transpose. One copy of ``U_EC`` (data and row indices) is made, where
    slicing ``U[:nE, nE:]`` and converting it made three while scipy's copies of both
    triangles were held (the peak of the condensation). Falls back to that slicing if
    the trailing block is not the identity pattern."""
    nC = U.shape[1] - nE
    start = U.indptr[nE]
    rows = U.indices[start:]
    keep = rows < nE
    dropped = np.flatnonzero(~keep)
    colptr = U.indptr[nE:] - start
    own = np.searchsorted(colptr, dropped, side="right") - 1
    if len(dropped) != nC or not (np.array_equal(own, np.arange(nC))
                                  and np.array_equal(rows[dropped], nE + own)):
        return U[:nE, nE:].tocsr().T.tocsr()
    indptr = colptr - np.arange(nC + 1, dtype=colptr.dtype)
    return sp.csr_matrix((U.data[start:][keep], rows[keep], indptr), shape=(nC, nE))


def _low_rank_sum(L_CE, d):
    r"""``L_CE diag(d) L_CE^T`` (dense, d > 0; ``L_CE`` sparse, CSC) in blocks of columns, each block a
    symmetric rank-k update (BLAS ``dsyrk``, upper triangle) over the rows it touches
    (found by a mask, not a sort):
    the nested-dissection order keeps the early blocks (subdomains) on few rows, only
    the last (separators) touch all of C. The lower triangle is mirrored at the end."""
    L_CE = sp.csc_matrix(L_CE)
    nC, nE = L_CE.shape
    ptr, rows_of = L_CE.indptr, L_CE.indices
    root = np.sqrt(d)
    out = np.zeros((nC, nC), order="F")
    touched = np.zeros(nC, dtype=bool)
    local_of = np.zeros(nC, dtype=np.int64)
    for j in range(0, nE, SCHUR_UPDATE_COLUMNS):
        k = min(j + SCHUR_UPDATE_COLUMNS, nE)
        a, b = ptr[j], ptr[k]
        if a == b:
            continue
        touched[:] = False
        touched[rows_of[a:b]] = True
        rows = np.flatnonzero(touched)              # sorted: upper stays upper
        local_of[rows] = np.arange(len(rows))
        cols = np.repeat(np.arange(k - j), np.diff(ptr[j:k + 1]))
        D = np.zeros((len(rows), k - j), order="F")
        D[local_of[rows_of[a:b]], cols] = L_CE.data[a:b] * root[j + cols]
        if len(rows) == nC:
            sla_blas.dsyrk(1.0, D, beta=1.0, c=out, overwrite_c=True, lower=0)
        else:
            out[np.ix_(rows, rows)] += sla_blas.dsyrk(1.0, D, lower=0)
    return mirror_triangle(out.T, "lower")          # C order, no copy


def _bordered_solver(lu, p, nC):
    """``K_EE^-1 b`` from the LU of ``[[A, 0], [B, I]]``, ``A = K_EE[p][:, p]``."""
    nE = len(p)

    def whole(b):
        rhs = np.zeros((nE + nC,) + b.shape[1:], order="F")
        rhs[:nE] = b[p]
        x = np.empty_like(b)
        x[p] = lu.solve(rhs)[:nE]
        return x

    def solve(b):
        return solved_by_columns(whole, b)
    return solve
