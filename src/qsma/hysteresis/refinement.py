"""A stabilised loop with its increments refined to a tolerance: :func:`compute_loop`
drives the cycles (:mod:`.cycles`) on the initial increments, then refinement rounds
on halved increments until the error estimate (:mod:`.estimates`) meets the
tolerance."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from .cycles import _changed, _Closings, _cycles, _one_cycle
from .estimates import (_parents, _path_error, _settled_intervals, _shape_change,
                        cycle_area_error)
from .loop import Loop, _failed, cycle_area, cycle_path

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


def compute_loop(step, modal, amplitude, start, fractions, *, k_ref, max_cycles=8,
                 rtol=5e-3, atol=0.0, refine_rounds=None,
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
        ``refine_rounds`` rounds, each halving the increments where pair states change;
        ``None``: :data:`REFINE_ROUNDS` as it is at the call).
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
    refine_rounds = REFINE_ROUNDS if refine_rounds is None else refine_rounds
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


def _refined(u, changed):
    """Midpoints of the branch intervals where a pair changed state (all if none did)."""
    lo = np.concatenate([[0.0], u[:-1]])
    pick = changed if changed.any() else np.ones_like(changed)
    return np.union1d(u, 0.5 * (lo + u)[pick])
