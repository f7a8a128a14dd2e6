"""No exception but InputError for finite input; outcomes and fallbacks as data."""
import warnings

import numpy as np
import pytest

from qsma.contact import (FALLBACKS, METHODS, ContactProblem, Iterate, Outcome, PairState,
                          OPEN, SLIPPING, STUCK, legacy_residual, residual, solve)
from qsma.contact import registry


def quiet_solve(*args, **kwargs):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return solve(*args, **kwargs)


def pair3d(scale=1.0):
    K = scale * np.array([[10.0, 1.0, 2.0], [1.0, 12.0, -1.5], [2.0, -1.5, 20.0]])
    return ContactProblem(K, 0.5, dim=3)


def test_pair_states_are_an_int_enum_with_module_aliases():
    assert (STUCK, SLIPPING, OPEN) == (PairState.STUCK, PairState.SLIPPING, PairState.OPEN)
    assert [int(s) for s in PairState] == [0, 1, 2]
    r = solve(pair3d(), np.array([[0.0, 0.0, -1.0]]))                  # pulled apart
    assert r.status[0] == OPEN and r.n_open == 1 and r.outcome is Outcome.CONVERGED
    assert r.fallback is None


@pytest.mark.parametrize("method", sorted(METHODS))
@pytest.mark.parametrize("load_scale, k_scale", [(1e200, 1.0), (1e-200, 1.0), (1.0, 1e-300),
                                                 (1.0, 1e300), (1e150, 1e-150)])
def test_extreme_but_finite_scales_give_an_answer_or_a_clean_failure(method, load_scale, k_scale):
    problem = pair3d(k_scale)
    lam_w = load_scale * np.array([[3.0, -2.0, 4.0]])                 # slips: |Q| > mu P
    r = quiet_solve(problem, lam_w, method=method)
    assert r.success, r.message
    assert r.status[0] == SLIPPING
    assert np.all(np.isfinite(r.d)) and np.all(np.isfinite(r.lam))
    # the same problem at unit scale: the answer scales exactly
    unit = solve(pair3d(), np.array([[3.0, -2.0, 4.0]]), method=method)
    np.testing.assert_allclose(r.lam / load_scale, unit.lam, rtol=1e-9)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_3d_pair_loaded_exactly_at_the_slip_limit(method):
    """|Q| = mu P exactly: stuck and slipping coincide (the old local solve raised
    LinAlgError here)."""
    problem = ContactProblem(np.diag([10.0, 10.0, 20.0]), 0.5, dim=3)
    lam_w = np.array([[3.0, 4.0, 10.0]])                                # |Q| = 5 = mu P
    r = solve(problem, lam_w, method=method)
    assert r.success and residual(problem, lam_w, r.d, r.lam) == 0.0


def test_a_method_that_raises_gives_a_numerical_error_outcome(monkeypatch):
    def broken(problem, lam_w, previous, *, tol, maxiter=None, guess=None):
        raise np.linalg.LinAlgError("Singular matrix")
    monkeypatch.setitem(registry.METHODS, "broken", broken)
    monkeypatch.setitem(registry._OPTIONS, "broken", ())
    r = quiet_solve(pair3d(), np.array([[1.0, 0.0, 2.0]]), method="broken")
    assert not r.success and r.outcome is Outcome.NUMERICAL_ERROR
    assert "LinAlgError" in r.message


def test_a_method_returning_nan_is_not_a_success(monkeypatch):
    def nan(problem, lam_w, previous, *, tol, maxiter=None, guess=None):
        return Iterate(np.full_like(lam_w, np.nan), lam_w, 1, True, "converged")
    monkeypatch.setitem(registry.METHODS, "nan", nan)
    monkeypatch.setitem(registry._OPTIONS, "nan", ())
    r = quiet_solve(pair3d(), np.array([[1.0, 0.0, 2.0]]), method="nan")
    assert not r.success and r.outcome is Outcome.NUMERICAL_ERROR


def test_the_registry_sets_the_fallback_field_and_message(monkeypatch):
    def gives_up(problem, lam_w, previous, *, tol, maxiter=None, guess=None):
        return Iterate(previous.d, previous.lam, 3, False, "gave up")
    monkeypatch.setitem(registry.METHODS, "gives_up", gives_up)
    monkeypatch.setitem(registry._OPTIONS, "gives_up", ())
    monkeypatch.setitem(registry.FALLBACKS, "gives_up", "basket")
    lam_w = np.array([[3.0, -2.0, 4.0]])
    r = quiet_solve(pair3d(), lam_w, method="gives_up")
    assert r.success and r.fallback == "basket" and r.nit > 3
    assert "fell back to basket" in r.message and r.method == "gives_up"
    r = quiet_solve(pair3d(), lam_w, method="gives_up", fallback=False)
    assert not r.success and r.fallback is None and r.outcome is Outcome.NOT_CONVERGED


def test_fallback_chain_is_between_the_two_production_methods():
    assert FALLBACKS == {"basket": "active_set", "active_set": "basket"}


def test_a_claimed_success_that_fails_the_check_is_rejected(monkeypatch):
    def liar(problem, lam_w, previous, *, tol, maxiter=None, guess=None):
        return Iterate(previous.d, np.zeros_like(lam_w), 1, True, "trust me")
    monkeypatch.setitem(registry.METHODS, "liar", liar)
    monkeypatch.setitem(registry._OPTIONS, "liar", ())
    r = quiet_solve(pair3d(), np.array([[1.0, 0.0, 2.0]]), method="liar", fallback=False)
    assert not r.success and r.outcome is Outcome.REJECTED


def test_new_residual_sees_a_force_error_the_old_one_hides():
    """Ill-conditioned K, load far above the reaction: a 3 % error in one pair's
    pressure (equilibrium kept exactly) reads ~1e-12 in the old measure."""
    rng = np.random.default_rng(0)
    Qm, _ = np.linalg.qr(rng.normal(size=(6, 6)))
    K = (Qm * np.geomspace(1.0, 1e11, 6)) @ Qm.T
    problem = ContactProblem(K, 0.3, dim=3)
    d = np.array([[0.0, 0.0, 0.0], [5e3, -2e3, 0.0]])                  # pair 1 slips far
    lam = np.array([[0.5, -0.3, 10.0], [-0.3 * 12.0 * 5 / np.hypot(5, 2),
                                        0.3 * 12.0 * 2 / np.hypot(5, 2), 12.0]])
    lam_w = lam - (K @ d.ravel()).reshape(2, 3)
    assert residual(problem, lam_w, d, lam) <= 1e-10                   # exact answer passes
    wrong = lam.copy()
    wrong[0, 2] *= 1.03                                                 # 3 % more pressure...
    d_wrong = d + np.linalg.solve(K, (wrong - lam).ravel()).reshape(2, 3)  # ...in equilibrium
    assert residual(problem, lam_w, d_wrong, wrong) > 1e-3
    assert legacy_residual(problem, lam_w, d_wrong, wrong) < 1e-9
