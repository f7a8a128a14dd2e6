"""Convergence, failure paths and the public residual."""
import itertools
import warnings

import numpy as np
import pytest

from qsma.contact import (METHODS, OPEN, SLIPPING, STUCK, ContactProblem, ContactState, Iterate,
                          residual, residual_components, solve)
from qsma.contact import registry
from qsma.contact.linear import basket_system, solve_partitioned
from qsma.errors import ContactConvergenceWarning


def bar(n=30, k=50.0, kn=1e4, mu=0.3):
    Kt = k * (2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1))
    Kt[0, 0] = k
    K = np.zeros((2 * n, 2 * n))
    K[0::2, 0::2], K[1::2, 1::2] = Kt, kn * np.eye(n)
    return ContactProblem(K, mu)


def bar_load(n, F, p=2.0):
    lam_w = np.zeros((n, 2))
    lam_w[:, 1] = p
    lam_w[0, 0] = -F
    return lam_w


def ill_conditioned(n=40, cond=1e6, seed=0):
    """A chain with a dense coupling and cond(K) ~ 1e6 (benchmark family, small)."""
    x = np.linspace(0, 1, n)
    h = x[1] - x[0]
    Kt = (np.diag(np.r_[1.0, np.full(n - 1, 2.0)]) - np.eye(n, k=1) - np.eye(n, k=-1)) / h
    Kn0 = np.eye(n) + np.exp(-np.abs(x[:, None] - x[None, :]) / 0.05)
    scale = cond * np.linalg.eigvalsh(Kt)[0] / np.linalg.eigvalsh(Kn0)[-1]
    K = np.zeros((2 * n, 2 * n))
    K[0::2, 0::2], K[1::2, 1::2] = Kt, scale * Kn0
    lam_w = np.zeros((n, 2))
    lam_w[:, 1] = (1.0 - 1.3 * x) * h * scale
    lam_w[0, 0] = -0.5 * 0.6 * np.sum(np.maximum(lam_w[:, 1], 0))
    return ContactProblem(K, 0.6), lam_w


@pytest.mark.parametrize("method", sorted(METHODS))
def test_maxiter_one_reports_failure_with_warning_and_last_iterate(method):
    problem, n = bar(), 30
    lam_w = bar_load(n, 13.1)                       # ~21 pairs slip: needs several steps
    with pytest.warns(ContactConvergenceWarning, match=f"contact method '{method}'"):
        r = solve(problem, lam_w, method=method, maxiter=1)
    assert not r.success and r.nit == 1
    assert r.residual > 1e-10 and np.isfinite(r.residual)
    assert "maxiter=1" in r.message or "no convergence" in r.message
    assert np.all(np.isfinite(r.d)) and np.all(np.isfinite(r.lam))
    assert r.state.d is r.d                       # the last iterate, to inspect or restart
    assert r.residual == pytest.approx(residual(problem, lam_w, r.d, r.lam))


def test_nodal_gauss_seidel_is_honest_on_an_ill_conditioned_problem():
    problem, lam_w = ill_conditioned()
    assert np.linalg.cond(problem.K) == pytest.approx(1e6, rel=0.05)
    with pytest.warns(ContactConvergenceWarning):
        slow = solve(problem, lam_w, method="nodal_gs", maxiter=300)
    assert not slow.success and slow.nit == 300 and slow.residual > 1e2 * 1e-10
    for method in ("basket", "active_set"):
        fast = solve(problem, lam_w, method=method)
        assert fast.success and fast.nit <= 10 and fast.residual <= 1e-13


def test_literal_basket_gauss_seidel_gives_the_same_answer():
    problem, lam_w = ill_conditioned()
    joint = solve(problem, lam_w)
    literal = solve(problem, lam_w, coupling="gauss_seidel", fallback=False)
    assert literal.success and literal.nit >= joint.nit
    F = np.abs(lam_w).max()
    np.testing.assert_allclose(literal.lam, joint.lam, atol=1e-8 * F)


def test_solve_rejects_a_method_that_claims_success_wrongly(monkeypatch):
    def liar(problem, lam_w, previous, *, tol, maxiter=None, guess=None):
        return Iterate(previous.d, np.zeros_like(lam_w), 1, True, "trust me")
    monkeypatch.setitem(registry.METHODS, "liar", liar)
    monkeypatch.setitem(registry._OPTIONS, "liar", ())
    problem = bar()
    with pytest.warns(ContactConvergenceWarning, match="rejected: residual"):
        r = solve(problem, bar_load(30, 1.0), method="liar")
    assert not r.success and r.residual == pytest.approx(1.0)


def test_all_stuck_is_immediate_and_exact():
    problem, n = bar(), 30
    lam_w = bar_load(n, 0.5)                        # below mu p at the loaded pair
    previous = ContactState(np.full((n, 2), [1e-3, 0.0]), np.zeros((n, 2)), np.zeros(n, int))
    r = solve(problem, lam_w, previous)
    assert r.success and r.nit == 1
    expected = problem.K @ previous.d.ravel() + lam_w.ravel()
    # equal to round-off of the product's summation order (the solver reads one triangle)
    np.testing.assert_allclose(r.lam.ravel(), expected, rtol=1e-14,
                               atol=1e-14 * np.abs(expected).max())
    np.testing.assert_array_equal(r.d, previous.d)


@pytest.mark.parametrize("method", ["basket", "active_set"])
def test_warm_started_ramp_takes_few_iterations_per_level(method):
    problem, n = bar(60), 60
    state, total = None, 0
    for F in np.linspace(0, 13.1, 51)[1:]:
        r = solve(problem, bar_load(n, F), state, method=method)
        assert r.success
        state, total = r.state, total + r.nit
    assert total <= 2 * 50                          # at most one extra step per level


def test_residual_is_zero_at_a_solution_and_sees_every_violation():
    problem = ContactProblem(np.diag([10.0, 100.0]), 0.5)
    lam_w = np.array([[6.0, 10.0]])
    r = solve(problem, lam_w)
    assert residual(problem, lam_w, r.d, r.lam) <= 1e-15
    parts = residual_components(problem, lam_w, r.d, r.lam)
    assert parts.force_scale == 10.0 and parts.stiffness_scale == 55.0
    cases = {
        "equilibrium": (r.d, r.lam + [[0.1, 0.0]]),                     # lam != K d + lam_w
        "penetration": (r.d - [[0.0, 1e-3]], r.lam - [[0.0, 0.1]]),      # w < 0
        "tension": (r.d + [[0.0, 1e-3]], r.lam + [[0.0, 0.1]]),          # P > 0 and w > 0
    }
    for name, (d, lam) in cases.items():
        assert residual(problem, lam_w, d, lam) > 1e-4, name
    # friction force above mu P (stuck state, forces inconsistent with the law)
    stuck_d, stuck_lam = np.zeros((1, 2)), np.array([[6.0, 10.0]])
    parts = residual_components(problem, lam_w, stuck_d, stuck_lam)
    assert parts.equilibrium == 0.0 and parts.tangential[0] == pytest.approx(0.1)
    # slip in the wrong direction: Q = -mu P sign(dv) violated
    wrong = residual_components(problem, np.array([[-4.0, 10.0]]), np.array([[-0.1, 0.0]]),
                                np.array([[-5.0, 10.0]]))
    assert wrong.equilibrium == 0.0 and wrong.tangential[0] > 0.09 and wrong.worst_pair == 0


def test_residual_of_an_unloaded_problem_is_finite():
    problem = ContactProblem(np.eye(2), 0.5)
    r = solve(problem, np.zeros((1, 2)))
    assert r.success and r.residual == 0.0
    np.testing.assert_array_equal(r.d, 0.0)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_tighter_and_looser_tolerances_are_honoured(method):
    problem, lam_w = bar(), bar_load(30, 13.1)
    options = {"maxiter": 200000} if method == "nodal_gs" else {}
    for tol in (1e-6, 1e-12):
        with warnings.catch_warnings():
            warnings.simplefilter("error", ContactConvergenceWarning)
            r = solve(problem, lam_w, method=method, tol=tol, **options)
        assert r.success and r.residual <= tol


def two_pair_cycle_problem():
    """A level of the adversarial sweep (bench_contact_adversarial.py, seed 21,
    problem 456, level 3): 2D, 2 pairs, cond(K) = 4.8e7, mu = 1.17, both pairs open
    before. Its only solution has pair 0 open and pair 1 slipping; the basket's
    tabu search used to move only the pair that failed its check and went back and
    forth between two seen configurations for 200 block steps."""
    K = np.array([[2695747.542231221, 221965.8498229164, 8919269.09511267, 6412304.506412802],
                  [221965.8498229164, 97171.74710131309, 543468.6831451105, 373631.71843940316],
                  [8919269.09511267, 543468.6831451105, 29979476.329462938, 21594754.083743073],
                  [6412304.506412802, 373631.71843940316, 21594754.083743073,
                   15558749.420591185]])
    problem = ContactProblem(K, 1.1677567760157264,
                             gap0=[-7.2044385050836590e-11, -1.1315808542836871e-11])
    lam_w = np.array([[0.07746123282413464, -0.22396485058652615],
                      [-0.05281716847093776, -0.0029949647723697126]])
    previous = ContactState(np.array([[0.0010571917736716162, 0.0009676392828481705],
                                      [-0.006310269921177116, 0.008299393579086612]]),
                            np.array([[0.0, 4.547473508864641e-13], [0.0, 0.0]]),
                            np.array([OPEN, OPEN]))
    return problem, lam_w, previous


def enumerate_2d_solutions(problem, lam_w, previous, tol=1e-9):
    """Every combination of (stuck, slip +, slip -, open) per pair, solved with the
    states held and kept if its residual is below ``tol``: the statuses found."""
    n, found = problem.n_pairs, []
    for combo in itertools.product(range(4), repeat=n):
        combo = np.array(combo)
        status = np.where(combo == 3, OPEN, np.where(combo == 0, STUCK, SLIPPING))
        direction = np.where(combo == 2, -1.0, 1.0)[:, None]
        R, b, free, known = basket_system(problem, lam_w.ravel(), status, direction, np.zeros(n),
                                          previous.d, problem.kappa)
        d = solve_partitioned(R, b, free, known).reshape(n, 2)
        lam = (problem.K @ d.ravel() + lam_w.ravel()).reshape(n, 2)
        if residual(problem, lam_w, d, lam, previous) <= tol:
            found.append(tuple(status))
    return found


def test_tabu_search_also_moves_pairs_that_passed_their_check():
    problem, lam_w, previous = two_pair_cycle_problem()
    assert enumerate_2d_solutions(problem, lam_w, previous) == [(OPEN, SLIPPING)]
    r = solve(problem, lam_w, previous, method="basket", fallback=False)
    assert r.success, r.message
    assert tuple(r.status) == (OPEN, SLIPPING)
