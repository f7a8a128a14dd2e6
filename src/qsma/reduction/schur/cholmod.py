"""The ``"cholmod"`` backend (``cvxopt``): CHOLMOD's supernodal Cholesky of ``K``
ordered ``[E by AMD, C last]``, ``K = L L^T`` with ``Kc = L_CC L_CC^T``."""
from __future__ import annotations

import time

import numpy as np
import scipy.sparse as sp

from .registry import SchurParts, register_backend

@register_backend("cholmod", requires="cvxopt")
def _schur_cholmod(K, C, E) -> SchurParts:
    r"""Supernodal Cholesky ``P K P^T = L L^T`` (CHOLMOD, cvxopt's wheel) with
    ``P = [E (AMD of K_EE), C]`` and no postorder, so that ``Kc = L_CC L_CC^T``.
    Reading ``L`` turns cvxopt's factor into a symbolic one, so the solver is a second
    CHOLMOD factor, of ``K_EE`` with CHOLMOD's own ordering (cheap: no dense C block)."""
    import cvxopt
    from cvxopt import amd, cholmod

    t0 = time.perf_counter()
    nE, n = len(E), K.shape[0]
    K_EE = K[E][:, E]
    A_EE = _cvx_lower(K_EE, cvxopt)
    pE = np.asarray(amd.order(A_EE), dtype=np.int64).ravel()
    order = np.concatenate([E[pE], C])
    A = _cvx_lower(K[order][:, order], cvxopt)
    L = _cholmod_factor(A, cvxopt, cholmod, p=cvxopt.matrix(np.arange(n).tolist()),
                        supernodal=2, postorder=False, nmethods=1)
    if L is None:
        return SchurParts(np.zeros((len(C), len(C))), None, -np.inf, {})
    colptr, rows, vals = (np.asarray(a).ravel() for a in cholmod.getfactor(L).CCS)
    diag = vals[colptr[:-1]]                      # sorted columns: diagonal first
    ratio = float(np.min(diag[:nE] ** 2 / K_EE.diagonal()[pE]))
    s = colptr[nE]
    L_CC = sp.csc_matrix((vals[s:], rows[s:] - nE, colptr[nE:] - s),
                         shape=(len(C), len(C))).toarray()
    Kc = L_CC @ L_CC.T
    t1 = time.perf_counter()
    F = _cholmod_factor(A_EE, cvxopt, cholmod)
    t2 = time.perf_counter()
    return SchurParts(Kc, _cholmod_solver(F, cvxopt, cholmod), ratio if F else -np.inf,
                      {"schur": t1 - t0, "factorization": t2 - t1})


def _cvx_lower(A, cvxopt):
    A = sp.tril(A, format="coo")
    return cvxopt.spmatrix(A.data, A.row.astype(np.int64), A.col.astype(np.int64), A.shape)


def _cholmod_factor(A, cvxopt, cholmod, p=None, **options):
    """Numeric CHOLMOD factor of ``A`` (None if not positive definite); ``options``
    temporarily override ``cvxopt.cholmod.options``."""
    saved = dict(cholmod.options)
    cholmod.options.update(options)
    try:
        F = cholmod.symbolic(A) if p is None else cholmod.symbolic(A, p=p)
        cholmod.numeric(A, F)
        return F
    except ArithmeticError:
        return None
    finally:
        cholmod.options.clear()
        cholmod.options.update(saved)


def _cholmod_solver(F, cvxopt, cholmod):
    def solve(b):
        X = cvxopt.matrix(np.asfortranarray(b.reshape(b.shape[0], -1)))
        cholmod.solve(F, X)
        return np.array(X).reshape(b.shape)
    return solve
