"""Computed hysteresis loops against closed forms where Masing's rules fail.

The lumped system: a unit mass (mass-normalised mode phi = 1, so the modal force is
alpha and q = x) held to ground by a linear spring k0, a Jenkins element (spring k in
series with a frictional slider of strength F_s = mu P0) and a unilateral spring k_u
that touches a stop after a gap g (contact closing under load: the joint stiffens).
Condensed onto the slider s and the contact node c of the unilateral spring, the mass
x is the interior DOF:

    K = [[k0+k+ku, -k, -ku], [-k, k, 0], [-ku, 0, ku]] on (x, s, c),  F = (alpha, 0, 0)
    Kc = K_CC - K_CE K_EE^-1 K_EC,  Fc = (k, ku) alpha / kt,  kt = k0 + k + ku
    x = (alpha + k s + ku c) / kt

Closed forms of the stabilised cycle between -A and +A (the slider slips at both ends):
at +A, k0 x_max + F_s + ku max(x_max - g, 0) = A; at -A, k0 x_min - F_s = -A; the
unilateral spring stores and returns energy, the slider dissipates
D = 2 F_s (x_max - x_min - 2 F_s / k), and the peak-to-peak secant stiffness is
2 A / (x_max - x_min).
"""
import multiprocessing
import os
import threading
import time
import warnings

import numpy as np
import pytest

from qsma.contact import OPEN, ContactProblem, solve
from qsma.errors import InputError
from qsma._infra.forked import parallel_available
from qsma.hysteresis import compute_loop, cycle_area, map_loops, masing_checks, masing_estimate
from qsma.analysis.options import RunOptions

k0, k, ku, g, kn, mu, P0 = 1.0e6, 3.0e6, 4.0e6, 2.0e-4, 1.0e9, 0.5, 400.0
Fs = mu * P0
kt = k0 + k + ku


def _problem(pre_shear=0.0):
    """ContactProblem of the lumped system and its welded force per alpha.

    Pair 0: slider (t = s, n = a stiff decoupled normal carrying P0). Pair 1: the stop
    (t = a decoupled dummy, n = -c: opening w = g - c). ``pre_shear``: a constant shear
    on the slider (what a preload can leave)."""
    Kc = np.array([[k - k * k / kt, -k * ku / kt], [-k * ku / kt, ku - ku * ku / kt]])
    K = np.zeros((4, 4))
    K[0, 0], K[0, 3], K[3, 0], K[3, 3] = Kc[0, 0], -Kc[0, 1], -Kc[1, 0], Kc[1, 1]
    K[1, 1], K[2, 2] = kn, kn
    problem = ContactProblem(K, [mu, 0.0], gap0=[0.0, g])

    def lam_w(alpha):
        return np.array([[-k * alpha / kt + pre_shear, P0], [0.0, ku * alpha / kt]])
    return problem, lam_w


def _modal(d, alpha):
    return (alpha + k * d[0, 0] - ku * d[1, 1]) / kt


def _stepper(problem, lam_w):
    def step(alpha, state):
        res = solve(problem, lam_w(alpha), state)
        assert res.success, res.message
        return res
    return step


def _ramp(problem, lam_w, alphas):
    state, q, out = None, [], []
    for a in alphas:
        res = solve(problem, lam_w(a), state)
        assert res.success
        state = res.state
        q.append(_modal(res.d, a))
        out.append(res)
    return np.array(q), out


def _x_max(A):
    x = (A - Fs) / k0
    return x if x <= g else (A - Fs + ku * g) / (k0 + ku)


def _exact(A):
    x_max, x_min = _x_max(A), (-A + Fs) / k0
    return 2 * Fs * (x_max - x_min - 2 * Fs / k), 2 * A / (x_max - x_min), x_max, x_min


def _kinks(A):
    """Fractions u of 2A at which the cycle's branches change slope (exact events)."""
    x_max, x_min = _exact(A)[2:]
    alpha_of = lambda x, fJ: k0 * x + fJ + ku * max(x - g, 0.0)
    down = [alpha_of(x_max - 2 * Fs / k, -Fs)]
    up = [alpha_of(x_min + 2 * Fs / k, Fs)]
    if x_max > g:
        down.append(alpha_of(g, Fs - k * (x_max - g)))
        xg = g
        fJ = -Fs + k * (xg - x_min)
        up.append(alpha_of(xg, min(fJ, Fs)))
    u = [(A - a) / (2 * A) for a in down] + [(a + A) / (2 * A) for a in up]
    return np.array(u)


@pytest.mark.parametrize("A", [900.0, 1600.0])
def test_loop_matches_closed_form_where_masing_fails(A):
    """With the kinks among the increments the trapezoidal rule is exact: D and the
    secant stiffness to 1e-8 (A = 900: stop not reached; 1600: the stop closes)."""
    problem, lam_w = _problem()
    step = _stepper(problem, lam_w)
    q, res = _ramp(problem, lam_w, [A])
    u = np.union1d(np.linspace(0, 1, 9)[1:], _kinks(A))
    loop = compute_loop(step, _modal, A, res[-1].state, u, k_ref=kt, refine_rounds=0)
    D, k_sec, x_max, x_min = _exact(A)
    assert loop.success and loop.stabilised and loop.n_cycles == 1
    assert loop.dissipation == pytest.approx(D, rel=1e-8)
    assert loop.omega ** 2 == pytest.approx(k_sec, rel=1e-8)
    assert loop.q_top == pytest.approx(x_max, rel=1e-10)
    assert loop.q_bottom == pytest.approx(x_min, rel=1e-10)
    assert loop.zeta == pytest.approx(D / (np.pi * A * (x_max - x_min)), rel=1e-8)


def test_masing_is_wrong_and_the_checks_say_so():
    """On the stiffening branch Masing's construction from the +alpha backbone is far
    from the true loop; the checks reject Masing once the stop closes."""
    problem, lam_w = _problem()
    alphas = np.linspace(100.0, 1600.0, 61)
    q_pos, res_pos = _ramp(problem, lam_w, alphas)
    q_neg, res_neg = _ramp(problem, lam_w, -alphas)
    est = masing_estimate(alphas, q_pos, kt)
    D_true = _exact(1600.0)[0]
    assert abs(est.dissipation[-1] / D_true - 1) > 0.2
    P = lambda rs: np.array([r.lam[:, -1] for r in rs])
    opened = lambda rs: np.array([r.status == 2 for r in rs])
    pre = solve(problem, lam_w(0.0))
    checks = masing_checks(alphas, q_pos, q_neg, P(res_pos), P(res_neg), pre.lam[:, -1],
                           opened(res_pos), opened(res_neg), pre.status == 2, kt, 5e-3, 0.0)
    closes = np.flatnonzero(opened(res_pos)[:, 1] == 0)[0]
    assert not checks.valid[closes:].any()
    assert "contact set changed" in checks.reason[closes]


def test_refinement_converges_to_the_closed_form():
    """Generic increments: each refinement round halves the increments where pair
    states change; the loop energy converges to the closed form within the estimate."""
    A = 1600.0
    problem, lam_w = _problem()
    step = _stepper(problem, lam_w)
    _, res = _ramp(problem, lam_w, [A])
    D = _exact(A)[0]
    errors = []
    for rounds in (0, 1, 2, 3):
        loop = compute_loop(step, _modal, A, res[-1].state, np.linspace(0, 1, 6)[1:],
                            k_ref=kt, rtol=1e-12, refine_rounds=rounds)
        errors.append(abs(loop.dissipation - D))
        assert abs(loop.dissipation - D) <= 4 * loop.error + 1e-12 * abs(D)
    assert errors[-1] < 0.1 * errors[0] and errors[-1] < 2e-3 * D


def test_the_default_refinement_rounds_are_read_when_a_loop_is_computed(monkeypatch):
    """REFINE_ROUNDS changed at run time (as benchmarks/bench_loop_accuracy.py does for
    its reference) reaches the loops of a run, which leave refine_rounds at its
    default: no refinement cycles with 0 rounds, some with the default 3."""
    from qsma.hysteresis import refinement
    A = 1600.0
    problem, lam_w = _problem()
    step = _stepper(problem, lam_w)
    _, res = _ramp(problem, lam_w, [A])
    loop = lambda: compute_loop(step, _modal, A, res[-1].state, np.linspace(0, 1, 6)[1:],
                                k_ref=kt, rtol=1e-12)
    assert loop().refinement_cycles > 0
    monkeypatch.setattr(refinement, "REFINE_ROUNDS", 0)
    assert loop().refinement_cycles == 0


def test_settled_intervals_are_those_whose_share_of_the_loop_did_not_change():
    """An interval of a refinement round whose trapezoids of D and increments of q are
    those of the coarser cycle (here the first) is settled and its fine intervals with
    it; one whose share changed (a kink inside it, here the second) is not, unless the
    budget holds its change; the bound is the sum of the settled changes."""
    from qsma.hysteresis import Loop, cycle_path
    from qsma.hysteresis.estimates import _settled_intervals
    A, k = 2.0, 3.0
    coarse_u, fine_u = np.array([0.5, 1.0]), np.array([0.25, 0.5, 0.75, 1.0])
    loop = lambda u, q: Loop(A, cycle_path(A, u), q, cycle_area(cycle_path(A, u), q, k),
                             np.nan, 0.0, q[0], q[len(u)], 1, 0, "stabilised", "")
    coarse_path, fine_path = cycle_path(A, coarse_u), cycle_path(A, fine_u)
    coarse = loop(coarse_u, coarse_path / k)             # a line: no area
    q_fine = fine_path / k
    q_fine[3] += 0.01                  # unloading, u = 0.75: inside the second interval
    fine = loop(fine_u, q_fine)
    # r = q - alpha / k is 0.01 at point 3 only: the trapezoids 3 and 4 change by
    # 0.5 (alpha_3 + alpha_2) 0.01 - 0.5 (alpha_4 + alpha_3) 0.01; the q increments
    # of the interval add up as before
    changed = 0.5 * (fine_path[2] - fine_path[4]) * 0.01
    settled, bound = _settled_intervals(fine, coarse, fine_u, coarse_u, k, 1e-6)
    assert settled.tolist() == [True, True, False, False] and bound == 0.0
    settled, bound = _settled_intervals(fine, coarse, fine_u, coarse_u, k, 10.0)
    assert settled.all() and bound == pytest.approx(changed, rel=1e-12)


def test_settled_intervals_are_not_halved_again_and_the_estimate_holds(monkeypatch):
    """With a share of the tolerance for the intervals whose share of the loop no longer
    changes (LOCAL_SHARE), the refinement rounds halve fewer intervals, and the loop
    stays within its error estimate of the closed form (the Jenkins element with its
    stop, increments that miss the kinks)."""
    from qsma.hysteresis import refinement
    A = 1600.0
    problem, lam_w = _problem()
    step = _stepper(problem, lam_w)
    _, res = _ramp(problem, lam_w, [A])
    D = _exact(A)[0]
    loops = {}
    for share in (0.0, 0.25):
        monkeypatch.setattr(refinement, "LOCAL_SHARE", share)
        loops[share] = compute_loop(step, _modal, A, res[-1].state, np.linspace(0, 1, 6)[1:],
                                    k_ref=kt, rtol=3e-3, refine_rounds=3)
    for lp in loops.values():
        assert lp.success and abs(lp.dissipation - D) <= lp.error
    assert len(loops[0.25].q) < len(loops[0.0].q)
    assert loops[0.25].n_solves < loops[0.0].n_solves


def test_refinement_rounds_continue_the_history_one_cycle_each():
    """Each refinement round is one more cycle on the halved increments, started where
    the previous cycle ended: the backbone state is the history of the first solve
    only, and the solves are the cycles on the initial increments plus one cycle per
    round (a round used to solve every cycle again from the backbone)."""
    A = 1600.0
    problem, lam_w = _problem()
    inner = _stepper(problem, lam_w)
    histories = []

    def step(alpha, state):
        histories.append(state)
        return inner(alpha, state)
    _, res = _ramp(problem, lam_w, [A])
    start = res[-1].state
    u0 = np.linspace(0, 1, 6)[1:]
    loop = compute_loop(step, _modal, A, start, u0, k_ref=kt, rtol=1e-12, refine_rounds=3)
    assert loop.success and loop.n_cycles == 1        # Jenkins + stop: no transient
    assert sum(h is start for h in histories) == 1
    n_final = (len(loop.alpha) - 1) // 2
    assert n_final > 2 * len(u0)                      # the rounds did refine
    assert loop.n_solves == len(histories)
    # one cycle on u0, then one per round; every round adds at least one point
    assert 2 * len(u0) + 2 * n_final + 2 * (len(u0) + 1) + 2 * (len(u0) + 2) \
        <= loop.n_solves <= 2 * len(u0) + 3 * 2 * n_final
    # the first cycle is the stabilised one on the initial increments: no shakedown
    assert np.isfinite(loop.coarse_dissipation) and not loop.shakedown
    assert abs(loop.dissipation - _exact(A)[0]) <= 4 * loop.error


def test_shakedown_first_cycle_dissipates_then_elastic():
    """A slider left near its friction limit by the preload (pre-shear 0.999 F_s): the
    first unloading slips it once, every later cycle is elastic, because the slider
    force swings by 2 A k / (k0 + k) = 1.2 F_s < 2 F_s (stop open: the unilateral
    spring is slack). The stabilised dissipation is zero, the first is not."""
    problem, lam_w = _problem(pre_shear=Fs * 0.999)
    step = _stepper(problem, lam_w)
    A = 0.6 * Fs * (k0 + k) / k
    _, res = _ramp(problem, lam_w, [A])
    loop = compute_loop(step, _modal, A, res[-1].state, np.linspace(0, 1, 17)[1:], k_ref=kt)
    assert loop.success and loop.stabilised and loop.n_cycles == 2
    assert loop.first_dissipation > 1e-3 * A * loop.q_amplitude
    assert abs(loop.dissipation) <= 1e-9 * A * loop.q_amplitude
    assert loop.shakedown


def test_cycle_area_is_exact_for_a_parallelogram():
    """The trapezoidal loop area of a Jenkins parallelogram with its corners as points."""
    Fs_, k_, xa = 2.0, 10.0, 1.0
    x = np.array([xa, xa - 2 * Fs_ / k_, -xa, -xa + 2 * Fs_ / k_, xa])
    f = np.array([Fs_, -Fs_, -Fs_, Fs_, Fs_])
    alpha = f + 0.0 * x            # force = Jenkins force (k0 = 0)
    assert cycle_area(alpha, x, k_ref=1.0) == pytest.approx(4 * Fs_ * (xa - Fs_ / k_),
                                                            rel=1e-14)


def _closed_form_loops(amplitudes, workers):
    """The lumped system's loops at ``amplitudes`` through :func:`map_loops`; the job is
    a closure (not picklable), so the workers must inherit it."""
    problem, lam_w = _problem()
    step = _stepper(problem, lam_w)
    starts = [_ramp(problem, lam_w, [A])[1][-1].state for A in amplitudes]
    u = np.linspace(0, 1, 9)[1:]
    job = lambda i: compute_loop(step, _modal, amplitudes[i], starts[i], u, k_ref=kt)
    return map_loops(job, range(len(amplitudes)), workers)


@pytest.mark.skipif(not parallel_available(), reason="no fork start method (Windows)")
def test_loops_on_worker_processes_are_the_serial_loops_bit_for_bit():
    """Two workers return the loops of the serial path in the order asked, with the
    same bits, each within its estimate of the closed form."""
    amplitudes = [700.0, 900.0, 1600.0, 2000.0, 1200.0]
    serial = _closed_form_loops(amplitudes, 1)
    parallel = _closed_form_loops(amplitudes, 2)
    for A, a, b in zip(amplitudes, serial, parallel):
        assert b.amplitude == A and b.success
        assert np.array_equal(a.q, b.q) and np.array_equal(a.alpha, b.alpha)
        assert (a.dissipation, a.error, a.n_solves, a.n_cycles) == \
            (b.dissipation, b.error, b.n_solves, b.n_cycles)
        assert abs(b.dissipation - _exact(A)[0]) <= 3 * b.error + 1e-9 * _exact(A)[0]


def test_a_failing_loop_job_raises_in_the_caller():
    """An exception in a worker is raised by map_loops, not swallowed; a warning raised
    in a worker reaches the caller's filters."""
    def job(i):
        if i == 2:
            raise InputError("level 2 refused")
        if i == 3:
            warnings.warn(f"level {i} warns", UserWarning)
        return i
    with pytest.raises(InputError, match="level 2 refused"):
        map_loops(job, range(4), 2)
    with pytest.warns(UserWarning, match="level 3 warns"):
        assert map_loops(job, [0, 1, 3], 2) == [0, 1, 3]


def _pid_job(tag):
    return lambda i: (tag, i, os.getpid())


def _in_a_thread(fn):
    box = {}
    t = threading.Thread(target=lambda: box.update(out=fn()))
    t.start()
    return t, box


@pytest.mark.skipif(not parallel_available(), reason="no fork start method (Windows)")
def test_loop_workers_fork_only_from_the_main_thread():
    """Two threads asking for workers at once each get their own job's results (the
    job reaches forked workers through a module variable, so only the main thread may
    fork: the threads compute their loops themselves)."""
    calls = [_in_a_thread(lambda tag=tag: map_loops(_pid_job(tag), range(4), 2))
             for tag in "AB"]
    for (t, box), tag in zip(calls, "AB"):
        t.join()
        assert box["out"] == [(tag, i, os.getpid()) for i in range(4)]
    on_workers = map_loops(_pid_job("C"), range(4), 2)
    assert [r[:2] for r in on_workers] == [("C", i) for i in range(4)]
    assert all(pid != os.getpid() for *_, pid in on_workers)


def _loops_in_a_daemon(queue):
    queue.put(map_loops(_pid_job("D"), range(3), 2) + [os.getpid()])


@pytest.mark.skipif(not parallel_available(), reason="no fork start method (Windows)")
def test_loop_workers_in_a_daemonic_process_run_in_it():
    """A daemonic process (a sweep's worker) may not have children: the loops run in it
    instead of failing."""
    ctx = multiprocessing.get_context("fork")
    queue = ctx.Queue()
    p = ctx.Process(target=_loops_in_a_daemon, args=(queue,), daemon=True)
    p.start()
    *out, pid = queue.get(timeout=60)
    p.join(timeout=60)
    assert out == [("D", i, pid) for i in range(3)]


@pytest.mark.skipif(not parallel_available(), reason="no fork start method (Windows)")
def test_a_failing_loop_stops_the_other_workers():
    """When one loop raises, the caller gets the exception without waiting for the
    loops still running on other workers (they would take 60 s here)."""
    def job(i):
        if i == 0:
            time.sleep(0.5)
            raise InputError("level 0 refused")
        time.sleep(60)
        return i
    t0 = time.monotonic()
    with pytest.raises(InputError, match="level 0 refused"):
        map_loops(job, range(3), 3)
    assert time.monotonic() - t0 < 30


@pytest.mark.parametrize("bad", [0, -1, 1.5, "2", True, 10 ** 6])
def test_loop_workers_must_be_a_sane_process_count(bad):
    with pytest.raises(InputError, match="loop_workers"):
        RunOptions(loop_workers=bad)


@pytest.mark.parametrize("bad", ["", "  ", 8786])
def test_a_loop_scheduler_is_an_address(bad):
    with pytest.raises(InputError, match="loop_scheduler must be the address"):
        RunOptions(loop_scheduler=bad)


def test_loop_workers_and_a_loop_scheduler_are_one_or_the_other():
    with pytest.raises(InputError, match="give one of the two"):
        RunOptions(loop_workers=2, loop_scheduler="tcp://host:8786")


def test_each_solve_of_a_loop_is_told_the_pairs_closed_there_a_cycle_before():
    """``expect_closing``: from the second cycle on, every solve gets the pairs closed at
    the same point of the cycle before (a refined cycle's new point: those of the
    coarser cycle's next point in the direction of travel). That the answers do not
    change is tested through the zone solves (tests/test_analysis.py): this stepper
    ignores ``closing``."""
    A = 1600.0
    problem, lam_w = _problem()
    inner = _stepper(problem, lam_w)
    _, res = _ramp(problem, lam_w, [A])
    start, u0 = res[-1].state, np.linspace(0, 1, 6)[1:]
    calls = []

    def step(alpha, state, closing=None):
        out = inner(alpha, state)
        calls.append((alpha, None if closing is None else closing.copy(),
                      out.status != OPEN))
        return out
    told = compute_loop(step, _modal, A, start, u0, k_ref=kt, rtol=1e-12, refine_rounds=2,
                        expect_closing=True)
    assert told.success
    first = 2 * len(u0)                                # the first cycle: nothing known
    assert all(c is None for _, c, _ in calls[:first])
    assert all(c is not None for _, c, _ in calls[first:])
    # the stop (pair 1) closes and opens along the cycle: the masks are not all alike
    assert len({c.tobytes() for _, c, _ in calls[first:]}) > 1
    # the second cycle (the first refined one) was told the first cycle's states: at a
    # shared point that point's, at a new one the next coarse point's (travelling
    # down to -A, then up to +A)
    n0 = len(u0)
    first_loads = np.array([a for a, _, _ in calls[:first]])
    first_closed = [s for _, _, s in calls[:first]]
    n1 = 1 + next(j for j, (a, _, _) in enumerate(calls[first:]) if a == -A)
    second = calls[first:first + 2 * n1]
    assert n1 > n0                                     # it was refined
    for j, (a, told_mask, _) in enumerate(second):
        if j < n1:
            i = next(i for i in range(n0) if first_loads[i] <= a)
        else:
            i = next(i for i in range(n0, 2 * n0) if first_loads[i] >= a)
        assert np.array_equal(told_mask, first_closed[i])


def test_a_warm_started_loop_starts_each_solve_from_the_state_a_cycle_before():
    """``warm_start``: a solve at a load the cycle before also had is handed the state
    reached there (on the same branch) as its guess; the first cycle and the new points
    of a refined cycle get none. The loop is the same as without (this stepper solves
    from the guess, the solver judges the answer alone)."""
    A = 1600.0
    problem, lam_w = _problem()
    _, res = _ramp(problem, lam_w, [A])
    start, u0 = res[-1].state, np.linspace(0, 1, 6)[1:]
    calls = []

    def step(alpha, state, closing=None, guess=None):
        out = solve(problem, lam_w(alpha), state, guess=guess)
        assert out.success, out.message
        calls.append((alpha, guess, out.state))
        return out
    warm = compute_loop(step, _modal, A, start, u0, k_ref=kt, rtol=1e-12, refine_rounds=2,
                        expect_closing=True, warm_start=True)
    cold = compute_loop(_stepper(problem, lam_w), _modal, A, start, u0, k_ref=kt,
                        rtol=1e-12, refine_rounds=2)
    assert warm.success and cold.success
    assert warm.n_solves == cold.n_solves == len(calls)
    np.testing.assert_allclose(warm.q, cold.q, rtol=1e-9)
    np.testing.assert_allclose(warm.dissipation, cold.dissipation, rtol=1e-9)
    # replay the cycles: each one starts at +A, its branches down to -A and back up
    cycles, current = [], []
    for j, (a, guess, state) in enumerate(calls):
        current.append((a, guess, state))
        if a == A:
            cycles.append(current)
            current = []
    assert len(cycles) >= 3 and all(g is None for _, g, _ in cycles[0])
    told = 0
    for before, cycle in zip(cycles, cycles[1:]):
        n_before = len(before) // 2
        for k, (a, guess, _) in enumerate(cycle):
            branch = before[:n_before] if k < len(cycle) // 2 else before[n_before:]
            same = [s for b, _, s in branch if b == a]
            if same:
                assert guess is not None and np.array_equal(guess.d, same[0].d)
                told += 1
            else:
                assert guess is None
    assert told > 0


def test_closings_of_a_refined_cycle_come_from_the_next_coarse_point():
    from qsma.hysteresis import cycle_path
    from qsma.hysteresis.cycles import _Closings
    A = 2.0
    coarse = cycle_path(A, [0.5, 1.0])            # A, 0, -A, 0, A
    status = [np.array([0]), np.array([2]), np.array([0]), np.array([2]), np.array([0])]
    memory = _Closings()
    assert memory.expected(coarse, 1) is None
    memory.record(coarse, [np.array([s[0], 2 - s[0]]) for s in status])
    fine = cycle_path(A, [0.25, 0.5, 0.75, 1.0])  # A, 1, 0, -1, -A, -1, 0, 1, A
    got = [memory.expected(fine, k).tolist() for k in range(1, len(fine))]
    # unloading: 1 -> coarse 0 (open), 0 -> 0, -1 -> -A (closed), -A -> -A;
    # reloading: -1 -> coarse 0 (open), 0 -> 0, 1 -> A (closed), A -> A
    assert got == [[False, True], [False, True], [True, False], [True, False],
                   [False, True], [False, True], [True, False], [True, False]]


@pytest.mark.parametrize("rtol, rounds", [(1e-12, 3), (0.5, 1)])
def test_a_loop_counts_its_refinement_cycles(rtol, rounds):
    """``refinement_cycles`` counts the cycles of the refinement rounds: one per round
    here (the Jenkins element with its stop settles at once), all three rounds at a
    tolerance no round meets, one where the first round settles the loop. Every cycle
    ends at +A, so the solves at +A count the cycles."""
    A = 1600.0
    problem, lam_w = _problem()
    inner = _stepper(problem, lam_w)
    loads = []

    def step(alpha, state):
        loads.append(alpha)
        return inner(alpha, state)
    _, res = _ramp(problem, lam_w, [A])
    loop = compute_loop(step, _modal, A, res[-1].state, np.linspace(0, 1, 6)[1:],
                        k_ref=kt, rtol=rtol, refine_rounds=3)
    assert loop.success and loop.refinement_cycles == rounds
    assert loads.count(A) == loop.n_cycles + loop.refinement_cycles


def _slow_shakedown(r, a, w_star=1e-3, k0=1e6):
    """A loop whose cycles settle geometrically: the width of the unloading branch
    after cycle k is ``w_k = w* (1 - a r^k)`` (the drift at +A shrinks by ``r`` per
    cycle), ``q = alpha / k0 + w (1 - alpha^2 / A^2)`` down, ``alpha / k0`` up, so that
    D is proportional to ``w``: ``D_k = D* (1 - a r^k)``. Returns ``(step, modal,
    start, D*)`` for :func:`compute_loop` at A = 1."""
    from types import SimpleNamespace
    calls = {"n": 0, "w": w_star * (1 - a)}
    n_branch = 16
    status = np.zeros(1, int)

    def result(w, down):
        d = np.array([[w, float(down)]])
        state = SimpleNamespace(d=d, lam=np.zeros_like(d), status=status)
        return SimpleNamespace(success=True, state=state, d=d, status=status,
                               message="", residual=0.0)

    def step(alpha, state):
        k = calls["n"] % (2 * n_branch)
        calls["n"] += 1
        if k == 0:                       # the first solve of a cycle: the next width
            calls["w"] = w_star + r * (calls["w"] - w_star)
        return result(calls["w"], k < n_branch - 1)

    def modal(d, alpha):
        return alpha / k0 + d[0, 0] * d[0, 1] * (1 - alpha ** 2)
    fractions = np.linspace(0, 1, n_branch + 1)[1:]
    path = np.concatenate([[1.0], 1 - 2 * fractions, 2 * fractions - 1])
    q_star = [modal(np.array([[w_star, 1.0 if 0 < k < n_branch else 0.0]]), a)
              for k, a in enumerate(path)]
    return step, modal, result(calls["w"], False).state, cycle_area(path, q_star, k0)


def test_a_slow_shakedown_is_not_taken_for_settled_after_two_agreeing_cycles():
    """Cycles that agree to 0.4 % after two cycles but settle 2 % further on (r = 0.85,
    as the tetrahedral lap joint's loop at its highest levels): the loop goes on until
    what the contraction leaves to come is within the tolerance, and its error covers
    the distance to the settled cycle."""
    step, modal, start, D_star = _slow_shakedown(r=0.85, a=0.03)
    loop = compute_loop(step, modal, 1.0, start, np.linspace(0, 1, 17)[1:], k_ref=1e6,
                        refine_rounds=0)
    assert loop.success and loop.n_cycles > 8           # beyond max_cycles: contracting
    assert abs(loop.dissipation - D_star) <= loop.error * (1 + 1e-9)
    assert abs(loop.dissipation / D_star - 1) <= 5e-3 * (1 + 1e-9)
    # two cycles agree within the tolerance: what used to be accepted
    D1, D2 = (1 - 0.03 * 0.85), (1 - 0.03 * 0.85 ** 2)
    assert abs(D2 - D1) <= 5e-3 * D2 and 1 - D2 > 0.02


def test_the_path_error_still_to_come_after_a_refinement_round():
    from qsma.hysteresis.estimates import _path_error
    assert _path_error(1.0, None) == 1.0                 # first round: the change
    assert _path_error(0.5, 1.0) == 0.5                  # halved: first order
    assert _path_error(0.2, 1.0) == 0.2
    assert _path_error(0.8, 1.0) == pytest.approx(3.2)   # slower: 0.8 x 0.8 / 0.2
    assert _path_error(1.5, 1.0) == 1.5 and _path_error(0.5, 0.4) == 0.5
    # the intervals no longer halved add their last changes, with the same factor
    assert _path_error(1.0, None, 0.25) == 1.25
    assert _path_error(0.5, 1.0, 0.25) == 0.75
    assert _path_error(0.8, 1.0, 0.2) == pytest.approx(4.0)
