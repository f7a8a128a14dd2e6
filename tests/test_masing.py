"""Masing post-processing against closed forms.

A lumped system with a known backbone: unit mass (mass-normalised mode phi = 1, so the
modal force is alpha) held by a linear spring k0 to ground and, in parallel, by a
Jenkins element (spring k in series with a frictional contact pair, slip force
F_s = mu P0). The Jenkins pair is solved by ``qsma.contact`` on the statically
condensed problem and the backbone goes through the same ``qsma.hysteresis.masing`` as QSMA.

Closed forms: stuck while alpha <= alpha_s = F_s (k + k0)/k, q = alpha/(k + k0);
beyond, q = (alpha - F_s)/k0. Masing loop area D = 4 F_s (q_a - F_s/k).
"""
import numpy as np
import pytest

from qsma.contact import METHODS, ContactProblem, solve
from qsma.errors import InputError
from qsma.hysteresis.masing import loop_area, masing, masing_loop

k, k0, kn, mu, P0 = 3.0e6, 1.0e6, 1.0e9, 0.5, 200.0
Fs = mu * P0
alpha_s = Fs * (k + k0) / k


def _backbone(alphas, method):
    # body 2 = slider s and mass x; condensed onto s: Kc = k k0/(k + k0), Fc = k alpha/(k + k0);
    # body 1 = rigid ground, so K = Kc and lam_w = -Fc (tangential), P0 (normal)
    Kc = k * k0 / (k + k0)
    problem = ContactProblem(np.diag([Kc, kn]), mu)
    state, q = None, []
    for a in alphas:
        lam_w = np.array([[-k * a / (k + k0), P0]])
        res = solve(problem, lam_w, state, method=method)
        assert res.success, res.message
        state = res.state
        s = res.d[0, 0]
        q.append((a + k * s) / (k + k0))       # mass displacement = modal amplitude
    return np.array(q)


def _exact_q(alpha):
    return np.where(alpha <= alpha_s, alpha / (k + k0), (alpha - Fs) / k0)


@pytest.mark.parametrize("method", sorted(METHODS))
def test_lumped_jenkins_backbone_dissipation_and_damping(method):
    alphas = np.unique(np.concatenate([np.linspace(0.1, 1.0, 10) * alpha_s,
                                       np.linspace(1.0, 4.0, 16) * alpha_s]))
    q = _backbone(alphas, method)
    assert np.allclose(q, _exact_q(alphas), rtol=1e-9)
    m = masing(alphas, q)
    D_exact = np.where(q > Fs / k, 4 * Fs * (q - Fs / k), 0.0)
    assert np.allclose(m.dissipation, D_exact, rtol=1e-8, atol=1e-12 * Fs * q.max())
    w = np.sqrt(alphas / q)
    assert np.allclose(m.omega, w, rtol=1e-12)
    assert np.allclose(m.zeta, D_exact / (2 * np.pi * (q * w) ** 2), rtol=1e-8, atol=1e-12)
    stuck = alphas <= alpha_s
    assert np.allclose(m.omega[stuck], np.sqrt(k + k0), rtol=1e-9)   # tied frequency
    assert np.all(np.diff(m.omega) <= 1e-9 * m.omega[0])              # never increases


def test_masing_loop_area_equals_formula():
    alphas = np.linspace(0.1, 3.0, 30) * alpha_s
    q = _exact_q(alphas)
    m = masing(alphas, q)
    for kk in (5, 20, 29):
        ql, fl = masing_loop(alphas, q, kk, n=400)
        assert loop_area(ql, fl) == pytest.approx(m.dissipation[kk], rel=2e-3)


def test_masing_rejects_bad_backbones():
    with pytest.raises(InputError):
        masing([1.0, 2.0], [1.0])
    with pytest.raises(InputError):
        masing([1.0, np.nan], [1.0, 2.0])
    with pytest.raises(InputError):
        masing([-1.0, 2.0], [1.0, 2.0])
