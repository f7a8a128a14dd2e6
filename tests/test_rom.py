"""Reduced-order model export: Segalman's four-parameter Iwan element, its fit to a
modal backbone and rom.json."""
import json

import numpy as np
import pytest
from scipy.integrate import quad

import qsma
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.hysteresis.masing import masing
from qsma.study.rom import (Iwan4, JenkinsSeries, ModalIwan, export_rom, fit_iwan,
                            fit_jenkins, read_rom)

#: The tied first mode of sandwich-2d (212.5 Hz, tests/test_analysis.py) and Iwan
#: parameters spanning Segalman's lap-joint identifications (-1 < chi <= 0, beta >= 0).
OMEGA0 = 2 * np.pi * 212.5
KNOWN = [Iwan4(800.0, 0.3 * OMEGA0 ** 2, -0.4, 0.7),
         Iwan4(50.0, 0.8 * OMEGA0 ** 2, -0.9, 0.05),
         Iwan4(3e3, 0.1 * OMEGA0 ** 2, 0.0, 4.0)]


def by_quadrature(el, u):
    """Force and Masing dissipation at amplitude u integrated from the density."""
    pm, R, S, c = el.phi_max, el.R, el.S, el.chi
    v = min(u, pm)
    F = quad(lambda p: R * p ** c * p, 0, v)[0] + u * (quad(lambda p: R * p ** c, v, pm)[0]
                                                       + S) if u < pm else \
        quad(lambda p: R * p ** c * p, 0, pm)[0] + S * pm
    D = quad(lambda p: 4 * p * (u - p) * R * p ** c, 0, v)[0] + \
        (4 * S * pm * (u - pm) if u > pm else 0.0)
    return F, D


@pytest.mark.parametrize("el", KNOWN)
def test_closed_forms_match_the_density(el):
    pm = el.phi_max
    K = quad(lambda p: el.R * p ** el.chi, 0, pm)[0] + el.S
    assert K == pytest.approx(el.K_T, rel=1e-9)
    assert el.force(10 * pm) == pytest.approx(el.F_S, rel=1e-12)
    for u in (1e-3 * pm, 0.5 * pm, 0.999 * pm, 3 * pm):
        F, D = by_quadrature(el, u)
        assert el.force(u) == pytest.approx(F, rel=1e-8)
        assert el.dissipation(u) == pytest.approx(D, rel=1e-8)


@pytest.mark.parametrize("el", KNOWN)
def test_fit_recovers_a_known_iwan_element(el):
    m = ModalIwan(OMEGA0, el)
    q = np.logspace(np.log10(el.phi_max) - 3, np.log10(el.phi_max) + 0.5, 30)
    fit = fit_iwan(q, m.alpha(q), OMEGA0)
    assert fit.success, fit.message
    got = fit.model.element
    for name in ("F_S", "K_T", "chi", "beta"):
        assert getattr(got, name) == pytest.approx(getattr(el, name), rel=1e-6, abs=1e-9)
    assert fit.max_error < 1e-9


def test_a_backbone_short_of_macroslip_is_not_a_success():
    el = KNOWN[0]
    q = np.logspace(np.log10(el.phi_max) - 3, np.log10(el.phi_max) - 0.5, 20)
    fit = fit_iwan(q, ModalIwan(OMEGA0, el).alpha(q), OMEGA0)
    assert not fit.success
    assert "not identified" in fit.message


def test_too_few_levels_are_refused():
    with pytest.raises(InputError, match="at least 5 levels"):
        fit_iwan([1e-6, 2e-6], [1.0, 2.0], OMEGA0)


def test_rom_json_of_a_sandwich_run(tmp_path):
    res = qsma.run(sandwich_2d(1), levels=qsma.Levels.log("tip", 1e-6, 1e-3, 11))
    path = tmp_path / "rom.json"
    fit = export_rom(res, path)
    data = json.loads(path.read_text())
    assert data["kind"] == "modal_iwan4" and data["fit"]["success"] is fit.success
    lv = data["levels"]
    assert len(lv["q"]) == 11
    assert np.allclose(lv["fit_error"], np.array(lv["alpha_fit"]) / res.alpha - 1)
    assert data["fit"]["max_relative_error"] == pytest.approx(np.max(np.abs(lv["fit_error"])))
    back = read_rom(path)
    assert np.allclose(back.alpha(res.q), lv["alpha_fit"], rtol=1e-12)
    # the tied stiffness at small amplitude is kept by construction
    assert back.frequency(1e-12 * res.q[0]) == pytest.approx(res.f0_hz, rel=1e-6)


# --------------------------------------------------------------- modal Jenkins series

#: A series with slip amplitudes on the default log grid of a 1e-6..1e-3 backbone and
#: two elements switched off (NNLS must find the zeros too).
SLIP = np.logspace(-6, -3, 9)[:-1]
K_SERIES = np.array([1e5, 3e4, 0.0, 2e4, 5e3, 1e4, 0.0, 2e3])


def test_jenkins_fit_recovers_a_known_series():
    known = JenkinsSeries(4e5, tuple(K_SERIES), tuple(SLIP))
    q = np.logspace(-6, -3, 40)
    series, err = fit_jenkins(q, known.alpha(q))
    assert series.k_inf == pytest.approx(known.k_inf, rel=1e-6)
    assert np.allclose(series.stiffness, K_SERIES, rtol=0, atol=1e-6 * K_SERIES.max())
    assert np.max(np.abs(err)) < 1e-9


def test_jenkins_dissipation_is_masing_of_its_backbone():
    """On a grid holding every slip amplitude the backbone is piecewise linear, so the
    trapezoidal Masing integral of qsma.hysteresis.masing is exact."""
    known = JenkinsSeries(4e5, tuple(K_SERIES), tuple(SLIP))
    q = np.union1d(np.logspace(-6.5, -2.5, 30), SLIP)
    D = masing(known.alpha(q), q).dissipation
    assert np.allclose(known.dissipation(q), D, rtol=1e-9, atol=1e-12 * D.max())


def test_iwan_dissipation_is_masing_of_its_backbone():
    """The closed-form dissipation agrees with Masing's rule applied to the closed-form
    backbone, to the trapezoidal error of a fine grid."""
    el = KNOWN[0]
    m = ModalIwan(OMEGA0, el)
    q = np.logspace(np.log10(el.phi_max) - 4, np.log10(el.phi_max) + 0.3, 4000)
    D = masing(m.alpha(q), q).dissipation
    sel = slice(2000, None)
    assert np.allclose(D[sel], el.dissipation(q[sel]), rtol=1e-3)
