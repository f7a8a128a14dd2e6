"""Figures of a study: frequency and damping versus amplitude, one curve per case,
one figure per varied parameter (matplotlib Agg, as :mod:`qsma.output.plots`)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..output.plots import agg_figure, save_png
from ..units import quantity_unit


def _cases(table):
    """Per case index: row indices of its levels (cases without levels are left out)."""
    out = {}
    for i, (c, lv) in enumerate(zip(table["case"], table["level"])):
        if lv is not None:
            out.setdefault(c, []).append(i)
    return out


def plot_parameter(table, parameter, others, path, units="SI", dim=3, amplitude=None):
    """Secant frequency and damping ratio versus the amplitude, a curve per case,
    coloured by the value of ``parameter`` (the other parameters in the label), in
    the model's ``units``. ``amplitude``: the measure of a run's figures
    (:data:`qsma.output.plots.AMPLITUDES`, default the peak tip deflection)."""
    from ..output.plots import AMPLITUDES, DEFAULT_AMPLITUDE, check_amplitude
    field, text, quantity = AMPLITUDES[check_amplitude(amplitude or DEFAULT_AMPLITUDE)]
    from matplotlib import colormaps
    fig, (a1, a2) = agg_figure(2, 1, figsize=(6.5, 7), sharex=True)
    rows = _cases(table)
    values = sorted({table[parameter][r[0]] for r in rows.values()}, key=str)
    cmap = colormaps["viridis"]
    for c, r in rows.items():
        v = table[parameter][r[0]]
        colour = cmap(values.index(v) / max(len(values) - 1, 1))
        amp = np.abs(np.array([np.nan if table[field][i] is None else table[field][i]
                               for i in r], float))
        f = np.array([table["f_hz"][i] for i in r], float)
        z = np.array([table["zeta"][i] for i in r], float)
        label = f"{parameter} = {v:.4g}" if isinstance(v, float) else f"{parameter} = {v}"
        rest = ", ".join(f"{o} = {table[o][r[0]]:.3g}" if isinstance(table[o][r[0]], float)
                         else f"{o} = {table[o][r[0]]}" for o in others)
        a1.semilogx(amp, f, "-", color=colour, lw=1.2, label=label + (f" ({rest})" if rest
                                                                       else ""))
        a2.semilogx(amp, z, "-", color=colour, lw=1.2)
    a1.set_ylabel("secant frequency [Hz]")
    a2.set_ylabel("damping ratio \u03b6 [-]")
    a2.set_yscale("symlog", linthresh=1e-6)   # zero and round-off stay visible
    a2.set_xlabel(f"{text} [{quantity_unit(quantity, units, dim, pretty=True)}]")
    a1.set_title(f"Study over {parameter}")
    for a in (a1, a2):
        a.grid(True, alpha=0.3)
    if len(rows) <= 12:
        a1.legend(fontsize=7)
    return save_png(fig, path)


def plot_study(table, parameters, out, units="SI", dim=3, amplitude=None) -> dict:
    """One figure per varied parameter: ``sweep_<parameter>.png`` in ``out``."""
    paths = {}
    if not _cases(table):
        return paths
    for p in parameters:
        others = [o for o in parameters if o != p]
        safe = p.replace(":", "_")
        paths[f"plot_{p}"] = plot_parameter(table, p, others, Path(out) / f"sweep_{safe}.png",
                                            units, dim, amplitude)
    return paths


def plot_fit(fr, path, start_prediction=None):
    """Measured frequency and damping (markers) against the fitted run's curves and,
    dashed, the interpolated values of the start point."""
    fig, (a1, a2) = agg_figure(2, 1, figsize=(6.5, 7), sharex=True)
    m, res = fr.measured, fr.result
    amp = np.abs(np.asarray(getattr(res, m.kind), float))
    fitted = ", ".join(f"{k} = {v:.4g}" for k, v in fr.values.items())
    a1.semilogx(amp, res.f_hz, "-", lw=1.4, label=f"fitted ({fitted})")
    a2.loglog(amp, np.maximum(res.zeta, 1e-12), "-", lw=1.4)
    if start_prediction is not None:
        start = ", ".join(f"{k} = {v:.4g}" for k, v in fr.start.items())
        a1.semilogx(m.amplitude, start_prediction["f_hz"], "--", color="0.5", lw=1,
                    label=f"start ({start})")
        a2.loglog(m.amplitude, start_prediction["zeta"], "--", color="0.5", lw=1)
    a1.semilogx(m.amplitude, m.f_hz, "ko", ms=4, mfc="none", label="measured")
    a2.loglog(m.amplitude, m.zeta, "ko", ms=4, mfc="none")
    a1.set_ylabel("secant frequency [Hz]")
    a2.set_ylabel(r"damping ratio $\zeta$")
    unit = quantity_unit("length" if m.kind == "tip" else "modal_amplitude", res.units,
                         res.model.dim, pretty=True)
    a2.set_xlabel(f"peak tip deflection [{unit}]" if m.kind == "tip"
                  else f"peak modal amplitude q [{unit}]")
    lo, hi = m.amplitude.min(), m.amplitude.max()
    a2.set_xlim(lo / 2, hi * 2)
    z = m.zeta[np.isfinite(m.zeta)]
    if z.size:
        a2.set_ylim(z.min() / 5, z.max() * 5)
    a1.set_title("Fit: " + ("converged" if fr.success else "NOT determined / converged"))
    for a in (a1, a2):
        a.grid(True, which="both", alpha=0.3)
    a1.legend(fontsize=7)
    return save_png(fig, path)
