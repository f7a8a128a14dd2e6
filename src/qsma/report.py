"""``report.html``: a self-contained page a person reads, for a run and for a study.

One HTML file, no network: the figures are PNG images (the mesh of a 2D model an SVG
drawing written here) embedded as base64 ``data:`` URIs, the style is inline, there
is no script. A run's report holds the model summary, a picture of the mesh with the
interface, the figures of the run (:mod:`qsma.plots`), the per-level table, the
solver statistics and every warning the result carries (the message, flagged levels,
the direct loop's outcome). A study's report holds the parameters, the case table with
statuses and messages, and the study figures.
"""
from __future__ import annotations

import base64
from dataclasses import dataclass
from html import escape
import io
from pathlib import Path
import tempfile

import numpy as np

from .result import FAILURE_FLAGS
from .units import column_label, level_units

REPORT_NAME = "report.html"
#: Columns of the per-level table of a run's report: (field, heading, format); the
#: heading gets the field's unit in the model's system (:func:`qsma.units.level_units`).
LEVEL_TABLE = (("tip_lin", "linear tip", "{:.3e}"), ("tip", "peak tip", "{:.3e}"),
               ("f_hz", "f", "{:.4f}"), ("zeta", "zeta", "{:.3e}"),
               ("dissipation", "dissipation", "{:.3e}"),
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


def _figure_html(image: bytes, caption: str, mime: str = "image/png") -> str:
    data = base64.b64encode(image).decode("ascii")
    return (f'<figure><img alt="{escape(caption)}" src="data:{mime};base64,{data}">'
            f"<figcaption>{escape(caption)}</figcaption></figure>")


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
    from .contact.state import PairState
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
    preload, as ``(MIME type, image bytes)``: a 2D model as SVG written here
    (:func:`mesh_svg`, no matplotlib), a 3D model as PNG (matplotlib, nodes only)."""
    if res.model.dim == 2:
        return "image/svg+xml", mesh_svg(res).encode("utf-8")
    return "image/png", _mesh_png_3d(res)


def _mesh_png_3d(res) -> bytes:
    from .plots import _figure
    model, p = res.model, res.pairing
    fig = _figure(figsize=(7.5, 3.9), margins=MESH_MARGINS_IN)[0]
    fig.clf()
    ax = fig.add_subplot(projection="3d")
    for k, b in enumerate(model.bodies):
        pts = b.mesh.points
        ax.scatter(pts[:, 0], pts[:, 1], pts[:, 2], s=0.5,
                   color=BODY_COLOURS[k % len(BODY_COLOURS)], label=b.name)
    for _, label, colour, sel in _pair_states(res.preload.status):
        ax.scatter(*p.x[sel].T, s=8, color=colour, zorder=3,
                   label=f"interface pair, {label} after preload ({int(sel.sum())})")
    fig.suptitle(f"{model.name}: {model.n_nodes} nodes, {p.n_pairs} interface pairs",
                 fontsize=10)
    ax.legend(fontsize=7, loc="upper right", bbox_to_anchor=(0.995, 0.88),
              bbox_transform=fig.transFigure)       # in the right margin
    return _png(fig)


def nice_ticks(lo, hi, n=5) -> np.ndarray:
    """Tick values inside ``[lo, hi]`` at a step of 1, 2 or 5 times a power of ten,
    chosen so that about ``n`` ticks fall in the interval: the smallest such step
    ``s >= (hi - lo) / n``, ticks at the multiples of ``s``."""
    span = max(hi - lo, 1e-300)
    raw = span / n
    power = 10.0 ** np.floor(np.log10(raw))
    step = next(m * power for m in (1, 2, 5, 10) if m * power >= raw * (1 - 1e-9))
    first = np.ceil(lo / step - 1e-9) * step
    ticks = first + step * np.arange(int(np.floor((hi - first) / step + 1e-9)) + 1)
    return np.where(np.abs(ticks) < 1e-12 * span, 0.0, ticks)


def tick_labels(ticks) -> list[str]:
    """Labels of :func:`nice_ticks` with as many decimals as their step needs, so
    that neighbouring ticks never read the same (a mesh far from the origin: ticks
    123456.5 and 123457 m keep their half metre)."""
    ticks = np.asarray(ticks, float)
    if len(ticks) < 2:                   # no step to read: the value's own digits
        return [f"{t:g}" for t in ticks]
    decimals = max(0, int(-np.floor(np.log10(np.min(np.diff(ticks))) + 1e-9)))
    return [f"{t:.{decimals}f}" for t in ticks]


@dataclass(frozen=True)
class _Panel:
    """One panel of an SVG figure: the data window ``(x0, x1, y0, y1)`` shown at equal
    scale in the pixel box with top-left corner ``(left, top)``, ``scale`` pixels per
    data unit."""
    window: tuple
    left: float
    top: float
    scale: float

    @property
    def size(self):
        x0, x1, y0, y1 = self.window
        return (x1 - x0) * self.scale, (y1 - y0) * self.scale

    def pixels(self, xy):
        """Pixel coordinates of data points ``xy`` (..., 2): y grows downwards."""
        x0, _, _, y1 = self.window
        return np.stack([self.left + (xy[..., 0] - x0) * self.scale,
                         self.top + (y1 - xy[..., 1]) * self.scale], axis=-1)


def _fit_panel(window, left, top, width, max_height) -> _Panel:
    """The panel of ``window`` at equal scale, as wide as ``width`` pixels unless that
    makes it taller than ``max_height``."""
    x0, x1, y0, y1 = window
    scale = min(width / max(x1 - x0, 1e-300), max_height / max(y1 - y0, 1e-300))
    return _Panel(window, left, top, scale)


#: Cells of one body drawn in one panel of the SVG mesh figure, at most: a finer mesh
#: is drawn by its outline (cells of a pixel or less read as a solid area anyway, and
#: the page stays small: about 40 bytes per cell).
MAX_SVG_CELLS = 20000


#: Corner nodes of the 2D cell types (the first ones of quadratic cells, in order).
CORNERS_2D = {"triangle": 3, "triangle6": 3, "quad": 4, "quad8": 4, "quad9": 4}


def _body_corner_blocks(mesh) -> list:
    """Corner node indices of a 2D mesh, one array per cell block (mixed meshes hold
    triangles and quadrilaterals side by side)."""
    return [block.cells[:, :CORNERS_2D[block.cell_type]] for block in mesh.cell_blocks]


def _svg_cells(panel, points, blocks, colour, inside=False) -> str:
    """One ``<path>`` of the outlines of the cells of ``blocks`` (arrays of corner node
    indices into ``points``, one per cell type) in ``panel``; when ``inside``, only
    the cells whose bounding box meets the window (the rest would be clipped away
    whole). Beyond :data:`MAX_SVG_CELLS` cells, the edges that belong to one cell only
    (the outline of the body)."""
    kept = []
    for cells in blocks:
        if inside:
            polys = points[cells]
            x0, x1, y0, y1 = panel.window
            lo, hi = polys.min(axis=1), polys.max(axis=1)
            cells = cells[(hi[:, 0] >= x0) & (lo[:, 0] <= x1) & (hi[:, 1] >= y0)
                          & (lo[:, 1] <= y1)]
        kept.append(cells)
    if sum(len(c) for c in kept) > MAX_SVG_CELLS:
        edges = _outline_edges(kept)
        px = panel.pixels(points[edges]).reshape(len(edges), -1)
        d = "".join("M%.1f %.1fL%.1f %.1f" % tuple(row) for row in px.tolist())
        kind = "outline"
    else:
        d = ""
        for cells in kept:
            move = "M%.1f %.1f" + "L%.1f %.1f" * (cells.shape[1] - 1) + "Z"
            px = panel.pixels(points[cells]).reshape(len(cells), -1)
            d += "".join(move % tuple(row) for row in px.tolist())
        kind = "cells"
    return (f'<path d="{d}" fill="none" stroke="{colour}" stroke-width="0.5" '
            f'class="{kind}"/>')


def _outline_edges(blocks) -> np.ndarray:
    """The edges (node pairs) of the cells of ``blocks`` (arrays of corner nodes in
    cyclic order) that belong to one cell only: the boundary of the meshed region."""
    edges = np.concatenate([np.stack([c, np.roll(c, -1, axis=1)], axis=-1).reshape(-1, 2)
                            for c in blocks])
    _, first, count = np.unique(np.sort(edges, axis=1), axis=0, return_index=True,
                                return_counts=True)
    return edges[first[count == 1]]


def _svg_axes(panel, clip_id) -> str:
    """Frame, tick marks and tick labels of ``panel``, and its clip rectangle."""
    x0, x1, y0, y1 = panel.window
    w, h = panel.size
    left, top = panel.left, panel.top
    out = [f'<clipPath id="{clip_id}"><rect x="{left:.1f}" y="{top:.1f}" '
           f'width="{w:.1f}" height="{h:.1f}"/></clipPath>',
           f'<rect x="{left:.1f}" y="{top:.1f}" width="{w:.1f}" height="{h:.1f}" '
           f'fill="none" stroke="#000" stroke-width="0.8"/>']
    nx = max(2, min(8, int(w // 70)))
    xt = nice_ticks(x0, x1, nx)
    for t, label in zip(xt, tick_labels(xt)):
        x = panel.pixels(np.array([t, y0]))[0]
        out.append(f'<line x1="{x:.1f}" y1="{top + h:.1f}" x2="{x:.1f}" '
                   f'y2="{top + h + 4:.1f}" stroke="#000"/><text x="{x:.1f}" '
                   f'y="{top + h + 15:.1f}" text-anchor="middle">{label}</text>')
    yt = nice_ticks(y0, y1, max(2, min(5, int(h // 25))))
    for t, label in zip(yt, tick_labels(yt)):
        y = panel.pixels(np.array([x0, t]))[1]
        out.append(f'<line x1="{left - 4:.1f}" y1="{y:.1f}" x2="{left:.1f}" '
                   f'y2="{y:.1f}" stroke="#000"/><text x="{left - 6:.1f}" '
                   f'y="{y + 4:.1f}" text-anchor="end">{label}</text>')
    return "\n".join(out)


#: Size of the 2D mesh figure in pixels and its margins (left for the tick labels,
#: right for the legend, top for the title).
MESH_SVG = dict(width=950, left=60, right=270, top=30, whole_height=70,
                zoom_height=220, gap=45)


def mesh_svg(res) -> str:
    """The 2D mesh figure as an SVG document: the whole model (cell outlines of each
    body), below it the interface region with a margin of 15 % of its extent (cells
    clipped to it, interface pairs as dots coloured by their state after the preload),
    the legend on the right. Both panels at equal scale in x and y; coordinates as in
    the model. Written directly (no matplotlib): 2D cells are outlines, text and dots.
    A body of more than :data:`MAX_SVG_CELLS` cells in a panel is drawn by its
    outline there."""
    model, p = res.model, res.pairing
    g = MESH_SVG
    width = g["width"] - g["left"] - g["right"]
    points = np.vstack([b.mesh.points[:, :2] for b in model.bodies])
    lo, hi = points.min(axis=0), points.max(axis=0)
    whole = _fit_panel((lo[0], hi[0], lo[1], hi[1]), g["left"], g["top"] + 20, width,
                       g["whole_height"])
    xy = p.x[:, :2]
    plo, phi = xy.min(axis=0), xy.max(axis=0)
    pad = 0.15 * max(phi[0] - plo[0], phi[1] - plo[1], 1e-12)
    zoom = _fit_panel((plo[0] - pad, phi[0] + pad, plo[1] - pad, phi[1] + pad),
                      g["left"], whole.top + whole.size[1] + g["gap"], width,
                      g["zoom_height"])
    height = zoom.top + zoom.size[1] + 25
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{g["width"]}" '
             f'height="{height:.0f}" viewBox="0 0 {g["width"]} {height:.0f}" '
             f'font-family="DejaVu Sans, sans-serif" font-size="11">',
             f'<rect width="100%" height="100%" fill="#fff"/>',
             f'<text x="{g["width"] / 2:.0f}" y="18" text-anchor="middle" font-size="13">'
             f'{escape(model.name)}: {model.n_nodes} nodes, {p.n_pairs} interface pairs'
             f'</text>',
             f'<text x="{whole.left + whole.size[0] / 2:.1f}" y="{whole.top - 6:.1f}" '
             f'text-anchor="middle">whole model</text>']
    for k, (panel, clip) in enumerate(((whole, "whole"), (zoom, "zoom"))):
        parts.append(_svg_axes(panel, clip))
        parts.append(f'<g clip-path="url(#{clip})">')
        for i, b in enumerate(model.bodies):
            parts.append(_svg_cells(panel, b.mesh.points[:, :2], _body_corner_blocks(b.mesh),
                                    BODY_COLOURS[i % len(BODY_COLOURS)], inside=k == 1))
        if panel is zoom:
            parts.append(_svg_pairs(zoom, xy, res.preload.status))
        parts.append("</g>")
    parts.append(_svg_legend(model, res.preload.status, g["width"] - g["right"] + 20,
                             g["top"] + 20))
    parts.append("</svg>")
    return "\n".join(parts) + "\n"


def _svg_pairs(panel, xy, status) -> str:
    """The interface pairs as dots, coloured by their state (class ``pair-STATE``)."""
    px = panel.pixels(xy)
    out = []
    for _, label, colour, sel in _pair_states(status):
        out += [f'<circle cx="{x:.1f}" cy="{y:.1f}" r="2.5" fill="{colour}" '
                f'class="pair-{label}"/>' for x, y in px[sel].tolist()]
    return "\n".join(out)


def _svg_legend(model, status, left, top) -> str:
    """Swatches and names of the bodies and of the pair states (with their counts)."""
    rows = [(f'<rect x="{left}" y="{{y}}" width="14" height="8" fill="none" '
             f'stroke="{BODY_COLOURS[i % len(BODY_COLOURS)]}"/>', b.name)
            for i, b in enumerate(model.bodies)]
    for _, label, colour, sel in _pair_states(status):
        rows.append((f'<circle cx="{left + 7}" cy="{{c}}" r="3" fill="{colour}"/>',
                     f"interface pair, {label} after preload ({int(sel.sum())})"))
    out = [f'<rect x="{left - 6}" y="{top - 12}" width="{MESH_SVG["right"] - 24}" '
           f'height="{16 * len(rows) + 8}" fill="#fff" stroke="#ccc"/>']
    for j, (mark, text) in enumerate(rows):
        y = top + 16 * j
        out.append(mark.format(y=y - 7, c=y - 3) + f'<text x="{left + 20}" y="{y:.0f}" '
                   f'font-size="10">{escape(text)}</text>')
    return "\n".join(out)


def _run_figures(res, figures) -> list:
    """(caption, image bytes, MIME type) of the run's figures: those given (name -> PNG path, e.g.
    written beside results.json), else drawn into a temporary folder."""
    captions = {"backbone": "Backbone: modal force versus modal amplitude",
                "damping": "Secant frequency and damping ratio versus amplitude",
                "loops": "Hysteresis loops (tied linear force subtracted)",
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
                          for k, v in write_plots(res, tmp).items()]
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


def run_report_html(res, figures=None) -> str:
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
        **{f"elements of {b}": e for b, e in info["elements"].items()}}))
    parts.append("<h2>Mode</h2>" + _pairs({
        "mode index": res.mode_index, "f0 [Hz]": f"{res.f0_hz:.4f}",
        "omega0 [rad/s]": f"{res.omega0:.4f}", "phi at the tip": f"{res.phi_tip:.6g}",
        "tied frequencies [Hz]": ", ".join(f"{f:.2f}" for f in res.modes.f_hz)}))
    parts.append("<h2>Figures</h2>" + "\n".join(
        _figure_html(image, cap, mime) for cap, image, mime in _run_figures(res, figures)))
    rows = [[k] + [_level_cell(getattr(res, name)[k], fmt) for name, _, fmt in LEVEL_TABLE]
            + [", ".join(res.flags[k])] for k in range(res.n_levels)]
    unit = level_units(res.units, res.model.dim)
    parts.append("<h2>Levels</h2>" + _table(
        ["level"] + [column_label(h, unit[name]) for name, h, _ in LEVEL_TABLE]
        + ["flags"], rows, text_columns=(6, len(LEVEL_TABLE) + 1)))
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
    from .rundir import atomic_write
    atomic_write(path, study_report_html(parameters, cases, table, figures))
    return Path(path)


__all__ = ["write_report", "run_report_html", "write_study_report", "study_report_html",
           "mesh_figure", "mesh_svg", "nice_ticks", "tick_labels", "run_warnings", "REPORT_NAME"]
