"""A solve started from a guess (the same level on a neighbouring path) ends at the
answer of the solve started from the previous state, and is judged the same way."""
import numpy as np
import pytest

from qsma.contact import ContactProblem, ContactState, solve
from qsma.contact.zone import solve_in_zone, zone_from_state
from qsma.errors import InputError


def _ramp_problem(seed=3, n=20):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3 * n, 3 * n))
    p = ContactProblem(A @ A.T / n + np.diag(np.full(3 * n, 3.0)), 0.3, dim=3)
    base = np.zeros((n, 3))
    base[:, 2] = np.where(np.arange(n) < 14, 1.0, -0.3)
    return p, base


def _level(base, s, turn=0.0):
    lw = base.copy()
    lw[:, 0], lw[:, 1] = 0.5 * s * np.cos(turn), 0.5 * s * np.sin(turn)
    return lw


@pytest.mark.parametrize("method", ["basket", "active_set"])
def test_guess_from_a_coarser_path_gives_the_same_answer(method):
    """Coarse path 0 -> s2, fine path 0 -> s1 -> s2 (s1 sheared in another direction,
    so the paths end in different states): the fine level s2 solved from the coarse
    answer at s2 equals the fine level solved from s1 alone."""
    p, base = _ramp_problem()
    pre = solve(p, base, method=method)
    coarse = solve(p, _level(base, 1.0), pre.state, method=method)
    mid = solve(p, _level(base, 0.6, turn=1.2), pre.state, method=method)
    plain = solve(p, _level(base, 1.0), mid.state, method=method)
    guessed = solve(p, _level(base, 1.0), mid.state, method=method, guess=coarse.state)
    assert plain.success and guessed.success and guessed.residual <= 1e-10
    assert np.array_equal(plain.status, guessed.status)
    assert (plain.status == 1).sum() > 0                 # slipping pairs: the path matters
    assert np.abs(coarse.d - plain.d).max() > 1e-6 * np.abs(plain.d).max()
    np.testing.assert_allclose(guessed.d, plain.d, rtol=0, atol=1e-9 * np.abs(plain.d).max())
    np.testing.assert_allclose(guessed.lam, plain.lam, rtol=0,
                               atol=1e-9 * np.abs(plain.lam).max())
    # and on the zone, as qsma.run does it
    zone = zone_from_state(p, mid.state)
    zoned, _ = solve_in_zone(zone, _level(base, 1.0), mid.state, method=method,
                             guess=coarse.state)
    assert zoned.success
    np.testing.assert_allclose(zoned.d, plain.d, rtol=0, atol=1e-9 * np.abs(plain.d).max())


def test_a_guess_of_another_problem_is_refused():
    p, base = _ramp_problem()
    wrong = ContactState(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3, int))
    with pytest.raises(InputError, match="state.d must have shape"):
        solve(p, base, guess=wrong)


def test_a_guess_of_another_problem_is_refused_on_the_zone_too():
    """The zone path checks the guess before using its states (it used to fail with a
    numpy broadcasting error), and a guess that is not a state is named."""
    p, base = _ramp_problem()
    pre = solve(p, base)
    zone = zone_from_state(p, pre.state)
    wrong = ContactState(np.zeros((3, 3)), np.zeros((3, 3)), np.zeros(3, int))
    with pytest.raises(InputError, match="state.d must have shape"):
        solve_in_zone(zone, _level(base, 0.2), pre.state, guess=wrong)
    for call in (lambda: solve(p, base, guess="x"),
                 lambda: solve_in_zone(zone, _level(base, 0.2), pre.state, guess="x")):
        with pytest.raises(InputError, match="guess must be a ContactState"):
            call()
