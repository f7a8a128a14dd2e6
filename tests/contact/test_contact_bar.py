"""A bar on a rigid frictional foundation, pulled at one end.

n nodes, axial springs k between neighbours and from the last node to a wall
(so K is positive definite; the slip zone never reaches it), normal
stiffness kn per pair, uniform normal preload p, tangential load F at node 0
(lam_w = the welded force: -F at node 0, p everywhere).

Exact discrete solution (derived in the module docstring of this test):
the slip zone is nodes 0..m-1 with m = ceil(F/(mu p)) - 1; each slipping
node carries Q = -mu p, the spring between nodes j-1 and j carries
N_j = F - j mu p, so u_i = sum_{j=i+1}^{m} N_j / k and

    u_0 = (m F - mu p m (m + 1) / 2) / k .

Continuum limit (EA = k h, p_line = p / h): slip length a = F / (mu p_line),
end displacement u_0 = F^2 / (2 EA mu p_line); the discrete u_0 is below it
by (mu p / k) ((R - m)^2 + m) / 2 with R = F/(mu p), relative error O(h).

Unloading from F1 to F2 = F1 - dF (Cattaneo-Mindlin): the change is the
loading solution for the load -dF with twice the friction capacity,
m' = ceil(dF/(2 mu p)) - 1 reverse-slipping nodes carrying +mu p.
"""
import numpy as np
import pytest

from qsma.contact import METHODS, SLIPPING, STUCK, ContactProblem, solve

FAST = ["basket", "active_set"]


def bar_problem(n, k, kn, mu):
    Kt = k * (2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1))
    Kt[0, 0] = k                                   # free loaded end, wall beyond node n-1
    K = np.zeros((2 * n, 2 * n))
    K[0::2, 0::2], K[1::2, 1::2] = Kt, kn * np.eye(n)
    return ContactProblem(K, mu)


def bar_load(n, F, p):
    lam_w = np.zeros((n, 2))
    lam_w[:, 1] = p
    lam_w[0, 0] = -F
    return lam_w


def exact_loading(n, k, mu, p, F):
    """Discrete exact (u, Q, number of slipping nodes) for a monotonic load F."""
    m = int(np.ceil(F / (mu * p))) - 1
    N = F - np.arange(1, m + 1) * mu * p            # spring forces N_1..N_m
    u = np.zeros(n)
    u[:m] = np.cumsum(N[::-1])[::-1] / k
    Q = np.zeros(n)
    Q[:m] = -mu * p
    Q[m] = -N[-1] if m else -F
    return u, Q, m


def ramp(problem, loads, method, state=None):
    for lam_w in loads:
        r = solve(problem, lam_w, state, method=method)
        assert r.success, r.message
        state = r.state
    return r


@pytest.mark.parametrize("method", FAST)
def test_slip_zone_and_end_displacement_match_the_exact_discrete_solution(method):
    n, k, kn, mu, p, F = 60, 50.0, 1e4, 0.3, 2.0, 13.1      # R = F/(mu p) = 21.83
    problem = bar_problem(n, k, kn, mu)
    r = ramp(problem, [bar_load(n, f, p) for f in np.linspace(0, F, 21)[1:]], method)
    u, Q, m = exact_loading(n, k, mu, p, F)
    assert m == 21
    assert np.flatnonzero(r.status == SLIPPING).tolist() == list(range(m))
    assert np.all(r.status[m:] == STUCK)
    np.testing.assert_allclose(r.d[:, 0], u, rtol=1e-10, atol=1e-12 * u[0])
    np.testing.assert_allclose(r.Q[:, 0], Q, rtol=1e-10, atol=1e-10 * F)
    np.testing.assert_allclose(r.P, p, rtol=1e-12)
    assert r.d[0, 0] == pytest.approx((m * F - mu * p * m * (m + 1) / 2) / k, rel=1e-12)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_small_bar_in_one_step_all_methods(method):
    n, k, kn, mu, p, F = 8, 10.0, 100.0, 0.4, 1.0, 1.9       # R = 4.75 -> m = 4
    problem = bar_problem(n, k, kn, mu)
    r = solve(problem, bar_load(n, F, p), method=method)
    assert r.success, r.message
    u, Q, m = exact_loading(n, k, mu, p, F)
    np.testing.assert_allclose(r.d[:, 0], u, atol=1e-9 * u[0])
    np.testing.assert_allclose(r.Q[:, 0], Q, atol=1e-9 * F)


def continuum_case(n, method="basket"):
    """Same physical bar (L = 1, EA = 1, p_line = 10, mu = 0.5, F = 2.03) with n nodes."""
    L, EA, p_line, mu, F = 1.0, 1.0, 10.0, 0.5, 2.03     # F/(mu p) not an integer
    h = L / n
    problem = bar_problem(n, EA / h, 1e3 * EA / h, mu)
    loads = [bar_load(n, f, p_line * h) for f in np.linspace(0, F, 21)[1:]]
    r = ramp(problem, loads, method)
    slip_length = np.count_nonzero(r.status == SLIPPING) * h
    return r.d[0, 0], slip_length, F / (mu * p_line), F ** 2 / (2 * EA * mu * p_line), h


def test_continuum_limits_within_discretisation_error():
    for n in (40, 80, 160):
        u0, a, a_exact, u_exact, h = continuum_case(n)
        assert a_exact == pytest.approx(0.406)
        assert abs(a - a_exact) <= h                      # slip length F/(mu p_line)
        assert abs(u0 - u_exact) <= 1.5 * h / a_exact * u_exact  # F^2/(2 EA mu p_line)


def test_end_displacement_converges_at_first_order():
    sizes = np.array([25, 50, 100, 200])
    errors = []
    for n in sizes:
        u0, _, _, u_exact, _ = continuum_case(n)
        errors.append(abs(u0 - u_exact) / u_exact)
    rate = -np.polyfit(np.log(sizes), np.log(errors), 1)[0]
    assert rate == pytest.approx(1.0, abs=0.1)


def exact_unloading(n, k, mu, p, F1, F2):
    """Cattaneo-Mindlin: loaded state plus the loading solution for -dF at 2 mu p."""
    u1, Q1, m = exact_loading(n, k, mu, p, F1)
    du, dQ, m_rev = exact_loading(n, k, 2 * mu, p, F1 - F2)
    return u1 - du, Q1 - dQ, m, m_rev


@pytest.mark.parametrize("method", FAST)
@pytest.mark.parametrize("steps", [1, 7])
def test_partial_unloading_follows_cattaneo_mindlin(method, steps):
    n, k, kn, mu, p, F1, F2 = 60, 50.0, 1e4, 0.3, 2.0, 13.1, 7.3   # dF/(2 mu p) = 4.83
    problem = bar_problem(n, k, kn, mu)
    loaded = ramp(problem, [bar_load(n, f, p) for f in np.linspace(0, F1, 21)[1:]], method)
    unloads = [bar_load(n, f, p) for f in np.linspace(F1, F2, steps + 1)[1:]]
    r = ramp(problem, unloads, method, loaded.state)
    u, Q, m, m_rev = exact_unloading(n, k, mu, p, F1, F2)
    assert (m, m_rev) == (21, 4)
    reverse = r.status == SLIPPING
    assert np.flatnonzero(reverse).tolist() == list(range(m_rev))
    np.testing.assert_allclose(r.Q[:m_rev, 0], mu * p, rtol=1e-12)     # friction reversed
    assert np.all(r.d[:m_rev, 0] < loaded.d[:m_rev, 0])                  # slipping back
    np.testing.assert_allclose(r.d[:, 0], u, rtol=1e-10, atol=1e-12 * u[0])
    np.testing.assert_allclose(r.Q[:, 0], Q, atol=1e-10 * F1)
    # the end displacement lost on unloading is that of loading by dF at 2 mu p
    dF = F1 - F2
    assert loaded.d[0, 0] - r.d[0, 0] == pytest.approx(
        (m_rev * dF - 2 * mu * p * m_rev * (m_rev + 1) / 2) / k, rel=1e-10)
