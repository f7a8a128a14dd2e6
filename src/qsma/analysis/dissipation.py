"""The dissipation per cycle at each level: Masing's rules where their checks hold,
no loop where the cycle is elastic (no pair with friction slipped), the stabilised
loop elsewhere (:mod:`qsma.hysteresis`), collected in a :class:`Dissipation`."""
from __future__ import annotations

from dataclasses import dataclass, field, replace
import logging
import time

import numpy as np

from .._infra.threads import blas_threads as threads_limited
from ..contact import OPEN, SLIPPING
from ..contact.zone import ContactZone
from ..hysteresis import compute_loop, loop_area, map_loops, masing_checks, masing_estimate
from ..progress import Progress
from .checks import ZETA_ZERO
from .options import RunOptions
from .result import DirectLoop
from .solves import _Solver

log = logging.getLogger("qsma")


@dataclass(eq=False)
class Dissipation:
    """The dissipation per cycle at each of the user's levels, by Masing's rules and by
    the computed loop (NaN where not computed), and which of them the level uses, or
    that its cycle is elastic.

    A field named like a column of the level table (:class:`qsma.analysis.result.LevelTable`)
    is that column: the run takes it from here (:meth:`columns`). The arrays are
    settled in place where a value is zero to the precision it was computed with
    (:func:`qsma.analysis.checks._settle_dissipation`).

    Attributes
    ----------
    f_hz_masing, zeta_masing, dissipation_masing, masing_error : (n,) arrays
        Masing's rules on the +alpha backbone, with the error estimate of the dissipation.
    f_hz_loop, zeta_loop, dissipation_loop, loop_error : (n,) arrays
        The stabilised loop (NaN where none was computed or it failed).
    dissipation_first_cycle : (n,) array
        ``D`` of the loop's first cycle.
    loop_cycles : (n,) int array
        Cycles of the loop on its initial increments (0: no loop).
    shakedown : (n,) bool array
        The first cycle or the first loadings differ from the settled cycle.
    use_loop : (n,) bool array
        The level reports the loop (else Masing's rules, or the elastic cycle).
    method_reason : (n,) object array
        Why the level uses the method it does.
    no_slip : (n,) bool array
        No pair with friction slipped on either ramp up to the level (``D = 0`` exactly).
    linear : (n,) bool array
        No pair has left its preload state on either ramp up to the level.
    elastic : (n,) bool array
        The level reports the elastic cycle, without a loop: Masing's checks failed, but
        no pair with friction slipped on either ramp up to it (:func:`_elastic_cycle`).
        ``D = 0`` exactly; the frequency is the loop's peak-to-peak secant of the two
        backbones, which the cycle retraces (``f_hz_elastic``, NaN elsewhere).
    loops : dict
        Level index -> :class:`qsma.hysteresis.Loop` of the levels whose loop was computed.
    n_solves : int
        Contact solves of all the loops.
    """

    f_hz_masing: np.ndarray
    zeta_masing: np.ndarray
    dissipation_masing: np.ndarray
    masing_error: np.ndarray
    f_hz_loop: np.ndarray
    zeta_loop: np.ndarray
    dissipation_loop: np.ndarray
    loop_error: np.ndarray
    dissipation_first_cycle: np.ndarray
    loop_cycles: np.ndarray
    shakedown: np.ndarray
    use_loop: np.ndarray
    method_reason: np.ndarray
    no_slip: np.ndarray
    linear: np.ndarray
    elastic: np.ndarray = None
    f_hz_elastic: np.ndarray = None
    loops: dict = field(default_factory=dict)
    n_solves: int = 0

    def __post_init__(self):
        n = len(self.use_loop)
        if self.elastic is None:
            self.elastic = np.zeros(n, bool)
        if self.f_hz_elastic is None:
            self.f_hz_elastic = np.full(n, np.nan)

    def _chosen(self, masing, loop, elastic=0.0):
        return np.where(self.use_loop, loop, np.where(self.elastic, elastic, masing))

    @property
    def f_hz(self) -> np.ndarray:
        """Secant frequency of the method each level uses."""
        return self._chosen(self.f_hz_masing, self.f_hz_loop, self.f_hz_elastic)

    @property
    def zeta(self) -> np.ndarray:
        """Damping ratio of the method each level uses."""
        return self._chosen(self.zeta_masing, self.zeta_loop)

    @property
    def dissipation(self) -> np.ndarray:
        """Dissipation per cycle of the method each level uses."""
        return self._chosen(self.dissipation_masing, self.dissipation_loop)

    @property
    def dissipation_error(self) -> np.ndarray:
        """Error estimate of :attr:`dissipation`."""
        return self._chosen(self.masing_error, self.loop_error)

    @property
    def dissipation_method(self) -> np.ndarray:
        """``"loop"``, ``"elastic"`` or ``"masing"`` per level."""
        return np.where(self.use_loop, "loop",
                        np.where(self.elastic, "elastic", "masing")).astype(object)

    @property
    def masing_unused(self) -> np.ndarray:
        """The level reports another value than Masing's (a loop or the elastic cycle)."""
        return self.use_loop | self.elastic

    def columns(self, names) -> dict:
        """The values of the level-table columns ``names`` held here (fields and the
        chosen values above), by name."""
        return {name: getattr(self, name) for name in names if hasattr(self, name)}


def level_dissipation(solver, response, grid, user, pos, neg, pre, opts, k_ref,
                      report=None, threads=None) -> Dissipation:
    """The :class:`Dissipation` at the user's levels: Masing's estimates and checks,
    and the loops where the checks fail or ``opts.dissipation`` asks for them;
    ``threads``: the BLAS thread limit of the loops' contact solves."""
    n_ok, n = len(user), pos.n
    est = masing_estimate(grid, pos.q, k_ref)
    nn = min(n, neg.n)
    q_neg = np.full(n, np.nan)
    q_neg[:nn] = neg.q[:nn]
    P_pre, open_pre = pre.lam[:, -1], pre.status == OPEN
    P_neg = np.full((n, len(P_pre)), np.nan)
    P_neg[:nn] = neg.lam[:nn, :, -1]
    neg_status = np.broadcast_to(pre.status, (n, len(P_pre))).copy()
    neg_status[:nn] = neg.status[:nn]
    open_neg = neg_status == OPEN
    atol = ZETA_ZERO * 2 * np.pi * grid * np.abs(pos.q)
    linear = _untouched(pos.status, pre) & _untouched(neg_status, pre)
    checks = masing_checks(grid, pos.q, np.where(np.isnan(q_neg), -pos.q, q_neg),
                           pos.lam[:, :, -1], np.where(np.isnan(P_neg), P_pre, P_neg), P_pre,
                           pos.status == OPEN, open_neg, open_pre, k_ref,
                           opts.dissipation_rtol, atol, linear=linear)
    valid = checks.valid.copy()
    valid[nn:] = False                 # no negative backbone there: nothing verified
    reason = np.where(valid, np.where(linear, "linear: no pair has left its preload state",
                                      "Masing's assumptions verified"),
                      checks.reason).astype(object)
    reason[~valid & (checks.reason == "")] = "negative ramp failed: symmetry not verified"
    no_slip = _no_rubbing(solver.problem.mu, pos.status, neg_status, nn)
    elastic = np.zeros(n, bool)
    if opts.dissipation == "masing":
        use_loop = np.zeros(n, bool)
        reason = np.array([r if v else f"forced by dissipation='masing' although {r}"
                           for r, v in zip(reason, valid)], dtype=object)
    elif opts.dissipation == "loop":
        use_loop = np.ones(n, bool)
        reason = np.full(n, "forced by dissipation='loop'", dtype=object)
    else:
        elastic = _elastic_cycle(valid, no_slip, q_neg)
        reason[elastic] = [f"elastic: no pair with friction slipped on either ramp, the "
                           f"cycle retraces both backbones ({r})" for r in reason[elastic]]
        use_loop = ~valid & ~elastic
    f_elastic = np.full(n, np.nan)
    f_elastic[elastic] = np.sqrt(2 * grid[elastic] / (pos.q[elastic] - q_neg[elastic])) \
        / (2 * np.pi)
    nan = np.full(n_ok, np.nan)
    out = Dissipation(
        f_hz_masing=est.omega[user] / (2 * np.pi), zeta_masing=est.zeta[user],
        dissipation_masing=est.dissipation[user], masing_error=est.error[user],
        f_hz_loop=nan.copy(), zeta_loop=nan.copy(), dissipation_loop=nan.copy(),
        loop_error=nan.copy(), dissipation_first_cycle=nan.copy(),
        loop_cycles=np.zeros(n_ok, int), shakedown=np.zeros(n_ok, bool),
        use_loop=use_loop[user], method_reason=reason[user], no_slip=no_slip[user],
        linear=linear[user], elastic=elastic[user], f_hz_elastic=f_elastic[user])
    todo = np.flatnonzero(out.use_loop)
    job = _LevelLoops(solver.layer, _InterfaceLoads.of(solver.reduced), solver.method,
                      solver.opts, _outermost(solver.zone), response, grid, user, pos,
                      neg_status,
                      _linear_end(pos, pre), opts, k_ref, threads)
    report = report or Progress()
    report.task("loops", len(todo))
    done = lambda j: report.advance("loops", j, len(todo))
    run_on = opts.execution
    loops = map_loops(job, todo, run_on.loop_worker_count, done, run_on.loop_scheduler)
    for i, lp in zip(todo, loops):
        out.loops[i] = lp
        out.n_solves += lp.n_solves
        log.info("level %d: loop at A=%.4g, %s, %d solves in %d cycles, %.2f s, "
                 "D=%.4g +- %.1g", i, lp.amplitude, lp.message, lp.n_solves,
                 lp.n_cycles + lp.refinement_cycles, lp.seconds, lp.dissipation, lp.error)
        out.loop_cycles[i] = lp.n_cycles
        if lp.success:
            out.f_hz_loop[i] = lp.omega / (2 * np.pi)
            out.zeta_loop[i] = lp.zeta
            out.dissipation_loop[i] = lp.dissipation
            out.loop_error[i] = lp.error
            out.dissipation_first_cycle[i] = lp.first_dissipation
            out.shakedown[i] = lp.shakedown or _first_loading_differs(
                lp, pos.q[user[i]], q_neg[user[i]], opts.dissipation_rtol)
    return out


@dataclass(frozen=True, eq=False)
class _InterfaceLoads:
    """What the contact solves of a run read of its reduced model: the welded force per
    load pattern (``W``, ``patterns``) and the regularising spring of bodies held only
    by the joint with their names (:func:`qsma.rigid.held_by_joint`). Small enough to
    ship to another process, where the bodies' factorisations could not go."""

    W: np.ndarray
    patterns: tuple
    ghost: object
    bodies: tuple

    @classmethod
    def of(cls, reduced):
        bodies = tuple(_HeldBody(b.name, getattr(b, "rigid", None))
                       for b in getattr(reduced, "bodies", ()))
        return cls(reduced.W, tuple(reduced.patterns), getattr(reduced, "ghost", None),
                   bodies)


@dataclass(frozen=True)
class _HeldBody:
    """A body's name and its rigid motions free of clamps (None: clamped)."""

    name: str
    rigid: object


@dataclass(frozen=True, eq=False)
class _LevelLoops:
    """The loop of a level given the backbones: a job of
    :func:`qsma.hysteresis.map_loops`, called with the level's index.

    Holds everything a loop reads: the interface's contact problem (in ``layer``),
    the ramps' contact zone with its eliminations, the backbone states and the options;
    not the bodies or their factorisations, so that it can be shipped to the workers of
    a Dask scheduler as it is (pickled; nothing is condensed again there). Every loop
    starts from a solver of its own on the ramps' zone and layer, so that its bits do
    not depend on the loops solved before it, nor on the process solving it.
    """

    layer: object
    loads: _InterfaceLoads
    method: str
    solver_options: dict
    zone: object
    response: object
    grid: np.ndarray
    user: np.ndarray
    pos: object
    neg_status: np.ndarray
    linear_end: int
    opts: RunOptions
    k_ref: float
    threads: object

    def __call__(self, i):
        g = self.user[i]
        A = self.grid[g]
        u = _loop_fractions(self.grid, g, self.linear_end, self.opts.loop_steps)
        zone = _loop_zone(self.zone, self.pos.status[:g + 1], self.neg_status[:g + 1])
        solver = _Solver(self.layer, self.loads, self.method, self.solver_options, zone)

        def step(a, s, closing=None, guess=None):
            solver.guess = guess        # the state at this load a cycle before, or None
            return solver(a, s, f"loop at A={A:.4g} (alpha={a:.4g})", closing)

        started = time.perf_counter()
        with threads_limited(self.threads):
            lp = compute_loop(step, self.response.q, A, self.pos.state(g), u,
                              k_ref=self.k_ref, max_cycles=self.opts.max_cycles,
                              rtol=self.opts.dissipation_rtol,
                              atol=ZETA_ZERO * 2 * np.pi * A * abs(self.pos.q[g]),
                              expect_closing=True, warm_start=True)
        return replace(lp, seconds=time.perf_counter() - started)


def _no_rubbing(mu, pos_status, neg_status, n_neg) -> np.ndarray:
    """Per ramp point: no pair with friction (mu > 0) slips on either ramp up to it. A
    cycle within that range is elastic (opening and closing store energy, only
    friction dissipates), so its dissipation is exactly zero. Points beyond the
    ``n_neg`` solved points of the -alpha ramp are not known to be so."""
    rubbing = np.broadcast_to(np.asarray(mu, float) > 0, pos_status.shape[1:])
    slips = np.any((pos_status == SLIPPING) & rubbing, axis=1) | \
        np.any((neg_status == SLIPPING) & rubbing, axis=1)
    slips[n_neg:] = True
    return ~np.logical_or.accumulate(slips)


def _elastic_cycle(valid, no_slip, q_neg) -> np.ndarray:
    """Per ramp point: the cycle is elastic and needs no loop. Where Masing's checks
    failed (``valid`` false) but no pair with friction slipped on either ramp up to the
    point (``no_slip``), every pair with friction stuck and the frictionless ones slid
    without dissipating: the state at each load is the unique minimiser of the elastic
    energy under the contact constraints, whatever the path, so a cycle between -A and
    +A retraces the -alpha and the +alpha backbone, from the first cycle on, and
    encloses no area. Needs the -alpha backbone there (``q_neg`` finite, negative)."""
    with np.errstate(invalid="ignore"):
        below = q_neg < 0
    return ~valid & no_slip & below


def _first_loading_differs(lp, q_top, q_bottom, rtol) -> bool:
    """Whether the stabilised loop turns elsewhere than the first loadings to ``+A`` and
    ``-A`` (the backbones' ``q_top``, ``q_bottom``) by more than ``rtol`` of its
    half-range: the ramps slipped where the cycle does not (pairs left at the friction
    limit by the preload slide once, then the cycle is elastic). The level's ``q`` and
    ``tip`` are then those of the first loading and its ``f`` and ``zeta`` those of the
    settled cycle: a shakedown, flagged as one."""
    off = max(abs(lp.q_top - q_top), abs(lp.q_bottom - q_bottom) if np.isfinite(q_bottom)
              else 0.0)
    return bool(off > rtol * abs(lp.q_amplitude))


def _with_closed(zone, status):
    """``zone`` grown by the pairs closed at some point of ``status`` (a ramp's states,
    levels x pairs) outside it: the -alpha ramp is solved with a solver of its own
    (:class:`_NegativeRamp`), so the pairs only it closed join the ramps' zone here,
    before the loops are carved out of it (:func:`_loop_zone`)."""
    if zone is None or isinstance(zone, str) or len(status) == 0:
        return zone
    outside = np.any(np.asarray(status) != OPEN, axis=0) & ~zone.keep
    return zone.grown(outside) if outside.any() else zone


def _outermost(zone):
    """``zone`` reduced to its outermost elimination, all the loops carve theirs from
    (:func:`_loop_zone`): what a loop needs of it, and no more to ship."""
    if zone is None or isinstance(zone, str):
        return zone
    outer = zone.steps[0]
    return ContactZone(zone.full, outer.keep, (outer,))


def _loop_zone(zone, *statuses):
    """The zone of a loop: the pairs closed anywhere on either backbone up to its
    amplitude, carved out of the ramps' zone (which holds every pair closed on them).
    The elimination is exact; a pair that closes only within the loop joins the zone
    when it closes (:func:`qsma.contact.zone.solve_in_zone`)."""
    if zone is None or isinstance(zone, str):
        return zone
    keep = np.zeros_like(zone.keep)
    for status in statuses:
        keep |= np.any(np.asarray(status) != OPEN, axis=0)
    return zone.narrowed(keep & zone.steps[0].keep)


def _untouched(status, pre):
    """Per ramp point: no pair has left its preload state (status) up to it; a slipping
    pair in the preload counts as moved."""
    same = np.all(status == pre.status[None, :], axis=1) & \
        np.all(status != SLIPPING, axis=1)
    return np.cumprod(same).astype(bool)


def _linear_end(pos, pre):
    """Index of the last ramp point before any pair left its preload state (the
    backbone is the tied linear response up to it), or -1."""
    same = np.all(pos.status == pre.status[None, :], axis=1) & \
        np.all(pos.status != SLIPPING, axis=1)
    moved = np.flatnonzero(~same)
    return (moved[0] if moved.size else pos.n) - 1


#: Fewest increments per loop branch: a loop at one of the first backbone points has
#: few points below it to mirror, and a branch of one increment has no area.
MIN_LOOP_STEPS = 8


def _loop_fractions(grid, g, linear_end, steps):
    """Branch increments of the loop at grid point ``g`` as fractions of ``2A``: the
    backbone points below it (Masing's construction unloads by twice each), from the
    end of the linear range, thinned to at most ``steps``, with at least
    :data:`MIN_LOOP_STEPS` (uniform ones added where the backbone has fewer)."""
    start = max(min(linear_end, g - 1), 0)
    u = grid[start:g + 1] / grid[g]
    if len(u) > steps:
        keep = np.unique(np.round(np.linspace(0, len(u) - 1, steps)).astype(int))
        u = u[keep]
    if len(u) < MIN_LOOP_STEPS:
        u = np.union1d(u, np.linspace(0.0, 1.0, MIN_LOOP_STEPS + 1)[1:])
    return u


def _direct_loop(solver, response, grid, top, pos, d_masing):
    """The first cycle at the largest level: unload from +alpha_max to -alpha_max and
    reload, by twice each backbone point below it (Masing's construction), so that its
    area equals Masing's wherever Masing is exact. Stops at the first step whose contact
    solve fails: the points before it are kept, no area is given."""
    amax = grid[top]
    steps = np.concatenate([[0.0], 2 * grid[:top + 1]])
    path = np.concatenate([amax - steps, -amax + steps[1:]])
    state, qs, ts = pos.state(top), [], []
    for a in path:
        res = solver(a, state, f"direct loop (alpha={a:.4g})")
        if not res.success:
            n = len(qs)
            return DirectLoop(path[:n], np.array(qs), np.array(ts), None, d_masing, False,
                              f"direct loop stopped at alpha={a:.6g} (step {n} of "
                              f"{len(path)}): {res.message}; residual {res.residual:.2e}")
        state = res.state
        qs.append(response.q(res.d, a))
        ts.append(response.tip(res.d, a))
    qs, ts = np.array(qs), np.array(ts)
    return DirectLoop(path, qs, ts, loop_area(qs, path), d_masing, True, "loop closed")
