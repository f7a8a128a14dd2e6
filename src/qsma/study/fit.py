r"""Fitting model parameters to measured frequency and damping versus amplitude.

The measured data (:func:`read_measured`, docs/studies.md "Fitting") give, at peak
amplitudes :math:`a_i`, a secant frequency :math:`f_i` and/or a damping ratio
:math:`\zeta_i`. For parameters :math:`p` (friction coefficient, preload scale,
material constants: the parameters of a sweep) a QSMA run gives the curves
:math:`f(a; p)`, :math:`\zeta(a; p)`, interpolated at :math:`a_i` linearly in
:math:`\ln a` (and in :math:`\ln\zeta` for the damping). The fit minimises

.. math::

    \Phi(x) = \tfrac12 \sum_i \Big(\frac{f(a_i; p)/f_i - 1}{\sigma_f}\Big)^2
            + \tfrac12 \sum_i \Big(\frac{\ln \zeta(a_i; p) - \ln \zeta_i}{\sigma_\zeta}\Big)^2,
    \qquad p = e^{x},

over the logarithms :math:`x` of the parameters within their bounds
(:func:`scipy.optimize.least_squares`, trust region reflective, forward-difference
Jacobian). :math:`\sigma_f` and :math:`\sigma_\zeta` are the expected relative
scatter of the measured frequency and damping: they weigh the two kinds of data.

Uncertainty: with :math:`J = U S V^T` the Jacobian of the weighted residuals at the
optimum and :math:`s^2 = 2\Phi/(m - n)` the residual variance (m data, n parameters),
the covariance of :math:`x` is :math:`s^2 V S^{-2} V^T`; the standard uncertainty of
:math:`p_j` is :math:`p_j \sigma_{x_j}` (linearised). Each singular pair
:math:`(S_k, v_k)` is a combination :math:`\prod_j p_j^{v_{kj}}` known to a relative
uncertainty :math:`s / S_k`: when the data determine only a product of parameters
(e.g. :math:`\mu s`), the other combinations have a large uncertainty and the fit
says so instead of reporting the arbitrary point of the valley it stopped at.

Every evaluation is one case of the sweep machinery (:func:`qsma.study.cases.
case_inputs`): the preparation (assembly, condensation) is made once per set of
material constants and reused; a friction coefficient or preload scale costs only
the preload solve and the ramps.
"""
from __future__ import annotations

from contextlib import ExitStack
from dataclasses import dataclass, field
import csv
import json
import math
from pathlib import Path

import numpy as np

from ..analysis import STUDY_MU_FIX
from ..errors import AnalysisError, InputError
from ..analysis.levels import Levels
from ..analysis.options import RunOptions
from ..output.folders import RunFolder
from .cases import (MATERIAL_PARAMETERS, Case, case_inputs, check_bodies, material_key,
                    model_with_materials, parameter_kind)

#: Amplitude column names of the measured CSV: kind_unit -> (result field, factor to SI).
#: ``tip``: peak deflection of the tip probe (``tip`` of results.json); ``q``: peak
#: modal amplitude (kg^0.5 m, ``q`` of results.json).
AMPLITUDE_COLUMNS = {"tip_m": ("tip", 1.0), "tip_mm": ("tip", 1e-3),
                     "tip_um": ("tip", 1e-6), "q": ("q", 1.0)}
#: Default bounds of the fitted parameters, as factors of their start value; ``mu``
#: and ``nu`` have absolute bounds of their own.
BOUND_FACTOR = 10.0
ABSOLUTE_BOUNDS = {"mu": (1e-3, 10.0), "nu": (1e-3, 0.4999)}
#: A parameter counts as determined by the data when its relative standard
#: uncertainty is below this.
DETERMINED_RSIGMA = 0.25
#: Computed damping ratios below this (stuck levels: 0 to round-off) are taken as it
#: in the logarithmic residual.
ZETA_FLOOR = 1e-9
#: Default load levels of an evaluation: log spaced in the linear tip deflection from
#: half the smallest to the largest measured tip amplitude (the joint softens, so the
#: peak tip deflection of the last level is at least the largest measured one).
DEFAULT_FIT_LEVELS = 12
#: Forward-difference step of the Jacobian, on the logarithm of each parameter.
DIFF_STEP = 3e-3


@dataclass(frozen=True, eq=False)
class Measured:
    """Measured amplitude-dependent frequency and damping (arrays of equal length;
    NaN where a value is missing). ``amplitude`` in SI units, of ``kind`` ``tip`` or
    ``q`` (:func:`fit` compares them in the model's units, :func:`in_model_units`)."""

    kind: str
    amplitude: np.ndarray
    f_hz: np.ndarray
    zeta: np.ndarray
    source: str = ""

    @property
    def n_points(self) -> int:
        return int(np.sum(np.isfinite(self.f_hz)) + np.sum(np.isfinite(self.zeta)))


@dataclass(frozen=True, eq=False)
class FitResult:
    """Outcome of :func:`fit`.

    ``values`` and ``sigma`` are per name of ``names`` (standard uncertainties, inf
    where the data do not determine the parameter); ``correlation`` is that of the
    logarithms of the parameters; ``combinations`` lists the parameter combinations
    the data determine, best first. ``success`` is True only when the optimiser
    converged and every parameter is determined (``message`` says which is not).
    """

    success: bool
    message: str
    names: tuple
    values: dict
    sigma: dict
    start: dict
    bounds: dict
    correlation: np.ndarray
    combinations: tuple
    cost: float
    residual_sigma: float
    n_points: int
    nfev: int
    measured: Measured
    predicted: dict
    result: object
    history: tuple = ()
    paths: dict = field(default_factory=dict)


# ---------------------------------------------------------------------- measured data

def read_measured(path) -> Measured:
    """Read measured data: a CSV with a header row, ``#`` lines ignored.

    The first column is the amplitude, named ``tip_m``, ``tip_mm``, ``tip_um`` (peak
    tip deflection) or ``q`` (peak modal amplitude, kg^0.5 m); then ``f_hz`` (secant
    frequency) and/or ``zeta`` (damping ratio of the joint); empty cells are missing
    values.
    """
    from ..analysis.config import decode_utf8
    from ..mesh.io.common import read_regular
    path = Path(path)
    text = decode_utf8(read_regular(path, "a CSV of measured data"), str(path),
                       "measured data files")
    rows = [r for r in csv.reader(line for line in text.splitlines()
                                  if line.strip() and not line.lstrip().startswith("#"))]
    if len(rows) < 2:
        raise InputError(f"{path}: expected a header row and at least one data row")
    head = [h.strip() for h in rows[0]]
    twice = sorted({h for h in head if head.count(h) > 1})
    if twice:
        raise InputError(f"{path}: column {twice[0]!r} appears twice in the header "
                         f"{head}; give each column once")
    if head[0] not in AMPLITUDE_COLUMNS:
        raise InputError(f"{path}: the first column must be the amplitude, named one of "
                         f"{sorted(AMPLITUDE_COLUMNS)}, got {head[0]!r}")
    unknown = [h for h in head[1:] if h not in ("f_hz", "zeta")]
    if unknown or len(head) < 2:
        raise InputError(f"{path}: columns after the amplitude are f_hz and/or zeta, got "
                         f"{head[1:]}")
    cols = {h: [] for h in head}
    for n, row in enumerate(rows[1:], start=2):
        if len(row) != len(head):
            raise InputError(f"{path}: data row {n} has {len(row)} cells, the header "
                             f"{len(head)}")
        for h, cell in zip(head, row):
            cols[h].append(_number(cell, path, n, h))
    kind, factor = AMPLITUDE_COLUMNS[head[0]]
    nan = np.full(len(rows) - 1, np.nan)
    m = Measured(kind, np.asarray(cols[head[0]]) * factor,
                 np.asarray(cols.get("f_hz", nan), float),
                 np.asarray(cols.get("zeta", nan), float), str(path))
    return check_measured(m)


def in_model_units(m: Measured, units) -> Measured:
    """``m`` (amplitudes in SI) with its amplitudes in the model's unit system, where
    they are compared with the computed ones: a tip deflection of 1e-4 m is 0.1 in a
    millimetre model, a modal amplitude (kg^0.5 m) is divided by sqrt(t/kg) mm/m."""
    from dataclasses import replace
    from ..units import unit_system
    u = unit_system(units)
    scale = u.length_m * (1.0 if m.kind == "tip" else np.sqrt(u.mass_kg))
    return m if scale == 1.0 else replace(m, amplitude=np.asarray(m.amplitude) / scale)


def _number(cell, path, row, column):
    if not cell.strip():
        return math.nan
    try:
        return float(cell)
    except ValueError:
        raise InputError(f"{path}: row {row}, column {column}: {cell!r} is not a "
                         f"number") from None


def check_measured(m: Measured) -> Measured:
    """Refuse data that cannot be fitted, naming the bad entries."""
    if m.kind not in ("tip", "q"):
        raise InputError(f"measured amplitude kind must be 'tip' or 'q', got {m.kind!r}")
    a = np.asarray(m.amplitude, float)
    if not (np.all(np.isfinite(a)) and np.all(a > 0)):
        raise InputError(f"{m.source or 'measured data'}: every amplitude must be a "
                         f"positive number")
    for name, v in (("f_hz", m.f_hz), ("zeta", m.zeta)):
        bad = np.flatnonzero(np.isfinite(v) & (np.asarray(v) <= 0))
        if bad.size:
            raise InputError(f"{m.source or 'measured data'}: {name} must be positive "
                             f"(rows {(bad + 2).tolist()}); for the damping, give the "
                             f"joint's share (the material damping subtracted)")
    if m.n_points == 0:
        raise InputError(f"{m.source or 'measured data'}: no frequency or damping value")
    return m


# ------------------------------------------------------------------------ evaluation

class _Evaluator:
    """QSMA results at parameter values, through the sweep's preparation groups."""

    def __init__(self, model, options, names):
        self.model, self.options, self.names = model, options, tuple(names)
        self.groups = {}
        self.nruns = 0

    def result(self, values):
        from ..analysis import prepare, run_prepared
        case = Case(0, tuple(zip(self.names, (float(v) for v in values))))
        key = material_key(case, len(self.model.bodies),
                            [b.name for b in self.model.bodies])
        if key not in self.groups:
            if len(self.groups) > 2:         # material fits: keep the memory bounded
                self.groups.pop(next(iter(self.groups)))
            self.groups[key] = prepare(model_with_materials(self.model, key), self.options)
        self.nruns += 1
        res = run_prepared(*case_inputs(self.groups[key], case.as_dict(), self.options))
        if not res.success:
            raise AnalysisError(f"the run at {case.as_dict()} did not succeed "
                                f"({res.message}); narrow the bounds or change the start")
        return res


def predict(res, measured: Measured) -> dict:
    """Computed frequency and damping at the measured amplitudes, interpolated linearly
    in log amplitude (damping: in log damping, floored at :data:`ZETA_FLOOR`)."""
    amp = np.abs(np.asarray(getattr(res, measured.kind), float))
    x = np.log(amp)
    if np.any(np.diff(x) <= 0):
        raise AnalysisError(f"the computed peak {measured.kind} amplitude does not "
                            f"increase with the load level: it cannot be interpolated")
    xm = np.log(measured.amplitude)
    outside = (xm < x[0] - 1e-12) | (xm > x[-1] + 1e-12)
    if np.any(outside):
        raise AnalysisError(
            f"measured {measured.kind} amplitudes {measured.amplitude[outside].tolist()} "
            f"lie outside the computed range [{amp[0]:.4g}, {amp[-1]:.4g}]; give load "
            f"levels that span them")
    f = np.interp(xm, x, res.f_hz)
    z = np.exp(np.interp(xm, x, np.log(np.maximum(res.zeta, ZETA_FLOOR))))
    return {"f_hz": f, "zeta": z}


def residuals(pred: dict, measured: Measured, sigma_f: float, sigma_zeta: float):
    """Weighted residuals: (f/f_m - 1)/sigma_f and (ln zeta - ln zeta_m)/sigma_zeta at
    the points where the value was measured."""
    fm, zm = measured.f_hz, measured.zeta
    rf = (pred["f_hz"] / fm - 1) / sigma_f
    rz = (np.log(pred["zeta"]) - np.log(zm)) / sigma_zeta
    return np.concatenate([rf[np.isfinite(fm)], rz[np.isfinite(zm)]])


def default_levels(measured: Measured, n=DEFAULT_FIT_LEVELS) -> Levels:
    """Load levels spanning tip amplitudes: linear tip deflection from half the smallest
    to the largest measured one (:data:`DEFAULT_FIT_LEVELS`)."""
    if measured.kind != "tip":
        raise InputError("measured modal amplitudes (column q): give the load levels of "
                         "the evaluations (--levels, or levels in the configuration)")
    a = measured.amplitude
    return Levels.log("tip", 0.5 * a.min(), a.max(), n)


# ---------------------------------------------------------------------------- the fit

def parse_assignments(text, what) -> dict:
    """``"mu=0.5,preload=1.2"`` -> dict; for bounds ``"mu=0.1:1"`` -> (0.1, 1.0)."""
    out = {}
    for item in (t for t in (text or "").split(",") if t.strip()):
        name, sep, value = item.partition("=")
        try:
            if not sep:
                raise ValueError
            out[name.strip()] = (tuple(float(v) for v in value.split(":"))
                                 if what == "bounds" else float(value))
            if what == "bounds" and len(out[name.strip()]) != 2:
                raise ValueError
        except ValueError:
            example = "mu=0.1:1.5,preload=0.5:2" if what == "bounds" else "mu=0.5,preload=1"
            raise InputError(f"--{what} {item!r}: expected NAME=" +
                             ("LOW:HIGH" if what == "bounds" else "VALUE") +
                             f", e.g. {example}") from None
    return out


def _start_value(model, name):
    base, _, body = name.partition(":")
    if name == "mu":
        return float(model.mu)
    if name == "preload":
        return 1.0
    bodies = [b for b in model.bodies if not body or b.name == body]
    return float(getattr(bodies[0].material, base))


def _check_names(names):
    if not names:
        raise InputError("give the parameters to fit, e.g. --params mu,preload")
    for n in names:
        kind = parameter_kind(n)
        if kind == "option":
            raise InputError(f"{n!r} cannot be fitted (a run option); fittable: mu, "
                             f"preload, {', '.join(MATERIAL_PARAMETERS)}[:BODY]")
    if len(set(names)) != len(names):
        raise InputError(f"a parameter is named twice in {list(names)}")


def _bounds(names, start, given):
    lo, hi = [], []
    for n in names:
        if n in given:
            low, high = given[n]
        elif n in ABSOLUTE_BOUNDS:
            low, high = ABSOLUTE_BOUNDS[n]
        else:
            low, high = start[n] / BOUND_FACTOR, start[n] * BOUND_FACTOR
        if not (0 < low < high) or not (low <= start[n] <= high):
            raise InputError(f"bounds of {n}: need 0 < LOW < HIGH with the start "
                             f"{start[n]:g} inside, got {low:g}:{high:g}")
        lo.append(low)
        hi.append(high)
    return np.array(lo), np.array(hi)


def fit(model_or_config, measured, params, options: RunOptions | None = None, *,
        start: dict | None = None, bounds: dict | None = None, sigma_f: float = 1e-3,
        sigma_zeta: float = 0.1, max_evaluations: int = 60, out=None) -> FitResult:
    r"""Fit model parameters to measured frequency and damping versus amplitude.

    Minimises the weighted least-squares objective of the module docstring over the
    logarithms of the parameters (within ``bounds``) and reports the fitted values
    with their linearised standard uncertainty.

    Parameters
    ----------
    model_or_config : :class:`qsma.model.Model` or :class:`qsma.analysis.config.RunConfig`
    measured : :class:`Measured` or path of a CSV (:func:`read_measured`)
    params : sequence of str
        Parameters to fit: ``mu``, ``preload`` (scale of the 'preload' pattern),
        ``E``, ``nu``, ``rho`` (``E:BODY`` for one body).
    options : RunOptions, optional
        Options of every evaluation; without levels, :func:`default_levels`.
    start : dict, optional
        Start values (default: the model's; preload scale 1).
    bounds : dict, optional
        ``name -> (low, high)`` (default: :data:`ABSOLUTE_BOUNDS` or the start divided
        and multiplied by :data:`BOUND_FACTOR`).
    sigma_f, sigma_zeta : float
        Expected relative scatter of the measured frequency and damping (weights).
    max_evaluations : int
        Largest number of the optimiser's evaluations (``max_nfev``); each Jacobian
        costs one more QSMA run per parameter, not counted there.
    out : path, optional
        Folder for fit.json, fit.csv, fit.png and the best run's result folder
        ``best/`` (:func:`write_fit`).

    Returns
    -------
    FitResult
    """
    from scipy.optimize import least_squares
    from ..analysis.config import RunConfig
    if isinstance(model_or_config, RunConfig):
        model = model_or_config.model
        options = model_or_config.options if options is None else options
    else:
        model = model_or_config
    measured = read_measured(measured) if not isinstance(measured, Measured) \
        else check_measured(measured)
    measured = in_model_units(measured, model.units)
    names = tuple(params.split(",") if isinstance(params, str) else params)
    _check_names(names)
    check_bodies([Case(0, tuple((n, 1.0) for n in names if n != "mu"))], model)
    if "mu" in names:
        model.check_mu_reaches(None, STUDY_MU_FIX, what="fitting mu")
    for w, v in (("sigma_f", sigma_f), ("sigma_zeta", sigma_zeta)):
        if not (np.isfinite(v) and v > 0):
            raise InputError(f"{w} must be a positive number, got {v!r}")
    if measured.n_points <= len(names):
        raise InputError(f"{measured.n_points} measured values cannot determine "
                         f"{len(names)} parameters: give more amplitudes")
    options = options or RunOptions()
    if options.levels is None:
        options = options.replace(levels=default_levels(measured))
    given = dict(start or {})
    unknown = set(given) - set(names)
    if unknown or set(bounds or {}) - set(names):
        raise InputError(f"start or bounds name parameters not fitted: "
                         f"{sorted(unknown | (set(bounds or {}) - set(names)))}")
    p0 = {n: float(given.get(n, _start_value(model, n))) for n in names}
    lo, hi = _bounds(names, p0, bounds or {})
    ev = _Evaluator(model, options, names)
    history, keep = [], {}

    def fun(x):
        p = np.exp(x)
        res = ev.result(p)
        pred = predict(res, measured)
        r = residuals(pred, measured, sigma_f, sigma_zeta)
        history.append((tuple(p.tolist()), 0.5 * float(r @ r)))
        if not keep or history[-1][1] <= keep["cost"]:
            keep.update(cost=history[-1][1], result=res, pred=pred, p=p)
        keep.setdefault("start", (res, pred))
        return r

    x0 = np.log([p0[n] for n in names])
    with ExitStack() as stack:          # the result folder taken before any evaluation
        folder = None if out is None else stack.enter_context(RunFolder(out, kind="fit"))
        sol = least_squares(fun, x0, bounds=(np.log(lo), np.log(hi)), method="trf",
                            diff_step=DIFF_STEP, x_scale=1.0, max_nfev=max_evaluations,
                            xtol=1e-4, ftol=1e-6)
        fr = _summarise(sol, names, p0, lo, hi, measured, ev, history, keep)
        if folder is not None:
            fr = write_fit(fr, folder, start_prediction=keep["start"][1])
    return fr


def _summarise(sol, names, p0, lo, hi, measured, ev, history, keep):
    """FitResult from the optimiser's solution: values, uncertainty, combinations."""
    p = np.exp(sol.x)
    res = ev.result(p) if not np.allclose(keep["p"], p, rtol=1e-14) else keep["result"]
    pred = predict(res, measured)
    m, n = sol.fun.size, len(names)
    s2 = float(sol.fun @ sol.fun) / max(m - n, 1)
    cov, combos = _covariance(sol.jac, s2, names)
    for c in combos:
        c["value"] = float(np.prod([v ** c["exponents"][k] for k, v in zip(names, p)]))
    sigma_x = np.sqrt(np.diag(cov))
    sigma = {k: float(v * s) for k, v, s in zip(names, p, sigma_x)}
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov / np.outer(sigma_x, sigma_x)
    at_bound = [k for k, v, a, b in zip(names, p, lo, hi)
                if v <= a * (1 + 1e-6) or v >= b * (1 - 1e-6)]
    undetermined = [k for k, s in zip(names, sigma_x) if not s < DETERMINED_RSIGMA]
    converged = sol.status > 0
    problems = []
    if not converged:
        problems.append(f"the optimiser stopped before converging ({sol.message})")
    if at_bound:
        problems.append(f"{at_bound} at a bound (widen it: the uncertainty there is "
                        f"not meaningful)")
    if undetermined:
        best = combos[0]
        problems.append(f"the data do not determine {undetermined} separately (relative "
                        f"uncertainty above {DETERMINED_RSIGMA:g}); they determine "
                        f"{best['expression']} = {best['value']:.6g} to "
                        f"{100 * best['relative_sigma']:.2g}%: fix all but one of them")
    ok = converged and not problems
    message = ("converged: " + ", ".join(f"{k} = {v:.6g} +- {sigma[k]:.2g}"
                                         for k, v in zip(names, p))) if ok \
        else "; ".join(problems)
    return FitResult(ok, message, names, dict(zip(names, p.tolist())), sigma, p0,
                     {k: (float(a), float(b)) for k, a, b in zip(names, lo, hi)},
                     corr, combos, float(sol.cost), math.sqrt(s2), measured.n_points,
                     int(ev.nruns), measured, pred, res, tuple(history))


def _covariance(jac, s2, names):
    """Covariance of the log-parameters, s^2 V S^-2 V^T (inf along null directions),
    and the combinations prod p_j^v_j the data determine (one per singular value)."""
    _, S, Vt = np.linalg.svd(np.atleast_2d(jac), full_matrices=False)  # m > n: n values
    n = len(names)
    inv = np.where(S > S.max() * 1e-12, 1.0 / np.maximum(S, 1e-300) ** 2, np.inf)
    V = Vt.T
    with np.errstate(invalid="ignore"):
        cov = s2 * np.einsum("ik,k,jk->ij", V, inv, V)
    combos = []
    for k in range(n):
        v = V[:, k] / V[np.argmax(np.abs(V[:, k])), k]
        expr = " * ".join(f"{nm}^{e:.3g}" if abs(e - 1) > 5e-4 else nm
                          for nm, e in zip(names, v) if abs(e) > 1e-3)
        combos.append({"expression": expr, "exponents": dict(zip(names, v.tolist())),
                       "relative_sigma": float(math.sqrt(s2) * math.sqrt(inv[k]) /
                                               np.max(np.abs(V[:, k])))})
    return cov, tuple(combos)


# --------------------------------------------------------------------------- writing

def fit_dict(fr: FitResult) -> dict:
    """The content of fit.json (docs/studies.md)."""
    def num(v):
        return None if not np.isfinite(v) else float(v)
    m = fr.measured
    return {
        "schema_version": 1,
        "success": fr.success, "message": fr.message,
        "parameters": {k: {"value": fr.values[k], "sigma": num(fr.sigma[k]),
                           "start": fr.start[k], "bounds": list(fr.bounds[k])}
                       for k in fr.names},
        "correlation": [[num(v) for v in row] for row in np.asarray(fr.correlation)],
        "combinations": [{**c, "relative_sigma": num(c["relative_sigma"])}
                         for c in fr.combinations],
        "objective": {"cost": fr.cost, "residual_sigma": fr.residual_sigma,
                      "n_points": fr.n_points, "evaluations": fr.nfev},
        "measured": {"source": m.source, "kind": m.kind,
                     "amplitude": m.amplitude.tolist(),
                     "f_hz": [num(v) for v in m.f_hz], "zeta": [num(v) for v in m.zeta],
                     "f_hz_fit": fr.predicted["f_hz"].tolist(),
                     "zeta_fit": fr.predicted["zeta"].tolist()},
        "history": [{"values": dict(zip(fr.names, p)), "cost": c} for p, c in fr.history],
    }


def write_fit(fr: FitResult, out, start_prediction=None) -> FitResult:
    """Write fit.json, fit.csv (measured against fitted per amplitude), fit.png (the
    overlay) and ``best/`` (the result folder of the fitted run) as one result folder
    ``out`` (a path, or an entered :class:`qsma.output.folders.RunFolder` of kind ``fit``),
    swapped into place as a whole."""
    if not isinstance(out, RunFolder):
        with RunFolder(out, kind="fit") as folder:
            return write_fit(fr, folder, start_prediction)
    from dataclasses import replace
    from ..output.files import atomic_write, write_all
    from .plots import plot_fit
    folder, out = out, out.staging
    paths = {"json": out / "fit.json", "csv": out / "fit.csv"}
    atomic_write(paths["json"], json.dumps(fit_dict(fr), indent=1) + "\n")
    m = fr.measured
    from ..analysis.result import level_units
    from ..units import column_label
    unit = level_units(fr.result.units, fr.result.model.dim)
    lines = [",".join(column_label(c, unit[c]) for c in (m.kind, "f_hz", "zeta"))
             + ",f_hz_fit [Hz],zeta_fit [-]"]
    for k in range(m.amplitude.size):
        vals = (m.amplitude[k], m.f_hz[k], m.zeta[k], fr.predicted["f_hz"][k],
                fr.predicted["zeta"][k])
        lines.append(",".join("" if not np.isfinite(v) else f"{v:.10g}" for v in vals))
    atomic_write(paths["csv"], "\n".join(lines) + "\n")
    paths["plot"] = plot_fit(fr, out / "fit.png", start_prediction)
    best = folder.subfolder("best")
    write_all(fr.result, best.path, plots=True, vtu=False, folder=best)
    folder.commit()
    paths = {k: folder.path / Path(p).name for k, p in paths.items()}
    paths["best"] = best.path / "results.json"
    return replace(fr, paths=paths)


__all__ = ["fit", "read_measured", "Measured", "FitResult", "predict", "residuals",
           "default_levels", "write_fit", "fit_dict", "parse_assignments"]
