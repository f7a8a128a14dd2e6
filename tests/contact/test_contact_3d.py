"""3D contact (Coulomb cone): joint projection of the shear on the friction disk."""
import numpy as np
import pytest

from qsma.contact import METHODS, SLIPPING, STUCK, ContactProblem, solve

KT, KN, MU, P = 10.0, 100.0, 0.5, 10.0          # friction capacity mu p = 5


def radial_return(d_prev_t, q):
    """Exact one-pair answer for K = diag(kt, kt, kn): return mapping of the trial shear."""
    trial = KT * d_prev_t + q
    size = np.linalg.norm(trial)
    if size <= MU * P:
        return d_prev_t, trial
    Q = MU * P * trial / size
    return d_prev_t + (Q - trial) / KT, Q


@pytest.fixture
def pair3d():
    return ContactProblem(np.diag([KT, KT, KN]), MU, dim=3)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_oblique_load_slips_along_the_load_with_shear_mu_p(pair3d, method):
    q = np.array([6.0, 4.0])                       # |q| = 7.2 > mu p, not along an axis
    r = solve(pair3d, np.array([[*q, P]]), method=method)
    d_t, Q = radial_return(np.zeros(2), q)
    assert r.success and r.status.tolist() == [SLIPPING]
    np.testing.assert_allclose(r.Q[0], Q, rtol=1e-10)
    np.testing.assert_allclose(r.d[0, :2], d_t, rtol=1e-10)
    assert np.linalg.norm(r.Q[0]) == pytest.approx(MU * r.P[0], rel=1e-12)
    # a per-component clamp would give |Q_i| = mu P on each axis (|Q| = 7.07 > mu P)
    assert np.all(np.abs(r.Q[0]) < MU * P)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_rotating_load_slip_follows_the_increment(pair3d, method):
    """Shear load of constant size 1.4 mu p turning by 20 degrees per level."""
    state, d_prev = None, np.zeros(2)
    for angle in np.deg2rad(np.arange(0, 361, 20)):
        q = 1.4 * MU * P * np.array([np.cos(angle), np.sin(angle)])
        r = solve(pair3d, np.array([[*q, P]]), state, method=method)
        d_t, Q = radial_return(d_prev, q)
        assert r.success
        np.testing.assert_allclose(r.Q[0], Q, rtol=1e-9, atol=1e-12 * P)
        np.testing.assert_allclose(r.d[0, :2], d_t, rtol=1e-9, atol=1e-12)
        dv = r.d[0, :2] - d_prev
        if np.linalg.norm(dv) > 1e-9:                            # slipping: Q = -mu P dv/|dv|
            np.testing.assert_allclose(r.Q[0], -MU * r.P[0] * dv / np.linalg.norm(dv),
                                       rtol=1e-9, atol=1e-12 * P)
            assert r.status.tolist() == [SLIPPING]
        state, d_prev = r.state, r.d[0, :2].copy()
    assert np.linalg.norm(d_prev) > 0.1             # it did slip around the circle


@pytest.mark.parametrize("method", sorted(METHODS))
def test_stick_and_separation_in_3d(pair3d, method):
    stick = solve(pair3d, np.array([[3.0, -3.0, P]]), method=method)     # |q| = 4.24 < 5
    assert stick.success and stick.status.tolist() == [STUCK]
    np.testing.assert_allclose(stick.d, 0.0, atol=1e-14)
    lift = solve(pair3d, np.array([[3.0, -3.0, -P]]), method=method)
    assert lift.success and lift.n_open == 1
    np.testing.assert_allclose(lift.lam, 0.0, atol=1e-14)
    np.testing.assert_allclose(lift.d, [[-0.3, 0.3, 0.1]], rtol=1e-12)


def bar2d(n, k=50.0, kn=1e4):
    Kt = k * (2 * np.eye(n) - np.eye(n, k=1) - np.eye(n, k=-1))
    Kt[0, 0] = k
    rng = np.random.default_rng(3)
    C = np.diag(rng.uniform(-0.05, 0.05, n)) * k          # weak t-n coupling
    return Kt, kn * np.eye(n), C


@pytest.mark.parametrize("method", sorted(METHODS))
def test_2d_problem_embedded_in_3d_gives_the_2d_answer(method):
    n = 8 if method == "nodal_gs" else 30             # the baseline is slow on long bars
    mu, p = 0.3, 2.0
    Kt, Kn, C = bar2d(n)
    K2 = np.zeros((2 * n, 2 * n))
    K2[0::2, 0::2], K2[1::2, 1::2], K2[0::2, 1::2], K2[1::2, 0::2] = Kt, Kn, C, C
    K3 = np.zeros((3 * n, 3 * n))
    K3[0::3, 0::3], K3[2::3, 2::3], K3[0::3, 2::3], K3[2::3, 0::3] = Kt, Kn, C, C
    K3[1::3, 1::3] = 2.0 * Kt                               # t2: decoupled, unloaded
    p2, p3 = ContactProblem(K2, mu), ContactProblem(K3, mu, dim=3)
    state2 = state3 = None
    for F in np.linspace(0, 8.0, 9)[1:] * n / 30:
        lam2 = np.zeros((n, 2))
        lam2[:, 1], lam2[0, 0] = p * np.linspace(1.0, -0.5, n), -F    # slip and opening
        lam3 = np.zeros((n, 3))
        lam3[:, [0, 2]] = lam2
        r2 = solve(p2, lam2, state2, method=method)
        r3 = solve(p3, lam3, state3, method=method)
        assert r2.success and r3.success
        np.testing.assert_allclose(r3.lam[:, [0, 2]], r2.lam, atol=1e-9 * F)
        np.testing.assert_allclose(r3.d[:, [0, 2]], r2.d, atol=1e-9 * F / 50.0)
        np.testing.assert_allclose(r3.lam[:, 1], 0.0, atol=1e-9 * F)
        np.testing.assert_array_equal(r3.status, r2.status)
        state2, state3 = r2.state, r3.state
    assert r2.n_slipping >= max(1, n // 10) and r2.n_open >= max(1, n // 10)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_isotropic_bar_pulled_obliquely_is_the_rotated_1d_answer(method):
    """Same bar stiffness in t1 and t2: an oblique pull gives the 1D slip zone, rotated."""
    n, mu, p, F, theta = 12, 0.4, 1.0, 2.9, np.deg2rad(35.0)
    Kt, Kn, _ = bar2d(n, k=10.0, kn=100.0)
    K3 = np.zeros((3 * n, 3 * n))
    K3[0::3, 0::3], K3[1::3, 1::3], K3[2::3, 2::3] = Kt, Kt, Kn
    lam3 = np.zeros((n, 3))
    lam3[:, 2], lam3[0, :2] = p, -F * np.array([np.cos(theta), np.sin(theta)])
    r = solve(ContactProblem(K3, mu, dim=3), lam3, method=method)
    assert r.success, r.message
    m = int(np.ceil(F / (mu * p))) - 1                 # 7 slipping pairs
    N = F - np.arange(1, m + 1) * mu * p
    u = np.zeros(n)
    u[:m] = np.cumsum(N[::-1])[::-1] / 10.0
    np.testing.assert_allclose(r.d[:, 0], u * np.cos(theta), atol=1e-9)
    np.testing.assert_allclose(r.d[:, 1], u * np.sin(theta), atol=1e-9)
    assert np.flatnonzero(r.status == SLIPPING).tolist() == list(range(m))
    np.testing.assert_allclose(np.linalg.norm(r.Q[:m], axis=1), mu * p, atol=1e-9 * F)
