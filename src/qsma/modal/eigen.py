"""Block Krylov shift-invert: the eigenpairs of ``K^-1 M`` with the inverse applied to
blocks of vectors (one multi-RHS solve per block)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import AnalysisError

#: Converged when every wanted Ritz pair ``(mu, x)`` of ``S = K^-1 M`` (``x^T M x = 1``)
#: has ``||S x - mu x||_M <= EIG_RESIDUAL_RTOL * mu``. The eigenvalue error is then
#: below ``EIG_RESIDUAL_RTOL^2 / gap`` and the angle of the shape below
#: ``EIG_RESIDUAL_RTOL / gap`` (relative gap to the other eigenvalues of ``S``).
EIG_RESIDUAL_RTOL = 1e-11
#: Also converged when every relative residual is below this and the worst one fell by
#: less than half over the last block: the round-off floor of the solves (``eps``
#: times the condition number of ``K``) is reached. lap-2d with a bolt and the top
#: plate free stops at 1.7e-11.
EIG_RESIDUAL_FLOOR = 1e-8
#: Extra columns of the block beyond the wanted modes (they speed up the convergence
#: of the last wanted ones); blocks of 4-16 columns cost 1.6-5 single solves of a
#: SuperLU factor (CHANGELOG.md, "Tied modes").
EIG_GUARD = 2
#: Most columns of a block (the inverse applied to that many vectors at once).
EIG_BLOCK = 6
#: Largest basis, in blocks, before a thick restart keeps the best Ritz vectors.
EIG_MAX_BLOCKS = 8
#: Restarts before the iteration gives up (AnalysisError).
EIG_MAX_RESTARTS = 30
#: Seed of the random start block (reproducible runs).
EIG_SEED = 20240611


def block_shift_invert(solve, M, k, Z=None, gram=None, start=None):
    r"""The ``k`` smallest eigenpairs of ``K x = lambda M x`` from ``solve(B) = K^{-1} B``
    applied to blocks of columns (block Lanczos with full reorthogonalisation and thick
    restarts).

    ``S = K^{-1} M`` is self-adjoint in the ``M`` inner product; its largest eigenvalues
    ``mu = 1 / lambda`` are wanted. The basis ``Q`` (``Q^T M Q = I``) grows by blocks
    of at most :data:`EIG_BLOCK` columns, ``S Q_j`` orthogonalised against ``Q``; the
    Rayleigh-Ritz step solves the small symmetric eigenproblem of
    ``H = Q^T M S Q = (M Q)^T W`` (``W = S Q`` kept: no further solve) and the residual
    of a Ritz pair ``(mu, x = Q y)`` is ``r = W y - mu x``. Converged when
    ``||r||_M <= EIG_RESIDUAL_RTOL mu`` for the ``k`` wanted pairs (the criterion of
    ARPACK with a tolerance instead of machine epsilon), or when they stagnate below
    :data:`EIG_RESIDUAL_FLOOR` (round-off of the solves). A basis of
    :data:`EIG_MAX_BLOCKS` blocks is restarted from the best ``k +`` :data:`EIG_GUARD`
    Ritz vectors, the next block being the Krylov continuation (:meth:`_Basis.restarted`).

    ``Z``, ``gram``: rigid motions of a free-free assembly (``solve`` already returns the
    part M-orthogonal to them) and ``Z^T M Z``; the start block is made M-orthogonal to
    them as well. ``start``: smooth columns for the first block (at most ``b``); each
    gets a seeded random part of its own norm (:data:`EIG_SEED`) and the block is
    completed by random columns. Rigid-body fields as start make the first block
    close to the static deflections under uniform accelerations, close to the low
    modes (load-dependent Ritz vectors). The random part is not optional: a start
    made of the rigid fields alone has no component in the modes of some symmetry
    classes of a symmetric structure, which a Krylov space built from it never
    reaches, and the iteration would converge to the wrong "lowest" modes
    (tests/test_modal.py, the symmetric clamped box).

    Returns ``(lam, vec)``, ``lam`` increasing, ``vec`` M-orthonormal. Raises
    :class:`AnalysisError` if the iteration does not converge.
    """
    return ShiftInvert(solve, M, k, Z, gram, start).finish()


def _converged(worst, previous):
    """The convergence test of :func:`block_shift_invert` on the worst relative residual
    of the pairs judged, ``previous`` that of the step before."""
    return worst <= EIG_RESIDUAL_RTOL or EIG_RESIDUAL_FLOOR >= worst > 0.5 * previous


def same_eigenvalues(lam_a, lam_b):
    """Whether two sets of eigenvalues that each passed the convergence test of
    :func:`block_shift_invert` are the same eigenvalues: a Ritz value whose relative
    residual is at most ``EIG_RESIDUAL_FLOOR`` lies within that fraction of an
    eigenvalue of ``K^-1 M`` (a residual bound of a self-adjoint operator), so two of
    the same eigenvalue differ by at most twice that; a different eigenvalue (a mode
    that one set missed) is farther off by the gap between them."""
    lam_a, lam_b = np.asarray(lam_a, dtype=float), np.asarray(lam_b, dtype=float)
    bound = 2 * EIG_RESIDUAL_FLOOR * np.maximum(np.abs(lam_a), np.abs(lam_b))
    return lam_a.shape == lam_b.shape and bool(np.all(np.abs(lam_a - lam_b) <= bound))


class ShiftInvert:
    """The iteration of :func:`block_shift_invert`, advanced on demand.

    :meth:`leading` advances it until its first ``m`` wanted pairs pass the convergence
    test (the test of the whole set applied to those pairs) and returns them;
    :meth:`finish` goes on from there until all ``k`` pass and returns them, the same
    numbers as :func:`block_shift_invert`. The leading pairs are eigenpairs to the same
    tolerance as the finished ones, not the same bits (they come from a smaller
    basis). The state lives in this object, so a forked process can finish the
    iteration while its parent goes on with the leading pairs.
    """

    def __init__(self, solve, M, k, Z=None, gram=None, start=None):
        self.k = k
        self._steps = _ritz_steps(solve, M, k, Z, gram, start)
        self._done = None

    def leading(self, m):
        """``(lam, vec)`` of the first ``m <= k`` pairs once they have converged."""
        previous = np.inf
        while self._done is None:
            try:
                mu, Y, res, Q = next(self._steps)
            except StopIteration as stop:
                self._done = stop.value
                break
            worst = float(np.max(res[:m] / mu[:m]))
            if _converged(worst, previous):
                return 1.0 / mu[:m], Q @ Y[:, :m]
            previous = worst
        lam, vec = self._done
        return lam[:m], vec[:, :m]

    def finish(self):
        """``(lam, vec)`` of all ``k`` pairs (:func:`block_shift_invert`)."""
        while self._done is None:
            try:
                next(self._steps)
            except StopIteration as stop:
                self._done = stop.value
        return self._done


def _ritz_steps(solve, M, k, Z, gram, start):
    """The iteration of :func:`block_shift_invert` as a generator: yields ``(mu, Y, res,
    Q)`` after each Rayleigh-Ritz step (``Q`` a view of the basis, valid until the next
    step) and returns ``(lam, vec)`` of the ``k`` pairs once they all converged."""
    n = M.shape[0]
    b = min(EIG_BLOCK, k + EIG_GUARD, n - k)
    want = min(k + EIG_GUARD, n - 1)           # basis size before convergence is judged
    rng = np.random.default_rng(EIG_SEED)
    V = rng.standard_normal((n, b))
    if start is not None:                   # smooth start plus an equal random part:
        S = np.asarray(start, dtype=float)[:, :b]   # every column reaches every mode
        scale = np.linalg.norm(V[:, :S.shape[1]], axis=0) / np.maximum(
            np.linalg.norm(S, axis=0), np.finfo(float).tiny)
        V[:, :S.shape[1]] += S * scale
    MZ = None if Z is None else M @ Z

    def off_motions(V):                       # the part of V M-orthogonal to Z
        return V if Z is None else V - Z @ np.linalg.solve(gram, MZ.T @ V)

    V = off_motions(V)
    basis, worst = _Basis.empty(n, want + EIG_MAX_BLOCKS * b), np.inf
    for _ in range(EIG_MAX_RESTARTS):
        for _ in range(EIG_MAX_BLOCKS):
            V, MV = _m_orthonormal(V, basis, M)
            if V.shape[1] == 0 and basis.size >= want:    # invariant subspace (the
                mu, Y, _ = basis.ritz(want)               # whole space when n is small):
                return 1.0 / mu[:k], basis.Q @ Y[:, :k]   # the Ritz pairs are exact
            if V.shape[1] == 0:              # start in the span of Z: random directions
                V = off_motions(rng.standard_normal((n, b)))
                continue
            W = solve(MV)
            basis = basis.extended(V, MV, W, M @ W)
            if basis.size < want:
                V = W
                continue
            mu, Y, res = basis.ritz(want)
            yield mu, Y, res, basis.Q
            worst, previous = float(np.max(res[:k] / mu[:k])), worst
            if _converged(worst, previous):
                return 1.0 / mu[:k], basis.Q @ Y[:, :k]
            V = W
        mu, Y, res = basis.ritz(want)
        basis, V = basis.restarted(Y[:, :min(want, basis.size)], V)
    raise AnalysisError(f"tied modes: the block shift-invert iteration did not converge "
                        f"in {EIG_MAX_RESTARTS} restarts (relative residuals up to "
                        f"{worst:.2e} > {EIG_RESIDUAL_RTOL})")


@dataclass(frozen=True)
class _Basis:
    """M-orthonormal basis ``Q`` of :func:`block_shift_invert` with ``M Q``, ``W = S Q``
    and ``M W`` (each sparse product done once per column).

    The four are the first ``size`` columns of preallocated column-major arrays
    (``arrays``, shared by the bases that :meth:`extended` and :meth:`restarted`
    return: the previous basis is not used again). A new block is written in place
    instead of copying the whole basis (``np.hstack`` held the old and the new basis
    at once: ~0.5 GB more at 222k unknowns)."""

    arrays: tuple
    size: int

    @classmethod
    def empty(cls, n, capacity):
        return cls(tuple(np.zeros((n, capacity), order="F") for _ in range(4)), 0)

    @property
    def Q(self):
        return self.arrays[0][:, :self.size]

    @property
    def MQ(self):
        return self.arrays[1][:, :self.size]

    @property
    def W(self):
        return self.arrays[2][:, :self.size]

    @property
    def MW(self):
        return self.arrays[3][:, :self.size]

    def extended(self, V, MV, W, MW):
        k, m = self.size, V.shape[1]
        arrays = self.arrays
        if k + m > arrays[0].shape[1]:             # not expected: grow
            grown = tuple(np.zeros((a.shape[0], k + m), order="F") for a in arrays)
            for g, a in zip(grown, arrays):
                g[:, :k] = a[:, :k]
            arrays = grown
        for a, new in zip(arrays, (V, MV, W, MW)):
            a[:, k:k + m] = new
        return _Basis(arrays, k + m)

    def ritz(self, wanted):
        """Ritz values ``mu`` (decreasing), coefficients ``Y`` and the residual norms
        ``||W y - mu Q y||_M`` of the first ``wanted`` pairs."""
        H = self.MQ.T @ self.W
        mu, Y = np.linalg.eigh(0.5 * (H + H.T))
        mu, Y = mu[::-1], Y[:, ::-1]
        return mu, Y, self.residuals(Y[:, :wanted], mu[:wanted])

    def residuals(self, Y, mu):
        """``||W y - mu Q y||_M`` per column of ``Y``."""
        R, MR = self.W @ Y - (self.Q @ Y) * mu, self.MW @ Y - (self.MQ @ Y) * mu
        return np.sqrt(np.abs(np.einsum("ik,ik->k", R, MR)))

    def restarted(self, Y, W_last):
        """The basis of the Ritz vectors ``Q Y`` and the next block: the last block's
        ``S Q_j`` without its part in ``Q``, which spans the residuals of all the Ritz
        pairs (thick restart: the Krylov recurrence goes on from there)."""
        nxt = W_last - self.Q @ (self.MQ.T @ W_last)
        j = Y.shape[1]
        for a in self.arrays:                      # a[:, :j] = a[:, :size] Y, one at
            a[:, :j] = a[:, :self.size] @ Y        # a time (one n x j temporary)
        return _Basis(self.arrays, j), nxt


def _m_orthonormal(V, basis, M):
    """``(V', M V')``: the columns of ``V`` minus their M-projection on the basis,
    M-orthonormalised by the eigenvectors of their Gram matrix; two passes (round-off).
    Directions whose norm fell below ``1e-12`` of the largest column of ``V``
    (numerically in the span of the basis or of the other columns) are dropped."""
    MV = M @ V
    scale = float(np.max(np.einsum("ik,ik->k", V, MV), initial=0.0))
    for _ in range(2):
        V = V - basis.Q @ (basis.MQ.T @ V)
        MV = M @ V
        G = V.T @ MV
        w, U = np.linalg.eigh(0.5 * (G + G.T))
        keep = w > 1e-24 * scale
        U = U[:, keep] / np.sqrt(w[keep])
        V, MV = V @ U, MV @ U
        scale = 1.0
    return V, MV
