"""The cheap parts of an ``active_set`` solve: the block step of one set of pair states
built once and its LU factors reused by iterative refinement, and the residual check
skipped where a bound shows it must fail. Each against the path it replaces: the same
answers to round-off on the zones of real joints, never an accepted iterate that the
check rejects, and a failure still reported as one."""
import numpy as np
import pytest

import qsma
from qsma.contact import ContactProblem, ContactState, residual, solve
from qsma.contact import active_set, linear
from qsma.contact.active_set import surely_rejected
from qsma.contact.linear import basket_system, solve_partitioned
from qsma.contact.residual import measures, residual_components
from qsma.examples import EXAMPLES
import qsma.contact.zone as zone_module

TOL = 1e-10


def _reference_newton_point(self, sets):
    """The Newton point as the whole system of the states, rows of every unknown
    gathered from ``K`` and solved by ``numpy.linalg.solve`` at every step."""
    R, b, unknown, d_known = basket_system(self.problem, self.lw, sets.status, -sets.h,
                                           sets.alpha, self.prev, self.c)
    return solve_partitioned(R, b, unknown, d_known)


def _zone_solves(name):
    """The zone problems, loads and states of the solves of a short computed loop of an
    example at refine 1 (one level, four increments per branch, at most two cycles)."""
    seen = []
    original = zone_module.solve

    def recorded(problem, lam_w, state=None, **kw):
        res = original(problem, lam_w, state, **kw)
        seen.append((problem, np.array(lam_w), state, kw))
        return res

    zone_module.solve = recorded
    try:
        qsma.run(EXAMPLES[name](1), levels=qsma.Levels("tip", (1e-3,)),
                 dissipation="loop", loop_steps=4, max_cycles=2, loop_workers=1)
    finally:
        zone_module.solve = original
    return seen


@pytest.fixture(scope="module", params=["brb", "lap-3d"])
def zone_solves(request):
    return _zone_solves(request.param)


def test_newton_steps_equal_the_whole_system_on_real_zones(zone_solves, monkeypatch):
    """Every recorded zone solve, with the steps of :class:`BlockSystem` and with the
    whole system solved afresh at every step: the same pair states, Newton steps and
    outcome, ``d`` and ``lam`` the same to round-off."""
    assert len(zone_solves) > 40
    fast = [solve(p, lw, st, **kw) for p, lw, st, kw in zone_solves]
    monkeypatch.setattr(active_set._Newton, "_newton_point", _reference_newton_point)
    slow = [solve(p, lw, st, **kw) for p, lw, st, kw in zone_solves]
    assert any(kw.get("method") == "active_set" for *_, kw in zone_solves)
    for a, b in zip(fast, slow):
        assert a.success and b.success
        assert (a.nit, a.fallback) == (b.nit, b.fallback)
        np.testing.assert_array_equal(a.status, b.status)
        for x, y in ((a.d, b.d), (a.lam, b.lam)):
            assert np.max(np.abs(x - y)) <= 1e-11 * np.max(np.abs(y))


def test_refined_steps_are_taken_on_real_zones(zone_solves, monkeypatch):
    """The reuse is exercised: on these zones some steps are solved with the factors of
    an earlier step of the same states (refinement accepted), not all afresh."""
    refined = []
    original = linear.BlockSystem._refined

    def counted(self, law):
        x = original(self, law)
        refined.append(x is not None)
        return x

    monkeypatch.setattr(linear, "REFINE_MIN", 1)
    monkeypatch.setattr(linear.BlockSystem, "_refined", counted)
    for p, lw, st, kw in zone_solves:
        assert solve(p, lw, st, **kw).success
    assert sum(refined) > 0


def _shifted(problem, lam_w, state, scale, seed):
    """The same contact solution with terms ``scale`` times larger: a displacement
    ``K^{-1} v`` added to every ``d`` (the gap and the slip reference moved with it)
    and ``v`` taken off the load, so ``lam`` is unchanged while ``|K| |d|`` and
    ``|lam_w|`` grow; the round-off allowance of the check then matters."""
    v = scale * np.random.default_rng(seed).normal(size=problem.size)
    u = np.linalg.solve(problem.K, v).reshape(-1, problem.dim)
    moved = ContactProblem(problem.K, problem.mu, problem.gap0 - u[:, -1], problem.dim)
    prev = ContactState(state.d + u, state.lam, state.status)
    return moved, lam_w - v.reshape(lam_w.shape), prev, u


def _random_problem(seed, n=20, dim=3):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(dim * n, dim * n))
    p = ContactProblem(A @ A.T / n + np.diag(np.full(dim * n, 3.0)), 0.3, dim=dim)
    base = np.zeros((n, dim))
    base[:, -1] = np.where(np.arange(n) < 14, 1.0, -0.3)
    return p, base, rng


@pytest.mark.parametrize("scale", [0.0, 1e6, 1e10])
def test_surely_rejected_never_rejects_what_the_check_accepts(scale):
    """Answers of a 3D ramp, perturbed from 1e-17 to 1e-6 of their size (with ``lam =
    K d + lam_w``, as the Newton iterates), and the same answers with terms up to 1e10
    times the reaction: wherever :func:`surely_rejected` says so, the residual exceeds
    ``tol``; it says so for clearly wrong iterates, never for an answer."""
    p0, base, rng = _random_problem(5)
    state = solve(p0, base).state
    rejected = accepted = 0
    for level in range(1, 6):
        lw0 = base.copy()
        lw0[:, 0] = 0.4 * level
        lw0[:, 1] = -0.2 * level
        res = solve(p0, lw0, state, method="active_set")
        assert res.success
        p, lw, prev, u = _shifted(p0, lw0, state, scale, level)
        d_answer = res.d + u
        assert not surely_rejected(p, lw, d_answer, p.product(d_answer).reshape(lw.shape) + lw,
                                   prev.d, TOL)
        for size in 10.0 ** np.arange(-17, -5):
            d = d_answer + size * np.abs(d_answer).max() * rng.normal(size=d_answer.shape)
            lam = (p.K @ d.ravel()).reshape(d.shape) + lw
            r = residual_components(p, lw, d, lam, prev).total
            sure = surely_rejected(p, lw, d, lam, prev.d, TOL)
            assert not (sure and r <= TOL), (size, r)
            rejected += sure
            accepted += r <= TOL
        state = res.state
    assert rejected > 10 and accepted > 5


def test_a_wrong_refined_step_is_never_returned_as_an_answer(monkeypatch):
    """Refinement made to accept any answer (its tolerance 0.5): the solves either
    still converge, their answers meeting the residual when checked afresh, or report
    the failure; a step made wrong on purpose fails the solve."""
    p, base, _ = _random_problem(7, n=80)
    monkeypatch.setattr(linear, "REFINE_ETA", 0.5)
    monkeypatch.setattr(linear, "REFINE_MIN", 1)
    state = solve(p, base).state
    for level in range(1, 5):
        lw = base.copy()
        lw[:, 0] = 0.5 * level
        res = solve(p, lw, state, method="active_set")
        if res.success:
            assert residual(p, lw, res.d, res.lam, state) <= TOL
        state = res.state if res.success else state
    original = linear.BlockSystem.solve

    def wrong(self, direction, alpha, c):
        return original(self, direction, alpha, c) * (1.0 + 1e-3)

    monkeypatch.setattr(linear.BlockSystem, "solve", wrong)
    lw = base.copy()
    lw[:, 0] = 2.5
    with pytest.warns(qsma.errors.ContactConvergenceWarning):
        res = solve(p, lw, state, method="active_set", fallback=False)
    assert not res.success and res.residual > TOL


def test_a_zone_of_every_pair_reports_the_measures_of_the_full_problem(monkeypatch):
    """When no pair is eliminated the zone problem is the full problem: the level's
    measures are taken from its zone solve, and they are those of the full problem
    evaluated afresh."""
    p, base, _ = _random_problem(11, n=16)
    base[:, -1] = 1.0                                   # every pair pressed
    state = solve(p, base).state
    zone = zone_module.zone_from_state(p, state)
    assert zone.sub is p
    for level in range(1, 6):
        lw = base.copy()
        lw[:, 0], lw[:, 1] = 0.3 * level, 0.1 * level
        res, zone = zone_module.solve_in_zone(zone, lw, state, method="active_set")
        assert res.success and zone.sub is p
        fresh = measures(p, lw, res.d, res.lam, state)
        np.testing.assert_allclose([res.residual, res.residual_force, res.residual_legacy],
                                   fresh, rtol=1e-12, atol=1e-300)
        assert fresh[0] <= TOL
        state = res.state
