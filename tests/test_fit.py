"""Fitting parameters to measured frequency and damping versus amplitude: recovery of
the parameters behind synthetic noisy data, the reported uncertainty, the measured-data
format and the command line."""
import json

import numpy as np
import pytest

import qsma
from qsma.cli import main
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.study.fit import Measured, fit, predict, read_measured

#: Coarse evaluations: 6 levels, Masing's rules, no inserted levels (the synthetic data
#: are made with the same options, so the model can reproduce them exactly).
OPTIONS = qsma.RunOptions(levels=qsma.Levels.log("tip", 1e-5, 6e-4, 6),
                          dissipation="masing", refine_levels=False)
#: Measured amplitudes in the microslip range of sandwich-2d (stuck below ~1.5e-5 m).
AMPLITUDES = np.logspace(np.log10(2.5e-5), np.log10(5e-4), 8)
#: Noise of the synthetic data: relative on the frequency, on log of the damping; the
#: fit is told these scatters, so its residual sigma is about 1.
NOISE_F, NOISE_ZETA = 1e-4, 0.03
TRUE_MU, TRUE_PRELOAD = 0.5, 1.0


@pytest.fixture(scope="module")
def measured():
    """Frequency and damping of sandwich-2d at mu = 0.5 (preload scale 1) interpolated at
    AMPLITUDES, with seeded Gaussian noise."""
    res = qsma.run(sandwich_2d(1, mu=TRUE_MU), OPTIONS)
    assert res.success
    nan = np.full(AMPLITUDES.size, np.nan)
    exact = predict(res, Measured("tip", AMPLITUDES, nan, nan))
    rng = np.random.default_rng(20261125)
    return Measured("tip", AMPLITUDES,
                    exact["f_hz"] * (1 + NOISE_F * rng.standard_normal(AMPLITUDES.size)),
                    exact["zeta"] * np.exp(NOISE_ZETA * rng.standard_normal(AMPLITUDES.size)))


def test_fit_recovers_mu_within_its_uncertainty(measured, tmp_path):
    fr = qsma.fit(sandwich_2d(1, mu=0.7), measured, ["mu"], OPTIONS, sigma_f=NOISE_F,
             sigma_zeta=NOISE_ZETA, out=tmp_path)
    assert fr.success, fr.message
    mu, sigma = fr.values["mu"], fr.sigma["mu"]
    assert abs(mu - TRUE_MU) <= 3 * sigma, (mu, sigma)
    assert sigma < 0.01 * TRUE_MU            # the data determine mu: not a vacuous check
    assert 0.3 < fr.residual_sigma < 3       # the noise is what the weights said
    written = json.loads((tmp_path / "fit.json").read_text())
    assert written["parameters"]["mu"]["value"] == pytest.approx(mu, rel=1e-12)
    assert written["success"] is True
    assert (tmp_path / "fit.png").stat().st_size > 0
    best = json.loads((tmp_path / "best" / "results.json").read_text())
    assert best["model"]["mu"] == pytest.approx(mu, rel=1e-12)


def test_mu_and_preload_scale_are_reported_as_one_combination(measured):
    """Contact with Coulomb friction is positively homogeneous: scaling the preload by s
    at fixed mu shifts the curves in amplitude, as does scaling mu by about s; on
    sandwich-2d the curves depend on mu * s alone to 1e-4, so the data determine that
    product and not each factor. The fit must say so, and the reported (large)
    uncertainty of each must contain the true value."""
    fr = fit(sandwich_2d(1, mu=0.7), measured, ["mu", "preload"], OPTIONS,
             start={"preload": 1.3}, sigma_f=NOISE_F, sigma_zeta=NOISE_ZETA)
    assert not fr.success
    assert "do not determine" in fr.message and "fix all but one" in fr.message
    assert fr.correlation[0, 1] < -0.99
    for name, true in (("mu", TRUE_MU), ("preload", TRUE_PRELOAD)):
        assert abs(fr.values[name] - true) <= fr.sigma[name], (name, fr.values, fr.sigma)
    best = fr.combinations[0]            # the combination the data determine
    assert best["exponents"]["mu"] == pytest.approx(best["exponents"]["preload"], abs=0.02)
    at_truth = TRUE_MU ** best["exponents"]["mu"] * TRUE_PRELOAD ** best["exponents"]["preload"]
    assert abs(best["value"] / at_truth - 1) <= 5 * best["relative_sigma"]
    assert best["relative_sigma"] < 1e-3 < fr.combinations[1]["relative_sigma"]


def test_read_measured_units_and_missing_values(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text("# bench test 3\ntip_mm,f_hz,zeta\n0.02,212.3,\n0.1,211.9,0.001\n")
    m = read_measured(path)
    assert m.kind == "tip"
    np.testing.assert_allclose(m.amplitude, [2e-5, 1e-4], rtol=1e-15)
    assert np.isnan(m.zeta[0]) and m.zeta[1] == 0.001
    assert m.n_points == 3


@pytest.mark.parametrize("text, match", [
    ("amp,f_hz\n1e-5,200\n", "first column"),
    ("tip_m,freq\n1e-5,200\n", "f_hz and/or zeta"),
    ("tip_m,zeta\n1e-5,0\n", "zeta must be positive"),
    ("tip_m,zeta\n1e-5,abc\n", "not a number"),
    ("tip_m,zeta\n", "at least one data row"),
])
def test_read_measured_refuses_bad_files(tmp_path, text, match):
    path = tmp_path / "m.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=match):
        read_measured(path)


def test_fit_refuses_what_it_cannot_fit(measured):
    model = sandwich_2d(1)
    with pytest.raises(InputError, match="cannot be fitted"):
        fit(model, measured, ["method"], OPTIONS)
    with pytest.raises(InputError, match="bounds of mu"):
        fit(model, measured, ["mu"], OPTIONS, bounds={"mu": (0.7, 0.9)})
    one = Measured("tip", AMPLITUDES[:1], measured.f_hz[:1], np.full(1, np.nan))
    with pytest.raises(InputError, match="cannot determine"):
        fit(model, one, ["mu"], OPTIONS)


def test_cli_fit_writes_its_files(measured, tmp_path, capsys):
    """One optimiser step from the command line: not converged, so exit code 1, the
    files written and the reason printed."""
    csv = tmp_path / "m.csv"
    csv.write_text("tip_m,f_hz,zeta\n" + "".join(
        f"{a:.17g},{f:.17g},{z:.17g}\n" for a, f, z in zip(measured.amplitude, measured.f_hz,
                                                   measured.zeta)))
    code = main(["fit", "--example", "sandwich-2d", "--mu", "0.6", "--measured", str(csv),
                 "--params", "mu", "--levels", "tip:log:1e-5:6e-4:5",
                 "--max-evaluations", "1", "--out", str(tmp_path / "fit")])
    err = capsys.readouterr().err
    assert code == 1 and "did not converge" not in err
    assert "optimiser stopped before converging" in err
    assert json.loads((tmp_path / "fit" / "fit.json").read_text())["success"] is False
    assert main(["fit", "--example", "sandwich-2d", "--measured", str(csv), "--params",
                 "mu", "--bounds", "mu=0.1", "--out", str(tmp_path / "x")]) == 2
