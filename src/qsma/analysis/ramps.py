"""The monotonic ramps of a run: the +alpha ramp on the user's levels refined where
the Masing integral needs it, and the -alpha ramp on the final grid (on a forked
process while the last refinement round runs)."""
from __future__ import annotations

from dataclasses import dataclass
import logging
import time

import numpy as np

from .._infra.forked import ChildFailed, ForkedCall, fork_refusal, second_core_refusal
from ..contact import ContactState
from ..contact.zone import expected_closing
from ..hysteresis import masing_estimate
from .checks import ZETA_ZERO
from .solves import _Solver

log = logging.getLogger("qsma")

#: Rounds of backbone level refinement (each inserts midpoints where needed).
LEVEL_REFINE_ROUNDS = 3
#: Largest ratio of a ramp's next load increment to its last one over which the pairs
#: about to close are extrapolated (:func:`_expected_closing`): the refined grids step
#: by 0.5 to 2 times the last increment; across a larger jump a straight line says
#: little.
EXPECT_MAX_RATIO = 4.0


@dataclass
class _RampOut:
    """A ramp's solutions, one row per point of its grid that was solved."""

    d: np.ndarray
    lam: np.ndarray
    status: np.ndarray
    residual: np.ndarray
    nit: np.ndarray
    ok: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    fallback: list
    success: bool
    message: str
    failed_at: int | None
    work: "_Tally | None" = None

    @property
    def n(self):
        return len(self.q)

    def state(self, k):
        return ContactState(self.d[k], self.lam[k], self.status[k])


def _ramp(solver, alpha, start, keep_going, progress, where="load level", response=None,
          prefix=None, guesses=None, work=None):
    """Monotonic ramp through ``alpha`` from ``start``; ``prefix`` (a :class:`_RampOut`
    and its length) reuses levels already solved on the same path; ``guesses`` maps a
    level to a state to start its iteration from (the same level solved on a coarser
    grid: the path differs, so the level is solved again, but from near its answer),
    handed to a :class:`_Solver` as its ``guess``. ``work``: the :class:`_Tally` each
    solve is counted in (a new one if None), returned as the ramp's ``work``."""
    work = _Tally() if work is None else work
    rows = {k: [] for k in ("d", "lam", "status", "residual", "nit", "ok", "q", "tip")}
    fallback, success, message, failed = [], True, "all levels converged", None
    state, first = start, 0
    if prefix is not None:
        old, first = prefix
        for name in rows:
            rows[name] = list(getattr(old, name)[:first])
        fallback = [k for k in old.fallback if k < first]
        if first:
            state = old.state(first - 1)
    for k in range(first, len(alpha)):
        a = alpha[k]
        if guesses is not None:
            solver.guess = guesses.get(float(a))      # read (and cleared) by the solve
        started = time.perf_counter()
        res = solver(a, state, f"{where} {k} (alpha={a:.4g})",
                     _expected_closing(solver.problem, alpha, k, rows))
        work.add(a, time.perf_counter() - started)
        if not res.success:
            success = False
            failed = k if failed is None else failed
            message = (f"contact solve failed at {where} {k} (alpha={a:.6g}): "
                       f"{res.message}; residual {res.residual:.2e}")
            if not keep_going:
                break
        if res.fallback is not None:          # set by the contact method registry
            fallback.append(k)
            log.info("%s %d: solver fell back: %s", where, k, res.message)
        for name, v in (("d", res.d), ("lam", res.lam), ("status", res.status),
                        ("residual", res.residual), ("nit", res.nit), ("ok", res.success)):
            rows[name].append(v)
        rows["q"].append(response.q(res.d, a) if response else np.nan)
        rows["tip"].append(response.tip(res.d, a) if response else np.nan)
        state = res.state
        if progress is not None:
            progress(k + 1, len(alpha))
    n = len(rows["q"])
    arr = {k: np.array(v) for k, v in rows.items()}
    shape = (n,) + start.d.shape
    return _RampOut(arr["d"].reshape(shape), arr["lam"].reshape(shape),
                    arr["status"].reshape(n, len(start.status)).astype(int),
                    arr["residual"].astype(float), arr["nit"].astype(int),
                    arr["ok"].astype(bool), arr["q"].astype(float),
                    arr["tip"].astype(float), fallback, success, message, failed, work)


class _Tally:
    """The contact solves of a ramp, by the modal force of each: its level's share of
    the run's work (:func:`_level_costs`); a refinement round's re-solves count again."""

    def __init__(self):
        self.alpha, self.seconds = [], []

    def add(self, alpha, seconds):
        self.alpha.append(abs(float(alpha)))
        self.seconds.append(float(seconds))

    def per_level(self, levels):
        """``(solves, seconds)`` per level of the increasing ``levels``: each solve
        counts at the first level at or above its ``|alpha|`` (the interval it refines
        or reaches the level through); solves beyond the last level are not counted."""
        at = np.searchsorted(np.asarray(levels, float), self.alpha, side="left")
        inside = at < len(levels)
        solves = np.bincount(at[inside], minlength=len(levels))
        seconds = np.bincount(at[inside], np.asarray(self.seconds)[inside],
                              minlength=len(levels))
        return solves.astype(int), seconds.astype(float)


def _expected_closing(problem, alpha, k, rows):
    """Pairs expected to close at level ``k`` of a ramp, extrapolated from the two
    converged levels before it (:func:`qsma.contact.zone.expected_closing`), or None
    (fewer than two, a failed one, or a next increment that is not 0 to
    :data:`EXPECT_MAX_RATIO` times the last one: a grid that turns back or jumps)."""
    if k < 2 or not (rows["ok"][k - 1] and rows["ok"][k - 2]):
        return None
    last = alpha[k - 1] - alpha[k - 2]
    ratio = (alpha[k] - alpha[k - 1]) / last if last != 0 else 0.0
    if not 0 < ratio <= EXPECT_MAX_RATIO:
        return None
    return expected_closing(problem, rows["d"][k - 2], rows["d"][k - 1], ratio)


class _NegativeRamp:
    """The -alpha ramp on the final backbone grid, from the contact zone that the
    +alpha ramp had when it chose that grid.

    The last refinement round of the +alpha ramp and this ramp need the same grid and
    nothing of each other. :meth:`start`, called with the grid of the last round before
    that round is solved, forks a child process that solves this ramp while the round
    runs here (``RunOptions.parallel_ramps``, on Linux where
    :func:`qsma._forked.fork_refusal` allows it). :meth:`result` takes the child's
    ramp if it was solved on the grid finally kept, and otherwise (no last round, a
    round that failed and kept the coarser grid, no fork, a child that failed) solves
    it here from the same zone: either way the same floating-point operations, the
    same bits. The ramp has a solver of its own; the pairs it closed join the +alpha
    ramp's zone afterwards (:func:`_with_closed`), which the loops start from."""

    def __init__(self, solver, response, pre, fork):
        self.solver, self.response, self.pre, self.fork = solver, response, pre, fork
        self.zone = self.grid = self.child = None

    def start(self, grid):
        self.zone, self.grid = self.solver.zone, np.array(grid, dtype=float)
        if not self.fork:
            return
        why_not = fork_refusal() or second_core_refusal()
        if why_not is not None:
            log.info("negative ramp solved after the positive one: %s", why_not)
            return
        self.child = ForkedCall(lambda: self._solved(self.grid))

    def result(self, grid):
        """The -alpha ramp on ``grid``."""
        if self.grid is None:                    # no last round: the zone is the last one
            self.zone = self.solver.zone
        if self.child is not None and np.array_equal(grid, self.grid):
            try:
                return self.child.result()
            except ChildFailed as exc:
                log.warning("negative ramp solved again in this process: %s", exc)
            finally:
                self.child = None
        self.cancel()
        return self._solved(grid)

    def cancel(self):
        if self.child is not None:
            self.child.cancel()
            self.child = None

    def _solved(self, grid):
        s = self.solver
        solver = _Solver(s.layer, s.reduced, s.method, s.opts, self.zone)
        return _ramp(solver, -np.asarray(grid, dtype=float), self.pre.state, True, None,
                     "negative load level", response=self.response)


def _refined_backbone(solver, alpha, pre, opts, report, response, k_ref, last_round=None):
    """The +alpha ramp on the user's levels, then on a grid refined where the Masing
    integral needs it (pair states change in an interval, or the error estimate exceeds
    ``dissipation_rtol``). Returns ``(grid, user_index, ramp)``: ``grid[user_index]``
    are the user's levels that were solved. ``last_round(grid)``, optional, is called
    with the grid of the last refinement round before that round is solved (the
    grid kept unless the round fails)."""
    grid = np.asarray(alpha, float)
    report.task("levels", len(alpha))
    tick = lambda k, n: report.advance("levels", min(k, len(alpha)), len(alpha))
    out = _ramp(solver, grid, pre.state, opts.continue_on_failure, tick, response=response)
    work = out.work
    rounds = LEVEL_REFINE_ROUNDS if opts.refine_levels and out.success else 0
    for r in range(rounds):
        new = _insert_levels(grid, out, k_ref, opts.dissipation_rtol, pre.status)
        if new is None:
            break
        first = int(np.flatnonzero(new[:len(grid)] != grid)[0]) if not np.array_equal(
            new[:len(grid)], grid) else len(grid)
        if last_round is not None and r == rounds - 1:
            last_round(new)
        report.task("refinement", len(new))
        trial = _ramp(solver, new, pre.state, False,
                      lambda k, n: report.advance("refinement", k, n), response=response,
                      prefix=(out, first),
                      guesses={float(grid[j]): out.state(j) for j in range(first, out.n)
                               if out.ok[j]}, work=work)
        if not trial.success:          # keep the converged coarser grid
            break
        grid, out = new, trial
        log.info("backbone refined to %d points", len(grid))
    user = np.flatnonzero(np.isin(grid, np.asarray(alpha, float)))
    user = user[user < out.n]
    if not opts.continue_on_failure and not out.success:
        user = user[user < out.failed_at] if out.failed_at is not None else user
    return grid, user, out


def _insert_levels(grid, out, k_ref, rtol, pre_status):
    """The grid with midpoints inserted where the backbone needs them, or None.

    The interval ending at point ``k`` is ``(k-1, k]``, the first one ``(0, alpha_0]``
    from the preload; it is halved where a pair changed state across it or where the
    error estimate at ``k`` (which covers ``(k-2, k]``) or at ``k+1`` is too large."""
    n = out.n
    est = masing_estimate(grid[:n], out.q, k_ref)
    atol = ZETA_ZERO * 2 * np.pi * grid[:n] * np.abs(out.q)
    need = est.error > rtol * np.abs(est.dissipation) + atol
    before = np.concatenate([pre_status[None, :], out.status[:-1]])
    changed = np.any(out.status != before, axis=1)
    pick = need | changed
    pick[:-1] |= need[1:]
    if not pick.any():
        return None
    lo = np.concatenate([[0.0], grid[:n - 1]])
    return np.union1d(grid, 0.5 * (lo + grid[:n])[pick])
