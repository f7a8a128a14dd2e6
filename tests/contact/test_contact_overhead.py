"""The overhead of a solve (issue 14): a guess that already is the answer is accepted
after the one check of the full problem, a 3D pass ends as soon as its iterate meets
the residual, the slip-direction line search hands its product on; each against the
path it shortens (same answers), and the full problem is read twice per solve."""
import numpy as np
import pytest

from qsma.contact import ContactProblem, solve
from qsma.contact import basket
from qsma.contact.zone import solve_in_zone, zone_from_state

TOL = 1e-10


def _problem(seed=3, n=20, dim=3):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(dim * n, dim * n))
    p = ContactProblem(A @ A.T / n + np.diag(np.full(dim * n, 3.0)), 0.3, dim=dim)
    base = np.zeros((n, dim))
    base[:, -1] = np.where(np.arange(n) < 14, 1.0, -0.3)
    return p, base


def _level(base, s, turn=0.0):
    lw = base.copy()
    lw[:, 0] = 0.5 * s * np.cos(turn)
    if lw.shape[1] == 3:
        lw[:, 1] = 0.5 * s * np.sin(turn)
    return lw


def _ramp(p, base, levels, **kw):
    state, out = solve(p, base).state, []
    for s in levels:
        res = solve(p, _level(base, s, turn=0.7 * s), state, **kw)
        out.append(res)
        state = res.state
    return out


@pytest.mark.parametrize("dim", [2, 3])
def test_a_guess_that_is_the_answer_is_accepted_without_iterating(dim):
    """The same level from the same previous state with its own answer as the guess:
    no iteration, the answer itself (bit for bit), judged on the residual as always;
    on the zone too."""
    p, base = _problem(dim=dim)
    pre = solve(p, base)
    first = solve(p, _level(base, 1.0), pre.state)
    assert first.success and first.nit > 0 and first.n_slipping > 0
    again = solve(p, _level(base, 1.0), pre.state, guess=first.state)
    assert again.success and again.nit == 0 and again.residual <= TOL
    assert "starting guess" in again.message
    np.testing.assert_array_equal(again.d, first.d)
    np.testing.assert_array_equal(again.status, first.status)
    zone = zone_from_state(p, pre.state)
    zoned, _ = solve_in_zone(zone, _level(base, 1.0), pre.state, guess=first.state)
    assert zoned.success and zoned.nit == 0 and zoned.residual <= TOL
    np.testing.assert_array_equal(zoned.d, first.d)


def test_the_zone_after_an_accepted_guess_holds_every_closed_pair():
    """An accepted guess on a zone that lacks some of its closed pairs returns a zone
    grown by them, judged by the answer's own classification even when the guess
    labels every pair open (found in review: the next level then needed 13 block
    steps instead of 4); the answer is not a view of the guess's arrays."""
    from qsma.contact import ContactState
    from qsma.contact.state import OPEN
    from qsma.contact.zone import ContactZone
    p, base = _problem()
    pre = solve(p, base)
    first = solve(p, _level(base, 1.0), pre.state)
    closed = first.status != OPEN
    keep = closed.copy()
    keep[np.flatnonzero(closed)[:4]] = False          # four closed pairs left out
    mislabelled = ContactState(first.d.copy(), first.lam.copy(),
                               np.full_like(first.status, OPEN))
    got, zone = solve_in_zone(ContactZone.build(p, keep), _level(base, 1.0), pre.state,
                              guess=mislabelled)
    assert got.nit == 0 and got.success
    np.testing.assert_array_equal(got.status, first.status)
    assert zone.keep[closed].all()
    assert not np.shares_memory(got.d, mislabelled.d)


@pytest.mark.parametrize("on_zone", [False, True])
def test_a_guess_that_meets_the_law_but_not_equilibrium_is_solved_from(on_zone):
    """The product-free filter looks at the contact law only: a guess whose forces obey
    the law but belong to another load passes it, and the full check (equilibrium)
    must reject it; the level is then iterated from the guess to the right answer."""
    p, base = _problem()
    pre = solve(p, base)
    lw = _level(base, 1.0)
    first = solve(p, lw, pre.state)
    other = lw * (1 + 1e-6)                 # the law of `first` holds, equilibrium not
    plain = solve(p, other, pre.state)
    if on_zone:
        got, _ = solve_in_zone(zone_from_state(p, pre.state), other, pre.state,
                               guess=first.state)
    else:
        got = solve(p, other, pre.state, guess=first.state)
    assert got.success and got.nit > 0 and got.residual <= TOL
    np.testing.assert_allclose(got.d, plain.d, rtol=0, atol=1e-9 * np.abs(plain.d).max())


def test_a_guess_from_another_path_is_iterated():
    """A guess from a path that sheared the other way fails the check: iterated, and
    the answer is that of the plain solve."""
    p, base = _problem()
    pre = solve(p, base)
    coarse = solve(p, _level(base, 1.0), pre.state)
    mid = solve(p, _level(base, 0.6, turn=1.2), pre.state)
    plain = solve(p, _level(base, 1.0), mid.state)
    guessed = solve(p, _level(base, 1.0), mid.state, guess=coarse.state)
    assert guessed.success and guessed.nit > 0
    np.testing.assert_allclose(guessed.d, plain.d, rtol=0, atol=1e-9 * np.abs(plain.d).max())


def test_early_end_of_a_3d_pass_gives_the_answer_of_the_confirming_step(monkeypatch):
    """A 3D ramp with slipping pairs, the pass accepted as soon as its iterate meets the
    residual against the old rule (one more block step that must not move ``d``): same
    states, the same answers to round-off, fewer block steps."""
    p, base = _problem()
    levels = np.linspace(0.2, 2.0, 8)
    fast = _ramp(p, base, levels)
    monkeypatch.setattr(basket._BasketRun, "_accepted_early", lambda self, tr: None)
    slow = _ramp(p, base, levels)
    assert all(r.success and r.residual <= TOL for r in fast + slow)
    assert sum(r.n_slipping for r in fast) > 0
    for a, b in zip(fast, slow):
        np.testing.assert_array_equal(a.status, b.status)
        np.testing.assert_allclose(a.d, b.d, rtol=0, atol=1e-12 * np.abs(b.d).max())
        np.testing.assert_allclose(a.lam, b.lam, rtol=0, atol=1e-12 * np.abs(b.lam).max())
    assert sum(r.nit for r in fast) < sum(r.nit for r in slow)


def test_early_end_of_a_3d_pass_needs_the_residual(monkeypatch):
    """Every pair passing its check is not enough: an iterate whose residual is above
    tol (here the measured residual raised to 10 tol) is not accepted early, the pass
    goes on (a verdict of None), and the ramp still converges to the same answers."""
    p, base = _problem()
    levels = np.linspace(0.2, 2.0, 8)
    plain = _ramp(p, base, levels)
    original, real = basket._BasketRun._accepted_early, basket.measures
    verdicts = []

    def above_tol(self, tr):
        def raised(*args):
            m = real(*args)
            return (max(m[0], 10 * self.tol),) + tuple(m[1:])
        monkeypatch.setattr(basket, "measures", raised)
        try:
            verdicts.append(original(self, tr))
        finally:
            monkeypatch.setattr(basket, "measures", real)
        return verdicts[-1]

    monkeypatch.setattr(basket._BasketRun, "_accepted_early", above_tol)
    slower = _ramp(p, base, levels)
    assert verdicts and all(v is None for v in verdicts)
    assert all(r.success and r.residual <= TOL for r in slower)
    for a, b in zip(slower, plain):
        np.testing.assert_array_equal(a.status, b.status)
        np.testing.assert_allclose(a.d, b.d, rtol=0, atol=1e-12 * np.abs(b.d).max())


def test_line_search_products_handed_on_give_the_same_ramp(monkeypatch):
    """The full step's ``K d`` handed to the next Newton step against forming it again
    from ``d``: the same block steps and answers (round-off only)."""
    p, base = _problem()
    levels = np.linspace(0.2, 2.0, 8)
    handed = _ramp(p, base, levels)
    plain_set = basket._BasketRun._set_iterate
    monkeypatch.setattr(basket._BasketRun, "_set_iterate",
                        lambda self, d, Kd=None: plain_set(self, d))
    fresh = _ramp(p, base, levels)
    for a, b in zip(handed, fresh):
        assert a.success and b.success and a.nit == b.nit
        np.testing.assert_allclose(a.d, b.d, rtol=0, atol=1e-12 * np.abs(b.d).max())


def test_the_full_problem_is_read_twice_per_zone_solve(monkeypatch):
    """Per level on the zone, ``K`` of the full problem enters one ``K d`` and one
    ``|K| |d|`` (the check of the answer); the iteration works on the zone's matrix.
    With an accepted guess the check is all there is; a guess that the product-free
    filter rejects costs nothing more; one that passes the filter and fails the check
    (the law holds, equilibrium not) costs a second check."""
    p, base = _problem(n=30)
    pre = solve(p, base)
    zone = zone_from_state(p, pre.state)
    calls = {"product": 0, "abs_product": 0}
    for name in calls:
        original = getattr(ContactProblem, name)

        def counted(self, *args, _original=original, _name=name, **kw):
            calls[_name] += self is p
            return _original(self, *args, **kw)
        monkeypatch.setattr(ContactProblem, name, counted)

    def level(s, previous, guess=None):
        nonlocal zone
        res, zone = solve_in_zone(zone, _level(base, s, turn=0.7 * s), previous, guess=guess)
        assert res.success and res.residual <= TOL
        return res

    first = level(0.5, pre.state)
    second = level(1.0, first.state)
    assert first.nit > 0 and second.nit > 0 and calls == {"product": 2, "abs_product": 2}
    assert level(1.0, first.state, guess=second.state).nit == 0
    assert calls == {"product": 3, "abs_product": 3}
    other_path = level(1.0, level(0.5, pre.state, guess=None).state)   # same path: 2 reads
    assert calls == {"product": 5, "abs_product": 5}
    sideways = level(1.0, pre.state)                    # another path to 1.0
    assert calls == {"product": 6, "abs_product": 6}
    assert level(1.0, first.state, guess=sideways.state).nit > 0      # filter rejects
    assert calls == {"product": 7, "abs_product": 7}
    assert level(1.0, first.state, guess=first.state).nit > 0         # check rejects
    assert calls == {"product": 9, "abs_product": 9}
    np.testing.assert_allclose(other_path.d, second.d, rtol=0, atol=1e-12 * np.abs(second.d).max())


def test_linearised_first_step_gives_the_same_ramp(monkeypatch):
    """The first block step of a 3D solve linearised at the starting iterate against the
    directions of the starting forces with ``alpha = 0``: the same states and answers
    to round-off, not more block steps."""
    p, base = _problem()
    levels = np.linspace(0.2, 2.0, 8)
    newton = _ramp(p, base, levels)
    monkeypatch.setattr(basket._BasketRun, "_linearised_start", lambda self: None)
    plain = _ramp(p, base, levels)
    for a, b in zip(newton, plain):
        assert a.success and b.success
        np.testing.assert_array_equal(a.status, b.status)
        np.testing.assert_allclose(a.d, b.d, rtol=0, atol=1e-11 * np.abs(b.d).max())
    assert sum(r.nit for r in newton) <= sum(r.nit for r in plain)


@pytest.mark.parametrize("dim", [2, 3])
def test_active_set_hands_its_measures_on_and_they_are_the_iterates(dim, monkeypatch):
    """``active_set`` reports the measures of the iterate it stopped on, from the same
    products as its stopping test: they equal the measures formed afresh, and the
    registry does not form them again (a ramp with a counting spy on the registry's
    own evaluation: no call)."""
    from qsma.contact import registry
    from qsma.contact.active_set import solve_active_set
    from qsma.contact.residual import measures
    from qsma.contact.state import ContactState
    p, base = _problem(dim=dim)
    pre = solve(p, base, method="active_set")
    lw = _level(base, 1.0, turn=0.7)
    out = solve_active_set(p, lw, pre.state, tol=TOL)
    assert out.converged and out.nit > 0 and out.measures is not None
    assert out.measures == measures(p, lw, out.d, out.lam, pre.state)
    assert out.measures[0] <= TOL
    calls = []
    real = registry._measures
    monkeypatch.setattr(registry, "_measures", lambda *a: calls.append(1) or real(*a))
    ramp = _ramp(p, base, np.linspace(0.2, 2.0, 8), method="active_set")
    assert all(r.success and r.residual <= TOL for r in ramp)
    assert any(r.n_slipping > 0 for r in ramp) and not calls
