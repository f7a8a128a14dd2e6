"""Exact one-pair solutions against brute-force enumeration; small multi-pair problems."""
import itertools

import numpy as np
import pytest

from qsma.contact import METHODS, OPEN, SLIPPING, STUCK, ContactProblem, solve
from qsma.contact.local import _trig_f, pair_solution, solve_pair, solve_pairs


def random_spd(rng, n, cond):
    """SPD matrix with eigenvalues log-spaced over ``cond`` and random eigenvectors."""
    Qm, _ = np.linalg.qr(rng.normal(size=(n, n)))
    return (Qm * np.geomspace(1.0, cond, n)) @ Qm.T


def is_solution(A, r, t_prev, g0, mu, d, rtol=1e-9):
    """The contact law of one pair at ``d``, checked directly (no natural map)."""
    lam = A @ d + r
    m = len(r) - 1
    scale = np.abs(A).max() * max(np.abs(d).max(), np.abs(t_prev).max(), abs(g0), 1e-300) \
        + np.abs(r).max()
    tol = rtol * scale
    P, Q, w, v = lam[m], lam[:m], d[m] + g0, d[:m] - t_prev
    if abs(P) <= tol and np.linalg.norm(Q) <= tol:                       # open
        return w >= -tol / A[m, m]
    if abs(w) > tol / A[m, m] or P < -tol:
        return False
    if np.linalg.norm(v) <= tol / A[0, 0]:                               # stuck
        return np.linalg.norm(Q) <= mu * P + tol
    return np.linalg.norm(Q + mu * P * v / np.linalg.norm(v)) <= tol     # slipping


def brute_force_slip_directions_3d(A, Q0, P0, mu, n=20000):
    """Sign changes of ``f`` on a fine grid of angles (independent of the quartic)."""
    theta = np.linspace(0, 2 * np.pi, n, endpoint=False)
    f = _trig_f(A, Q0, P0, mu, theta)
    change = np.flatnonzero(np.sign(f) != np.sign(np.roll(f, -1)))
    return theta[change]


def one_pair(rng, dim):
    A = random_spd(rng, dim, 10 ** rng.uniform(0, 3))
    r = rng.normal(size=dim) * 10 ** rng.uniform(-2, 2)
    return A, r, rng.normal(size=dim - 1) * 0.1, rng.uniform(-0.1, 0.1) * (rng.random() < 0.5), \
        rng.uniform(0, 2)


@pytest.mark.parametrize("dim", [2, 3])
def test_every_valid_candidate_is_a_solution_and_one_always_exists(dim):
    rng = np.random.default_rng(17 + dim)
    for _ in range(400):
        A, r, t_prev, g0, mu = one_pair(rng, dim)
        candidates = solve_pair(A, r, t_prev, g0, mu)
        valid = [c for c in candidates if c.violation == 0.0]
        for c in valid:
            assert is_solution(A, r, t_prev, g0, mu, c.d), c
        best = pair_solution(A, r, t_prev, g0, mu)
        assert is_solution(A, r, t_prev, g0, mu, best.d, rtol=1e-8)


def test_slip_directions_3d_match_a_fine_grid():
    rng = np.random.default_rng(3)
    for _ in range(60):
        A, r, t_prev, g0, mu = one_pair(rng, 3)
        d = np.append(t_prev, -g0)
        lam = A @ d + r
        roots = brute_force_slip_directions_3d(A, lam[:2], lam[2], mu)
        found = [c.s for c in solve_pair(A, r, t_prev, g0, mu)[2:]]
        # every slipping candidate (rho > 0) sits at a root of f on the grid
        for s in found:
            angle = np.arctan2(s[1], s[0]) % (2 * np.pi)
            gap = np.min(np.abs((roots - angle + np.pi) % (2 * np.pi) - np.pi))
            assert gap < 1e-3


def test_2d_pairs_with_several_solutions_report_each_of_them():
    """mu |b| > a: one 2D pair can have up to three solutions (non-uniqueness);
    every one reported is verified, and such cases occur."""
    rng = np.random.default_rng(21)
    several = 0
    for _ in range(3000):
        b = rng.uniform(-0.95, 0.95)
        A = np.array([[1.0, b], [b, 1.0]])
        mu, r = rng.uniform(1.1, 3.0), rng.normal(size=2)
        valid = [c for c in solve_pair(A, r, np.zeros(1), 0.0, mu) if c.violation == 0.0]
        for c in valid:
            assert is_solution(A, r, np.zeros(1), 0.0, mu, c.d)
        several += len(valid) >= 2
    assert several > 0


def test_3d_pair_that_slips_into_compression_is_not_returned_open():
    """The reported bug: stuck trial pressure negative, slipping raises it through
    the coupling; the old local solve returned lam = 0 with a penetration."""
    rng = np.random.default_rng(5)
    found = 0
    for _ in range(2000):
        A, r, t_prev, g0, mu = one_pair(rng, 3)
        mu = 0.6
        lam_stuck = A @ np.append(t_prev, -g0) + r
        d_open = -np.linalg.solve(A, r)
        if lam_stuck[2] >= 0 or d_open[2] + g0 >= 0:
            continue                                   # only stuck-in-tension, open-penetrating
        best = pair_solution(A, r, t_prev, g0, mu)
        assert best.state == SLIPPING and is_solution(A, r, t_prev, g0, mu, best.d, rtol=1e-8)
        found += 1
    assert found > 10


def brute_force_2d(problem, lam_w):
    """All solutions of a 2D problem by enumeration of (stuck, open, slip +, slip -)."""
    K, n = problem.K, problem.n_pairs
    out = []
    for combo in itertools.product(range(4), repeat=n):
        rows, rhs, d_fixed, free = [], [], np.zeros(2 * n), []
        for i, c in enumerate(combo):
            t, nn = 2 * i, 2 * i + 1
            if c == 1:                                            # open: lam_i = 0
                free += [t, nn]
                rows += [K[t], K[nn]]
                rhs += [-lam_w[i, 0], -lam_w[i, 1]]
            elif c >= 2:                                          # slipping: Q + mu s P = 0
                s = 1.0 if c == 2 else -1.0
                free.append(t)
                rows.append(K[t] + problem.mu[i] * s * K[nn])
                rhs.append(-(lam_w[i, 0] + problem.mu[i] * s * lam_w[i, 1]))
        d = d_fixed.copy()
        if free:
            R = np.array(rows)
            try:
                d[free] = np.linalg.solve(R[:, free], np.array(rhs))
            except np.linalg.LinAlgError:
                continue
        lam = (K @ d).reshape(n, 2) + lam_w
        if all(is_solution(problem.diagonal_blocks[i], lam[i] - problem.diagonal_blocks[i]
                           @ d.reshape(n, 2)[i], np.zeros(1), 0.0, problem.mu[i],
                           d.reshape(n, 2)[i], rtol=1e-8) for i in range(n)):
            out.append(d.reshape(n, 2))
    return out


@pytest.mark.parametrize("method", sorted(METHODS))
def test_two_pair_2d_answers_are_among_the_enumerated_solutions(method):
    rng = np.random.default_rng(11)
    checked = 0
    for _ in range(60):
        problem = ContactProblem(random_spd(rng, 4, 10 ** rng.uniform(0, 4)), rng.uniform(0, 1.5))
        lam_w = rng.normal(size=(2, 2))
        exact = brute_force_2d(problem, lam_w)
        with _no_check():
            r = solve(problem, lam_w, method=method, maxiter=2000 if method == "nodal_gs" else None)
        if r.success:
            scale = max(np.abs(e).max() for e in exact) if exact else 1.0
            assert any(np.abs(r.d - e).max() <= 1e-6 * scale for e in exact), (problem, lam_w)
            checked += 1
    assert checked >= 40


class _no_check:
    def __enter__(self):
        import warnings
        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("ignore")

    def __exit__(self, *exc):
        return self._w.__exit__(*exc)


@pytest.mark.parametrize("dim", [2, 3])
def test_batch_solve_matches_the_one_pair_solve(dim):
    """solve_pairs (numpy, all pairs at once) finds, per state, the smallest violation
    and the least violated slip direction of solve_pair's candidates, pair by pair."""
    rng = np.random.default_rng(101 + dim)
    pairs = [one_pair(rng, dim) for _ in range(500)]
    A, r, t_prev, g0, mu = (np.array([p[j] for p in pairs]) for j in range(5))
    found = solve_pairs(A, r, t_prev, g0, mu)
    slips_seen = 0
    for k, pair in enumerate(pairs):
        candidates = solve_pair(*pair)
        for state in (STUCK, SLIPPING, OPEN):
            own = [c.violation for c in candidates if c.state == state]
            expected = min(own) if own else np.inf
            assert found.violation[k, state] == pytest.approx(expected, rel=1e-9, abs=1e-12)
        slips = sorted((c for c in candidates if c.state == SLIPPING), key=lambda c: c.violation)
        assert found.has_slip[k] == bool(slips)
        if slips:
            slips_seen += 1
            np.testing.assert_allclose(found.direction[k], slips[0].s, atol=1e-9)
    assert slips_seen > 100                      # the slipping branch was exercised


def test_batch_solve_of_a_degenerate_quartic_uses_the_scalar_path():
    """An isotropic, uncoupled 3D pair: f(t) has no degree-2 terms (the quartic drops
    to lower degree); the slip direction is then exactly opposite to the trial shear."""
    A = np.eye(3)[None] * 2.0
    r = np.array([[3.0, 4.0, 1.0]])                  # Q0 = (3, 4), P0 = 1, mu = 0.5
    found = solve_pairs(A, r, np.zeros((1, 2)), np.zeros(1), np.array([0.5]))
    assert found.has_slip[0]
    np.testing.assert_allclose(found.direction[0], [-0.6, -0.8], atol=1e-12)
    assert found.violation[0, SLIPPING] == 0.0
