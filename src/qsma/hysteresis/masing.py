r"""Masing's rules, in one place: the loop, dissipation, secant frequency and damping
ratio from a modal backbone, and the checks of the assumptions under which they are
exact.

For a backbone ``alpha(q)`` through the origin (mass-normalised modal force equal
to ``alpha``), the Masing loop of amplitude ``(q_a, alpha_a)`` encloses

.. math:: D = 8 \int_0^{q_a} \alpha\,dq - 4 \alpha_a q_a ,

the secant frequency is :math:`\omega = \sqrt{\alpha_a / q_a}` and the equivalent
viscous damping ratio :math:`\zeta = D / (2\pi (q_a \omega)^2)`. The run uses
:func:`masing_estimate` (the same rule on the deviation from the tied line, with an
error estimate) and :func:`masing_checks`; :func:`masing`, :func:`masing_loop` and
:func:`loop_area` are the plain closed forms of the benchmark's definition and the
figures.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import InputError


@dataclass(frozen=True)
class MasingResult:
    """Per backbone point: dissipation per cycle, secant circular frequency, damping."""

    dissipation: np.ndarray
    omega: np.ndarray
    zeta: np.ndarray

    @property
    def f_hz(self):
        return self.omega / (2 * np.pi)


def masing(alpha, q) -> MasingResult:
    """Masing dissipation, secant frequency and damping ratio at each backbone point.

    The integral is the trapezoidal rule from (0, 0) through every point up to the
    current one (the benchmark's definition, docs/theory.md section 7; the analysis
    itself uses :func:`masing_estimate`, the same rule written on the
    deviation from the tied line, with an error estimate).
    """
    alpha = np.asarray(alpha, dtype=float)
    q = np.asarray(q, dtype=float)
    if alpha.shape != q.shape or alpha.ndim != 1:
        raise InputError(f"alpha and q must be 1-D arrays of equal length, got "
                         f"{alpha.shape} and {q.shape}")
    if not (np.all(np.isfinite(alpha)) and np.all(np.isfinite(q))):
        raise InputError("alpha and q must be finite")
    if np.any(alpha <= 0) or np.any(q <= 0):
        raise InputError("backbone points must have alpha > 0 and q > 0")
    qa = np.concatenate([[0.0], q])
    fa = np.concatenate([[0.0], alpha])
    area = np.cumsum(0.5 * (fa[1:] + fa[:-1]) * np.diff(qa))
    D = 8.0 * area - 4.0 * alpha * q
    omega = np.sqrt(alpha / q)
    zeta = D / (2 * np.pi * (q * omega) ** 2)
    return MasingResult(D, omega, zeta)


def masing_loop(alpha_b, q_b, k, n=64):
    """Points ``(q, f)`` of the Masing loop at backbone point ``k`` (unloading branch
    from ``+q_a`` to ``-q_a`` then reloading), built from the backbone by linear
    interpolation: ``f = alpha_a - 2 f_b((q_a - q)/2)`` and ``f = 2 f_b((q + q_a)/2) - alpha_a``.
    """
    qb = np.concatenate([[0.0], np.asarray(q_b, float)])
    fb = np.concatenate([[0.0], np.asarray(alpha_b, float)])
    qa, fa = qb[k + 1], fb[k + 1]
    s = np.linspace(0.0, 2 * qa, n)
    down_q, down_f = qa - s, fa - 2 * np.interp(s / 2, qb, fb)
    up_q, up_f = -qa + s, -fa + 2 * np.interp(s / 2, qb, fb)
    return np.concatenate([down_q, up_q]), np.concatenate([down_f, up_f])


def loop_area(q, f) -> float:
    """Area enclosed by a closed (or closing) polygon ``(q, f)`` (shoelace formula)."""
    q = np.asarray(q, float)
    f = np.asarray(f, float)
    return 0.5 * abs(np.dot(q, np.roll(f, -1)) - np.dot(f, np.roll(q, -1)))


@dataclass(frozen=True, eq=False)
class MasingEstimate:
    """Masing's rules on a backbone, with the integration error of each dissipation.

    ``dissipation``, ``omega``, ``zeta`` per backbone point; ``error`` the estimate of
    the trapezoidal error of ``dissipation`` (absolute).
    """

    dissipation: np.ndarray
    omega: np.ndarray
    zeta: np.ndarray
    error: np.ndarray


def masing_estimate(alpha, q, k_ref) -> MasingEstimate:
    r"""Masing dissipation at every backbone point, on the deviation ``g = alpha - k q``.

    .. math:: D_k = 8 \int_0^{q_k} \alpha\,dq - 4 \alpha_k q_k
                  = 8 \int_0^{q_k} g\,dq - 4 g_k q_k ,

    the trapezoidal rule through the origin and every point up to ``k``; the error
    estimate compares it with the rule on every second point counted back from ``k``.
    """
    alpha = np.asarray(alpha, dtype=float)
    q = np.asarray(q, dtype=float)
    g = np.concatenate([[0.0], alpha - k_ref * q])
    qa = np.concatenate([[0.0], q])
    piece = 0.5 * (g[1:] + g[:-1]) * np.diff(qa)
    fine = np.concatenate([[0.0], np.cumsum(piece)])
    coarse = np.zeros_like(fine)
    if len(fine) > 1:
        coarse[1] = fine[1]
    for p in range(2, len(fine)):
        coarse[p] = coarse[p - 2] + 0.5 * (g[p] + g[p - 2]) * (qa[p] - qa[p - 2])
    D = 8.0 * fine[1:] - 4.0 * g[1:] * q
    error = 8.0 * np.abs(fine[1:] - coarse[1:]) / 3.0
    with np.errstate(invalid="ignore", divide="ignore"):   # q <= 0: NaN, flagged later
        omega = np.sqrt(alpha / q)
        zeta = D / (2 * np.pi * alpha * q)
    return MasingEstimate(D, omega, zeta, error)


@dataclass(frozen=True, eq=False)
class MasingChecks:
    """Per level: whether Masing's rules are verified up to it, and why not.

    ``valid`` (n,) bool; ``reason`` (n,) text ("" where valid); ``pressure_change``
    (n,) the largest change of any pair's pressure since the preload, relative to the
    largest preload pressure, over both ramps up to the level; ``mirror_mismatch`` (n,)
    ``|D+ - D-| / |D+|`` of the Masing dissipations of the two backbones.
    """

    valid: np.ndarray
    reason: np.ndarray
    pressure_change: np.ndarray
    mirror_mismatch: np.ndarray


#: Largest relative change of the contact pressures for which Masing counts as exact:
#: with the pressures unchanged the joint is a network of elastic springs and
#: frictional sliders of fixed strength (no normal-tangential coupling). Measured on
#: sandwich-2d refine 1: 5.4e-10 (round-off), on the dissimilar-beam variant 0.28.
PRESSURE_RTOL = 1e-6
#: Relative rise of the secant stiffness alpha/q that counts as stiffening: twice the
#: 1e-6 to which a stuck level's secant frequency equals f0 (the modal response of the
#: smallest resolvable levels carries ~1e-8 relative noise, measured on sandwich-2d at
#: a tip deflection of 1 nm).
SECANT_RTOL = 2e-6


def masing_checks(alpha, q_pos, q_neg, P_pos, P_neg, P_pre, open_pos, open_neg, open_pre,
                  k_ref, rtol, atol, linear=None) -> MasingChecks:
    """Check, level by level, the assumptions under which Masing's rules are exact.

    0. Where ``linear[k]`` (no pair has left its preload state on either ramp up to
       level ``k``: the joint responds linearly for ``|alpha| <= alpha_k``, so every
       cycle within that range is a line, ``D = 0``, and Masing gives exactly that),
       the level is valid whatever the pressures do.
    1. The contact set does not change: no pair opens or closes with respect to the
       preload on either ramp (a closing pair stiffens the joint: hardening).
    2. The pressures do not change (relative change <= :data:`PRESSURE_RTOL`): no
       normal-tangential coupling, so the friction limits are fixed.
    3. The backbone for ``-alpha`` mirrors the one for ``+alpha``: their peak modal
       amplitudes agree within ``rtol`` and their Masing dissipations within
       ``rtol |D| + atol`` (a pre-shear left by the preload, or pairs at the friction
       limit, make them differ).
    4. The secant stiffness does not rise.

    A level is valid only if every level up to it is (the loop of an amplitude sweeps
    every smaller one).
    """
    alpha = np.asarray(alpha, float)
    n = len(alpha)
    scale = max(float(np.max(P_pre, initial=0.0)), np.finfo(float).tiny)
    dP = np.maximum(np.abs(P_pos - P_pre[None, :]).max(axis=1, initial=0.0),
                    np.abs(P_neg - P_pre[None, :]).max(axis=1, initial=0.0)) / scale
    set_change = np.any(open_pos != open_pre[None, :], axis=1) | \
        np.any(open_neg != open_pre[None, :], axis=1)
    d_pos = masing_estimate(alpha, q_pos, k_ref).dissipation
    d_neg = masing_estimate(alpha, -np.asarray(q_neg, float), k_ref).dissipation
    mismatch = np.abs(d_pos - d_neg) / np.maximum(np.abs(d_pos), np.finfo(float).tiny)
    # the backbones themselves, not only their dissipations: two straight backbones of
    # different slopes (pairs at the friction limit after the preload slip one way
    # only) both give D = 0, yet they are no mirror images
    q_apart = np.abs(np.asarray(q_pos, float) + np.asarray(q_neg, float)) / \
        np.maximum(np.abs(np.asarray(q_pos, float)), np.finfo(float).tiny)
    mirror_bad = (np.abs(d_pos - d_neg) > rtol * np.abs(d_pos) + atol) | (q_apart > rtol)
    secant = alpha / np.asarray(q_pos, float)
    rising = np.concatenate([[False], secant[1:] > secant[:-1] * (1 + SECANT_RTOL)])
    linear = np.zeros(n, bool) if linear is None else np.asarray(linear, bool)
    reasons = []
    valid = np.ones(n, bool)
    why = ""
    for k in range(n):
        if linear[k]:
            reasons.append("")
            continue
        if not why:
            at = f"at alpha = {alpha[k]:.4g}"
            if set_change[k]:
                why = f"contact set changed {at} (a pair opened or closed)"
            elif dP[k] > PRESSURE_RTOL:
                why = f"pressures changed by {dP[k]:.2e} of the peak {at}"
            elif mirror_bad[k]:
                why = (f"backbones for +alpha and -alpha differ {at} "
                       + (f"(Masing dissipations differ by {mismatch[k]:.2e})"
                          if q_apart[k] <= rtol else
                          f"(peak modal amplitudes differ by {q_apart[k]:.2e})"))
            elif rising[k]:
                why = f"secant stiffness rises {at}"
        valid[k] = not why
        reasons.append(why)
    return MasingChecks(valid, np.array(reasons, dtype=object),
                        np.maximum.accumulate(dP) if n else dP, mismatch)
