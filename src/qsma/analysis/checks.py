"""What the physics guarantees, checked per level: the flags of a level, the
dissipation that is zero to the precision it was computed with, and the outcome of a
run (:data:`qsma.analysis.result.FAILURE_FLAGS`)."""
from __future__ import annotations

import numpy as np

from ..hysteresis import SECANT_RTOL
from .result import FAILURE_FIXES, FAILURE_FLAGS

#: A damping ratio below this in magnitude is zero to the precision of the contact
#: solves (tol 1e-10 on forces; the stuck sandwich-2d levels give |zeta| ~ 1e-12).
ZETA_ZERO = 1e-8
#: Relative deviation of the secant frequency from f0 accepted while the interface has
#: not moved from its preload state (stuck sandwich-2d levels: 2.5e-10).
STUCK_FREQUENCY_RTOL = 1e-6


#: A damping ratio below which a joint's damping is negligible to an engineer (a
#: hundredth of the least a bolted joint gives, about 1e-2 at its microslip levels).
ZETA_NEGLIGIBLE = 1e-4


def _negligible_negative(D, error, alpha, q) -> bool:
    """Whether a negative dissipation ``D`` is zero within its own error estimate and
    that estimate, as a damping ratio, is negligible (:data:`ZETA_NEGLIGIBLE`): then
    the level's damping is reported as 0 with its estimate (a cycle cannot create
    energy, and the true value lies between 0 and the estimate). lap-3d refine 1 at
    its level 12: D = -1.2e-9 J within its estimate 1.6e-8 J (zeta 3.6e-5) between
    neighbours of +4e-7 and +2e-7. A negative value beyond its estimate, or with an
    estimate that is not negligible, stays a failure (``negative_dissipation``). "Within"
    allows the round-off of the contact solves (:data:`ZETA_ZERO` as a damping ratio):
    where the estimate is the distance to a loop that dissipated nothing, D and its
    estimate are one number but for the last digits (lap-3d with C3D8I bricks, the
    level where the first pair slips: D = -1.0092894569939e-10 J, estimate
    1.0092894569925e-10 J)."""
    scale = 2 * np.pi * abs(alpha) * abs(q)
    return bool(np.isfinite(D) and np.isfinite(error) and D < 0
                and -D <= error + ZETA_ZERO * scale and error <= ZETA_NEGLIGIBLE * scale)


def _settle_dissipation(hyst, flags, alpha, q):
    """The dissipation as reported, where it is zero to the precision it was computed
    with: exactly 0 where no pair with friction slipped (``hyst.no_slip``), and 0 for
    a negative value within the round-off bound ``ZETA_ZERO 2 pi alpha |q|`` of the
    contact solves it comes from (a cycle cannot create energy). A negative value
    beyond that bound is flagged ``negative_dissipation`` (:func:`_flags`) and kept, as
    is every value of a level with a failure flag. Where no pair with friction slipped
    the cycle is elastic whatever a computed loop's quadrature gave (a frictionless
    joint whose pairs open and close along the loop): ``D = 0`` with error 0, and
    neither its sign nor its integration error is flagged."""
    bound = ZETA_ZERO * 2 * np.pi * np.asarray(alpha) * np.abs(q)
    sound = np.array([not set(f) & set(FAILURE_FLAGS) for f in flags], bool)
    for method in ("masing", "loop"):
        D, zeta = getattr(hyst, f"dissipation_{method}"), getattr(hyst, f"zeta_{method}")
        err = getattr(hyst, f"{method}_error")
        negligible = np.array([_negligible_negative(*x) for x in zip(D, err, alpha, q)],
                              bool)
        zero = sound & np.isfinite(D) & (hyst.no_slip | ((D < 0) & (-D <= bound))
                                         | negligible)
        D[zero] = 0.0
        zeta[zero] = 0.0
        err[sound & np.isfinite(D) & hyst.no_slip] = 0.0     # zero by physics, exactly


def _flags(alpha, q, tip, hyst, omega0, opts):
    """Per level, what the physics forbids (failures) and what it allows but a reader
    should know (information); see :data:`FAILURE_FLAGS`. ``hyst``: the levels'
    :class:`qsma.analysis.dissipation.Dissipation`."""
    n = len(alpha)
    not_masing = hyst.masing_unused
    f, zeta, err, D = hyst.f_hz, hyst.zeta, hyst.dissipation_error, hyst.dissipation
    f0 = omega0 / (2 * np.pi)
    # no pair has left its preload state on either ramp up to the level (every point
    # of both refined ramps): the +alpha states of the output levels alone would call
    # a level whose -alpha ramp slips untouched, and its damping a misfire
    untouched = hyst.linear
    out = []
    for k in range(n):
        fl = []
        if not (np.isfinite(f[k]) and np.isfinite(zeta[k])):
            lp = hyst.loops.get(k)
            fl.append("not_finite" if lp is None else
                      "loop_not_stabilised" if lp.outcome == "not_stabilised" else
                      "loop_failed")
        elif D[k] < -ZETA_ZERO * 2 * np.pi * alpha[k] * abs(q[k]) and not \
                _negligible_negative(D[k], err[k], alpha[k], q[k]) and not hyst.no_slip[k]:
            fl.append("negative_dissipation")       # beyond round-off and not negligible
        if hyst.zeta_masing[k] < -ZETA_ZERO and not_masing[k]:
            fl.append("masing_negative")
        hard = f[k] > f0 * (1 + STUCK_FREQUENCY_RTOL) or (
            k > 0 and q[k] * alpha[k - 1] * (1 + SECANT_RTOL) < q[k - 1] * alpha[k])
        if hard:
            fl.append("hardening" if not_masing[k] else "masing_on_hardening")
        if untouched[k] and (abs(f[k] / f0 - 1) > STUCK_FREQUENCY_RTOL
                             or abs(zeta[k]) > ZETA_ZERO):
            fl.append("stuck_not_linear")
        if k > 0 and not q[k] > q[k - 1]:
            fl.append("q_not_increasing")
        if k > 0 and not tip[k] > tip[k - 1]:
            fl.append("tip_not_increasing")
        if np.isfinite(err[k]) and np.isfinite(D[k]) and not hyst.no_slip[k] and \
                err[k] > opts.dissipation_rtol * abs(D[k]) + \
                ZETA_ZERO * 2 * np.pi * alpha[k] * abs(q[k]):
            fl.append("integration_error_above_rtol")
        if hyst.shakedown[k]:
            fl.append("shakedown")
        out.append(tuple(fl))
    return tuple(out)


def _outcome(pos, flags, loops=None):
    """``(success, message)`` of the run from the ramp and the level flags: per failure
    flag its levels and what to change (:data:`qsma.analysis.result.FAILURE_FIXES`), with the
    message of the first loop that failed or did not stabilise (``loops``: level ->
    :class:`qsma.hysteresis.Loop`)."""
    parts = [] if pos.success else [pos.message]
    for name in FAILURE_FLAGS:
        ks = [k for k, f in enumerate(flags) if name in f]
        if not ks:
            continue
        text = (f"{name} at level(s) {ks[:12]}{' ...' if len(ks) > 12 else ''}: "
                f"{FAILURE_FIXES[name]}")
        lp = (loops or {}).get(ks[0])
        if name in ("loop_failed", "loop_not_stabilised") and lp is not None:
            text += f" (level {ks[0]}: {lp.message})"
        parts.append(text)
    if not parts:
        return True, "all levels converged"
    return False, "; ".join(parts)
