"""The ``"pardiso"`` backend (``pypardiso``): Intel MKL PARDISO through pypardiso's
``mkl_rt``, the Schur complement computed during the factorisation (``iparm(36) =
1``), and a plain Cholesky of ``K_EE`` for the solver."""
from __future__ import annotations

import ctypes
import time
import weakref

import numpy as np
import scipy.sparse as sp

from ...errors import AnalysisError, InputError
from .registry import SchurParts, register_backend

_PARDISO_ERRORS = {-1: "input inconsistent", -2: "not enough memory",
                   -3: "reordering problem", -4: "zero pivot (matrix not positive definite)",
                   -5: "unclassified internal error", -6: "reordering failed",
                   -7: "diagonal matrix is singular", -8: "32-bit integer overflow",
                   -9: "not enough memory for out-of-core", -10: "error opening OOC files",
                   -11: "read/write error with OOC files"}


class _Pardiso:
    """One PARDISO handle for a real SPD matrix (``mtype = 2``, upper triangle, 0-based
    indices), released when the object is collected."""

    def __init__(self, A, *, schur_rows=None, keep_diagonal=False):
        self.lib = _mkl_rt()
        self.n = A.shape[0]
        U = sp.triu(A, format="csr")
        U.sort_indices()
        self.a = np.ascontiguousarray(U.data, dtype=float)
        self.ia = U.indptr.astype(np.int32)
        self.ja = U.indices.astype(np.int32)
        self.pt = np.zeros(64, dtype=np.int64)
        self.iparm = np.zeros(64, dtype=np.int32)
        self.iparm[[0, 1, 34]] = (1, 2, 1)        # own iparm, METIS ordering, 0-based
        self.perm = np.zeros(self.n, dtype=np.int32)
        if schur_rows is not None:
            self.iparm[35] = 1                    # Schur complement during factorisation
            self.perm[schur_rows] = 1
        if keep_diagonal:
            self.iparm[55] = 1                    # pivots for pardiso_getdiag
        self._finalizer = weakref.finalize(self, _pardiso_release, self.lib, self.pt,
                                           self.n, self.a, self.ia, self.ja, self.perm,
                                           self.iparm)

    def call(self, phase, b, x, nrhs=1):
        err = _pardiso_call(self.lib, self.pt, phase, self.n, self.a, self.ia, self.ja,
                            self.perm, nrhs, self.iparm, b, x)
        if err == -4 or err == -7:
            raise InputError(f"K_EE is singular or not positive definite (PARDISO error "
                             f"{err}: {_PARDISO_ERRORS[err]}); the body is not held "
                             f"against rigid-body motion apart from its interface: add "
                             f"clamps")
        if err != 0:
            raise AnalysisError(f"PARDISO phase {phase} failed with error {err}: "
                                f"{_PARDISO_ERRORS.get(err, 'unknown')}")

    def pivot_ratio(self):
        """``min_i d_i / a_ii`` from ``pardiso_getdiag`` (``d_i = l_ii^2`` for LL^T)."""
        df, da = np.zeros(self.n), np.zeros(self.n)
        err = ctypes.c_int32(0)
        getdiag = self.lib["pardiso_getdiag"]
        getdiag.restype = None
        getdiag(self.pt.ctypes.data_as(ctypes.c_void_p), df.ctypes.data_as(ctypes.c_void_p),
                da.ctypes.data_as(ctypes.c_void_p), ctypes.byref(ctypes.c_int32(1)),
                ctypes.byref(err))
        if err.value != 0:
            raise AnalysisError(f"pardiso_getdiag failed with error {err.value}")
        return float(np.min(df / da))


def _pardiso_call(lib, pt, phase, n, a, ia, ja, perm, nrhs, iparm, b, x):
    fn = lib["pardiso"]
    fn.restype = None
    i32, ptr = ctypes.c_int32, (lambda arr: arr.ctypes.data_as(ctypes.c_void_p))
    err = i32(0)
    fn(ptr(pt), ctypes.byref(i32(1)), ctypes.byref(i32(1)), ctypes.byref(i32(2)),
       ctypes.byref(i32(phase)), ctypes.byref(i32(n)), ptr(a), ptr(ia), ptr(ja), ptr(perm),
       ctypes.byref(i32(nrhs)), ptr(iparm), ctypes.byref(i32(0)), ptr(b), ptr(x),
       ctypes.byref(err))
    return err.value


def _pardiso_release(lib, pt, n, a, ia, ja, perm, iparm):
    dummy = np.zeros(1)
    _pardiso_call(lib, pt, -1, n, a, ia, ja, perm, 1, iparm, dummy, dummy)


_MKL_RT = []


def _mkl_rt():
    """``mkl_rt`` as found by pypardiso (its env variable, library path or wheel)."""
    if not _MKL_RT:
        import pypardiso
        _MKL_RT.append(pypardiso.PyPardisoSolver().libmkl)
    return _MKL_RT[0]


@register_backend("pardiso", requires="pypardiso")
def _schur_pardiso(K, C, E) -> SchurParts:
    r"""PARDISO (MKL) factorises ``K`` with the C rows marked as Schur rows
    (``iparm(36) = 1``): it orders E by nested dissection, eliminates it and returns
    the dense ``Kc`` (rows in increasing DOF number). A second PARDISO Cholesky, of
    ``K_EE`` alone, is the solver (its partial solves in Schur mode are less accurate)
    and gives the pivots."""
    t0 = time.perf_counter()
    nC = len(C)
    full = _Pardiso(K, schur_rows=C)
    out = np.zeros(max(nC * nC, K.shape[0]))
    full.call(12, np.zeros_like(out), out)
    del full                                      # release its factor now
    rank = np.argsort(np.argsort(C))              # C[i] is the rank[i]-th Schur row
    Kc = out[:nC * nC].reshape(nC, nC)[np.ix_(rank, rank)]
    t1 = time.perf_counter()
    ee = _Pardiso(K[E][:, E], keep_diagonal=True)
    ee.call(12, np.zeros(len(E)), np.zeros(len(E)))
    ratio = ee.pivot_ratio()
    t2 = time.perf_counter()
    return SchurParts(Kc, _pardiso_solver(ee), ratio,
                      {"schur": t1 - t0, "factorization": t2 - t1})


def _pardiso_solver(ee):
    def solve(b):
        B = np.asfortranarray(b.reshape(ee.n, -1))
        X = np.zeros_like(B)
        ee.call(33, B, X, nrhs=B.shape[1])
        return X.reshape(b.shape)
    return solve
