"""``report.html``: a self-contained page a person reads, for a run and for a study.

One HTML file, no network: the figures are images embedded as base64 ``data:`` URIs
(the run's figures PNG, the mesh of a 2D model an SVG drawing, both drawn by
matplotlib), the style is inline, there is no script. A run's report holds the model
summary, a picture of the mesh with the interface, the figures of the run
(:mod:`qsma.output.plots`), the per-level table, the solver statistics and every warning the
result carries (the message, flagged levels, the direct loop's outcome). A study's
report holds the parameters, the case table with statuses and messages, and the
study figures. The page is laid out for a screen of about 1200 pixels: the figures
side by side two to a row at close to their own size (the wide ones on a row of
their own), tables of names and values without a header row; tests/test_report.py
checks this in a real browser.
"""
from __future__ import annotations

import base64
from dataclasses import dataclass
from html import escape
import io
from pathlib import Path
import tempfile

import numpy as np

from ..mesh.celltypes import CELL_TYPES
from ..analysis.result import FAILURE_FLAGS, LEVEL_COLUMNS, level_units
from ..units import column_label

REPORT_NAME = "report.html"
#: Columns of the per-level table of a run's report: (field, heading, format), the
#: fields whose :func:`qsma.analysis.result.column` names a ``report`` column, in their order; the
#: heading gets the field's unit in the model's system (:func:`qsma.analysis.result.level_units`).
LEVEL_TABLE = tuple((name, *c["report"]) for name, c in LEVEL_COLUMNS.items()
                    if c["report"] is not None)

_STYLE = """
body { font-family: sans-serif; font-size: 16px; line-height: 1.4; margin: 1.5em auto;
       max-width: 76em; padding: 0 1em; color: #222; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-size: 0.875em; margin: 0.5em 0 1em; }
td, th { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: right; }
th { background: #f0f0f0; } td.text, th.text { text-align: left; }
table.pairs td:first-child { background: #f6f6f6; }
.ok { color: #060; font-weight: bold; } .bad { color: #a00; font-weight: bold; }
.warn { background: #fff4e0; border-left: 4px solid #e90; padding: 0.4em 0.8em; }
.figures { display: grid; grid-template-columns: repeat(auto-fill, minmax(34em, 1fr));
           gap: 1em; align-items: start; grid-auto-flow: dense; }
figure { margin: 0; } figure.wide { grid-column: 1 / -1; }
figure img { display: block; max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { font-size: 0.875em; color: #555; }
"""
#: A figure at least this many pixels wide gets a row of its own in the report (the
#: others two to a row at a 1200-pixel window, each shown at close to its own size).
WIDE_FIGURE_PX = 800


# ------------------------------------------------------------------------- page parts

def _page(title, body) -> str:
    return (f'<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
            f'<title>{escape(title)}</title>\n<style>{_STYLE}</style>\n</head>\n<body>\n'
            f'<h1>{escape(title)}</h1>\n{body}\n</body>\n</html>\n')


def _table(headings, rows, text_columns=(), css=None) -> str:
    """An HTML table; ``headings`` ``None``: no header row."""
    lines = [f'<table class="{css}">' if css else "<table>"]
    if headings is not None:
        head = "".join(f'<th class="text">{escape(str(h))}</th>' if i in text_columns
                       else f"<th>{escape(str(h))}</th>" for i, h in enumerate(headings))
        lines.append(f"<tr>{head}</tr>")
    for row in rows:
        cells = "".join(f'<td class="text">{escape(str(v))}</td>' if i in text_columns
                        else f"<td>{escape(str(v))}</td>" for i, v in enumerate(row))
        lines.append(f"<tr>{cells}</tr>")
    return "\n".join(lines) + "\n</table>"


def _pairs(mapping) -> str:
    """A two-column table of a mapping: names and values, no header row."""
    return _table(None, [(k, v) for k, v in mapping.items()], text_columns=(0, 1),
                  css="pairs")


def _figure_html(image: bytes, caption: str, mime: str = "image/png") -> str:
    """A figure of the page; one wider than :data:`WIDE_FIGURE_PX` (an SVG always)
    takes a row of its own."""
    data = base64.b64encode(image).decode("ascii")
    wide = mime != "image/png" or _png_width(image) >= WIDE_FIGURE_PX
    tag = '<figure class="wide">' if wide else "<figure>"
    return (f'{tag}<img alt="{escape(caption)}" src="data:{mime};base64,{data}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>")


def _png_width(png: bytes) -> int:
    """The width of a PNG image in pixels (its IHDR chunk)."""
    return int.from_bytes(png[16:20], "big") if png[:8] == b"\x89PNG\r\n\x1a\n" else 0


#: Margins of the 3D mesh figure in inches (left, right, bottom, top): the legend sits
#: in the right margin. Fixed margins draw the figure once, where
#: ``bbox_inches="tight"`` drew it twice.
MESH_MARGINS_IN = (0.1, 3.2, 0.1, 0.4)
#: Colours of the bodies (matplotlib's tab:blue, green, purple, brown) and of the pair
#: states after the preload, shared by the SVG and PNG figures.
BODY_COLOURS = ("#1f77b4", "#2ca02c", "#9467bd", "#8c564b")
STATE_COLOURS = {"stuck": "#ff0000", "slipping": "#ffa500", "open": "#999999"}


def _pair_states(status):
    """(state code, name, colour, selection) of each pair state that occurs in
    ``status``, in the order stuck, slipping, open."""
    from ..contact.state import PairState
    out = []
    for state in PairState:
        name = "slipping" if state == PairState.SLIPPING else state.name.lower()
        sel = status == state
        if np.any(sel):
            out.append((int(state), name, STATE_COLOURS[name], sel))
    return out


def _png(fig) -> bytes:
    from .plots import PNG_COMPRESSION
    buf = io.BytesIO()
    fig.savefig(buf, dpi=100, format="png", pil_kwargs={"compress_level": PNG_COMPRESSION})
    return buf.getvalue()


def _status(success, message) -> str:
    cls, word = ("ok", "success") if success else ("bad", "NOT successful")
    return f'<p><span class="{cls}">{word}</span>: {escape(str(message))}</p>'


# ---------------------------------------------------------------------------- figures

def mesh_figure(res) -> tuple:
    """The bodies' meshes and the interface pairs coloured by their state after the
    preload, as ``(MIME type, image bytes)``: a 2D model as an SVG drawing
    (:func:`draw_mesh_2d`), a 3D model as PNG (:func:`draw_mesh_3d`, nodes only), both
    drawn by matplotlib."""
    if res.model.dim == 2:
        return "image/svg+xml", _svg(draw_mesh_2d(res))
    return "image/png", _png(draw_mesh_3d(res))


def _svg(fig) -> bytes:
    """The SVG file of ``fig``: text as text (the browser's sans-serif), no date, fixed
    element ids (the same bytes for the same figure)."""
    import matplotlib
    buf = io.BytesIO()
    with matplotlib.rc_context({"svg.fonttype": "none", "svg.hashsalt": "qsma"}):
        fig.savefig(buf, format="svg", metadata={"Date": None})
    return buf.getvalue()


def _length(res) -> str:
    from ..units import quantity_unit
    return quantity_unit("length", res.units)


def draw_mesh_3d(res):
    """The nodes of each body and the interface pairs by their state after the preload
    in a 3D view scaled equally along x, y and z (a thin plate looks thin)."""
    from .plots import agg_figure
    model, p = res.model, res.pairing
    from matplotlib.ticker import MaxNLocator
    fig = agg_figure(figsize=(10.0, 4.6), margins=MESH_MARGINS_IN)[0]
    fig.clf()
    ax = fig.add_subplot(projection="3d")
    fig.subplots_adjust(left=0.0, right=1 - MESH_MARGINS_IN[1] / 10.0, bottom=0.0,
                        top=1 - MESH_MARGINS_IN[3] / 4.6)
    points = np.vstack([b.mesh.points for b in model.bodies])
    for k, b in enumerate(model.bodies):
        pts = b.mesh.points
        ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=0.5,
                   color=BODY_COLOURS[k % len(BODY_COLOURS)], label=b.name)
    for _, label, colour, sel in _pair_states(res.preload.status):
        ax.scatter(*p.x[sel].T, s=8, color=colour, zorder=3,
                   label=f"interface pair, {label} after preload ({int(sel.sum())})")
    extent = np.ptp(points, axis=0)
    ax.set_box_aspect(np.maximum(extent, 1e-3 * extent.max()), zoom=1.25)  # equal scales
    for axis, e in zip((ax.xaxis, ax.yaxis, ax.zaxis), extent):   # fewer on short sides
        axis.set_major_locator(MaxNLocator(int(np.clip(6 * e / extent.max(), 1, 4))))
    length = _length(res)
    ax.set_xlabel(f"x [{length}]", fontsize=8)
    ax.set_ylabel(f"y [{length}]", fontsize=8)
    ax.set_zlabel(f"z [{length}]", fontsize=8)
    ax.tick_params(labelsize=7)
    fig.suptitle(f"{model.name}: {model.n_nodes} nodes, {p.n_pairs} interface pairs",
                 fontsize=10)
    ax.legend(fontsize=7, loc="upper right", bbox_to_anchor=(0.995, 0.88),
              bbox_transform=fig.transFigure)       # in the right margin
    return fig


#: Cells of one body drawn in one panel of the 2D mesh figure, at most: a finer mesh
#: is drawn by its outline (cells of a pixel or less read as a solid area anyway, and
#: the page stays small: about 30 bytes per edge in the SVG file).
MAX_SVG_CELLS = 20000
#: The 2D mesh figure: width and margins in inches (left, right for the legend,
#: bottom, top), the gap between its two panels and the heights a panel may take.
MESH_2D = dict(width=10.0, margins=(0.9, 3.1, 0.6, 0.75), gap=0.95,
               whole=(0.6, 2.2), zoom=(1.4, 3.4))


def _body_corner_blocks(mesh) -> list:
    """Corner node indices of a 2D mesh, one array per cell block (mixed meshes hold
    triangles and quadrilaterals side by side)."""
    return [block.cells[:, :CELL_TYPES[block.cell_type].corners]
            for block in mesh.cell_blocks]


def _cell_edges(blocks) -> np.ndarray:
    """Every edge (node pair) of the cells of ``blocks`` (corner nodes in cyclic
    order), each once."""
    edges = np.concatenate([np.stack([c, np.roll(c, -1, axis=1)], axis=-1).reshape(-1, 2)
                            for c in blocks])
    return np.unique(np.sort(edges, axis=1), axis=0)


def _outline_edges(blocks) -> np.ndarray:
    """The edges (node pairs) of the cells of ``blocks`` (arrays of corner nodes in
    cyclic order) that belong to one cell only: the boundary of the meshed region."""
    edges = np.concatenate([np.stack([c, np.roll(c, -1, axis=1)], axis=-1).reshape(-1, 2)
                            for c in blocks])
    _, first, count = np.unique(np.sort(edges, axis=1), axis=0, return_index=True,
                                return_counts=True)
    return edges[first[count == 1]]


def _edges_path(points, edges, window=None):
    """One matplotlib path of the line segments ``edges`` of ``points`` (a single
    element in the SVG file); with ``window`` ``(x0, x1, y0, y1)``, only the segments
    whose bounding box meets it."""
    from matplotlib.path import Path as MplPath
    seg = points[edges]                                   # (m, 2, 2)
    if window is not None:
        x0, x1, y0, y1 = window
        lo, hi = seg.min(axis=1), seg.max(axis=1)
        seg = seg[(hi[:, 0] >= x0) & (lo[:, 0] <= x1) & (hi[:, 1] >= y0)
                  & (lo[:, 1] <= y1)]
    codes = np.tile([MplPath.MOVETO, MplPath.LINETO], len(seg)).astype(np.uint8)
    return MplPath(seg.reshape(-1, 2), codes)


def body_edges(mesh) -> tuple:
    """``(edges, kind)`` drawn for a 2D body: every cell edge (``"cells"``), or beyond
    :data:`MAX_SVG_CELLS` cells its outline (``"outline"``)."""
    blocks = _body_corner_blocks(mesh)
    if sum(len(c) for c in blocks) > MAX_SVG_CELLS:
        return _outline_edges(blocks), "outline"
    return _cell_edges(blocks), "cells"


def _filled(window, ratio):
    """``window`` ``(x0, x1, y0, y1)`` widened about its centre in x or y until its
    height is ``ratio`` times its width: it fills a panel of that shape at equal
    scales."""
    x0, x1, y0, y1 = window
    dx, dy = max(x1 - x0, 1e-300), max(y1 - y0, 1e-300)
    if dy < ratio * dx:
        c, dy = 0.5 * (y0 + y1), ratio * dx
        return x0, x1, c - dy / 2, c + dy / 2
    c, dx = 0.5 * (x0 + x1), dy / ratio
    return c - dx / 2, c + dx / 2, y0, y1


def draw_mesh_2d(res):
    """The 2D mesh figure: the whole model (cell edges of each body) above the
    interface region with a margin of 15 % of its extent (the interface pairs as dots
    coloured by their state after the preload), both at equal scale in x and y and as
    wide as the figure, the legend on the right. A body of more than
    :data:`MAX_SVG_CELLS` cells is drawn by its outline."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import PathPatch
    from .plots import agg_figure
    model, p = res.model, res.pairing
    g = MESH_2D
    left, right, bottom, top = g["margins"]
    width = g["width"] - left - right
    points = np.vstack([b.mesh.points[:, :2] for b in model.bodies])
    lo, hi = points.min(axis=0), points.max(axis=0)
    xy = (p.x if len(p.x) else np.vstack([c.pairing.x for c in p.tied]))[:, :2]
    pad = 0.15 * max(float(np.ptp(xy, axis=0).max()), 1e-12)
    plo, phi = xy.min(axis=0) - pad, xy.max(axis=0) + pad
    windows = ((lo[0], hi[0], lo[1], hi[1]), (plo[0], phi[0], plo[1], phi[1]))
    heights = [float(np.clip(width * (w[3] - w[2]) / max(w[1] - w[0], 1e-300), *bounds))
               for w, bounds in zip(windows, (g["whole"], g["zoom"]))]
    fig, axes = agg_figure(2, 1, figsize=(g["width"], sum(heights) + g["gap"] + bottom + top),
                           hspace=g["gap"] / np.mean(heights), margins=g["margins"],
                           gridspec_kw=dict(height_ratios=heights))
    edges = [body_edges(b.mesh) for b in model.bodies]
    length = _length(res)
    windows = [_filled(w, h / width) for w, h in zip(windows, heights)]
    for ax, window, title in zip(axes, windows, ("whole model", "interface region")):
        zoom = ax is axes[1]
        for i, (b, (e, kind)) in enumerate(zip(model.bodies, edges)):
            path = _edges_path(b.mesh.points[:, :2], e, window if zoom else None)
            # add_artist: the limits are set below (add_patch would walk every
            # segment to update them, most of the drawing time)
            ax.add_artist(PathPatch(path, fill=False, lw=0.5, gid=f"{kind}-{i}",
                                    edgecolor=BODY_COLOURS[i % len(BODY_COLOURS)]))
        ax.set_xlim(window[0], window[1])
        ax.set_ylim(window[2], window[3])
        ax.set_aspect("equal", adjustable="box")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(f"x [{length}]")
        ax.set_ylabel(f"y [{length}]")
    handles = [Line2D([], [], color=BODY_COLOURS[i % len(BODY_COLOURS)], lw=1.5,
                      label=b.name) for i, b in enumerate(model.bodies)]
    for _, label, colour, sel in _pair_states(res.preload.status):
        handles.append(axes[1].scatter(
            xy[sel, 0], xy[sel, 1], s=14, color=colour, zorder=3, gid=f"pairs-{label}",
            label=f"interface pair, {label} after preload ({int(sel.sum())})"))
    fig.legend(handles=handles, loc="upper left", fontsize=9, frameon=True,
               bbox_to_anchor=(1 - (right - 0.15) / g["width"], 1 - top / fig.get_figheight()))
    fig.suptitle(f"{model.name}: {model.n_nodes} nodes, {p.n_pairs} interface pairs",
                 fontsize=11)
    return fig


def _run_figures(res, figures, amplitude=None) -> list:
    """(caption, image bytes, MIME type) of the run's figures: those given (name -> PNG path, e.g.
    written beside results.json), else drawn into a temporary folder."""
    captions = {"backbone": "Backbone: modal force versus modal amplitude",
                "damping": "Secant frequency and damping ratio versus amplitude",
                "loops": "Hysteresis loops, each normalised by its amplitude (tied "
                          "linear force subtracted)",
                "interface": "Interface tractions and pair states",
                "interface_map": "Interface maps"}
    mime, image = mesh_figure(res)
    out = [("Mesh and interface pairs", image, mime)]
    if not res.n_levels:
        return out
    if figures is None:
        from .plots import write_plots
        with tempfile.TemporaryDirectory(prefix="qsma-report-") as tmp:
            return out + [(captions.get(k, k), Path(v).read_bytes(), "image/png")
                          for k, v in write_plots(res, tmp, amplitude).items()]
    return out + [(captions.get(k, k), Path(v).read_bytes(), "image/png")
                  for k, v in figures.items()]


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


def run_report_html(res, figures=None, amplitude=None) -> str:
    """The HTML of a run's report (see the module docstring)."""
    info = res.model_info
    parts = [_status(res.success, res.message)]
    warns = run_warnings(res)
    parts.append("<h2>Warnings</h2>" + (
        "".join(f'<p class="warn">{escape(w)}</p>' for w in warns) if warns
        else "<p>none</p>"))
    parts.append("<h2>Model</h2>" + _pairs({
        "name": info["name"], "unit system": _unit_text(res.units),
        "dimension": info["dim"], "nodes": info["n_nodes"],
        "degrees of freedom": info["n_dofs"], "interface pairs": info["n_pairs"],
        "coupling": info["coupling"], "friction coefficient": info["mu"],
        "pairs closed after the preload": info["n_closed_after_preload"],
        **({"tied interface points": info["n_tied_pairs"]}
           if info.get("n_tied_pairs") else {}),
        **{f"elements of {b}": e for b, e in info["elements"].items()}}))
    parts.append("<h2>Mode</h2>" + _pairs({
        "mode index": res.mode_index, "f0 [Hz]": f"{res.f0_hz:.4f}",
        "omega0 [rad/s]": f"{res.omega0:.4f}", "phi at the tip": f"{res.phi_tip:.6g}",
        "tied frequencies [Hz]": ", ".join(f"{f:.2f}" for f in res.modes.f_hz)}))
    parts.append('<h2>Figures</h2>\n<div class="figures">' + "\n".join(
        _figure_html(image, cap, mime)
        for cap, image, mime in _run_figures(res, figures, amplitude)) + "</div>")
    rows = [[k] + [_level_cell(getattr(res, name)[k], fmt) for name, _, fmt in LEVEL_TABLE]
            + [", ".join(res.flags[k])] for k in range(res.n_levels)]
    unit = level_units(res.units, res.model.dim)
    parts.append("<h2>Levels</h2>" + _table(
        ["level"] + [column_label(h, unit[name]) for name, h, _ in LEVEL_TABLE]
        + ["flags"], rows, text_columns=tuple(
            1 + k for k, (name, _, _) in enumerate(LEVEL_TABLE)
            if name == "dissipation_method") + (len(LEVEL_TABLE) + 1,)))
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


def write_report(res, path, figures=None, amplitude=None):
    """Write a run's report to ``path``; ``figures``: name -> PNG path of figures
    already drawn (:func:`qsma.output.plots.write_plots`), else they are drawn here against
    ``amplitude``."""
    from .folders import atomic_write
    atomic_write(path, run_report_html(res, figures, amplitude))
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
    parts.append('<h2>Figures</h2>\n<div class="figures">' + "\n".join(
        _figure_html(Path(p).read_bytes(), f"Study over {name}")
        for name, p in figures.items()) + "</div>")
    return _page(f"QSMA study over {', '.join(parameters)}", "\n".join(parts))


def _unit_text(u) -> str:
    """The unit system as a reader wants it: its name and base units."""
    return (f"{u.name} (length {u.length}, force {u.force}, time {u.time}, mass {u.mass}, "
            f"stress {u.stress})")


def _level_cell(v, fmt):
    """A cell of the levels table: a value that was not computed (NaN: a level whose
    loop failed, named in its flags) is shown as a dash, not as "nan"."""
    if isinstance(v, (float, np.floating)) and np.isnan(v):
        return "\u2014"
    return fmt.format(v)


def _fmt(v):
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def write_study_report(parameters, cases, table, figures, path):
    """Write a study's report to ``path`` (``figures``: name -> PNG path)."""
    from .folders import atomic_write
    atomic_write(path, study_report_html(parameters, cases, table, figures))
    return Path(path)


__all__ = ["write_report", "run_report_html", "write_study_report", "study_report_html",
           "mesh_figure", "draw_mesh_2d", "draw_mesh_3d", "run_warnings", "REPORT_NAME"]
