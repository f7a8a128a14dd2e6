"""One pair (a Jenkins element with a normal spring): exact answers for every method.

K = diag(kt, kn), welded force lam_w = (q, p). Stuck: d = (d_t,prev, 0),
lam = (kt d_t,prev + q, p). Slipping (|kt d_t,prev + q| > mu p):
Q = -mu p sign(dv), d_t = (Q - q)/kt. Open (p < 0): lam = 0, d = -(q/kt, p/kn).
"""
import numpy as np
import pytest
from scipy.integrate import trapezoid      # (numpy.trapezoid needs numpy >= 2)

from qsma.contact import METHODS, OPEN, SLIPPING, STUCK, ContactProblem, residual, solve

KT, KN, MU, P = 10.0, 100.0, 0.5, 10.0          # friction capacity mu p = 5


@pytest.fixture
def jenkins():
    return ContactProblem(np.diag([KT, KN]), MU)


def load(q, p=P):
    return np.array([[q, p]])


@pytest.mark.parametrize("method", sorted(METHODS))
def test_stick_below_the_friction_capacity(jenkins, method):
    r = solve(jenkins, load(4.0), method=method)
    assert r.success and r.residual <= 1e-10
    np.testing.assert_allclose(r.d, [[0.0, 0.0]], atol=1e-14)
    np.testing.assert_allclose(r.lam, [[4.0, 10.0]], rtol=1e-12)
    assert r.status.tolist() == [STUCK]


@pytest.mark.parametrize("method", sorted(METHODS))
@pytest.mark.parametrize("q, dt, Q", [(5.0, 0.0, 5.0),          # onset: |Q| = mu P, no slip yet
                                      (6.0, -0.1, 5.0),         # slip: d_t = (mu p - q)/kt
                                      (-8.0, 0.3, -5.0)])
def test_slip_onset_at_mu_p(jenkins, method, q, dt, Q):
    r = solve(jenkins, load(q), method=method)
    assert r.success
    np.testing.assert_allclose(r.d, [[dt, 0.0]], atol=1e-13)
    np.testing.assert_allclose(r.lam, [[Q, P]], rtol=1e-12)
    np.testing.assert_allclose(np.abs(r.Q[:, 0]), MU * r.P, rtol=1e-12)
    assert r.status.tolist() == [STUCK if dt == 0.0 else SLIPPING]


@pytest.mark.parametrize("method", sorted(METHODS))
def test_separation_under_a_lifting_load(jenkins, method):
    r = solve(jenkins, load(3.0, p=-5.0), method=method)
    assert r.success
    np.testing.assert_allclose(r.lam, [[0.0, 0.0]], atol=1e-14)
    np.testing.assert_allclose(r.d, [[-0.3, 0.05]], rtol=1e-12)    # w = -p/kn > 0
    assert r.status.tolist() == [OPEN]


@pytest.mark.parametrize("method", sorted(METHODS))
def test_reversal_of_slip_on_unloading(jenkins, method):
    """Load to q1 = 8 (slip to d1 = -0.3), then unload: stick while q1 - q <= 2 mu p."""
    loaded = solve(jenkins, load(8.0), method=method)
    np.testing.assert_allclose(loaded.d[0, 0], -0.3, rtol=1e-12)
    partly = solve(jenkins, load(0.0), loaded.state, method=method)       # q1 - q = 8 < 10
    assert partly.success and partly.status.tolist() == [STUCK]
    np.testing.assert_allclose(partly.d, [[-0.3, 0.0]], rtol=1e-12)        # frozen slip
    np.testing.assert_allclose(partly.lam, [[-3.0, P]], rtol=1e-12)       # kt d1 + q
    reversed_ = solve(jenkins, load(-4.0), partly.state, method=method)   # q1 - q = 12 > 10
    assert reversed_.success and reversed_.status.tolist() == [SLIPPING]
    np.testing.assert_allclose(reversed_.lam, [[-5.0, P]], rtol=1e-12)    # Q = -mu p
    np.testing.assert_allclose(reversed_.d, [[-0.1, 0.0]], rtol=1e-12)    # (-mu p - q)/kt
    assert reversed_.d[0, 0] - partly.d[0, 0] > 0                         # slips back


@pytest.mark.parametrize("method", sorted(METHODS))
def test_hysteresis_loop_of_the_jenkins_element(jenkins, method):
    """A load cycle +-q_a: the dissipated area is 4 F_s (u_a - F_s/k) (method.md 5)."""
    q = np.r_[np.linspace(0, 9, 10), np.linspace(9, -9, 19)[1:], np.linspace(-9, 9, 19)[1:]]
    state, u = None, []
    for qi in q:
        r = solve(jenkins, load(-qi), state, method=method)
        assert r.success
        state = r.state
        u.append(r.d[0, 0])
    u = np.array(u)
    cycle = slice(9, None)                       # from +q_a down and back up
    area = abs(trapezoid(q[cycle], u[cycle]))
    u_a = (9.0 - MU * P) / KT
    assert area == pytest.approx(4 * MU * P * u_a, rel=1e-12)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_gap_keeps_the_pair_open_until_closed(method):
    problem = ContactProblem(np.diag([KT, KN]), MU, gap0=[0.01])
    small = solve(problem, load(0.0, p=0.5), method=method)    # p/kn = 0.005 < gap
    assert small.success and small.status.tolist() == [OPEN]
    np.testing.assert_allclose(small.d, [[0.0, -0.005]], atol=1e-14)
    big = solve(problem, load(0.0, p=3.0), method=method)      # closes: P = p - kn g0 = 2
    assert big.success and big.status.tolist() == [STUCK]
    np.testing.assert_allclose(big.lam, [[0.0, 2.0]], atol=1e-12)
    np.testing.assert_allclose(big.d[0, 1], -0.01, rtol=1e-12)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_a_change_of_units_changes_nothing_relative(jenkins, method):
    """mm and kN instead of m and N: same answer scaled, same relative residual."""
    base = solve(jenkins, load(6.0), method=method)
    scaled_problem = ContactProblem(np.diag([KT, KN]) * 1e-3 / 1e3, MU)   # kN/mm
    scaled = solve(scaled_problem, load(6.0) / 1e3, method=method)
    np.testing.assert_allclose(scaled.d, base.d * 1e3, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(scaled.lam, base.lam / 1e3, rtol=1e-12)
    assert scaled.nit == base.nit
    assert residual(scaled_problem, load(6.0) / 1e3, scaled.d, scaled.lam) == pytest.approx(
        residual(jenkins, load(6.0), base.d, base.lam), abs=1e-15)


def test_result_repr_and_properties(jenkins):
    r = solve(jenkins, load(6.0))
    text = repr(r)
    assert "success=True" in text and "slipping=1" in text and "method='basket'" in text
    assert r.P.shape == (1,) and r.Q.shape == (1, 1)
    assert (r.n_stuck, r.n_slipping, r.n_open) == (0, 1, 0)
    assert r.state.d is r.d and "slipping=1" in repr(r.state)
    with pytest.raises(AttributeError):
        r.success = False
