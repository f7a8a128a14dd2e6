"""Open-pair elimination (qsma.contact.zone) equals the full solve, and grows the zone
when an eliminated pair closes."""
import numpy as np
import pytest

from qsma.contact import ContactProblem, ContactState, solve
from qsma.contact.zone import ContactZone, solve_in_zone, zone_from_state
from qsma.errors import ContactConvergenceWarning


def _problem(n=24, seed=3):
    """A chain of 2D pairs with dense elastic coupling (SPD), mu = 0.4."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(2 * n, 2 * n))
    K = A @ A.T / n + np.diag(np.full(2 * n, 2.0))
    return ContactProblem(K, 0.4)


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
