"""Coulomb contact law of one node pair, vectorised over pairs (method.md section 4).

Every per-pair rule of the package lives here: the kinematics (opening,
slip increment), the projection onto the friction disk, the natural-map
residual, the classification into stuck / slipping / open, and the state
checks of the basket method. The tangential part is always a vector of
``dim - 1`` components, so 2D and 3D (Coulomb cone) share one code path.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .local import solve_pairs
from .state import OPEN_CODE as OPEN, SLIPPING_CODE as SLIPPING, STUCK_CODE as STUCK


class PairQuantities(NamedTuple):
    """Forces and kinematics of every pair.

    ``P`` (n,) pressure, ``Q`` (n, m) shear, ``w`` (n,) opening ``d_n + g0``,
    ``dv`` (n, m) slip increment ``d_t - d_t_prev``, with ``m = dim - 1``.
    """

    P: np.ndarray
    Q: np.ndarray
    w: np.ndarray
    dv: np.ndarray


def row_norm(x):
    """Euclidean norm of each row of ``x`` ``(n, m)`` (``|x|`` when ``m = 1``)."""
    if x.shape[1] == 1:
        return np.abs(x[:, 0])
    return np.sqrt(np.einsum("ij,ij->i", x, x))


def pair_quantities(problem, d, lam, d_prev):
    """Split ``(d, lam)`` of shape ``(n_pairs, dim)`` into :class:`PairQuantities`."""
    return PairQuantities(lam[:, -1], lam[:, :-1], d[:, -1] + problem.gap0,
                          d[:, :-1] - d_prev[:, :-1])


def project_disk(x, radius):
    """Euclidean projection of each row of ``x`` onto the disk of radius ``radius``.

    .. math:: \\mathrm{proj}_r(x) = x \\min(1, r / \\lVert x \\rVert)

    Parameters
    ----------
    x : (n, m)
        Tangential vectors (``m = 1`` in 2D: the disk is ``[-r, r]``).
    radius : (n,)
        Non-negative radii.
    """
    if x.shape[1] == 1:
        return np.clip(x, -radius[:, None], radius[:, None])
    norm = row_norm(x)
    outside = norm > radius
    scale = np.ones_like(norm)
    scale[outside] = radius[outside] / norm[outside]
    return x * scale[:, None]


def natural_map(q, mu, c):
    """Absolute natural-map residuals of every pair.

    .. math::
        r_n = |P - \\max(0, P - c w)|, \\qquad
        r_t = \\lVert Q - \\mathrm{proj}_{\\mu \\max(P, 0)}(Q - c\\, dv) \\rVert

    Both vanish exactly when the pair satisfies one of the rows of the table
    of the contact law (open, stuck or slipping). ``c`` is a stiffness, a
    scalar or one per pair.
    """
    c = np.asarray(c, dtype=float)
    r_n = np.abs(q.P - np.maximum(0.0, q.P - c * q.w))
    radius = mu * np.maximum(q.P, 0.0)
    c_t = c[:, None] if c.ndim == 1 else c
    r_t = row_norm(q.Q - project_disk(q.Q - c_t * q.dv, radius))
    return r_n, r_t


class AugmentedForces(NamedTuple):
    """Alart-Curnier augmented forces and the sets they define.

    ``sigma_n = P - c w``, ``sigma_t = Q - c dv``; a pair is closed where
    ``sigma_n > 0`` and stuck where also ``|sigma_t| <= mu sigma_n``.
    """

    sigma_n: np.ndarray
    sigma_t: np.ndarray
    closed: np.ndarray
    stick: np.ndarray


def augmented_forces(q, mu, c):
    """Alart-Curnier augmented forces of every pair (see :class:`AugmentedForces`)."""
    sigma_n = q.P - c * q.w
    sigma_t = q.Q - c * q.dv
    closed = sigma_n > 0
    stick = closed & (row_norm(sigma_t) <= mu * sigma_n)
    return AugmentedForces(sigma_n, sigma_t, closed, stick)


def classify(q, mu, c, threshold=0.0):
    """Status of every pair from its forces and kinematics.

    Open where ``P - c w <= 0``; otherwise stuck where
    ``|Q - c dv| <= mu (P - c w) + threshold`` and slipping elsewhere (the
    Alart-Curnier sets with ``c`` the stiffness scale). At a solution this is
    the row of the table of method.md section 4 that the pair satisfies. A
    pair on the border of two rows satisfies both: zero pressure and zero
    opening is reported open, a shear at the friction limit with a slip
    increment below ``threshold / c`` (round-off) is reported stuck.
    """
    a = augmented_forces(q, mu, c)
    stick = row_norm(a.sigma_t) <= mu * a.sigma_n + threshold
    return np.where(~a.closed, OPEN, np.where(stick, STUCK, SLIPPING))


class Transitions(NamedTuple):
    """Result of the basket state checks.

    ``status`` (n,) proposed status, ``direction`` (n, m) slip direction of
    the one-pair solution for the pairs that failed (the current direction
    elsewhere), ``violation`` (n,) size of the violated inequality in force
    units (0 where the check passed). New arrays, never the inputs.
    """

    status: np.ndarray
    direction: np.ndarray
    violation: np.ndarray


def basket_transitions(status, direction, q, mu, kappa, threshold, local):
    """Check every pair against the inequalities of its basket (paper 16-18).

    Failed checks:

    * stuck: ``P < 0`` or ``|Q| > mu P``;
    * slipping: ``P < 0``, or a slip increment against the assumed slip
      direction, ``dv . s < 0`` (with ``mu P > 0``);
    * open: ``w < 0``.

    A pair that fails moves to the paper's default basket (stuck -> open if
    ``P < 0`` else slipping along ``-Q/|Q|``; slipping -> open if ``P < 0``
    else stuck; open -> stuck) if its exact one-pair solution with the other
    pairs held (``local``, :func:`local_states`) allows that state; otherwise
    to the first other state the one-pair solution allows (stuck, slipping,
    open), or to the default if none does; ``direction`` is then the slip
    direction of the one-pair solution. A check fails only if its violation
    exceeds ``threshold`` (force units; displacements are turned into forces
    with ``kappa``), so that round-off does not move pairs back and forth.

    Parameters
    ----------
    local : callable
        ``local(pairs) -> LocalStates``, the one-pair solutions at the
        current iterate of the pairs ``pairs`` (an index array); called only
        for the pairs that failed.
    """
    opened, stuck = status == OPEN, status == STUCK
    mu_p = mu * q.P
    shear = np.where(stuck, row_norm(q.Q) - mu_p,                              # overload
                     np.where(mu_p > 0, -kappa * np.einsum("ij,ij->i", q.dv, direction),
                              -np.inf))                                        # reversal
    viol = np.where(opened, -kappa * q.w, np.maximum(-q.P, shear))             # closing, tension
    failed = viol > threshold
    if not failed.any():
        return Transitions(status.copy(), direction.copy(), np.zeros_like(viol))
    tension = ~opened & (q.P < -threshold)
    default = np.where(opened | tension, OPEN, np.where(stuck, SLIPPING, STUCK))
    new, s = status.copy(), direction.copy()
    pairs = np.flatnonzero(failed)
    alone = local(pairs)
    new[pairs] = _target(status[pairs], default[pairs], alone.valid)
    s[pairs] = alone.direction
    return Transitions(new, s, np.where(failed, viol, 0.0))


def _target(status, default, valid):
    """Default basket if locally valid, else the first valid other basket."""
    rows = np.arange(len(status))
    allowed = valid.copy()
    allowed[rows, status] = False
    first = np.where(allowed.any(axis=1), np.argmax(allowed, axis=1), default)
    return np.where(valid[rows, default], default, first)


class LocalStates(NamedTuple):
    """Exact one-pair solutions of every pair (the other pairs held).

    ``valid`` (n, 3) bool: whether the stuck, slipping and open candidates
    (columns in the order of the status codes) satisfy their inequalities;
    ``direction`` (n, m) the slip direction of the slipping candidate.
    """

    valid: np.ndarray
    direction: np.ndarray


def local_states(problem, d, lam, d_prev, threshold, pairs):
    """Which rows of the contact law each pair can satisfy when solved alone.

    With the other pairs held, pair ``i`` sees ``lam_i = K_ii d_i + r_i``,
    ``r_i = lam_i - K_ii d_i``; its exact candidates (stuck, open, every
    slipping direction) come from :func:`qsma.contact.local.solve_pairs`
    (all pairs at once, the batch form of :func:`qsma.contact.local.solve_pair`).

    Parameters
    ----------
    d, lam, d_prev : (n_pairs, dim)
    threshold : float or (k,)
        Tolerance of the inequalities, force units.
    pairs : (k,) int
        The pairs to solve; the result has ``k`` rows.

    Returns
    -------
    LocalStates
        ``direction`` is that of the first valid slipping candidate (else of
        the least violated one, else the current ``-Q/|Q|``).
    """
    pairs = np.asarray(pairs, dtype=int)
    threshold = np.broadcast_to(np.asarray(threshold, dtype=float), (len(pairs),))
    A = problem.diagonal_blocks[pairs]
    r = lam[pairs] - np.einsum("kij,kj->ki", A, d[pairs])
    found = solve_pairs(A, r, d_prev[pairs, :-1], problem.gap0[pairs], problem.mu[pairs])
    valid = found.violation <= threshold[:, None]
    Q = lam[pairs, :-1]
    q_norm = row_norm(Q)
    fallback = np.zeros_like(Q)
    fallback[:, 0] = 1.0
    fallback = np.where((q_norm > 0)[:, None], -Q / np.where(q_norm > 0, q_norm, 1.0)[:, None],
                        fallback)
    direction = np.where(found.has_slip[:, None], found.direction, fallback)
    return LocalStates(valid, direction)


def slip_directions_from_forces(Q, status):
    """Slip direction ``-Q/|Q|`` of slipping pairs (zero where ``Q = 0``)."""
    norm = row_norm(Q)
    s = np.zeros_like(Q)
    ok = (status == SLIPPING) & (norm > 0)
    s[ok] = -Q[ok] / norm[ok, None]
    return s
