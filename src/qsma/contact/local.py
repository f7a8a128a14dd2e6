r"""Exact solutions of the one-pair problem (2D and 3D, with normal-tangential coupling).

One pair alone (the others held) sees ``lam = A d + r`` with ``A = K_ii``
(SPD, ``dim x dim``, components ``(t..., n)``). With ``t_prev`` its previous
tangential displacement, ``g0`` its gap and ``mu`` its friction coefficient,
every solution is one of:

* **stuck**: ``d = (t_prev, -g0)``; valid if ``P >= 0`` and ``|Q| <= mu P``;
* **open**: ``lam = 0``, ``d = -A^{-1} r``; valid if ``d_n + g0 >= 0``;
* **slipping**: ``d = (t_prev + rho s, -g0)`` with a unit slip direction ``s``
  and ``rho > 0``; with the stuck trial forces ``(Q0, P0)``, ``A_tt`` the
  tangential block and ``b = A_nt``, the slip law ``Q = -mu P s`` reads

  .. math:: \rho\, M(s)\, s = g(s), \qquad M(s) = A_{tt} + \mu\, s\, b^T, \quad
            g(s) = -(Q_0 + \mu P_0 s),

  valid if ``rho > 0`` and ``P = P0 + rho b.s >= 0``. In 2D ``s = +-1`` and
  ``rho = s g / (M s)``. In 3D, ``s = (cos t, sin t)``, ``M(s) s`` and ``g(s)``
  must be parallel: ``f(t) = (M s) x g = 0`` is a trigonometric polynomial of
  degree 2 (at most four roots), found exactly as the unit-circle roots of a
  quartic in ``z = exp(i t)`` and polished by Newton steps on ``f``.

Several candidates can be valid at once (with ``mu |b| > a`` a 2D pair can
have three solutions): :func:`solve_pair` returns all of them, and
:func:`pair_solution` the first valid one in the order stuck, open, slipping
(or, if round-off leaves none valid, the least violated).
"""
from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .state import OPEN_CODE as OPEN, SLIPPING_CODE as SLIPPING, STUCK_CODE as STUCK

#: Roots of the quartic within this distance of the unit circle are kept and
#: polished (a double root, tangency of the two curves, sits ~sqrt(eps) = 1.5e-8
#: off it after rounding; 1e-4 keeps it and everything kept is verified).
CIRCLE_TOL = 1e-4
#: Newton steps that polish a root angle on ``f`` (quadratic convergence from
#: ~1e-8: two steps reach round-off; four leave a margin).
POLISH_STEPS = 4
#: Relative misfit of ``rho M(s) s = g(s)`` above which a root direction is not a
#: solution (a spurious root of the quartic, or ``M(s) s`` and ``g`` anti-parallel
#: with ``rho`` of the wrong sign is rejected by ``rho > 0``): round-off leaves
#: ~1e-15, a polished double root ~1e-8 of the angle; 1e-8 keeps both.
SLIP_MISFIT = 1e-8
#: Leading quartic coefficients below this (relative to the largest) are dropped:
#: the polynomial has lower degree (round-off of the FFT is ~1e-16).
DEGREE_DROP = 1e-14
#: Two directions closer than this (sum of component differences) are one root.
SAME_DIRECTION = 1e-12


class Candidate(NamedTuple):
    """One solution candidate of a pair: ``state``, displacement ``d`` (dim,),
    force ``lam`` (dim,), ``violation`` (force units, 0 if valid), slip
    direction ``s`` (dim-1,; zeros unless slipping)."""

    state: int
    d: np.ndarray
    lam: np.ndarray
    violation: float
    s: np.ndarray


def solve_pair(A, r, t_prev, g0, mu):
    """Every candidate solution of one pair, ``lam = A d + r`` (see module docstring).

    Parameters
    ----------
    A : (dim, dim) SPD
    r : (dim,)
    t_prev : (dim-1,)
    g0, mu : float

    Returns
    -------
    list of Candidate
        Stuck, open, then every slipping candidate with ``rho > 0`` (2D: up to
        two, 3D: up to four); ``violation`` measures how far each is from
        valid (``max(-P, |Q| - mu P)``, ``-k w`` with ``k = A_nn``, ``-P``).
    """
    A, r, t_prev = np.asarray(A, float), np.asarray(r, float), np.asarray(t_prev, float)
    stuck = _stuck(A, r, t_prev, g0, mu)
    return [stuck, _open(A, r, g0), *_slipping(A, r, t_prev, g0, mu, stuck.lam)]


def _stuck(A, r, t_prev, g0, mu):
    m = len(r) - 1
    d = np.append(t_prev, -g0)
    lam = A @ d + r
    P = float(lam[m])
    return Candidate(STUCK, d, lam, max(-P, math.hypot(*lam[:m]) - mu * P, 0.0), np.zeros(m))


def _open(A, r, g0):
    m = len(r) - 1
    d = -np.linalg.solve(A, r)
    return Candidate(OPEN, d, np.zeros_like(r), max(-A[m, m] * (d[m] + g0), 0.0), np.zeros(m))


def _slipping(A, r, t_prev, g0, mu, lam_stuck):
    m = len(r) - 1
    Q0, P0 = lam_stuck[:m], lam_stuck[m]
    out = []
    directions = _slip_directions_2d() if m == 1 else _slip_directions_3d(A, Q0, P0, mu)
    for s in directions:
        rho = _slip_length(A, Q0, P0, mu, s)
        if rho is None or not rho > 0:
            continue
        d = np.append(t_prev + rho * s, -g0)
        lam = A @ d + r
        out.append(Candidate(SLIPPING, d, lam, max(-lam[m], 0.0), s))
    return out


def pair_solution(A, r, t_prev, g0, mu):
    """One solution of one pair: the first valid candidate (stuck, open, slipping),
    else the least violated. Returns the :class:`Candidate`.

    Candidates are built lazily in that order, so the usual stuck or open pair
    costs one small product or solve.
    """
    A, r, t_prev = np.asarray(A, float), np.asarray(r, float), np.asarray(t_prev, float)
    stuck = _stuck(A, r, t_prev, g0, mu)
    if stuck.violation == 0.0:
        return stuck
    opened = _open(A, r, g0)
    if opened.violation == 0.0:
        return opened
    candidates = [stuck, opened, *_slipping(A, r, t_prev, g0, mu, stuck.lam)]
    for c in candidates[2:]:
        if c.violation == 0.0:
            return c
    return min(candidates, key=lambda c: c.violation)


def pair_solution_2d(a, b, c, rt, rn, tp, g0, mu):
    """:func:`pair_solution` of a 2D pair in scalar arithmetic (the inner loop of
    ``nodal_gs``): ``A = [[a, b], [b, c]]``, ``r = (rt, rn)``; returns ``(d_t, d_n)``.

    Stuck, open, then slipping with ``s = +-1`` and
    ``rho = -(s Q0 + mu P0) / (a + mu b s)``; if round-off leaves none valid,
    the least violated candidate of :func:`solve_pair`.
    """
    dn = -g0
    Q0, P0 = a * tp + b * dn + rt, b * tp + c * dn + rn
    if P0 >= 0.0 and abs(Q0) <= mu * P0:
        return tp, dn
    det = a * c - b * b
    dt_open, dn_open = (b * rn - c * rt) / det, (b * rt - a * rn) / det
    if dn_open + g0 >= 0.0:
        return dt_open, dn_open
    for s in ((-1.0, 1.0) if Q0 > 0 else (1.0, -1.0)):
        denom = a + mu * b * s
        if denom == 0.0:
            continue
        rho = -(s * Q0 + mu * P0) / denom
        if rho > 0.0 and P0 + rho * b * s >= 0.0:
            return tp + rho * s, dn
    best = pair_solution(np.array([[a, b], [b, c]]), np.array([rt, rn]), np.array([tp]), g0, mu)
    return float(best.d[0]), float(best.d[1])


def _slip_directions_2d():
    return [np.array([1.0]), np.array([-1.0])]


def _slip_length(A, Q0, P0, mu, s):
    """``rho`` of direction ``s``: least squares of ``rho M(s) s = g(s)``, None if
    the equation does not hold there (relative misfit above :data:`SLIP_MISFIT`)."""
    m = len(s)
    Ms = A[:m, :m] @ s + mu * (A[m, :m] @ s) * s
    g = -(Q0 + mu * P0 * s)
    denom = Ms @ Ms
    if not denom > 0:
        return None
    rho = (Ms @ g) / denom
    scale = max(np.linalg.norm(g), abs(rho) * np.sqrt(denom))
    if np.linalg.norm(rho * Ms - g) > SLIP_MISFIT * scale:
        return None
    return rho


def _trig_f(A, Q0, P0, mu, theta):
    """``f(t) = (M s) x g`` at angles ``theta`` (vectorised)."""
    s = np.stack([np.cos(theta), np.sin(theta)], axis=-1)
    As = s @ A[:2, :2].T
    bs = s @ A[2, :2]
    Ms = As + mu * bs[..., None] * s
    g = -(Q0 + mu * P0 * s)
    return Ms[..., 0] * g[..., 1] - Ms[..., 1] * g[..., 0]


def _slip_directions_3d(A, Q0, P0, mu):
    """Unit directions ``s`` where ``M(s) s`` is parallel to ``g(s)`` (roots of ``f``).

    ``f`` is a trigonometric polynomial of degree 2: its Fourier coefficients
    follow exactly from 8 samples, and ``z^2 f`` is a quartic in
    ``z = exp(i t)`` whose unit-circle roots are the angles.
    """
    n = 8
    theta = 2 * np.pi * np.arange(n) / n
    c = np.fft.fft(_trig_f(A, Q0, P0, mu, theta)) / n       # c[k] of exp(i k t)
    coeffs = np.array([c[2], c[1], c[0], c[-1], c[-2]])       # z^4 ... z^0 of z^2 f
    size = np.max(np.abs(coeffs))
    if not size > 0:
        return []
    coeffs = coeffs / size
    while abs(coeffs[0]) < DEGREE_DROP and len(coeffs) > 1:
        coeffs = coeffs[1:]
    roots = np.roots(coeffs) if len(coeffs) > 1 else np.array([])
    fourier = (c[0].real, 2 * c[1].real, -2 * c[1].imag, 2 * c[2].real, -2 * c[2].imag)
    out = []
    for z in roots:
        if abs(abs(z) - 1.0) > CIRCLE_TOL:
            continue
        t = _polish(fourier, float(np.angle(z)))
        s = np.array([math.cos(t), math.sin(t)])
        if not any(abs(s[0] - o[0]) + abs(s[1] - o[1]) <= SAME_DIRECTION for o in out):
            out.append(s)
    return out


def _polish(fourier, t):
    """Newton steps on ``f(t) = a0 + a1 cos t + b1 sin t + a2 cos 2t + b2 sin 2t``."""
    a0, a1, b1, a2, b2 = fourier
    for _ in range(POLISH_STEPS):
        c1, s1, c2, s2 = math.cos(t), math.sin(t), math.cos(2 * t), math.sin(2 * t)
        f = a0 + a1 * c1 + b1 * s1 + a2 * c2 + b2 * s2
        df = -a1 * s1 + b1 * c1 - 2 * a2 * s2 + 2 * b2 * c2
        if f == 0.0 or df == 0.0:
            break
        step = f / df
        if abs(step) > 1e-3:          # not in the quadratic basin: keep the root as found
            break
        t -= step
    return t


class PairViolations(NamedTuple):
    """What :func:`solve_pairs` finds for ``k`` pairs at once.

    ``violation`` (k, 3): per state (``STUCK``, ``SLIPPING``, ``OPEN`` columns)
    the smallest violation of a candidate of that state (force units; ``inf``:
    no slipping candidate); ``direction`` (k, m): the slip direction of the
    least violated slipping candidate (zeros where there is none);
    ``has_slip`` (k,) whether there is one.
    """

    violation: np.ndarray
    direction: np.ndarray
    has_slip: np.ndarray


def solve_pairs(A, r, t_prev, g0, mu):
    """:func:`solve_pair` for ``k`` independent pairs at once, in numpy arrays.

    Same candidates and violations as :func:`solve_pair` (stuck
    ``max(-P, |Q| - mu P)``, open ``-A_nn w``, slipping ``-P`` with ``rho > 0``),
    reduced to the least violated candidate of each state; the 3D slip
    directions are the unit-circle roots of each pair's quartic, found by
    batched eigenvalues of the companion matrices (pairs whose quartic drops a
    degree go through :func:`solve_pair`).

    Parameters
    ----------
    A : (k, dim, dim) SPD blocks
    r : (k, dim)
    t_prev : (k, dim-1)
    g0, mu : (k,)

    Returns
    -------
    PairViolations
    """
    A, r, t_prev = (np.asarray(a, float) for a in (A, r, t_prev))
    g0, mu = np.asarray(g0, float), np.asarray(mu, float)
    k, dim = r.shape
    m = dim - 1
    violation = np.full((k, 3), np.inf)
    d_stuck = np.concatenate([t_prev, -g0[:, None]], axis=1)
    lam = np.einsum("kij,kj->ki", A, d_stuck) + r
    Q0, P0 = lam[:, :m], lam[:, m]
    violation[:, STUCK] = np.maximum(np.maximum(-P0, np.linalg.norm(Q0, axis=1) - mu * P0), 0.0)
    d_open = -np.linalg.solve(A, r[:, :, None])[:, :, 0]
    violation[:, OPEN] = np.maximum(-A[:, m, m] * (d_open[:, m] + g0), 0.0)
    directions = (np.broadcast_to(np.array([[1.0], [-1.0]]), (k, 2, 1)) if m == 1
                  else _slip_directions_3d_batch(A, Q0, P0, mu))
    slip_violation = _slip_violations(A, Q0, P0, mu, directions)
    best = np.argmin(slip_violation, axis=1) if directions.shape[1] else np.zeros(k, int)
    has_slip = (np.isfinite(slip_violation).any(axis=1) if directions.shape[1]
                else np.zeros(k, bool))
    direction = np.zeros((k, m))
    if directions.shape[1]:
        chosen = directions[np.arange(k), best]
        direction[has_slip] = chosen[has_slip]
        violation[has_slip, SLIPPING] = slip_violation[has_slip, best[has_slip]]
    return PairViolations(violation, direction, has_slip)


def _slip_violations(A, Q0, P0, mu, directions):
    """``-P`` (clipped at 0) of each candidate direction ``(k, c, m)`` with ``rho > 0``
    and the slip equation met (:func:`_slip_length`); ``inf`` elsewhere (NaN
    directions are no candidates)."""
    m = Q0.shape[1]
    Att, b = A[:, :m, :m], A[:, m, :m]
    s = directions
    bs = np.einsum("km,kcm->kc", b, s)
    Ms = np.einsum("kij,kcj->kci", Att, s) + mu[:, None, None] * bs[:, :, None] * s
    g = -(Q0[:, None, :] + (mu * P0)[:, None, None] * s)
    with np.errstate(invalid="ignore", divide="ignore"):
        denom = np.sum(Ms * Ms, axis=2)
        rho = np.sum(Ms * g, axis=2) / denom
        scale = np.maximum(np.linalg.norm(g, axis=2), np.abs(rho) * np.sqrt(denom))
        misfit = np.linalg.norm(rho[:, :, None] * Ms - g, axis=2)
        ok = (denom > 0) & (misfit <= SLIP_MISFIT * scale) & (rho > 0)
        # d = (t_prev + rho s, -g0): P = P0 + rho b.s (the stuck trial plus the slip)
        P = P0[:, None] + rho * bs
    return np.where(ok, np.maximum(-P, 0.0), np.inf)


def _slip_directions_3d_batch(A, Q0, P0, mu):
    """Unit slip directions of 3D pairs, ``(k, 4, 2)`` with NaN rows where a pair has
    fewer than four (see :func:`_slip_directions_3d`, of which this is the batch)."""
    k = len(mu)
    theta = 2 * np.pi * np.arange(8) / 8
    s = np.stack([np.cos(theta), np.sin(theta)], axis=-1)                  # (8, 2)
    As = np.einsum("kij,tj->kti", A[:, :2, :2], s)
    bs = s @ A[:, 2, :2].T                                                 # (8, k)
    Ms = As + mu[:, None, None] * bs.T[:, :, None] * s[None]
    g = -(Q0[:, None, :] + (mu * P0)[:, None, None] * s[None])
    c = np.fft.fft(Ms[..., 0] * g[..., 1] - Ms[..., 1] * g[..., 0], axis=1) / 8
    coeffs = np.stack([c[:, 2], c[:, 1], c[:, 0], c[:, -1], c[:, -2]], axis=1)
    size = np.max(np.abs(coeffs), axis=1)
    out = np.full((k, 4, 2), np.nan)
    with np.errstate(invalid="ignore", divide="ignore"):
        regular = (size > 0) & (np.abs(coeffs[:, 0]) >= DEGREE_DROP * size)
    for i in np.flatnonzero(~regular & (size > 0)):                      # degree drops
        found = _slip_directions_3d(A[i], Q0[i], P0[i], mu[i])
        if found:
            out[i, :len(found)] = found
    idx = np.flatnonzero(regular)
    if idx.size == 0:
        return out
    p = coeffs[idx] / coeffs[idx, :1]
    companion = np.zeros((idx.size, 4, 4), complex)
    companion[:, 0, :] = -p[:, 1:]
    companion[:, [1, 2, 3], [0, 1, 2]] = 1.0
    z = np.linalg.eigvals(companion)                                       # (n, 4)
    fourier = np.stack([c[idx, 0].real, 2 * c[idx, 1].real, -2 * c[idx, 1].imag,
                        2 * c[idx, 2].real, -2 * c[idx, 2].imag], axis=1)
    t = _polish_batch(fourier, np.angle(z))
    dirs = np.stack([np.cos(t), np.sin(t)], axis=-1)                       # (n, 4, 2)
    keep = np.abs(np.abs(z) - 1.0) <= CIRCLE_TOL
    for j in range(1, 4):                                                  # one root once
        for i in range(j):
            same = np.abs(dirs[:, j] - dirs[:, i]).sum(axis=1) <= SAME_DIRECTION
            keep[:, j] &= ~(same & keep[:, i])
    out[idx] = np.where(keep[:, :, None], dirs, np.nan)
    return out


def _polish_batch(fourier, t):
    """:func:`_polish` for arrays of angles ``(n, 4)``: each root stops where the
    scalar version would (zero ``f`` or ``f'``, or a step above 1e-3)."""
    a0, a1, b1, a2, b2 = (fourier[:, j, None] for j in range(5))
    t = t.copy()
    active = np.ones(t.shape, bool)
    for _ in range(POLISH_STEPS):
        c1, s1, c2, s2 = np.cos(t), np.sin(t), np.cos(2 * t), np.sin(2 * t)
        f = a0 + a1 * c1 + b1 * s1 + a2 * c2 + b2 * s2
        df = -a1 * s1 + b1 * c1 - 2 * a2 * s2 + 2 * b2 * c2
        with np.errstate(invalid="ignore", divide="ignore"):
            step = f / df
        active &= (f != 0.0) & (df != 0.0) & (np.abs(step) <= 1e-3)
        t = np.where(active, t - np.where(active, step, 0.0), t)
    return t
