"""Linear algebra of a fixed set of pair states: the block step of the solvers.

With every pair's state fixed, ``lam = K d + lam_w`` plus the equality of
each state is a linear system (method.md sections 3-4):

* stuck: ``d_t = d_t_prev``, ``d_n = -g0`` (``d`` known, ``lam`` follows);
* open: ``lam = 0`` (``d`` unknown);
* slipping: ``d_n = -g0`` and ``Q + mu P s = 0`` with ``s`` the slip
  direction; in 3D linearised in the direction (:func:`slip_rows`), exact
  in 2D.

The unknowns are the displacement components ``U`` that the states leave
free (all of an open pair, the tangential ones of a slipping pair); the
components ``D`` are known. Writing the ``U`` equations as rows of ``d``,
``R d = b``, the block step is the small dense solve
``R[:, U] d_U = b - R[:, D] d_D``; with every pair stuck it is empty and
``lam = K d + lam_w`` is immediate.

Of that system only the slip-law rows depend on the slip directions, so the 3D
Newton steps on the directions of one set of states (:class:`BlockSystem`) reuse the
LU factors of an earlier step: iterative refinement with them, accepted only when the
step's own residual is at round-off, else a new factorisation.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.linalg as sla

from .state import OPEN_CODE as OPEN, SLIPPING_CODE as SLIPPING, STUCK_CODE as STUCK

#: Iterative refinement of a block step with an earlier step's LU factors
#: (:meth:`BlockSystem.solve`): the answer is accepted when every row's residual is at
#: most REFINE_ETA times the size of its terms, ``|b - A x| <= REFINE_ETA (|A||x| + |b|)``;
#: the factors are replaced after REFINE_STEPS corrections without that, or as soon as
#: a correction shrinks the residual by less than REFINE_RATE. REFINE_ETA is 16 eps:
#: a direct LU solve of the same steps meets 1-4 eps on this measure and converged
#: refinement 0.3-0.7 eps (every block step of two lap-3d refine-1 loops, docs/contact.md).
REFINE_ETA, REFINE_STEPS, REFINE_RATE = 2.0 ** -48, 6, 0.25
#: Fewest unknowns of a block step solved by refinement (below, a factorisation is
#: cheaper than the corrections; measured in benchmarks/bench_contact_overhead.py).
REFINE_MIN = 200
#: Margin on the size of the rows (of the first iterate) below which the componentwise
#: test is evaluated.
REFINE_SLACK = 2.0


def known_displacement(problem, status, d_prev):
    """Displacement fixed by the states: ``(d_t_prev, -g0)`` stuck, ``d_n = -g0`` slipping.

    Components left free by the state are zero. Returns ``(N,)``.
    """
    d = np.zeros((problem.n_pairs, problem.dim))
    stuck, closed = status == STUCK, status != OPEN
    d[stuck, :-1] = d_prev[stuck, :-1]
    d[closed, -1] = -problem.gap0[closed]
    return d.ravel()


def free_components(problem, pairs_open, pairs_slipping):
    """Flat indices left free: all components of open pairs, tangential of slipping."""
    return np.concatenate([(pairs_open[:, None] * problem.dim + np.arange(problem.dim)).ravel(),
                           problem.tangent_index[pairs_slipping].ravel()])


def open_rows(problem, lam_w, pairs):
    """Rows ``lam_i = K_i d + lam_w,i = 0`` of open pairs: ``(R, b)``."""
    index = (pairs[:, None] * problem.dim + np.arange(problem.dim)).ravel()
    return problem.K[index], -lam_w[index]


def slip_rows(problem, lam_w, pairs, direction, alpha, t_prev, c):
    r"""Rows of the slip law of slipping pairs: ``(R, b)`` with ``R d = b``.

    The slip law ``Q = -mu P s`` with the slip direction ``s`` taken from the
    augmented shear, ``s = -sigma_t/|sigma_t|``, ``sigma_t = Q - c dv``,
    linearised at the current iterate (a Newton step on the direction):

    .. math:: (I - \alpha \Pi) (Q - c\,dv) + c\,dv + \mu P s = 0 ,
              \qquad \Pi = I - s s^T, \quad
              \alpha = \mu \sigma_n / |\sigma_t| ,

    i.e. ``(I - alpha Pi) K_t d + mu s K_n d + alpha c Pi d_t =
    -(I - alpha Pi) lam_w,t - mu s lam_w,n + alpha c Pi d_t,prev``. With
    ``alpha = 0`` (always in 2D, where ``Pi = 0``, and for a direction held
    fixed) it is ``Q + mu P s = 0``.

    Parameters
    ----------
    pairs : (k,) int
    direction : (k, m)
        Slip direction ``s`` (unit vector of the expected slip increment).
    alpha : (k,)
        ``mu sigma_n / |sigma_t|`` in ``[0, 1]`` at the current iterate.
    t_prev : (k, m)
        Previous converged tangential displacement.
    c : float
        Augmentation of ``sigma_t``.
    """
    K, m = problem.K, problem.dim - 1
    T, N = problem.tangent_index[pairs], problem.normal_index[pairs]
    rows, rhs = _slip_law_rows(K[T], K[N], lam_w[T], lam_w[N], problem.mu[pairs], direction,
                               alpha, t_prev, c, T)
    return rows.reshape(-1, K.shape[1]), rhs.ravel()


def _slip_law_rows(K_t, K_n, f_t, f_n, mu, direction, alpha, t_prev, c, at):
    r"""The rows of :func:`slip_rows` on any set of columns.

    ``K_t`` (k, m, n) and ``K_n`` (k, n) are the tangential and normal rows of the
    slipping pairs on those columns, ``f_t`` (k, m) and ``f_n`` (k,) the force at zero
    displacement of those columns (``lam_w``, plus ``K d`` of the components held
    elsewhere), ``at`` (k, m) the columns of the pairs' own tangential components.
    Returns ``(rows (k, m, n), rhs (k, m))`` of
    ``(I - alpha Pi)(K_t x + f_t) + mu s (K_n x + f_n) + alpha c Pi (x_t - t_prev) = 0``.
    """
    m = K_t.shape[1]
    ms = mu[:, None] * direction
    rows = ms[:, :, None] * K_n[:, None, :]
    rows += K_t                                  # = K_t + ms K_n, one array fewer
    rhs = -(f_t + ms * f_n[:, None])
    if m > 1 and np.any(alpha):
        Pi = alpha[:, None, None] * (np.eye(m) - direction[:, :, None] * direction[:, None, :])
        rows -= np.einsum("kij,kjc->kic", Pi, K_t)
        rhs += np.einsum("kij,kj->ki", Pi, f_t + c * t_prev)
        k = np.arange(len(mu))[:, None, None]
        rows[k, np.arange(m)[None, :, None], at[:, None, :]] += c * Pi
    return rows, rhs


class BlockSystem:
    r"""The block step of one set of pair states, reduced to its unknowns.

    With the states fixed, the known components ``D`` (:func:`known_displacement`)
    enter as a force: ``f = lam_w + K d_known`` on the rows of the open and the
    slipping pairs. Built once per set of states (the rows ``K[R, U]`` and ``f``), it
    then gives the step of any slip directions with products of the size of the
    unknowns only, the system of :func:`basket_system` restricted to its columns ``U``:

    .. math:: K_{OU} x = -f_O, \qquad
              (I - \alpha \Pi)(K_{TU} x + f_T) + \mu s (K_{NU} x + f_N)
              + \alpha c \Pi (x_T - t_{prev}) = 0 .

    Only the slip-law rows depend on the directions ``s`` and ``alpha``. The LU
    factors of the last matrix factorised are kept, and a later step is solved by
    iterative refinement preconditioned with them (:meth:`solve`): the residual of
    the step's own system is evaluated exactly (in double, from ``K_RU x``) and the
    answer is accepted only when it meets :data:`REFINE_ETA` componentwise; else the
    step's matrix is formed and factorised (and kept for the next steps).

    Parameters
    ----------
    problem : ContactProblem
    lam_w : (N,)
    status : (n_pairs,) int
    d_prev : (n_pairs, dim)
    """

    def __init__(self, problem, lam_w, status, d_prev):
        dim, m = problem.dim, problem.dim - 1
        self.status = np.array(status)
        self.open = np.flatnonzero(self.status == OPEN)
        self.slip = np.flatnonzero(self.status == SLIPPING)
        self.unknown = free_components(problem, self.open, self.slip)
        self.d_known = known_displacement(problem, self.status, d_prev)
        n_o, k = len(self.open) * dim, len(self.slip)
        rows = np.concatenate([self.unknown[:n_o], problem.tangent_index[self.slip].ravel(),
                               problem.normal_index[self.slip]])
        K_R = problem.K[rows]          # whole rows once: K_RU from them (no second
        self.K_RU = K_R.take(self.unknown, axis=1)   # gather from K; C order), and f
        f = (K_R @ self.d_known if self.d_known.any() else 0.0) + lam_w[rows]
        K_RU = self.K_RU
        self.K_open, self.f_open = K_RU[:n_o], f[:n_o]
        self.K_t = K_RU[n_o:n_o + k * m].reshape(k, m, len(self.unknown))
        self.K_n = K_RU[n_o + k * m:]
        self.f_t, self.f_n = f[n_o:n_o + k * m].reshape(k, m), f[n_o + k * m:]
        self.at = (n_o + np.arange(k * m)).reshape(k, m)   # own tangential columns in U
        self.mu, self.t_prev = problem.mu[self.slip], d_prev[self.slip, :-1]
        self.factors = None          # (lu, piv) of the last matrix factorised
        self._abs_K_RU = None
        self.n_factorised = self.n_refined = self.n_corrections = 0

    def solve(self, direction, alpha, c):
        """The displacement ``(N,)`` of the step with slip directions ``direction`` and
        ``alpha`` (both over all pairs, read at the slipping ones; see :func:`slip_rows`).

        Solved with the kept LU factors if iterative refinement meets
        :data:`REFINE_ETA` within :data:`REFINE_STEPS` corrections, else by a new
        factorisation of the step's matrix. Raises ``numpy.linalg.LinAlgError`` if
        the block is singular."""
        d = self.d_known.copy()
        if self.unknown.size == 0:
            return d
        law = _SlipLaw.of(self.mu, direction[self.slip], alpha[self.slip], c)
        x = None if self.factors is None or self.unknown.size < REFINE_MIN else \
            self._refined(law)
        if x is None:
            x = self._factorised(law)
        d[self.unknown] = x
        return d

    def _factorised(self, law):
        """Form the step's matrix, factorise it (kept in :attr:`factors`), solve."""
        rows, rhs = _slip_law_rows(self.K_t, self.K_n, self.f_t, self.f_n, self.mu,
                                   law.s, law.alpha, self.t_prev, law.c, self.at)
        A = rows.reshape(-1, self.unknown.size)
        if len(self.K_open):
            A = np.concatenate([self.K_open, A])
        self.factors = _lu_factor(A)
        self.n_factorised += 1
        return _lu_solve(self.factors, np.concatenate([-self.f_open, rhs.ravel()]))

    def _refined(self, law):
        r"""Iterative refinement of the step with the kept factors ``L U = A_0``:
        ``x_{j+1} = x_j + A_0^{-1} (b - A x_j)``, ``x_0 = A_0^{-1} b``, the residual of
        the step's own matrix ``A`` applied without forming it (:meth:`_product`).

        Returns ``x`` once ``|b - A x| <= REFINE_ETA (|A| |x| + |b|)`` holds on every
        row (:meth:`_scale`), or None if the largest residual does not shrink by
        :data:`REFINE_RATE` per correction or, at the rate of the last correction,
        could not reach that test within :data:`REFINE_STEPS` corrections. The test is
        evaluated where it can pass: the largest residual at most ``REFINE_ETA`` times
        the largest row size (of the first iterate, times :data:`REFINE_SLACK`)."""
        b = self._rhs(law)
        x = _lu_solve(self.factors, b)
        goal = REFINE_SLACK * REFINE_ETA * float(np.max(self._scale(law, b, x)))
        sizes = [goal]
        for _ in range(REFINE_STEPS + 1):
            r = b - self._product(law, x)
            size = float(np.max(np.abs(r)))
            if size <= goal and np.all(np.abs(r) <= REFINE_ETA * self._scale(law, b, x)):
                self.n_refined += 1
                return x
            sizes.append(size)
            if not np.isfinite(size) or not _may_converge(sizes):
                return None
            x = x + _lu_solve(self.factors, r)
            self.n_corrections += 1
        return None

    def _rhs(self, law):
        """``b`` of the step: ``-f_O`` and the slip rows' constant terms."""
        rhs = -(self.f_t + law.ms * self.f_n[:, None])
        if law.Pi is not None:
            rhs += np.einsum("kij,kj->ki", law.Pi, self.f_t + law.c * self.t_prev)
        return np.concatenate([-self.f_open, rhs.ravel()])

    def _split(self, y):
        """The open, tangential ``(k, m)`` and normal ``(k,)`` parts of a vector over
        the rows of ``K_RU``."""
        n_o, (k, m) = len(self.K_open), self.f_t.shape
        return y[:n_o], y[n_o:n_o + k * m].reshape(k, m), y[n_o + k * m:]

    def _product(self, law, x):
        """``A x`` of the step's matrix ``A`` (the rows of :func:`_slip_law_rows`)
        without forming ``A``: one product with ``K_RU``, then the 2x3 slip law of
        each slipping pair."""
        y_o, y_t, y_n = self._split(self.K_RU @ x)
        Ax = law.ms * y_n[:, None] + y_t
        if law.Pi is not None:
            Ax += np.einsum("kij,kj->ki", law.Pi, law.c * x[self.at] - y_t)
        return np.concatenate([y_o, Ax.ravel()])

    def _scale(self, law, b, x):
        """``|A| |x| + |b|`` with ``|A|`` bounded by the absolute values of the terms
        of each row (``|K_t| + |mu s| |K_n| + |Pi| (|K_t| + c)``): the size of what a
        row sums, the round-off scale of its residual."""
        if self._abs_K_RU is None:
            self._abs_K_RU = np.abs(self.K_RU)
        e_o, e_t, e_n = self._split(self._abs_K_RU @ np.abs(x))
        bound = np.abs(law.ms) * e_n[:, None] + e_t
        if law.Pi is not None:
            bound += np.einsum("kij,kj->ki", np.abs(law.Pi), e_t + law.c * np.abs(x[self.at]))
        scale = np.concatenate([e_o, bound.ravel()]) + np.abs(b)
        return np.maximum(scale, np.finfo(float).tiny)


def _may_converge(sizes):
    """Whether refinement can still succeed: ``sizes[0]`` is the largest residual at
    which the acceptance test can pass, the rest the largest residuals so far (the
    last one not yet corrected). Each correction must shrink it by
    :data:`REFINE_RATE`, and at the rate of the last one the corrections left of
    :data:`REFINE_STEPS` must suffice."""
    goal, done = sizes[0], len(sizes) - 2
    if done >= REFINE_STEPS:
        return False
    if done == 0:
        return True
    rate = sizes[-1] / sizes[-2]
    if rate > REFINE_RATE:
        return False
    needed = np.log(goal / sizes[-1]) / np.log(max(rate, np.finfo(float).tiny))
    return needed <= REFINE_STEPS - done


class _SlipLaw(NamedTuple):
    """The slip-law coefficients of the slipping pairs of one step: ``mu s`` (k, m),
    the directions ``s``, ``alpha``, ``c`` and ``Pi = alpha (I - s s^T)`` (k, m, m),
    or None where it vanishes (2D, or ``alpha = 0`` everywhere)."""

    ms: np.ndarray
    s: np.ndarray
    alpha: np.ndarray
    c: float
    Pi: np.ndarray | None

    @classmethod
    def of(cls, mu, s, alpha, c):
        m = s.shape[1]
        Pi = None
        if m > 1 and np.any(alpha):
            Pi = alpha[:, None, None] * (np.eye(m) - s[:, :, None] * s[:, None, :])
        return cls(mu[:, None] * s, s, alpha, c, Pi)


def _lu_solve(factors, b):
    """``A^{-1} b`` from the LU factors of :func:`_lu_factor` (LAPACK ``getrs``)."""
    x, info = sla.lapack.dgetrs(factors[0], factors[1], b)
    return x


def _lu_factor(A):
    """LU factors of ``A`` (partial pivoting); ``numpy.linalg.LinAlgError`` if a pivot
    is exactly zero (as ``numpy.linalg.solve`` raises)."""
    lu, piv, info = sla.lapack.dgetrf(A)
    if info > 0:
        raise np.linalg.LinAlgError("Singular matrix")
    return lu, piv


def basket_system(problem, lam_w, status, direction, alpha, d_prev, c):
    """The linear system of fixed pair states: ``(R, b, U, d_known)``.

    ``lam_w`` is flat ``(N,)``; ``direction`` ``(n_pairs, m)`` and ``alpha``
    ``(n_pairs,)`` are read at the slipping pairs (see :func:`slip_rows`).
    """
    pairs_open = np.flatnonzero(status == OPEN)
    pairs_slip = np.flatnonzero(status == SLIPPING)
    Ro, bo = open_rows(problem, lam_w, pairs_open)
    Rs, bs = slip_rows(problem, lam_w, pairs_slip, direction[pairs_slip], alpha[pairs_slip],
                       d_prev[pairs_slip, :-1], c)
    unknown = free_components(problem, pairs_open, pairs_slip)
    return (np.vstack([Ro, Rs]), np.concatenate([bo, bs]), unknown,
            known_displacement(problem, status, d_prev))


def solve_partitioned(rows, rhs, unknown, d_fixed):
    """Solve ``rows @ d = rhs`` for ``d[unknown]``, the other components at ``d_fixed``.

    Returns a new ``(N,)`` vector. Raises ``numpy.linalg.LinAlgError`` if the
    block is singular.
    """
    d = np.array(d_fixed, dtype=float)
    if unknown.size == 0:
        return d
    d[unknown] = 0.0
    d[unknown] = np.linalg.solve(rows[:, unknown], rhs - rows @ d)
    return d
