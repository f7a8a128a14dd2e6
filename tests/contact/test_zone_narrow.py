"""Narrowing a zone by extending its inner elimination (Elimination.extended) gives the
zone problem of a fresh elimination: stiffness (the Schur complement of every pair
outside the zone), K_OO^-1 K_OA, loads, expansion and solves with K_OO^-1, to
round-off, alone and in chains mixed with borderings."""
import numpy as np
import pytest

from qsma.contact import ContactProblem
from qsma.contact import zone as zone_module
from qsma.contact.zone import ContactZone, Elimination, fitted_zone
from qsma.contact.state import OPEN, STUCK, ContactState

#: Agreement with a fresh elimination, relative to the scale of the compared numbers.
#: Measured: 1e-15 to 4e-15 after chains of up to MAX_BORDERS steps on these problems.
TOL = 1e-12


def _problem(n, dim, seed):
    """Dense SPD coupling of ``n`` pairs (eigenvalues >= 2), mu = 0.3."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(dim * n, dim * n))
    return ContactProblem(A @ A.T / n + np.diag(np.full(dim * n, 2.0)), 0.3, dim=dim)


def _schur(p, keep):
    """The zone stiffness by its definition, with a dense solve."""
    i = np.repeat(keep, p.dim)
    K = p.K
    return K[np.ix_(i, i)] - K[np.ix_(i, ~i)] @ np.linalg.solve(K[np.ix_(~i, ~i)],
                                                               K[np.ix_(~i, i)])


def _assert_same_step(step, fresh, seed=0):
    """Two eliminations of the same problem and zone hold the same numbers."""
    assert np.array_equal(step.keep, fresh.keep)
    assert np.array_equal(step.iA, fresh.iA) and np.array_equal(step.iO, fresh.iO)
    scale = np.abs(fresh.sub.K).max()
    np.testing.assert_allclose(step.sub.K, fresh.sub.K, rtol=0, atol=TOL * scale)
    np.testing.assert_allclose(step.sub.mu, fresh.sub.mu, rtol=0, atol=0)
    np.testing.assert_allclose(step.Bt, fresh.Bt, rtol=0,
                               atol=TOL * max(1.0, np.abs(fresh.Bt).max()))
    rng = np.random.default_rng(seed)
    p = step.problem
    lam_w = rng.normal(size=p.size)
    for got, want in zip(step.load(lam_w)[:2], fresh.load(lam_w)[:2]):
        np.testing.assert_allclose(got, want, rtol=0, atol=TOL * max(1.0, np.abs(want).max()))
    if fresh.inverse is not None:
        x = rng.normal(size=(len(fresh.iO), 3))
        want = fresh.inverse.solve(x)
        np.testing.assert_allclose(step.inverse.solve(x), want, rtol=0,
                                   atol=TOL * np.abs(want).max())
        np.testing.assert_allclose(step.inverse.solve(x[:, 0]), want[:, 0], rtol=0,
                                   atol=TOL * np.abs(want).max())
    d_A = rng.normal(size=len(fresh.iA))
    u = fresh.load(lam_w)[1]
    d = step.expand(d_A, u)
    np.testing.assert_allclose(d, fresh.expand(d_A, u), rtol=0,
                               atol=TOL * max(1.0, np.abs(d).max()))
    lam = p.K @ d + lam_w                       # the eliminated unknowns are force-free
    np.testing.assert_allclose(lam[step.iO], 0.0, atol=TOL * np.abs(lam).max())


@pytest.mark.parametrize("dim", [2, 3])
def test_extended_elimination_is_the_schur_complement(dim):
    p = _problem(30, dim, seed=dim)
    rng = np.random.default_rng(5)
    zone = rng.random(30) < 0.7
    narrower = zone & (rng.random(30) < 0.6)
    step = Elimination.build(p, zone).extended(narrower)
    assert isinstance(step.inverse, zone_module._ExtendedInverse)
    assert step.inverse.depth == 1
    S = _schur(p, narrower)
    np.testing.assert_allclose(step.sub.K, S, rtol=0, atol=TOL * np.abs(S).max())
    _assert_same_step(step, Elimination.build(p, narrower))


@pytest.mark.parametrize("dim", [2, 3])
def test_chain_of_narrowings_and_borderings_equals_fresh_eliminations(dim):
    """MAX_BORDERS steps in a row, narrowing and bordering alternating at random: every
    step equals the elimination built from scratch."""
    n = 40
    p = _problem(n, dim, seed=10 + dim)
    rng = np.random.default_rng(dim)
    step = Elimination.build(p, rng.random(n) < 0.8)
    kinds = []
    for k in range(zone_module.MAX_BORDERS):
        inside, outside = np.flatnonzero(step.keep), np.flatnonzero(~step.keep)
        pairs = np.zeros(n, bool)
        if (rng.random() < 0.6 or len(outside) == 0) and len(inside) > 3:
            pairs[rng.choice(inside, 1 + len(inside) // 4, replace=False)] = True
            step = step.extended(step.keep & ~pairs)
            kinds.append("narrow")
        else:
            pairs[rng.choice(outside, min(len(outside), 1 + k % 3), replace=False)] = True
            step = step.bordered(pairs)
            kinds.append("border")
        assert step.inverse.depth == k + 1
        _assert_same_step(step, Elimination.build(p, step.keep), seed=k)
    assert {"narrow", "border"} <= set(kinds)


def test_edge_cases_of_the_extension():
    p = _problem(12, 3, seed=1)
    keep = np.arange(12) < 8
    step = Elimination.build(p, keep)
    assert step.extended(keep) is step                                   # R empty
    one = np.arange(12) == 5
    _assert_same_step(step.extended(one), Elimination.build(p, one))    # all but one pair
    # a zone of one pair: bordered by two, then narrowed back to one (another one)
    single = Elimination.build(p, one)
    assert single.extended(one) is single
    three = single.bordered(np.isin(np.arange(12), [0, 11]))
    last = np.arange(12) == 11
    _assert_same_step(three.extended(last), Elimination.build(p, last))
    # nothing eliminated yet: the extension is a new elimination
    whole = Elimination.build(p, np.ones(12, bool))
    assert whole.inverse is None
    _assert_same_step(whole.extended(keep), Elimination.build(p, keep))
    with pytest.raises(ValueError, match="inside this zone"):
        step.extended(np.arange(12) >= 6)


def test_narrowed_zone_extends_the_inner_elimination_up_to_the_depth_cap():
    """ContactZone.narrowed inside the current zone extends the inner elimination (the
    outer one shared); at MAX_BORDERS steps it carves a fresh one out of the outer
    zone; a zone that is not inside the current one is carved afresh too."""
    n = 60
    p = _problem(n, 3, seed=4)
    zone = ContactZone.build(p, np.arange(n) < 50).narrowed(np.arange(n) < 45)
    outer = zone.steps[0]
    depths = []
    for k in range(zone_module.MAX_BORDERS + 2):
        keep = zone.keep.copy()
        keep[np.flatnonzero(keep)[-2:]] = False
        zone = zone.narrowed(keep)
        assert zone.steps[0] is outer and len(zone.steps) == 2
        depths.append(zone.steps[1].inverse.depth)
        fresh = ContactZone.build(p, keep)
        np.testing.assert_allclose(zone.sub.K, fresh.sub.K, rtol=0,
                                   atol=TOL * np.abs(fresh.sub.K).max())
        lam_w = np.random.default_rng(k).normal(size=(n, 3))
        np.testing.assert_allclose(zone.welded(lam_w), fresh.welded(lam_w), atol=TOL * 10)
        d_A = np.random.default_rng(k + 100).normal(size=(int(keep.sum()), 3))
        np.testing.assert_allclose(zone.expand(d_A, lam_w), fresh.expand(d_A, lam_w),
                                   atol=TOL * 10)
    assert depths[:zone_module.MAX_BORDERS] == list(range(1, zone_module.MAX_BORDERS + 1))
    assert depths[zone_module.MAX_BORDERS] == 0                       # rebuilt at the cap
    other = np.zeros(n, bool)
    other[[0, 48]] = True                                  # 48 left the zone: carved afresh
    assert zone.narrowed(other).steps[1].inverse.depth == 0


def test_fitted_zone_extends_and_a_growth_after_it_is_exact():
    """A level's zone narrowed to its closed pairs (fitted_zone) by extension, then grown
    by pairs that close again (bordering the extended elimination): both equal a fresh
    elimination."""
    n = 30
    p = _problem(n, 3, seed=8)
    zone = ContactZone.build(p, np.arange(n) < 24).narrowed(np.arange(n) < 20)
    status = np.full(n, OPEN)
    status[:8] = STUCK                                       # 12 of the 20 pairs opened
    state = ContactState(np.zeros((n, 3)), np.zeros((n, 3)), status)
    fitted = fitted_zone(zone, state)
    assert isinstance(fitted.steps[1].inverse, zone_module._ExtendedInverse)
    assert np.array_equal(fitted.keep, status != OPEN)
    _assert_same_step(fitted.steps[1], Elimination.build(zone.steps[0].sub, fitted.keep[:24]))
    grown = fitted.grown(np.isin(np.arange(n), [10, 15]))
    assert isinstance(grown.steps[1].inverse, zone_module._BorderedInverse)
    assert grown.steps[1].inverse.depth == 2
    fresh = ContactZone.build(p, grown.keep)
    np.testing.assert_allclose(grown.sub.K, fresh.sub.K, rtol=0,
                               atol=TOL * np.abs(fresh.sub.K).max())
    lam_w = np.random.default_rng(3).normal(size=(n, 3))
    d_A = np.random.default_rng(4).normal(size=(int(grown.keep.sum()), 3))
    np.testing.assert_allclose(grown.expand(d_A, lam_w), fresh.expand(d_A, lam_w),
                               atol=TOL * 10)


def test_solve_of_columns_on_the_removed_rows_skips_the_parent():
    """Unit columns of the rows that left the zone (what a bordering asks when those
    pairs close again) are solved without the parent inverse, with the same numbers."""
    p = _problem(20, 3, seed=9)
    step = Elimination.build(p, np.arange(20) < 14).extended(np.arange(20) < 9)
    inverse = step.inverse
    x = np.zeros((len(step.iO), 4))
    x[inverse.at_R[:4], np.arange(4)] = 1.0
    calls = []

    class Counted:
        depth = 0

        def solve(self, y):
            calls.append(y)
            return inverse.parent.solve(y)

    counted = zone_module._ExtendedInverse(Counted(), inverse.at_O, inverse.at_R,
                                           inverse.BR, inverse.L)
    got = counted.solve(x)
    assert not calls
    want = Elimination.build(p, np.arange(20) < 9).inverse.solve(x)
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL * np.abs(want).max())
    x[inverse.at_O[0], 0] = 1.0                                # a column reaching O
    np.testing.assert_allclose(counted.solve(x), inverse.solve(x), rtol=0, atol=0)
    assert len(calls) == 1
