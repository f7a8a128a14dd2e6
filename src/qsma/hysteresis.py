r"""Dissipation per cycle of the modal coordinate: computed loops and Masing's rules.

Two ways to the dissipation ``D`` of a cycle of modal-force amplitude ``A``
(docs/theory.md section 7):

* **the loop**: from the state reached on the backbone at ``+A``, unload to ``-A``
  and reload to ``+A`` with the history-dependent contact solver, repeated until
  the cycle repeats itself (the stabilised cycle), then continued with one cycle per
  refinement round on halved increments until ``D`` settles;
  ``D = \oint \alpha\,dq``;
* **Masing's rules** on the backbone ``alpha(q)``:
  ``D = 8 \int_0^{q_a} \alpha\,dq - 4 A q_a``, exact only for joints whose
  unloading branch is the backbone scaled by two (see :func:`masing_checks`).

Every area is computed by the trapezoidal rule on the deviation from a linear
reference ``k_ref`` (``r = q - alpha/k_ref``, ``g = alpha - k_ref q``): the result is
the same number in exact arithmetic (the trapezoidal rule integrates the linear part
exactly and its closed-path integral vanishes), but the round-off of two large,
nearly equal areas is avoided, so a joint that stays stuck gets ``D = 0`` to
round-off of the *nonlinear* part. Each value carries an estimate of its
integration error from the same rule on every second point (Richardson,
``|I_h - I_2h| / 3`` for a rule of order two).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import logging
import multiprocessing
import queue
import time
import warnings

import numpy as np

from ._infra.forked import (default_signals, fork_refusal, quiet_fork, raise_again,
                            recorded_warnings)
from .contact.state import OPEN

log = logging.getLogger("qsma")

#: Relative tolerance on the interface displacements for "the cycle ended in the state
#: it started from" (relative to the displacement range of the cycle). The contact
#: solves meet 1e-10 (qsma.contact.DEFAULT_TOL); 1e-7 leaves three decades of margin.
STATE_RTOL = 1e-7
#: The ways a loop computation ends (:attr:`Loop.outcome`).
LOOP_OUTCOMES = ("stabilised", "not_stabilised", "solve_failed")
#: Largest factor by which the drift of the state at ``+A`` (the largest change of an
#: interface displacement over one cycle) may shrink from cycle to cycle, over each of
#: the last two cycles, for a loop to get cycles beyond ``max_cycles``: a shakedown
#: that converges geometrically. Ratcheting (a constant drift) and a cycle that
#: alternates between two states (period two: a constant drift) do not contract.
#: Measured: the loop of stack-2d level 4 (A = 12.55, zeta 2.7e-5, the first levels
#: that slip) contracts by 0.55 per cycle and needs 10 cycles; a tetrahedral lap-3d
#: (each hexahedron of the example split into six tetrahedra) at its third default
#: level by 0.78 to 0.85 and repeats after 17 cycles.
CONTRACTION = 0.95
#: A contracting loop gets the cycles its contraction predicts (:func:`_cycles_needed`)
#: as long as they total at most this many times ``max_cycles``; beyond, it stops at
#: once, its message naming the ``max_cycles`` that would do.
CYCLE_CEILING = 4
#: Rounds of loop-increment refinement (each halves the increments where the pair
#: states change and continues the history with cycles on them until they settle; the
#: change of D from the previous round is the estimate of the path error).
REFINE_ROUNDS = 3
#: A refinement round of a loop whose drift contracted by this factor or faster on the
#: coarser increments is one cycle: what its transient leaves, at most ``r / (1 - r)
#: <= 1`` times the change of D the round makes, is within the path error estimated
#: from that change. Slower loops settle each round as on the initial increments
#: (the tetrahedral lap joint's highest levels: r = 0.6 to 0.85).
ONE_CYCLE_CONTRACTION = 0.5
#: Share of the tolerance of a loop's D that the intervals no longer refined may take
#: in all (:func:`_settled_intervals`): the intervals of a refinement round whose
#: shares of D and of q changed least when they were halved, within this share, are not
#: halved again, and their changes are added to the loop's error estimate. 0 refines
#: every interval where a pair changes state, round after round.
LOCAL_SHARE = 0.25


@dataclass(frozen=True, eq=False)
class Loop:
    """The stabilised quasi-static hysteresis loop at modal-force amplitude ``A``.

    Attributes
    ----------
    amplitude : float
        ``A``, the modal force at the turning points ``+A`` and ``-A``.
    alpha, q : (n,) arrays
        The stabilised cycle: from ``+A`` down to ``-A`` and back to ``+A``.
    dissipation : float
        ``D = \\oint alpha dq`` of the stabilised cycle (NaN if the loop failed).
    first_dissipation : float
        ``D`` of the first cycle after the monotonic ramp, on the initial increments
        (differs on shakedown).
    error : float
        Estimate of the integration error of ``dissipation`` (absolute).
    q_top, q_bottom : float
        ``q`` at ``+A`` and ``-A`` of the stabilised cycle.
    n_cycles : int
        Cycles on the initial increments until they settled (the refinement rounds'
        are :attr:`refinement_cycles`).
    n_solves : int
        Contact solves spent (all refinement rounds included).
    coarse_dissipation : float
        ``D`` of the cycle that repeated on the initial increments (NaN when
        ``refine_rounds = 0`` or when no cycle repeated): the reference of
        :attr:`shakedown`, on the same increments as ``first_dissipation``.
    refinement_cycles : int
        Cycles solved on refined increments (one or more per refinement round, until
        they settle).
    seconds : float
        Wall-clock seconds the loop took in the process that computed it (NaN where
        not measured).
    outcome : str
        One of :data:`LOOP_OUTCOMES`: ``"stabilised"`` (the answer), ``"not_stabilised"``
        (no cycle repeated within ``max_cycles``), ``"solve_failed"`` (a contact solve
        of the history failed; no dissipation).
    message : str
    """

    amplitude: float
    alpha: np.ndarray
    q: np.ndarray
    dissipation: float
    first_dissipation: float
    error: float
    q_top: float
    q_bottom: float
    n_cycles: int
    n_solves: int
    outcome: str
    message: str
    coarse_dissipation: float = float("nan")
    refinement_cycles: int = 0
    seconds: float = float("nan")

    @property
    def success(self) -> bool:
        """Only a stabilised loop is an answer."""
        return self.outcome == "stabilised"

    @property
    def stabilised(self) -> bool:
        return self.outcome == "stabilised"

    @property
    def q_amplitude(self) -> float:
        """Half the peak-to-peak modal amplitude, ``(q_top - q_bottom) / 2``."""
        return 0.5 * (self.q_top - self.q_bottom)

    @property
    def omega(self) -> float:
        """Secant circular frequency of the peak-to-peak line, ``sqrt(2A / (q_top - q_bottom))``."""
        return float(np.sqrt(self.amplitude / self.q_amplitude))

    @property
    def zeta(self) -> float:
        """Equivalent damping ratio ``D / (2 pi A q_a)`` (= ``D / (2 pi (q_a w)^2)``)."""
        return float(self.dissipation / (2 * np.pi * self.amplitude * self.q_amplitude))

    @property
    def shakedown(self) -> bool:
        """Whether the first cycle dissipated differently from the stabilised one (both
        on the initial increments)."""
        stabilised = (self.dissipation if np.isnan(self.coarse_dissipation)
                      else self.coarse_dissipation)
        return bool(self.n_cycles > 1 and not np.isclose(
            self.first_dissipation, stabilised, rtol=1e-6,
            atol=1e-9 * self.amplitude * abs(self.q_amplitude)))


def cycle_path(amplitude, fractions) -> np.ndarray:
    """Modal forces of one cycle: ``+A``, then ``A - 2A u`` and ``-A + 2A u`` for the
    increasing ``fractions`` ``u`` (the last is 1)."""
    u = np.asarray(fractions, dtype=float)
    return np.concatenate([[amplitude], amplitude * (1 - 2 * u), amplitude * (2 * u - 1)])


def cycle_area(alpha, q, k_ref) -> float:
    """``\\oint alpha dq`` of a path from ``+A`` to ``+A`` by the trapezoidal rule, on the
    deviation ``r = q - alpha / k_ref`` (the same value, without the cancellation)."""
    alpha = np.asarray(alpha, dtype=float)
    r = np.asarray(q, dtype=float) - alpha / k_ref
    return float(np.sum(0.5 * (alpha[1:] + alpha[:-1]) * np.diff(r)))


def _coarse(n_branch):
    """Indices of a cycle path of two branches of ``n_branch`` points each that keep
    every second point counted back from each turning point."""
    branch = np.arange(1, n_branch + 1)
    keep = branch[(n_branch - branch) % 2 == 0]
    return np.concatenate([[0], keep, n_branch + keep])


def cycle_area_error(alpha, q, k_ref) -> float:
    """Estimate ``|D_h - D_2h| / 3`` of the trapezoidal error of :func:`cycle_area`."""
    n_branch = (len(alpha) - 1) // 2
    if n_branch < 2:
        return 0.0
    idx = _coarse(n_branch)
    fine = cycle_area(alpha, q, k_ref)
    coarse = cycle_area(np.asarray(alpha)[idx], np.asarray(q)[idx], k_ref)
    return abs(fine - coarse) / 3.0


def compute_loop(step, modal, amplitude, start, fractions, *, k_ref, max_cycles=8,
                 rtol=5e-3, atol=0.0, refine_rounds=REFINE_ROUNDS,
                 expect_closing=False, warm_start=False) -> Loop:
    """The stabilised loop at ``amplitude``, with the increments refined to ``rtol``.

    Parameters
    ----------
    step : callable
        ``step(alpha, state) -> ContactResult``: one contact solve at modal force
        ``alpha`` from the history ``state``.
    modal : callable
        ``modal(d, alpha) -> float``: the modal amplitude of the interface
        displacements ``d`` at modal force ``alpha``.
    amplitude : float
        ``A > 0``.
    start : ContactState
        The state on the backbone at ``+A`` (the monotonic ramp's).
    fractions : array_like
        Initial increments of each branch as fractions of ``2A`` (increasing, the last 1).
    k_ref : float
        Linear reference stiffness of the deviation (the tied ``w0^2``).
    max_cycles : int
        Cycles on the initial increments before the loop is declared not stabilised,
        unless its drift contracts geometrically (:func:`_contracting`) and the
        cycles it then needs (:func:`_cycles_needed`) total at most
        ``CYCLE_CEILING max_cycles``.
    rtol, atol : float
        Refine until the error estimate is ``<= rtol |D| + atol`` (at most
        ``refine_rounds`` rounds, each halving the increments where pair states change).
    expect_closing : bool
        Call ``step(alpha, state, closing)`` from the second cycle on, ``closing`` the
        pairs closed at the same point of the cycle before (:class:`_Closings`), the
        pairs a solve on a contact zone lets in before it starts
        (:func:`qsma.contact.zone.solve_in_zone`). A guess: the same solution to the
        contact tolerance (the zones differ, so the bits do).
    warm_start : bool
        With ``expect_closing``: call ``step(alpha, state, closing, guess)`` where the
        cycle before had a point at the same load on the same branch, ``guess`` the
        state it reached there (a settling loop nearly repeats it): the iteration of
        the solve starts from it (the answer is judged as any other; the same
        solution to the contact tolerance, fewer iterations).

    Notes
    -----
    The error of a computed loop has three parts: the quadrature of the enclosed area
    on the computed points, the transient still to come (the cycles settle
    geometrically), and the path error of solving each increment in one step (a pair
    that sticks and slips again within an increment, and a settled cycle that depends
    on the history it was reached by). The cycles first run on the initial increments
    from ``start`` until they settle (:func:`_cycles`). Each refinement round then
    halves the increments where a pair changed state and continues the history on
    them, from the state the previous cycle ended in (it is not solved again from
    ``start``), until they settle again (:func:`_refinement_round`). The change of
    ``D`` between the settled cycles of two rounds estimates the path error
    (:func:`_path_error`). The estimate is the largest of the three; with
    ``refine_rounds = 0`` only the quadrature estimate and the transient are.
    """
    u = np.unique(np.clip(np.asarray(fractions, dtype=float), 0.0, 1.0))
    u = np.union1d(u[u > 0], [1.0])
    closings = _Closings(warm_start) if expect_closing else None
    loop, changed, end, ratio = _cycles(step, modal, amplitude, start, u, k_ref,
                                        max_cycles, rtol, atol, closings)
    provisional = None
    if (loop.outcome == "not_stabilised" and refine_rounds and changed.any()
            and ratio is not None and ratio < 1.0):
        # Cycles on increments too coarse for the pair states they cross settle slowly
        # and to another loop than the refined increments (lap-3d with a compliant law
        # at A = 290: 6.1e-7 J on 8 increments per branch, still drifting by 0.965 per
        # cycle after 8 cycles; 2.81e-6 J on 29 to 58, settled in two cycles each).
        # Their drift contracts: the refined rounds continue from where they stopped,
        # and only a refined round that settles gives the loop.
        provisional = loop
        loop = replace(loop, outcome="stabilised", error=np.inf)
    if not loop.success or refine_rounds == 0:
        return loop
    stabilised = loop
    if changed.any():
        loop = replace(loop, error=np.inf)     # no path estimate yet: refine once
    cycles, rounds, change = 0, 0, None
    settled = np.zeros(len(u), bool)       # branch intervals no longer refined
    settled_error = 0.0                    # what their path error may still be
    for _ in range(refine_rounds):
        if loop.error <= rtol * abs(loop.dissipation) + atol:
            break
        if settled.any() and not (changed & ~settled).any():
            break                           # every interval left to refine has settled
        u, coarse = _refined(u, changed & ~settled), u
        settled = settled[_parents(u, coarse)]
        refined, changed, end, n, change = _refinement_round(
            step, modal, loop, end, u, coarse, k_ref, max_cycles, rtol, atol, closings,
            ratio, change, settled_error)
        cycles, rounds = cycles + n, rounds + 1
        if refined.outcome == "not_stabilised":      # honest: keep the settled round
            if provisional is not None and loop.error == np.inf:
                return replace(provisional, n_solves=refined.n_solves,
                               message=provisional.message + f"; nor on {len(u)} "
                               f"increments per branch")
            loop = replace(loop, n_solves=refined.n_solves, message=loop.message
                           + f"; the cycles on {len(u)} increments per branch did not "
                           f"settle within max_cycles")
            break
        budget = LOCAL_SHARE * (rtol * abs(refined.dissipation) + atol) - settled_error
        if refined.success and budget > 0:
            newly, bound = _settled_intervals(refined, loop, u, coarse, k_ref, budget)
            newly &= ~settled
            settled |= newly
            settled_error += bound          # in this round's change; after it, not
        loop = refined
        if not loop.success:
            break
    if loop.success and loop.error > rtol * abs(loop.dissipation) + atol:
        loop = replace(loop, message=loop.message + f"; error estimate {loop.error:.3g} "
                       f"above the tolerance after {rounds} refinement round(s)")
    return replace(loop, first_dissipation=stabilised.first_dissipation,
                   n_cycles=stabilised.n_cycles, refinement_cycles=cycles,
                   coarse_dissipation=stabilised.dissipation)


def _parents(u, coarse):
    """Per branch interval of ``u`` (ending at ``u[i]``), the interval of ``coarse`` (a
    subset of ``u`` with the same last point) that holds it."""
    return np.searchsorted(coarse, u, side="left")


def _interval_pieces(alpha, q, k_ref):
    """Per branch interval, the trapezoids of :func:`cycle_area` and the increments of
    ``q``, each as ``(n, 2)``: the unloading branch, then the reloading one."""
    alpha, q = np.asarray(alpha, float), np.asarray(q, float)
    r = q - alpha / k_ref
    area = 0.5 * (alpha[1:] + alpha[:-1]) * np.diff(r)
    dq = np.diff(q)
    n = len(area) // 2
    return np.stack([area[:n], area[n:]], axis=1), np.stack([dq[:n], dq[n:]], axis=1)


def _settled_intervals(fine, coarse_loop, u, coarse, k_ref, budget):
    r"""The branch intervals of ``u`` whose coarse interval's share of the cycle hardly
    changed when its increments were halved: ``(settled (len(u),) bool, bound)``.

    Per interval ``j`` of ``coarse``, the change of its trapezoids of ``D`` over both
    branches, ``\Delta D_j``, and of its increments of ``q``, ``\Delta q_j``, from the
    cycle on ``coarse`` (``coarse_loop``) to the one on ``u`` (``fine``). The intervals
    of the smallest ``\Delta D_j`` are settled as long as their sum stays within
    ``budget`` and that of their ``\Delta q_j`` within ``budget / |D|`` times the range
    of ``q``: halving one again would change the loop by about its ``\Delta_j`` or
    less (a first-order path error halves with the increment), so ``bound``, the sum
    of their ``\Delta D_j``, is what their path error may still be, added to the
    loop's error estimate from the next round on (this round's change of ``D``, the
    estimate of the path error of all the intervals, holds their changes). A history
    shifted by the intervals before moves ``q`` along a branch, not the area or the
    increments of an interval, so ``\Delta_j`` is the interval's own."""
    n = len(coarse)
    parent = _parents(u, coarse)
    area_f, dq_f = _interval_pieces(fine.alpha, fine.q, k_ref)
    area_c, dq_c = _interval_pieces(coarse_loop.alpha, coarse_loop.q, k_ref)
    per = lambda x: np.stack([np.bincount(parent, x[:, b], minlength=n) for b in (0, 1)], 1)
    dD = np.abs(per(area_f) - area_c).sum(axis=1)
    dq = np.abs(per(dq_f) - dq_c).sum(axis=1)
    span = max(np.ptp(fine.q), np.finfo(float).tiny)
    q_budget = budget / max(abs(fine.dissipation), np.finfo(float).tiny) * span
    order = np.argsort(dD, kind="stable")            # the smallest changes first
    fits = (np.cumsum(dD[order]) <= budget) & (np.cumsum(dq[order]) <= q_budget)
    still = np.zeros(n, bool)
    still[order[:np.argmin(fits) if not fits.all() else n]] = True
    return still[parent], float(dD[still].sum())


def _refinement_round(step, modal, previous, state0, u, coarse, k_ref, max_cycles, rtol,
                      atol, closings, known, last_change=None, settled_error=0.0):
    """The cycles on the refined increments ``u`` from ``state0`` (where ``previous``,
    settled on the increments ``coarse``, a subset of ``u``, ended), until they settle
    as those of :func:`_cycles` (``known``: the contraction of the drift measured there):
    ``(Loop, changed, end state, cycles, change)``.

    ``change`` is the path error of the coarser increments: the change of ``D`` from
    ``previous``, the settled cycles of both compared (the change of the shape of ``q``
    at the shared points, relative to its range, counted as the same relative change
    of ``D`` when it exceeds ``rtol``). The error of the round is the largest of the
    quadrature estimate, what is left of the transient and of the path error still to
    come: the change itself where it shrank by half or more from ``last_change`` (the
    previous round's; first order), ``rho / (1 - rho)`` times it where it shrank by
    ``rho`` more slowly, and the larger of the two where it did not shrink; plus
    ``settled_error``, what the intervals no longer refined may still add
    (:func:`_settled_intervals`)."""
    A = previous.amplitude
    if known is not None and known <= ONE_CYCLE_CONTRACTION:
        loop, changed, end = _single_cycle(step, modal, A, state0, u, k_ref, closings)
    else:
        loop, changed, end, _ = _cycles(step, modal, A, state0, u, k_ref, max_cycles,
                                        rtol, atol, closings, known)
    n_solves = previous.n_solves + loop.n_solves
    if not loop.success:
        return replace(loop, first_dissipation=previous.first_dissipation,
                       n_solves=n_solves), changed, end, loop.n_cycles, None
    qs, D = loop.q, loop.dissipation
    at = np.searchsorted(u, coarse)            # the coarse points are among the new ones
    shared = np.concatenate([[0], 1 + at, 1 + len(u) + at])
    shape = _shape_change(qs[shared], previous.q)
    change = abs(D - previous.dissipation)
    if shape > rtol:
        change = max(change, shape * abs(D))
    return replace(loop, first_dissipation=previous.first_dissipation,
                   error=max(loop.error, _path_error(change, last_change, settled_error)),
                   n_cycles=previous.n_cycles, n_solves=n_solves,
                   message=previous.message.split(";")[0]
                   + f"; increments refined ({len(u)} per branch)"), \
        changed, end, loop.n_cycles, change


def _single_cycle(step, modal, A, state0, u, k_ref, closings):
    """One cycle on ``u`` from ``state0``, taken as settled: ``(Loop, changed, end)``."""
    path = cycle_path(A, u)
    out = _one_cycle(step, modal, A, state0, path, closings)
    if out.failure is not None:
        return _failed(A, path[:len(out.q)], out.q, None, 1, out.n_solves,
                       out.failure), None, None
    qs = out.q
    return Loop(A, path, qs, cycle_area(path, qs, k_ref), float("nan"),
                cycle_area_error(path, qs, k_ref), qs[0], qs[len(u)], 1, out.n_solves,
                "stabilised", "stabilised after 1 cycle(s)"), \
        _changed(out.status, len(u)), out.state


def _path_error(change, last_change, settled=0.0):
    """What is left of the path error after a round whose settled cycle changed ``D``
    by ``change``, the round before by ``last_change`` (None: the first round). Halving
    the increments halves the error of a first-order path, so the last change bounds
    what is left when the changes shrink by half or faster; a slower ratio ``rho``
    leaves ``rho / (1 - rho)`` times the last change (a geometric series); changes
    that did not shrink say only that the error is at least the larger one.
    ``settled``: the last changes of the intervals no longer halved
    (:func:`_settled_intervals`), counted with the same factor."""
    if last_change is None or last_change <= 0.0:
        return change + settled
    rho = change / last_change
    if rho >= 1.0:
        return max(change, last_change) + settled
    return (change + settled) * max(1.0, rho / (1.0 - rho))


def _shape_change(q, q_previous):
    """Largest change of ``q`` about its mean between two cycles on the same points,
    relative to the range of ``q``."""
    if len(q) != len(q_previous) or len(q) == 0:
        return np.inf
    diff = np.abs((q - q.mean()) - (q_previous - q_previous.mean())).max()
    return float(diff / max(np.ptp(q), np.finfo(float).tiny))


def _refined(u, changed):
    """Midpoints of the branch intervals where a pair changed state (all if none did)."""
    lo = np.concatenate([[0.0], u[:-1]])
    pick = changed if changed.any() else np.ones_like(changed)
    return np.union1d(u, 0.5 * (lo + u)[pick])


@dataclass(frozen=True, eq=False)
class _Cycle:
    """The solves of one cycle: ``q`` and ``status`` at every point (the start
    included), the end state, the largest interface displacement from the start
    (``span``), the solves spent and, if a solve failed, the message."""

    q: np.ndarray
    status: list
    state: object
    span: float
    n_solves: int
    failure: str | None


class _Closings:
    """The pairs closed at each point of the last cycle solved, per branch: what is
    expected to close at a point of the next cycle, a loop repeating itself. A point
    of a refined cycle that the last one did not have takes the pairs of the last
    one's next point in the direction of travel (the path of a refined cycle holds
    the coarser one's loads exactly). With the states of the last cycle recorded, the
    state it reached at the same load of the same branch is the next cycle's guess
    (:meth:`state`) when ``warm``."""

    def __init__(self, warm=False):
        self.warm = bool(warm)
        self.branches = None
        self.states = None

    def expected(self, path, k):
        """Pairs expected closed at ``path[k]`` (``k >= 1``), or None (no cycle yet)."""
        if self.branches is None:
            return None
        n = (len(path) - 1) // 2
        loads, closed = self.branches[0 if k <= n else 1]
        a = path[k]
        # unloading (first branch): the first load at or below a; reloading: at or above
        i = (np.searchsorted(-loads, -a, side="left") if k <= n
             else np.searchsorted(loads, a, side="left"))
        return closed[i] if i < len(closed) else None

    def state(self, path, k):
        """The state the last cycle reached at the load ``path[k]`` (``k >= 1``) on the
        same branch, or None (no cycle recorded with its states, or no point of the
        last cycle at this load: a new point of a refined cycle)."""
        if self.states is None:
            return None
        n = (len(path) - 1) // 2
        branch = 0 if k <= n else 1
        loads, a = self.branches[branch][0], path[k]
        i = (np.searchsorted(-loads, -a, side="left") if branch == 0
             else np.searchsorted(loads, a, side="left"))
        return self.states[branch][i] if i < len(loads) and loads[i] == a else None

    def record(self, path, status, states=None):
        """The closed pairs of a whole cycle on ``path`` (``status`` at every point,
        the start included) and, if given, its states (every point but the start)."""
        n = (len(path) - 1) // 2
        loads, closed = np.asarray(path[1:], float), np.asarray(status[1:]) != OPEN
        self.branches = ((loads[:n], closed[:n]), (loads[n:], closed[n:]))
        self.states = None if states is None else (states[:n], states[n:])


def _one_cycle(step, modal, A, state0, path, closings=None):
    """Solve the cycle ``path`` (``path[0] = A``, the state ``state0``); with
    ``closings`` (:class:`_Closings`), each solve is told the pairs closed at that
    point of the cycle before, and this cycle is recorded for the next; with
    ``closings.warm``, a solve at a load the cycle before also had starts from the
    state reached there, ``step(alpha, state, closing, guess)``."""
    qs, status, state, span = [modal(state0.d, A)], [state0.status], state0, 0.0
    warm = closings is not None and closings.warm
    states = [] if warm else None
    for k, a in enumerate(path[1:], start=1):
        expected = None if closings is None else closings.expected(path, k)
        guess = closings.state(path, k) if warm else None
        if guess is not None:
            res = step(a, state, expected, guess)
        else:
            res = step(a, state) if expected is None else step(a, state, expected)
        if not res.success:
            return _Cycle(np.array(qs), status, state, span, k,
                          f"loop at A = {A:.6g}: contact solve failed at alpha = {a:.6g}: "
                          f"{res.message} (residual {res.residual:.2e})")
        state = res.state
        qs.append(modal(res.d, a))
        status.append(res.status)
        if warm:
            states.append(state)
        span = max(span, float(np.abs(res.d - state0.d).max()))
    if closings is not None:
        closings.record(path, status, states)
    return _Cycle(np.array(qs), status, state, span, len(path) - 1, None)


def _cycles(step, modal, A, start, u, k_ref, max_cycles, rtol, atol, closings=None,
            known=None):
    """Cycles from ``start`` until one ends in the state it started from (it repeats
    exactly), or the cycles have settled: two successive cycles agree, the dissipation
    within ``rtol |D| + atol`` once multiplied by what a geometric contraction of the
    drift at ``+A`` still has to come (:func:`_remainder_factor`: ``r / (1 - r)`` times
    the last change), and the shape of ``q`` (about its mean) within ``rtol`` of its
    range. The contraction ``r`` is measured over the last three cycles, or over two
    with ``known`` (the one measured on coarser increments of the same loop): until
    then no agreement is taken for settled, since a drift that has shrunk once may
    still add up to many times the last change (the tetrahedral lap joint at A = 4561
    agrees to 0.2 % after two cycles and settles 2 % further on, r = 0.85).
    ``(Loop, changed, end, ratio)`` with ``changed[i]`` whether a pair changed state in
    branch interval ``i`` of the last cycle, ``end`` the state it ended in and
    ``ratio`` the contraction measured (0 for an exact repeat, None if unknown). The
    loop's error is the larger of the quadrature estimate and what is left of the
    transient.

    After ``max_cycles`` cycles the loop goes on only while it visibly converges
    (:func:`_contracting`: the drift of the state at ``+A`` shrinks by
    :data:`CONTRACTION` or more per cycle) and the cycles its contraction predicts
    (:func:`_cycles_needed`) total at most ``CYCLE_CEILING max_cycles``; otherwise it
    is not stabilised, its message saying why and what to change."""
    path = cycle_path(A, u)
    state0, first, previous, drifts, n_solves = start, None, None, [], 0
    cycle, needed, areas = 0, None, []
    while cycle < max_cycles or needed is not None and needed <= CYCLE_CEILING * max_cycles:
        cycle += 1
        out = _one_cycle(step, modal, A, state0, path, closings)
        n_solves += out.n_solves
        if out.failure is not None:
            return _failed(A, path[:len(out.q)], out.q, first, cycle, n_solves,
                           out.failure.replace(":", f", cycle {cycle}:", 1)), \
                None, None, None
        qs, state = out.q, out.state
        D = cycle_area(path, qs, k_ref)
        first = D if first is None else first
        areas.append(D)
        drifts.append(float(np.abs(state.d - state0.d).max(initial=0.0)))
        tol = rtol * abs(D) + atol
        remainder = None
        if _same(state, state0, out.span):
            remainder, ratio = 0.0, 0.0
        elif previous is not None and _shape_change(qs, previous[0]) <= rtol:
            factor = _remainder_factor(drifts, known)
            series = _series_factor(areas)
            if series is not None:
                factor = series if factor is None else min(factor, series)
            if factor is not None and factor * abs(D - previous[1]) <= tol:
                remainder, ratio = factor * abs(D - previous[1]), _measured(drifts, known)
        if remainder is not None:
            error = max(cycle_area_error(path, qs, k_ref), remainder)
            return Loop(A, path, qs, D, first, error, qs[0], qs[len(u)], cycle, n_solves,
                        "stabilised", f"stabilised after {cycle} cycle(s)"), \
                _changed(out.status, len(u)), state, ratio
        needed = None if previous is None or not _contracting(drifts) else \
            cycle + _cycles_needed(drifts, _tail_factor(drifts) * abs(D - previous[1]),
                                   tol)
        previous, state0 = (qs, D), state
    return Loop(A, path, qs, D, first, cycle_area_error(path, qs, k_ref), qs[0], qs[len(u)],
                cycle, n_solves, "not_stabilised", _not_stabilised(A, cycle, needed, drifts)), \
        _changed(out.status, len(u)), state, _measured(drifts, known)


def _not_stabilised(A, cycles, needed, drifts=()):
    """Why a loop stopped without repeating, and what to change: a contraction too slow
    for the cycles allowed (``needed``: the cycles it predicts in all), or a drift that
    does not contract (by how much it changed over the last cycles)."""
    if needed is not None:
        return (f"loop at A = {A:.6g} not stabilised after {cycles} cycles: its drift at "
                f"+A contracts, but too slowly for the cycles allowed: it would repeat "
                f"after about {needed} cycles; raise max_cycles to {needed} or more "
                f"(qsma run --max-cycles, [analysis] max_cycles)")
    ratio = (f" (its drift changed by a factor {_ratio(drifts):.3g} per cycle, slower "
             f"than {CONTRACTION:g})" if len(drifts) >= 3 else "")
    return (f"loop at A = {A:.6g} not stabilised after {cycles} cycles: the state at +A "
            f"still changes and does not converge geometrically{ratio}: ratcheting, or a "
            f"cycle alternating between two states (no steady cycle at this "
            f"amplitude); if it is a very slow shakedown, raise max_cycles "
            f"(qsma run --max-cycles, [analysis] max_cycles)")


def _contracting(drifts):
    """Whether the drift of the state at ``+A`` shrank by :data:`CONTRACTION` or more
    over each of the last two cycles (``drifts[i]``: the largest change of an interface
    displacement over cycle ``i``).

    A drift that contracts geometrically, ``delta_{k+1} <= c delta_k``, sums to a
    finite remaining change ``<= delta_k c / (1 - c)``: the loop converges, so more
    cycles will meet the agreement test; a ratcheting or alternating loop keeps a
    constant drift."""
    return len(drifts) >= 3 and all(
        drifts[i] <= CONTRACTION * drifts[i - 1] for i in (-1, -2))


def _ratio(drifts) -> float:
    """The slower of the last two contractions of the drift, ``delta_k / delta_{k-1}``."""
    tiny = np.finfo(float).tiny
    return max(drifts[-1] / max(drifts[-2], tiny), drifts[-2] / max(drifts[-3], tiny))


def _tail_factor(drifts) -> float:
    """``r / (1 - r)`` (at least 1) for a drift contracting by ``r`` per cycle
    (:func:`_contracting`): the change of ``D`` still to come is about that many times
    the last one (a geometric series); 1 while no contraction is established."""
    if not _contracting(drifts):
        return 1.0
    r = _ratio(drifts)
    return max(1.0, r / (1.0 - r))


def _remainder_factor(drifts, known=None):
    """``r / (1 - r)`` (at least 1) for the contraction ``r`` of the drift, the factor
    from the last change of ``D`` to what is still to come; None while ``r`` is not
    known to be below 1. ``r`` is the slower of the last two ratios of successive
    drifts (three cycles), or with ``known`` (the contraction measured on coarser
    increments of the same loop) the slower of it and the last ratio (two cycles)."""
    r = _measured(drifts, known)
    if r is None or r >= 1.0:
        return None
    return max(1.0, r / (1.0 - r))


def _series_factor(areas):
    """``r / (1 - r)`` (at least 1) for the dissipations of successive cycles when
    they converge geometrically themselves: the last three changes of one sign and
    shrinking, ``r`` the slower of their two ratios; None otherwise. The first cycle
    (from the backbone, or onto new increments) is left out. The change of ``D`` still
    to come is that many times its last change, whatever the drift of the state does
    (it may settle more slowly than the area it encloses: lap-3d with a compliant
    law, drift 0.965 per cycle, ``D`` 0.95)."""
    if len(areas) < 5:
        return None
    changes = np.diff(np.asarray(areas[-4:], dtype=float))
    if not (np.all(changes > 0) or np.all(changes < 0)):
        return None
    size = np.abs(changes)
    r = max(size[2] / size[1], size[1] / size[0])
    if r >= 1.0:
        return None
    return max(1.0, r / (1.0 - r))


def _measured(drifts, known=None):
    """The contraction of the drift as :func:`_remainder_factor` measures it, or None."""
    tiny = np.finfo(float).tiny
    if len(drifts) >= 3:
        return _ratio(drifts)
    if len(drifts) == 2 and known is not None:
        return max(known, drifts[-1] / max(drifts[-2], tiny))
    return None


def _cycles_needed(drifts, change, target) -> int:
    """More cycles until ``change`` (the last change of ``D``, times the tail factor)
    falls to ``target``, if it shrinks as the drift did over the last two cycles (the
    slower of the two ratios r): ``ceil(log(target / change) / log r)``, at least one."""
    r = _ratio(drifts)
    if change <= target or r <= 0:
        return 1
    return max(1, int(np.ceil(np.log(target / change) / np.log(r))))


def _same(a, b, span):
    """Same pair states and interface displacements within :data:`STATE_RTOL` of ``span``."""
    return bool(np.array_equal(a.status, b.status)
                and np.abs(a.d - b.d).max(initial=0.0)
                <= STATE_RTOL * max(span, np.finfo(float).tiny))


def _changed(status, n):
    """Per branch interval: did any pair change state (either branch)?"""
    s = np.asarray(status)
    step = np.any(s[1:] != s[:-1], axis=1)
    return step[:n] | step[n:2 * n]


def _failed(A, path, qs, first, cycle, n_solves, message):
    nan = float("nan")
    q = np.array(qs, dtype=float)
    return Loop(A, np.asarray(path, float), q, nan, nan if first is None else first, nan,
                q[0], nan, cycle, n_solves, "solve_failed", message)


# -- Loops on several processes --------------------------------------------------------

#: How long a run waits for its loop scheduler to answer (:func:`scheduler_client`),
#: as the sweep waits for its own.
SCHEDULER_TIMEOUT = "20s"
#: The job of the worker processes of :func:`map_loops` (inherited at the fork).
_JOB = None


def _call_job(i):
    """``_JOB(i)`` and the warnings it raised, for the parent to raise again."""
    return _call_shipped(_JOB, i)


def map_loops(job, indices, workers=1, done=None, scheduler=None) -> list:
    """``[job(i) for i in indices]``, on ``workers`` processes when ``workers > 1``, or
    on the workers of the Dask scheduler at the address ``scheduler``; ``done(j)``, if
    given, after ``j`` results are in (for progress).

    The levels' loops are independent given the backbone: each starts from the
    backbone state at its amplitude, on the ramps' contact zone, so the loop of a level
    is the same sequence of floating-point operations in whichever process solves it,
    and the results are those of the serial path bit for bit (``tests/test_lap.py``,
    ``tests/test_hysteresis.py``; on a Dask worker, as long as it runs the same numpy
    and BLAS). The largest amplitudes, whose loops take the most solves, are handed out
    first.

    Local workers are forked from this process, so ``job`` (a closure over the contact
    problem and the backbone states) is inherited, not pickled; only the level index
    goes to a worker and its :class:`Loop` comes back, with the warnings it raised
    (raised again here, in the order of ``indices``). The loops run in this process
    instead where forking is not possible or not safe
    (:func:`qsma._forked.fork_refusal`: Windows, a daemonic sweep worker, a thread
    other than the main one). An exception, or a signal handled here, stops the workers
    at once (their loops are abandoned).

    With ``scheduler``, ``job`` is pickled and sent once to every worker of the
    scheduler (:func:`_dask_map`), then each index as a task.
    """
    indices = [int(i) for i in indices]
    done = done or (lambda j: None)
    if scheduler is not None and indices:
        return _dask_map(job, indices, scheduler, done)
    workers = min(int(workers), len(indices))
    why_not = fork_refusal() if workers > 1 else None
    if why_not is not None:
        log.info("loops computed in this process, not on %d workers: %s", workers, why_not)
    if workers <= 1 or why_not is not None:
        out = []
        for i in indices:
            out.append(job(i))
            done(len(out))
        return out
    return _forked_map(job, indices, workers, done)


def _forked_map(job, indices, workers, done):
    """:func:`map_loops` on ``workers`` forked processes."""
    global _JOB
    _JOB = job
    with quiet_fork():
        pool = multiprocessing.get_context("fork").Pool(workers, initializer=default_signals)
    try:
        arrived = queue.SimpleQueue()        # (index, raised, result) as each one ends
        for i in indices[::-1]:
            pool.apply_async(_call_job, (i,),
                             callback=lambda out, i=i: arrived.put((i, False, out)),
                             error_callback=lambda exc, i=i: arrived.put((i, True, exc)))
        return _collected((arrived.get() for _ in indices), indices, done)
    finally:
        pool.terminate()        # idle workers at the end; running ones on an exception
        pool.join()
        _JOB = None


def _collected(arrivals, indices, done):
    """The results of ``indices`` from ``arrivals``, ``(index, raised, outcome)`` in
    the order the loops end (``outcome``: ``(Loop, warnings)``, or the exception it
    raised, raised here at once); ``done`` counts them as they come in, the warnings
    are raised again in the order of ``indices``."""
    got = {}
    for i, raised, outcome in arrivals:
        if raised:
            raise outcome
        got[i] = outcome
        done(len(got))
    for i in indices:
        raise_again(got[i][1])
    return [got[i][0] for i in indices]


def _dask_map(job, indices, scheduler, done):
    """:func:`map_loops` on the workers of the Dask scheduler at ``scheduler`` (an
    address such as ``tcp://host:8786``): ``job`` is scattered to every worker once
    (its contact problem and eliminations travel as they are: nothing is condensed
    there), then one task per index, the largest amplitudes first."""
    from distributed import as_completed
    client = scheduler_client(scheduler)
    try:
        started = time.perf_counter()
        shipped = client.scatter(job, broadcast=True, hash=False)
        log.info("loops: the interface problem sent to %d Dask worker(s) in %.2f s",
                 len(client.scheduler_info()["workers"]), time.perf_counter() - started)
        order = indices[::-1]
        futures = {client.submit(_call_shipped, shipped, i, pure=False,
                                 priority=len(order) - n): i for n, i in enumerate(order)}
        arrivals = ((futures[f], False, f.result()) for f in as_completed(futures))
        return _collected(arrivals, indices, done)
    finally:
        client.close()


def scheduler_client(address):
    """A ``distributed.Client`` of the Dask scheduler at ``address``; an
    :class:`qsma.errors.InputError` naming the fix if ``distributed`` is missing or
    nothing answers there. A run checks its ``loop_scheduler`` so before its ramps."""
    from .errors import InputError
    try:
        from distributed import Client
    except ImportError as exc:      # dask is the optional extra 'sweep'
        raise InputError(f"loops on a Dask scheduler need the 'distributed' package "
                         f"({exc}): pip install 'qsma[sweep]', or drop the loop "
                         f"scheduler") from None
    try:
        return Client(address, timeout=SCHEDULER_TIMEOUT)
    except OSError as exc:
        raise InputError(f"cannot reach the Dask scheduler at {address!r}: {exc}; start "
                         f"one (dask scheduler) or drop --scheduler") from None


def _call_shipped(job, i):
    """``job(i)`` and the warnings it raised, for the caller to raise again (on a
    forked or a Dask worker)."""
    with warnings.catch_warnings(record=True) as seen:
        warnings.simplefilter("always")
        out = job(i)
    return out, recorded_warnings(seen)


# -- Masing ---------------------------------------------------------------------------

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
