"""Open-pair elimination (qsma.contact.zone) equals the full solve, and grows the zone
when an eliminated pair closes."""
from dataclasses import replace

import numpy as np
import pytest

from qsma.contact import (ContactProblem, ContactState, force_residual, legacy_residual, residual,
                          solve)
from qsma.contact import zone as zone_module
from qsma.contact.residual import measures
from qsma.contact.zone import (ContactZone, expected_closing, predicted_zone, solve_in_zone,
                               solve_preload, zone_from_state)
from qsma.errors import ContactConvergenceWarning


def _problem(n=24, seed=3, dim=2):
    """A chain of pairs with dense elastic coupling (SPD), mu = 0.4."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(dim * n, dim * n))
    K = A @ A.T / n + np.diag(np.full(dim * n, 2.0))
    return ContactProblem(K, 0.4, dim=dim)


def test_zone_matches_full_solve_and_grows():
    p = _problem()
    n = p.n_pairs
    lam_w = np.zeros((n, 2))
    lam_w[:, 1] = np.where(np.arange(n) < n // 2, 1.0, -1.0)    # half pressed, half lifted
    pre = solve(p, lam_w)
    assert pre.success and 0 < (pre.status == 2).sum() < n
    zone = zone_from_state(p, pre.state)
    assert zone.n_eliminated == (pre.status == 2).sum()
    state_full = state_zone = pre.state
    for s in np.linspace(0.1, 1.5, 8):
        lw = lam_w.copy()
        lw[:, 0] = 0.3 * s                        # shear
        lw[:, 1] += 1.2 * s                       # pressing closes the lifted pairs
        full = solve(p, lw, state_full)
        zres, zone = solve_in_zone(zone, lw, state_zone)
        assert full.success and zres.success
        np.testing.assert_allclose(zres.d, full.d, atol=1e-9)
        np.testing.assert_allclose(zres.lam, full.lam, atol=1e-9)
        assert np.array_equal(zres.status, full.status)
        state_full, state_zone = full.state, zres.state
    assert zone.n_eliminated < (pre.status == 2).sum()     # the zone grew


def test_zone_without_open_pairs_is_the_problem():
    p = _problem(6)
    z = ContactZone.build(p, np.ones(6, bool))
    assert z.sub is p and z.n_eliminated == 0


def test_zone_that_cannot_settle_is_a_failure():
    """With no rebuild allowed, a closing eliminated pair must not pass as an answer."""
    p = _problem()
    n = p.n_pairs
    lam_w = np.zeros((n, 2))
    lam_w[:, 1] = np.where(np.arange(n) < n // 2, 1.0, -1.0)
    pre = solve(p, lam_w)
    zone = zone_from_state(p, pre.state)
    lw = lam_w.copy()
    lw[:, 1] += 2.0                                   # closes the lifted pairs
    with pytest.warns(ContactConvergenceWarning):
        res, _ = solve_in_zone(zone, lw, pre.state, max_growth=1)
    assert not res.success and "not settled" in res.message and res.residual > 1e-10


# -- the preload on a predicted zone, the elimination itself, the full check (issue 14) --

def _slipping_problem(seed=0, n=30):
    """Pairs pressed and sheared (they slip) next to pairs in slight tension: the slip of
    the pressed pairs closes some of the lifted ones through the coupling of K, so the
    welded solution predicts the zone wrongly (8 pairs for seed 0)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(2 * n, 2 * n))
    K = A @ A.T / n + np.diag(np.full(2 * n, 2.0))
    pressed = np.arange(n) % 2 == 0
    lam_w = np.zeros((n, 2))
    lam_w[:, 1] = np.where(pressed, 1.0, -0.05)
    lam_w[:, 0] = np.where(pressed, 2.0, 0.0)
    return ContactProblem(K, 0.3), lam_w


def _assert_same(zoned, full):
    assert zoned.success and full.success
    assert np.array_equal(zoned.status, full.status)
    scale_d, scale_lam = np.abs(full.d).max(), np.abs(full.lam).max()
    np.testing.assert_allclose(zoned.d, full.d, rtol=0, atol=1e-12 * scale_d)
    np.testing.assert_allclose(zoned.lam, full.lam, rtol=0, atol=1e-12 * scale_lam)


def test_preload_on_a_wrong_prediction_grows_to_the_full_answer():
    p, lam_w = _slipping_problem()
    full = solve(p, lam_w)
    missed = (full.status != 2) & ~predicted_zone(p, lam_w)
    assert missed.sum() == 8                  # the predictor is wrong for these pairs
    res, zone = solve_preload(p, lam_w)
    _assert_same(res, full)
    assert np.all(zone.keep[missed])          # they joined the zone
    assert "zone of" in res.message


def _model_preload(model):
    from qsma.analysis import _contact_problem, _load_factors, prepare
    prep = prepare(model)
    problem = _contact_problem(prep.model, prep.pairing, prep.reduced.K)
    return problem, prep.reduced.welded_contact_force(_load_factors(prep.reduced, 0.0))


@pytest.mark.parametrize("example", ["sandwich_2d", "sandwich_3d"])
def test_zone_preload_equals_the_whole_interface_preload(example):
    """Refine 1: states equal, d and lam to round-off (measured 1.5e-14 and 1.7e-15
    relative to their largest value, benchmarks/bench_ramp.py)."""
    from qsma import examples
    p, lam_w = _model_preload(getattr(examples, example)(1))
    full = solve(p, lam_w)
    res, zone = solve_preload(p, lam_w)
    _assert_same(res, full)
    assert zone.n_eliminated > p.n_pairs // 2            # most pairs were never solved for
    ramp_zone = zone_from_state(p, res.state)            # carved out of the preload's
    assert ramp_zone.steps[0] is zone.steps[0]
    assert np.array_equal(ramp_zone.keep, res.status != 2)


def test_elimination_is_the_schur_complement_and_nesting_is_exact():
    p = _problem(12, seed=5)
    outer_keep = np.arange(12) < 9
    inner_keep = np.arange(12) < 5
    outer = ContactZone.build(p, outer_keep)
    K, i = p.K, np.repeat(outer_keep, 2)
    S = K[np.ix_(i, i)] - K[np.ix_(i, ~i)] @ np.linalg.solve(K[np.ix_(~i, ~i)], K[np.ix_(~i, i)])
    np.testing.assert_allclose(outer.sub.K, S, rtol=0, atol=1e-13 * np.abs(S).max())
    nested, direct = outer.narrowed(inner_keep), ContactZone.build(p, inner_keep)
    assert len(nested.steps) == 2
    np.testing.assert_allclose(nested.sub.K, direct.sub.K, rtol=0,
                               atol=1e-12 * np.abs(direct.sub.K).max())
    rng = np.random.default_rng(1)
    lam_w, d_A = rng.normal(size=(12, 2)), rng.normal(size=(5, 2))
    np.testing.assert_allclose(nested.welded(lam_w), direct.welded(lam_w), atol=1e-12)
    np.testing.assert_allclose(nested.expand(d_A, lam_w), direct.expand(d_A, lam_w),
                               atol=1e-12)
    # the expanded displacement leaves the eliminated pairs force-free
    d = direct.expand(d_A, lam_w)
    lam = (p.K @ d.ravel() + lam_w.ravel()).reshape(-1, 2)
    np.testing.assert_allclose(lam[~inner_keep], 0.0, atol=1e-12)
    # a load given as a basis (lam_w = Wb a) is eliminated once and gives the same
    Wb = rng.normal(size=(24, 3))
    a = np.array([1.0, -0.5, 2.0])
    lw = (Wb @ a).reshape(-1, 2)
    np.testing.assert_allclose(nested.welded(lw, (Wb, a)), nested.welded(lw), atol=1e-12)
    np.testing.assert_allclose(nested.expand(d_A, lw, (Wb, a)), nested.expand(d_A, lw),
                               atol=1e-12)


def test_growth_outside_the_outer_zone_borders_it():
    """A pair closing outside the outer elimination joins it by bordering (no new
    factorisation); the zone problem, the loads and the expansion equal those of a
    fresh elimination to round-off."""
    p = _problem(10, seed=2)
    zone = ContactZone.build(p, np.arange(10) < 4).narrowed(np.arange(10) < 2)
    inside = zone.grown(np.arange(10) == 3)
    assert inside.steps[0] is zone.steps[0] and inside.keep.sum() == 3
    outside = zone.grown(np.arange(10) == 7)
    assert outside.keep[7] and outside.keep.sum() == 3
    outer = outside.steps[0]
    assert isinstance(outer.inverse, zone_module._BorderedInverse)
    assert np.array_equal(outer.keep, (np.arange(10) < 4) | (np.arange(10) == 7))
    _assert_same_zone(outside, ContactZone.build(p, outside.keep), p)


def test_growth_inside_the_outer_zone_borders_the_inner_elimination():
    p = _problem(14, seed=4, dim=3)
    zone = ContactZone.build(p, np.arange(14) < 10).narrowed(np.arange(14) < 3)
    inner = zone.steps[1]
    grown = zone.grown(np.isin(np.arange(14), [5, 8]))
    assert grown.steps[0] is zone.steps[0] and len(grown.steps) == 2
    assert isinstance(grown.steps[1].inverse, zone_module._BorderedInverse)
    assert grown.steps[1] is not inner and grown.keep.sum() == 5
    _assert_same_zone(grown, ContactZone.build(p, grown.keep), p)
    whole = grown.grown(np.arange(14) < 10)                 # the whole outer zone
    assert len(whole.steps) == 1 and whole.steps[0] is zone.steps[0]


def _assert_same_zone(zone, fresh, p, seed=1):
    """Zone stiffness, welded force (direct and through a basis) and expansion of two
    eliminations of the same zone agree to 1e-12 of their scale."""
    assert np.array_equal(zone.keep, fresh.keep)
    scale = np.abs(fresh.sub.K).max()
    np.testing.assert_allclose(zone.sub.K, fresh.sub.K, rtol=0, atol=1e-12 * scale)
    rng = np.random.default_rng(seed)
    lam_w = rng.normal(size=(p.n_pairs, p.dim))
    d_A = rng.normal(size=(int(zone.keep.sum()), p.dim))
    np.testing.assert_allclose(zone.welded(lam_w), fresh.welded(lam_w), atol=1e-12)
    Wb = rng.normal(size=(p.size, 2))
    a = np.array([0.7, -1.3])
    lw = (Wb @ a).reshape(-1, p.dim)
    np.testing.assert_allclose(zone.welded(lw, (Wb, a)), fresh.welded(lw), atol=1e-12)
    d = zone.expand(d_A, lam_w)
    np.testing.assert_allclose(d, fresh.expand(d_A, lam_w), atol=1e-12)
    lam = (p.K @ d.ravel() + lam_w.ravel()).reshape(-1, p.dim)
    np.testing.assert_allclose(lam[~zone.keep], 0.0, atol=1e-12)   # eliminated: force-free
    np.testing.assert_allclose(zone.expand(d_A, lw, (Wb, a)), fresh.expand(d_A, lw),
                               atol=1e-12)


@pytest.mark.parametrize("dim", [2, 3])
def test_repeated_bordering_equals_a_fresh_elimination(dim):
    """Pairs joining one or a few at a time, up to MAX_BORDERS borderings in a row (then
    a new elimination): each zone equals the elimination built from scratch."""
    rng = np.random.default_rng(7)
    n = 40
    A = rng.normal(size=(dim * n, dim * n))
    p = ContactProblem(A @ A.T / n + np.diag(np.full(dim * n, 2.0)), 0.3, dim=dim)
    zone = ContactZone.build(p, np.arange(n) < 6)
    order = rng.permutation(np.arange(6, n))
    depths = []
    for k in range(zone_module.MAX_BORDERS + 2):
        pairs = np.zeros(n, bool)
        pairs[order[k::zone_module.MAX_BORDERS + 2][:1 + k % 3]] = True
        zone = zone.grown(pairs)
        depths.append(zone.steps[0].inverse.depth)
        _assert_same_zone(zone, ContactZone.build(p, zone.keep), p, seed=k)
    assert max(depths) == zone_module.MAX_BORDERS and 0 in depths     # then rebuilt


def _closing_ramp(n_levels):
    """A 3D ramp that closes lifted pairs level by level (one or two per level): the
    problem, the preload's load and the levels' factors and loads."""
    rng = np.random.default_rng(11)
    n = 30
    A = rng.normal(size=(3 * n, 3 * n))
    p = ContactProblem(A @ A.T / n + np.diag(np.full(3 * n, 3.0)), 0.3, dim=3)
    base = np.zeros((n, 3))
    base[:, 2] = np.where(np.arange(n) < 10, 1.0, -np.linspace(0.1, 2.0, n))
    levels = np.linspace(0.2, 2.4, n_levels)
    loads = []
    for s in levels:
        lw = base.copy()
        lw[:, 0], lw[:, 1], lw[:, 2] = 0.3 * s, -0.1 * s, base[:, 2] + s
        loads.append(lw)
    return p, base, levels, loads


def test_ramp_whose_zone_grows_by_bordering_equals_the_full_solve():
    """A 3D ramp that closes lifted pairs level by level: every zone answer (zone grown
    by bordering) passes the full residual and equals the whole-interface solve."""
    p, base, _, loads = _closing_ramp(10)
    pre = solve(p, base)
    zone = zone_from_state(p, pre.state)
    first_outer = zone.steps[0]
    state_full = state_zone = pre.state
    bordered = 0
    for lw in loads:
        full = solve(p, lw, state_full)
        zres, zone = solve_in_zone(zone, lw, state_zone)
        bordered += isinstance(zone.steps[0].inverse, zone_module._BorderedInverse)
        _assert_same(zres, full)
        assert zres.residual <= 1e-10 and zres.residual_force <= 1e-6
        state_full, state_zone = full.state, zres.state
    assert bordered and zone.steps[0] is not first_outer


def _zone_ramp(p, base, levels, loads, expect, calls):
    """The ramp on a zone, with the pairs expected to close extrapolated from the two
    levels before (``expect``) or not; every answer checked against the whole
    interface. Returns the number of zone solves (``calls``: the list the patched zone
    solve appends to)."""
    calls.clear()
    pre = solve(p, base)
    zone = zone_from_state(p, pre.state)
    state_full = state_zone = pre.state
    done = []
    for k, lw in enumerate(loads):
        closing = None
        if expect and k >= 2:
            ratio = (levels[k] - levels[k - 1]) / (levels[k - 1] - levels[k - 2])
            closing = expected_closing(p, done[k - 2].d, done[k - 1].d, ratio)
        full = solve(p, lw, state_full)
        zres, zone = solve_in_zone(zone, lw, state_zone, closing=closing)
        _assert_same(zres, full)
        if closing is not None:
            assert zone.keep[closing].all()          # the expected pairs joined the zone
        state_full, state_zone = full.state, zres.state
        done.append(zres)
    return len(calls)


def test_pairs_expected_to_close_join_the_zone_before_the_solve(monkeypatch):
    """Extrapolating which pairs close takes away zone solves that found them closing,
    and every answer still equals the whole interface's."""
    p, base, levels, loads = _closing_ramp(23)
    calls, inner = [], zone_module.solve
    monkeypatch.setattr(zone_module, "solve", lambda *a, **k: calls.append(1) or inner(*a, **k))
    plain = _zone_ramp(p, base, levels, loads, False, calls)
    expected = _zone_ramp(p, base, levels, loads, True, calls)
    assert plain > len(levels)                # levels solved again on a grown zone
    assert expected < plain


def test_a_wrong_expectation_changes_no_answer():
    """Pairs expected to close that stay open are zone unknowns without force: the
    answer is the whole interface's."""
    p, base, _, loads = _closing_ramp(23)
    pre = solve(p, base)
    zone = zone_from_state(p, pre.state)
    every = np.ones(p.n_pairs, bool)
    res, grown = solve_in_zone(zone, loads[0], pre.state, closing=every)
    _assert_same(res, solve(p, loads[0], pre.state))
    assert grown.keep.all() and (res.status == 2).any()


def test_expected_closing_extrapolates_the_opening():
    p = ContactProblem(np.eye(9) * 2.0, 0.3, dim=3, gap0=np.array([0.0, 0.0, 1.0]))
    before, last = np.zeros((3, 3)), np.zeros((3, 3))
    before[:, 2] = [1.0, 1.0, 0.0]        # openings w = d_n + g0: 1, 1, 1
    last[:, 2] = [0.4, 0.6, -0.4]          # 0.4, 0.6, 0.6: closing by 0.6, 0.4, 0.4 a step
    assert expected_closing(p, before, last, 1.0).tolist() == [True, False, False]
    assert expected_closing(p, before, last, 2.0).tolist() == [True, True, True]
    assert not expected_closing(p, last, before, 1.0).any()       # opening pairs


def test_full_check_rejects_a_corrupted_zone_answer(monkeypatch):
    """The zone answer is judged on the full problem: a zone solve that reports success
    with a wrong force (1e-6 of the largest, on one pair) must come out as a failure."""
    import qsma.contact.zone as zone_module
    p, lam_w = _slipping_problem()
    honest, _ = solve_preload(p, lam_w)
    assert honest.success

    def corrupted(problem, welded, state, **kwargs):
        res = solve(problem, welded, state, **kwargs)
        lam = res.lam.copy()
        lam[np.argmax(np.abs(lam[:, -1])), -1] *= 1 + 1e-6
        return replace(res, lam=lam)

    monkeypatch.setattr(zone_module, "solve", corrupted)
    with pytest.warns(ContactConvergenceWarning):
        res, _ = solve_preload(p, lam_w)
    assert not res.success and res.residual > 1e-10


def test_measures_equal_the_three_functions():
    p, lam_w = _slipping_problem(3)
    res = solve(p, lam_w)
    rng = np.random.default_rng(4)
    d = res.d + 1e-7 * rng.normal(size=res.d.shape)
    lam = res.lam + 1e-7 * rng.normal(size=res.lam.shape)
    prev = ContactState.reference(p)
    got = measures(p, lam_w, d, lam, prev)
    want = (residual(p, lam_w, d, lam, prev), force_residual(p, lam_w, d, lam, prev),
            legacy_residual(p, lam_w, d, lam, prev))
    assert got == want and min(want) > 0


def test_lifting_ramp_narrows_the_zone_and_equals_the_full_solve():
    """Pairs pressed by the preload lift one group after another: the zone is narrowed to
    the closed pairs (fitted_zone) and every answer equals the whole-interface solve."""
    rng = np.random.default_rng(12)
    n = 30
    A = rng.normal(size=(3 * n, 3 * n))
    p = ContactProblem(A @ A.T / n + np.diag(np.full(3 * n, 3.0)), 0.3, dim=3)
    base = np.zeros((n, 3))
    base[:, 2] = 1.0
    pre = solve(p, base)
    assert np.all(pre.status != 2)
    zone = zone_from_state(p, pre.state)
    state_full = state_zone = pre.state
    narrowed = 0
    for s in np.linspace(0.2, 2.0, 10):
        lw = base.copy()
        lw[:, 0] = 0.2 * s
        lw[:, 2] = 1.0 - s * np.linspace(0.2, 1.6, n)       # lifts from the last pair on
        start = zone_module.fitted_zone(zone, state_zone)
        narrowed += start.keep.sum() < zone.keep.sum()
        full = solve(p, lw, state_full)
        zres, zone = solve_in_zone(zone, lw, state_zone)
        _assert_same(zres, full)
        assert zres.residual <= 1e-10 and zres.residual_force <= 1e-6
        state_full, state_zone = full.state, zres.state
    assert narrowed and (state_zone.status == 2).sum() > n // 2
