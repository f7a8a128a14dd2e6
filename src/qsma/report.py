"""``report.html``: a self-contained page a person reads, for a run and for a study.

One HTML file, no network: the figures are PNG images embedded as base64 ``data:``
URIs, the style is inline, there is no script. A run's report holds the model summary,
a picture of the mesh with the interface, the figures of the run (:mod:`qsma.plots`),
the per-level table, the solver statistics and every warning the result carries (the
message, flagged levels, the direct loop's outcome). A study's report holds the
parameters, the case table with statuses and messages, and the study figures.
"""
from __future__ import annotations

import base64
from html import escape
import io
from pathlib import Path
import tempfile

import numpy as np

from .result import FAILURE_FLAGS

REPORT_NAME = "report.html"
#: Columns of the per-level table of a run's report: (field, heading, format).
LEVEL_TABLE = (("tip_lin", "linear tip [m]", "{:.3e}"), ("tip", "peak tip [m]", "{:.3e}"),
               ("f_hz", "f [Hz]", "{:.4f}"), ("zeta", "zeta", "{:.3e}"),
               ("dissipation_method", "dissipation by", "{}"),
               ("n_stuck", "stuck", "{}"), ("n_slip", "slip", "{}"),
               ("n_open", "open", "{}"), ("iterations", "iterations", "{}"),
               ("residual", "residual", "{:.1e}"))

_STYLE = """
body { font-family: sans-serif; margin: 2em auto; max-width: 70em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-size: 0.85em; margin: 0.5em 0 1em; }
td, th { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: right; }
th { background: #f0f0f0; } td.text { text-align: left; }
.ok { color: #060; font-weight: bold; } .bad { color: #a00; font-weight: bold; }
.warn { background: #fff4e0; border-left: 4px solid #e90; padding: 0.4em 0.8em; }
figure { display: inline-block; margin: 0.5em; vertical-align: top; }
figure img { max-width: 34em; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; }
"""


# ------------------------------------------------------------------------- page parts

def _page(title, body) -> str:
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<title>{escape(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n'
            f'<h1>{escape(title)}</h1>\n{body}\n</body>\n</html>\n')


def _table(headings, rows, text_columns=()) -> str:
    head = "".join(f"<th>{escape(str(h))}</th>" for h in headings)
    lines = [f"<table>\n<tr>{head}</tr>"]
    for row in rows:
        cells = "".join(f'<td class="text">{escape(str(v))}</td>' if i in text_columns
                        else f"<td>{escape(str(v))}</td>" for i, v in enumerate(row))
        lines.append(f"<tr>{cells}</tr>")
    return "\n".join(lines) + "\n</table>"


def _pairs(mapping) -> str:
    """A two-column table of a mapping."""
    return _table(("", ""), [(k, v) for k, v in mapping.items()], text_columns=(0, 1))


def _figure_html(png: bytes, caption: str) -> str:
    data = base64.b64encode(png).decode("ascii")
    return (f'<figure><img alt="{escape(caption)}" src="data:image/png;base64,{data}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>")


#: Margins of the mesh figure in inches (left, right, bottom, top): the legend sits in
#: the right margin. Fixed margins draw the figure once, where ``bbox_inches="tight"``
#: drew it twice.
MESH_MARGINS_IN = {2: (0.6, 2.6, 0.35, 0.5), 3: (0.1, 3.2, 0.1, 0.4)}


def _png(fig) -> bytes:
    from .plots import PNG_COMPRESSION
    buf = io.BytesIO()
    fig.savefig(buf, dpi=100, format="png", pil_kwargs={"compress_level": PNG_COMPRESSION})
    return buf.getvalue()


def _status(success, message) -> str:
    cls, word = ("ok", "success") if success else ("bad", "NOT successful")
    return f'<p><span class="{cls}">{word}</span>: {escape(str(message))}</p>'


# ---------------------------------------------------------------------------- figures

def mesh_figure(res) -> bytes:
    """The bodies' meshes (2D: cell outlines; 3D: nodes), the interface pairs coloured
    by their state after the preload, the tip probe direction in the title."""
    from .contact import OPEN, SLIPPING, STUCK
    from .plots import _figure
    model, p = res.model, res.pairing
    colours = ("tab:blue", "tab:green", "tab:purple", "tab:brown")
    status = res.preload.status
    if model.dim == 2:
        from matplotlib.collections import PolyCollection
        fig, (whole, ax) = _figure(2, 1, figsize=(9.5, 3.9), hspace=0.45,
                                   margins=MESH_MARGINS_IN[2],
                                   gridspec_kw=dict(height_ratios=(1, 3)))
        for axis in (whole, ax):
            for k, b in enumerate(model.bodies):
                corners = 3 if b.mesh.cells.shape[1] in (3, 6) else 4
                polys = b.mesh.points[b.mesh.cells[:, :corners]]
                axis.add_collection(PolyCollection(
                    polys, facecolors="none", linewidths=0.3, edgecolors=colours[k % 4],
                    label=b.name))
            axis.autoscale()
            axis.set_aspect("equal")
        xy = p.x[:, :2]
        lo, hi = xy.min(axis=0), xy.max(axis=0)
        pad = 0.15 * max(hi[0] - lo[0], hi[1] - lo[1], 1e-12)
        ax.set_xlim(lo[0] - pad, hi[0] + pad)
        ax.set_ylim(lo[1] - pad, hi[1] + pad)
        whole.set_title("whole model", fontsize=9)
    else:
        fig = _figure(figsize=(7.5, 3.9), margins=MESH_MARGINS_IN[3])[0]
        fig.clf()
        ax = fig.add_subplot(projection="3d")
        for k, b in enumerate(model.bodies):
            pts = b.mesh.points
            ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=0.5, color=colours[k % 4],
                       label=b.name)
        xy = p.x
    for s, colour, label in ((STUCK, "red", "stuck"), (SLIPPING, "orange", "slipping"),
                             (OPEN, "0.6", "open")):
        sel = status == s
        if np.any(sel):
            ax.scatter(*xy[sel].T, s=8, color=colour, zorder=3,
                       label=f"interface pair, {label} after preload ({int(sel.sum())})")
    fig.suptitle(f"{model.name}: {model.n_nodes} nodes, {p.n_pairs} interface pairs",
                 fontsize=10)
    ax.legend(fontsize=7, loc="upper right", bbox_to_anchor=(0.995, 0.88),
              bbox_transform=fig.transFigure)       # in the right margin
    return _png(fig)


def _run_figures(res, figures) -> list:
    """(caption, PNG bytes) of the run's figures: those given (name -> PNG path, e.g.
    written beside results.json), else drawn into a temporary folder."""
    captions = {"backbone": "Backbone: modal force versus modal amplitude",
                "damping": "Secant frequency and damping ratio versus amplitude",
                "loops": "Hysteresis loops (tied linear force subtracted)",
                "interface": "Interface tractions and pair states",
                "interface_map": "Interface maps"}
    out = [("Mesh and interface pairs", mesh_figure(res))]
    if not res.n_levels:
        return out
    if figures is None:
        from .plots import write_plots
        with tempfile.TemporaryDirectory(prefix="qsma-report-") as tmp:
            return out + [(captions.get(k, k), Path(v).read_bytes())
                          for k, v in write_plots(res, tmp).items()]
    return out + [(captions.get(k, k), Path(v).read_bytes()) for k, v in figures.items()]


# ------------------------------------------------------------------------- run report

def run_warnings(res) -> list:
    """Sentences for every warning the result carries."""
    out = []
    if not res.success:
        out.append(res.message)
    by_flag = {}
    for k, flags in enumerate(res.flags):
        for f in flags:
            by_flag.setdefault(f, []).append(k)
    for f, ks in sorted(by_flag.items()):
        kind = "failure" if f in FAILURE_FLAGS else "note"
        out.append(f"{kind}: {f} at level(s) {ks}")
    dl = res.direct_loop
    if dl is not None and not dl.success:
        out.append(f"direct loop: {dl.message}")
    out.extend(f"warning: {w}" for w in res.warnings)
    return out


def run_report_html(res, figures=None) -> str:
    """The HTML of a run's report (see the module docstring)."""
    info = res.model_info
    parts = [_status(res.success, res.message)]
    warns = run_warnings(res)
    parts.append("<h2>Warnings</h2>" + (
        "".join(f'<p class="warn">{escape(w)}</p>' for w in warns) if warns
        else "<p>none</p>"))
    parts.append("<h2>Model</h2>" + _pairs({
        "name": info["name"], "dimension": info["dim"], "nodes": info["n_nodes"],
        "degrees of freedom": info["n_dofs"], "interface pairs": info["n_pairs"],
        "coupling": info["coupling"], "friction coefficient": info["mu"],
        "pairs closed after the preload": info["n_closed_after_preload"],
        **{f"elements of {b}": e for b, e in info["elements"].items()}}))
    parts.append("<h2>Mode</h2>" + _pairs({
        "mode index": res.mode_index, "f0 [Hz]": f"{res.f0_hz:.4f}",
        "omega0 [rad/s]": f"{res.omega0:.4f}", "phi at the tip": f"{res.phi_tip:.6g}",
        "tied frequencies [Hz]": ", ".join(f"{f:.2f}" for f in res.modes.f_hz)}))
    parts.append("<h2>Figures</h2>" + "\n".join(
        _figure_html(png, cap) for cap, png in _run_figures(res, figures)))
    rows = [[k] + [fmt.format(getattr(res, name)[k]) for name, _, fmt in LEVEL_TABLE]
            + [", ".join(res.flags[k])] for k in range(res.n_levels)]
    parts.append("<h2>Levels</h2>" + _table(
        ["level"] + [h for _, h, _ in LEVEL_TABLE] + ["flags"], rows,
        text_columns=(5, len(LEVEL_TABLE) + 1)))
    pre = res.preload
    stats = {"gross slip from level": res.gross_slip_level,
             "preload: stuck / slip / open": f"{pre.n_stuck} / {pre.n_slipping} / "
                                              f"{pre.n_open}",
             "preload residual": f"{pre.residual:.2e}",
             "preload iterations": pre.nit,
             "contact iterations over the levels": int(np.sum(res.iterations)),
             "largest level residual": f"{np.max(res.residual):.2e}" if res.n_levels
             else "-",
             **{f"solver {k}": v for k, v in res.solver.items()}}
    parts.append("<h2>Solver statistics</h2>" + _pairs(stats))
    parts.append("<h2>Timings [s]</h2>" + _pairs(
        {k: f"{v:.3f}" for k, v in res.timings_s.items()}))
    parts.append("<h2>Options</h2>" + _pairs(
        {k: v for k, v in res.options.as_dict().items()}))
    parts.append(f"<p>qsma {escape(res.version)}</p>")
    return _page(f"QSMA report: {info['name']}, mode {res.mode_index}", "\n".join(parts))


def write_report(res, path, figures=None):
    """Write a run's report to ``path``; ``figures``: name -> PNG path of figures
    already drawn (:func:`qsma.plots.write_plots`), else they are drawn here."""
    from .rundir import atomic_write
    atomic_write(path, run_report_html(res, figures))
    return Path(path)


# ----------------------------------------------------------------------- study report

def study_report_html(parameters, cases, table, figures) -> str:
    """The HTML of a study's report: the case table and the study figures."""
    n_ok = sum(o.status == "ok" for o in cases)
    parts = [_status(n_ok == len(cases), f"{n_ok} of {len(cases)} cases ok")]
    bad = [o for o in cases if o.status != "ok"]
    if bad:
        parts.append("<h2>Warnings</h2>" + "".join(
            f'<p class="warn">case {o.index} ({escape(str(o.params))}): {o.status}: '
            f"{escape(o.message)}</p>" for o in bad))
    rows = []
    for o in cases:
        sel = [i for i, c in enumerate(table["case"]) if c == o.index
               and table["level"][i] is not None]
        f = [table["f_hz"][i] for i in sel]
        z = [table["zeta"][i] for i in sel]
        rows.append([o.index] + [_fmt(o.params[p]) for p in parameters]
                    + [o.status, f"{f[0]:.4f}" if f else "-", f"{f[-1]:.4f}" if f else "-",
                       f"{max(z):.3e}" if z else "-",
                       f"{o.seconds:.2f}" if np.isfinite(o.seconds) else "-",
                       "yes" if o.skipped else "", o.message])
    n = len(parameters)
    parts.append("<h2>Cases</h2>" + _table(
        ["case", *parameters, "status", "f first level [Hz]", "f last level [Hz]",
         "largest zeta", "seconds", "resumed", "message"], rows,
        text_columns=(n + 1, n + 7)))
    parts.append("<h2>Figures</h2>" + "\n".join(
        _figure_html(Path(p).read_bytes(), f"Study over {name}")
        for name, p in figures.items()))
    return _page(f"QSMA study over {', '.join(parameters)}", "\n".join(parts))


def _fmt(v):
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def write_study_report(parameters, cases, table, figures, path):
    """Write a study's report to ``path`` (``figures``: name -> PNG path)."""
    from .rundir import atomic_write
    atomic_write(path, study_report_html(parameters, cases, table, figures))
    return Path(path)


__all__ = ["write_report", "run_report_html", "write_study_report", "study_report_html",
           "mesh_figure", "run_warnings", "REPORT_NAME"]
