"""The cycle driver: cycles from a backbone state until the loop repeats or settles,
with the contraction of its drift measured to tell a converging shakedown from
ratcheting (docs/theory.md section 7)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..contact.state import OPEN
from .estimates import _shape_change, cycle_area_error
from .loop import Loop, _failed, cycle_area, cycle_path

#: Relative tolerance on the interface displacements for "the cycle ended in the state
#: it started from" (relative to the displacement range of the cycle). The contact
#: solves meet 1e-10 (qsma.contact.DEFAULT_TOL); 1e-7 leaves three decades of margin.
STATE_RTOL = 1e-7
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
