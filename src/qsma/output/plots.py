"""Figures of a QSMA run (matplotlib, Agg backend; imported only when plotting)."""
from __future__ import annotations

from dataclasses import dataclass, replace
import io
from pathlib import Path

import numpy as np

from ..hysteresis import masing_loop
from .folders import atomic_write
from ..units import SI, display_stress, quantity_unit


#: Figure margins in inches (left, right, bottom, top): room for the tick labels, the
#: axis labels and the title. Fixed margins draw a figure once, where
#: ``bbox_inches="tight"`` or a layout engine draw it twice (a third of the plotting time).
MARGINS_IN = (0.95, 0.25, 0.65, 0.4)


def agg_figure(nrows=1, ncols=1, figsize=(6, 4.5), hspace=0.2, wspace=0.2,
               margins=MARGINS_IN, **kw):
    """A figure on the Agg canvas, independent of pyplot and of the user's backend, with
    the ``margins`` in inches (left, right, bottom, top; default :data:`MARGINS_IN`)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    fig = Figure(figsize=figsize)
    FigureCanvasAgg(fig)
    width, height = figsize
    left, right, bottom, top = margins
    fig.subplots_adjust(left=left / width, right=1 - right / width, bottom=bottom / height,
                        top=1 - top / height, hspace=hspace, wspace=wspace)
    return fig, fig.subplots(nrows, ncols, **kw)


#: zlib level of the PNG files: 1 writes them 15-20 % larger than the default 6 in a
#: fifth less time (benchmarks/bench_process.py, CHANGELOG.md "The small case").
PNG_COMPRESSION = 1


#: Resolution of the run's figures [dots per inch].
DPI = 120


def png_bytes(fig) -> bytes:
    """The PNG file of ``fig`` (:data:`DPI`, :data:`PNG_COMPRESSION`) as bytes: the same
    bytes whichever process draws it (:mod:`qsma.output.plotworker`)."""
    buf = io.BytesIO()
    fig.savefig(buf, dpi=DPI, format="png", pil_kwargs={"compress_level": PNG_COMPRESSION})
    return buf.getvalue()


def _unit(res, quantity) -> str:
    """The unit of ``quantity`` in the result's unit system, for an axis label."""
    return quantity_unit(quantity, getattr(res, "units", None) or SI, res.model.dim,
                         pretty=True)


def _stress(res) -> tuple:
    """``(label, factor)`` of the contact pressures drawn (MPa whatever the system)."""
    return display_stress(getattr(res, "units", None) or SI)


def save_png(fig, path):
    """Write ``fig`` as a PNG file at ``path``, atomically; the path."""
    atomic_write(path, png_bytes(fig), "wb")
    return Path(path)


_SUPERSCRIPT = str.maketrans("0123456789-", "\u2070\u00b9\u00b2\u00b3\u2074\u2075\u2076"
                             "\u2077\u2078\u2079\u207b")


def power_label(x, pos=None) -> str:
    """Tick label of a logarithmic axis in plain Unicode: ``10`` with a superscript
    exponent at powers of ten (``1e-05`` -> 10⁻⁵, with a real minus sign for negative
    values), three significant digits elsewhere. It reads like matplotlib's default
    ``10^{k}`` labels without the mathtext parser, which took most of the drawing time."""
    if x == 0:
        return "0"
    k = np.log10(abs(x))
    if abs(k - round(k)) > 1e-9:
        return f"{x:.3g}".replace("-", "\u2212")
    sign = "\u2212" if x < 0 else ""
    return f"{sign}10{str(int(round(k))).translate(_SUPERSCRIPT)}"


#: Minor ticks (and grid lines) of a logarithmic axis at 2 and 5 times each power of
#: ten: the 1-2-5 grid of engineering charts. Matplotlib's default of eight per decade
#: builds four times as many tick artists, the largest part of drawing a log axis.
LOG_MINOR_SUBS = (2.0, 5.0)


#: Number of intervals between the major ticks of a linear axis (at most; steps of 1,
#: 2, 2.5 or 5 times a power of ten). Matplotlib's automatic choice puts up to nine
#: ticks on these axes; five read as well and build a fifth less of the figure's
#: artists (each tick is two marks, a grid line and two labels; CHANGELOG.md).
LINEAR_BINS = 5


def _set_ticks(*axes):
    """Tick locators and labels of ``axes``: major tick labels of the log/symlog axes
    by :func:`power_label`, minor ticks at :data:`LOG_MINOR_SUBS` on the log axes, at
    most :data:`LINEAR_BINS` intervals on the linear axes that matplotlib ticks
    automatically (fixed ticks, e.g. the contact state axis, are kept)."""
    from matplotlib.ticker import AutoLocator, FuncFormatter, LogLocator, MaxNLocator
    for ax in axes:
        for axis in (ax.xaxis, ax.yaxis):
            if axis.get_scale() in ("log", "symlog"):
                axis.set_major_formatter(FuncFormatter(power_label))
            if axis.get_scale() == "log":
                axis.set_minor_locator(LogLocator(subs=LOG_MINOR_SUBS))
            elif (axis.get_scale() == "linear"
                  and type(axis.get_major_locator()) is AutoLocator):
                axis.set_major_locator(MaxNLocator(nbins=LINEAR_BINS,
                                                   steps=[1, 2, 2.5, 5, 10]))


def draw_backbone(res):
    """The modal backbone: modal force alpha versus modal amplitude q (log-log), with
    the tied linear line ``alpha = omega0^2 q`` that it leaves where the joint slips.

    Parameters
    ----------
    res : :class:`qsma.analysis.result.QSMAResult` or its :class:`PlotData`

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = agg_figure(figsize=(6, 4.5))
    ax.loglog(res.q, res.alpha, "o-", ms=3, label="QSMA backbone")
    ax.loglog(res.q, res.q * res.omega0 ** 2, "--", lw=1, label="linear (tied)")
    ax.set_xlabel(f"modal amplitude q [{_unit(res, 'modal_amplitude')}]")
    ax.set_ylabel(f"modal force \u03b1 [{_unit(res, 'modal_force')}]")
    _set_ticks(ax)
    ax.set_title(f"Backbone, mode {res.mode_index} (f0 = {res.f0_hz:.2f} Hz)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    return fig


#: Most loops drawn in loops.png (one panel each).
MAX_LOOP_PANELS = 6


def loop_levels(res, n=MAX_LOOP_PANELS) -> list:
    """The levels whose loops loops.png draws: up to ``n`` of those that dissipate
    (every computed loop first, then Masing levels), spread over the amplitudes and
    always with the largest level; the largest level alone where none dissipates."""
    last = res.n_levels - 1
    if last < 0:
        return []
    dissipating = [k for k in range(res.n_levels)
                   if np.isfinite(res.zeta_masing[k]) and res.zeta_masing[k] > 0
                   or res.loops.get(k) is not None]
    if not dissipating:
        return [last]
    if len(dissipating) > n:
        pick = np.unique(np.round(np.linspace(0, len(dissipating) - 1, n)).astype(int))
        dissipating = [dissipating[i] for i in pick]
    return sorted(set(dissipating) | {last})[-n:]


def loop_curve(res, k):
    """``(q, alpha, label)`` of the loop drawn at level ``k``: the computed stabilised
    loop where it exists, the two backbones at the user's levels where the level is
    elastic (its cycle runs down the -alpha backbone and back up the +alpha one), else
    Masing's construction from the backbone."""
    lp = res.loops.get(k)
    if lp is not None and lp.success:
        return lp.q, lp.alpha, "computed loop"
    if res.dissipation_method[k] == "elastic":
        q = np.concatenate([res.q[k::-1], [0.0], res.q_neg[:k + 1]])
        f = np.concatenate([res.alpha[k::-1], [0.0], -res.alpha[:k + 1]])
        return (np.concatenate([q, q[-2::-1]]), np.concatenate([f, f[-2::-1]]),
                "elastic cycle (the backbones)")
    q, f = masing_loop(res.alpha, res.q, k)
    return q, f, "Masing" + (" (its computed loop failed)" if lp is not None else "")


def draw_loops(res):
    """Hysteresis loops at up to :data:`MAX_LOOP_PANELS` levels (:func:`loop_levels`),
    one panel each so that the small loops are as visible as the large ones. Each loop
    is drawn normalised by its own amplitude: ``q / q_a`` against the deviation from
    the tied line ``(alpha - omega0^2 q) / (omega0^2 q_a)`` (both dimensionless), the
    computed stabilised loop where it exists and Masing's construction elsewhere, with
    the level's amplitude (:func:`amplitude_of`) and damping ratio in its title; the
    direct loop, if computed, in the panel of the largest level."""
    levels = loop_levels(res)
    ncols = min(3, len(levels))
    nrows = -(-len(levels) // ncols)
    fig, axes = agg_figure(nrows, ncols, figsize=(3.4 * ncols + 0.6, 3.3 * nrows + 0.5),
                           hspace=0.75, wspace=0.5, squeeze=False,
                           margins=(0.85, 0.2, 0.6, 1.0))
    k0 = res.omega0 ** 2
    kind, name, measure = amplitude_of(res)
    for ax, k in zip(axes.ravel(), levels):
        q, f, label = loop_curve(res, k)
        qa = abs(res.q[k])
        ax.plot(q / qa, (f - k0 * q) / (k0 * qa), lw=1.2, label=f"{label}, level {k}")
        if res.direct_loop is not None and k == res.n_levels - 1:
            dl = res.direct_loop
            dlabel = (f"direct loop (D = {dl.dissipation:.3g} vs Masing "
                      f"{dl.dissipation_masing:.3g})" if dl.success
                      else "direct loop (not closed: a contact solve failed)")
            ax.plot(dl.q / qa, (dl.alpha - k0 * dl.q) / (k0 * qa), "k.", ms=2,
                    label=dlabel)
        zeta = res.zeta[k]
        ax.set_title(f"level {k}: {kind} {measure[k]:.3g} {_unit(res, name)}\n"
                     f"\u03b6 = {zeta:.3g}, {label}", fontsize=8)
        ax.set_xlabel("q / q\u2090 [-]")
        ax.set_ylabel("(\u03b1 \u2212 \u03c9\u2080\u00b2q) / \u03c9\u2080\u00b2q\u2090 [-]")
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
        _set_ticks(ax)
        ax.grid(True, alpha=0.3)
        if res.direct_loop is not None and k == res.n_levels - 1:
            ax.legend(fontsize=6)
    for ax in axes.ravel()[len(levels):]:
        ax.set_visible(False)
    fig.suptitle("Hysteresis loops, each normalised by its amplitude (tied line "
                 "subtracted)", fontsize=10)
    return fig


#: Damping ratios below this are drawn on the linear part of the symmetric-log axis, so
#: zero, round-off and negative values stay visible (none is dropped from the figure).
ZETA_LINEAR = 1e-6

#: The amplitude measures the figures may draw against: key -> (result field, axis
#: text, quantity of :mod:`qsma.units`). The run's and the study's figures use the same
#: one (``amplitude``, default :data:`DEFAULT_AMPLITUDE`).
AMPLITUDES = {"tip": ("tip", "peak tip deflection", "length"),
              "velocity": ("tip_velocity", "peak tip velocity", "velocity"),
              "q": ("q", "peak modal amplitude q", "modal_amplitude")}
DEFAULT_AMPLITUDE = "tip"


def check_amplitude(amplitude) -> str:
    """``amplitude`` if it is a key of :data:`AMPLITUDES`, else :class:`InputError`."""
    from ..errors import InputError
    if amplitude not in AMPLITUDES:
        raise InputError(f"unknown amplitude measure {amplitude!r} for the figures; "
                         f"valid: {sorted(AMPLITUDES)} (tip: peak tip deflection, "
                         f"velocity: peak tip velocity, q: peak modal amplitude)")
    return amplitude


def amplitude_of(res):
    """``(axis text, quantity, values)`` of the amplitude measure the figures of
    ``res`` draw against (its ``amplitude``, default :data:`DEFAULT_AMPLITUDE`)."""
    field, text, quantity = AMPLITUDES[getattr(res, "amplitude", None) or DEFAULT_AMPLITUDE]
    return text, quantity, np.abs(np.asarray(getattr(res, field), float))


def draw_damping_frequency(res):
    """Secant frequency and damping ratio versus the amplitude (:func:`amplitude_of`,
    the peak tip deflection by default): the values used (filled), Masing's and the
    loops' where they differ, hardening levels marked.

    A level whose loop failed has no used frequency; drawn against the velocity it has
    no abscissa either, so its Masing values are drawn at Masing's own velocity
    ``2 pi f_masing |tip|`` and marked: no level leaves the figure unseen."""
    fig, (a1, a2) = agg_figure(2, 1, figsize=(6, 6.5), hspace=0.08, sharex=True)
    text, quantity, v = amplitude_of(res)
    loop = res.dissipation_method == "loop"
    hard = np.array(["hardening" in f or "masing_on_hardening" in f for f in res.flags])
    unused = loop & ~np.isfinite(res.f_hz)
    v_masing = v
    if quantity == "velocity":
        v_masing = np.where(unused, 2 * np.pi * res.f_hz_masing * np.abs(res.tip), v)
    a1.semilogx(v, res.f_hz, "o-", ms=3, label="used")
    a2.plot(v, res.zeta, "o-", ms=3, label="used")
    if loop.any():
        a1.semilogx(v_masing, res.f_hz_masing, "x--", ms=3, lw=0.8, label="Masing")
        a2.plot(v_masing, res.zeta_masing, "x--", ms=3, lw=0.8, label="Masing")
        done = loop & np.isfinite(res.zeta_loop)
        if done.any():
            a2.plot(v[done], res.zeta_loop[done], "s", ms=4, mfc="none",
                    label="computed loop")
    if unused.any():
        label = "loop failed: Masing shown, not used"
        a1.plot(v_masing[unused], res.f_hz_masing[unused], "X", color="tab:gray", ms=6,
                label=label)
        a2.plot(v_masing[unused], res.zeta_masing[unused], "X", color="tab:gray", ms=6,
                label=label)
    if hard.any():
        a1.plot(v[hard], res.f_hz[hard], "^", color="tab:red", ms=6, label="hardening")
        a2.plot(v[hard], res.zeta[hard], "^", color="tab:red", ms=6, label="hardening")
    span = [np.nanmin(v_masing), np.nanmax(v_masing)]     # (lines in data coordinates)
    a1.plot(span, [res.f0_hz] * 2, color="gray", lw=0.8, ls=":", label="f0 (tied)")
    a1.set_ylabel("secant frequency [Hz]")
    a2.set_yscale("symlog", linthresh=ZETA_LINEAR)
    a2.plot(span, [0.0, 0.0], color="gray", lw=0.8)
    shown = np.concatenate([res.zeta, res.zeta_masing if loop.any() else []])
    lowest = np.nanmin(shown) if np.isfinite(shown).any() else 0.0
    a2.set_ylim(bottom=min(-ZETA_LINEAR, 3 * lowest))
    a2.set_ylabel("damping ratio \u03b6 [-]")
    _set_ticks(a1, a2)
    a2.set_xlabel(f"{text} [{_unit(res, quantity)}]")
    for a in (a1, a2):
        a.grid(True, which="both", alpha=0.3)
        a.legend(fontsize=7)
    a1.set_title("Amplitude-dependent frequency and damping")
    return fig


def draw_interface(res, levels=None):
    """2D: contact pressure and shear along the interface (preload and chosen levels)
    and the pair states, pressures as ``lam / area`` in MPa.

    Parameters
    ----------
    res : :class:`qsma.analysis.result.QSMAResult` of a 2D model or its :class:`PlotData`
    levels : level indices; default the first, middle, three-quarter and last level

    Returns
    -------
    matplotlib.figure.Figure
    """
    n = res.n_levels
    levels = sorted({0, n // 2, (3 * n) // 4, n - 1}) if levels is None else levels
    p = res.pairing
    x = p.x[:, 0]
    fig, axes = agg_figure(3, 1, figsize=(7, 8), hspace=0.1, sharex=True)
    pre = res.preload.lam
    stress, factor = _stress(res)
    length = _unit(res, "length")
    axes[0].plot(x, pre[:, -1] / p.area * factor, "k--", lw=1, label="preload")
    for k in levels:
        lam = res.states.lam[k]
        lbl = f"level {k} (tip {res.tip[k]:.2e} {length})"
        axes[0].plot(x, lam[:, -1] / p.area * factor, lw=1.2, label=lbl)
        axes[1].plot(x, np.linalg.norm(lam[:, :-1], axis=1) * np.sign(lam[:, 0]) / p.area
                     * factor, lw=1.2, label=lbl)
        axes[2].plot(x, res.states.status[k] + 0.05 * levels.index(k), ".", ms=5, label=lbl)
    axes[0].set_ylabel(f"contact pressure [{stress}]")
    axes[1].set_ylabel(f"shear [{stress}]")
    axes[2].set_yticks([0, 1, 2], ["stuck", "slip", "open"])
    axes[2].set_ylabel("contact state [-]")
    axes[2].set_xlabel(f"x along the interface [{length}]")
    _set_ticks(*axes)
    for a in axes:
        a.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    axes[0].set_title("Interface tractions and states")
    return fig


def draw_interface_map(res, levels=None):
    """3D: maps over the interface plane (first two in-plane coordinates of the pair
    frames, x and z for sandwich-3d) of pressure, shear magnitude and state, one column
    per level. Each row has one colour scale over every level drawn (the largest
    pressure and shear of those levels; one colour bar per row), so that the colours
    of two levels compare."""
    from matplotlib.colors import ListedColormap, Normalize
    n = res.n_levels
    levels = sorted({n // 2, (3 * n) // 4, n - 1}) if levels is None else levels
    p = res.pairing
    t1, t2 = p.frames[0, 0], p.frames[0, 1]
    u, v = p.x @ t1, p.x @ t2
    fig, axes = agg_figure(3, len(levels), figsize=(3.6 * len(levels) + 1.4, 7.0),
                           hspace=0.3, wspace=0.15, squeeze=False, sharex=True, sharey=True,
                           margins=(0.85, 1.45, 0.65, 0.45))
    states = ListedColormap(["tab:blue", "tab:orange", "lightgray"])
    stress, factor = _stress(res)
    length = _unit(res, "length")
    pressure = {k: res.states.lam[k][:, -1] / p.area * factor for k in levels}
    shear = {k: np.linalg.norm(res.states.lam[k][:, :-1], axis=1) / p.area * factor
             for k in levels}
    top = lambda vals: max(max(float(np.max(x)) for x in vals.values()), 1e-300)
    rows = ((pressure, "viridis", f"contact pressure [{stress}]",
             Normalize(0.0, top(pressure))),
            (shear, "magma", f"shear [{stress}]", Normalize(0.0, top(shear))),
            ({k: res.states.status[k] for k in levels}, states, "state [-]",
             Normalize(-0.5, 2.5)))
    for i, (values, cmap, label, norm) in enumerate(rows):
        for j, k in enumerate(levels):
            ax = axes[i, j]
            sc = ax.scatter(u, v, c=values[k], cmap=cmap, norm=norm, s=12, marker="s")
            ax.set_aspect("equal")
            if i == 0:
                ax.set_title(f"level {k}, tip {res.tip[k]:.2e} {length}", fontsize=9)
            ax.set_xlabel(f"t1 coordinate [{length}]")
            ax.set_ylabel(f"t2 coordinate [{length}]")
            ax.label_outer()            # coordinates once per row and column
        bar = fig.colorbar(sc, ax=list(axes[i]), shrink=0.9, pad=0.02, label=label)
        if i == 2:
            bar.set_ticks([0, 1, 2], labels=["stuck", "slip", "open"])
    fig.suptitle("Interface maps (one colour scale per row)", fontsize=10)
    return fig


def plot_backbone(res, path):
    """:func:`draw_backbone` written to the PNG file ``path`` (atomically); returns it."""
    return save_png(draw_backbone(res), path)


def plot_loops(res, path):
    """:func:`draw_loops` written to the PNG file ``path`` (atomically); returns it."""
    return save_png(draw_loops(res), path)


def plot_damping_frequency(res, path):
    """:func:`draw_damping_frequency` written to the PNG file ``path`` (atomically)."""
    return save_png(draw_damping_frequency(res), path)


def plot_interface(res, path, levels=None):
    """:func:`draw_interface` written to the PNG file ``path`` (atomically)."""
    return save_png(draw_interface(res, levels), path)


def plot_interface_map(res, path, levels=None):
    """:func:`draw_interface_map` written to the PNG file ``path`` (atomically)."""
    return save_png(draw_interface_map(res, levels), path)


# -- What the figures read of a result ---------------------------------------------------

@dataclass(frozen=True)
class LoopCurve:
    """A computed loop as the figures draw it: the path ``(q, alpha)`` (``None`` for a
    loop that failed) and whether the loop closed (:class:`qsma.hysteresis.Loop`
    without the solver's details)."""

    q: np.ndarray | None
    alpha: np.ndarray | None
    success: bool


@dataclass(frozen=True)
class DirectCurve:
    """The directly computed loop (:class:`qsma.analysis.result.DirectLoop`) as drawn."""

    q: np.ndarray
    alpha: np.ndarray
    dissipation: float | None
    dissipation_masing: float
    success: bool


@dataclass(frozen=True)
class PairsView:
    """The interface pairs as drawn: positions ``x`` ``(n, dim)``, tributary areas
    ``area`` ``(n,)`` and the pair frames ``frames`` ``(n, dim, dim)``."""

    x: np.ndarray
    area: np.ndarray
    frames: np.ndarray


@dataclass(frozen=True)
class ContactView:
    """Contact forces ``lam`` (per level or of one solve) and pair states ``status``."""

    lam: np.ndarray
    status: np.ndarray


@dataclass(frozen=True)
class ModelView:
    """The model as the figures need it: its dimension."""

    dim: int


@dataclass(frozen=True)
class PlotData:
    """Everything the figures read of a :class:`qsma.analysis.result.QSMAResult`, under the same
    attribute names, and nothing else: small, picklable without the model, the
    condensed matrices or the solver objects, so that another process can draw the
    figures (:mod:`qsma.output.plotworker`). :func:`write_plots` draws from it in-process
    too, so both paths draw the same data."""

    mode_index: int
    f0_hz: float
    omega0: float
    alpha: np.ndarray
    q: np.ndarray
    q_neg: np.ndarray          # the -alpha backbone: an elastic level's cycle runs on it
    tip: np.ndarray
    tip_velocity: np.ndarray
    f_hz: np.ndarray
    zeta: np.ndarray
    f_hz_masing: np.ndarray
    zeta_masing: np.ndarray
    zeta_loop: np.ndarray
    dissipation_method: np.ndarray
    flags: tuple
    loops: dict
    direct_loop: DirectCurve | None
    pairing: PairsView
    preload: ContactView
    states: ContactView
    model: ModelView
    units: object = None        # qsma.units.UnitSystem of the model
    amplitude: str = DEFAULT_AMPLITUDE     # a key of AMPLITUDES

    @property
    def n_levels(self) -> int:
        return len(self.alpha)


def _loop_curve(loop) -> LoopCurve:
    """A computed loop as drawn: its path if it closed (a failed loop is named in the
    figure, not drawn)."""
    if loop.success:
        return LoopCurve(loop.q, loop.alpha, True)
    return LoopCurve(None, None, False)


def plot_data(res, amplitude=None) -> PlotData:
    """The :class:`PlotData` of ``res``, drawn against ``amplitude`` (a key of
    :data:`AMPLITUDES`; ``None``: :data:`DEFAULT_AMPLITUDE`, or a :class:`PlotData`'s
    own, which is returned as it is otherwise)."""
    if isinstance(res, PlotData):
        return res if amplitude is None else replace(res, amplitude=check_amplitude(
            amplitude))
    amplitude = check_amplitude(amplitude or DEFAULT_AMPLITUDE)
    dl = res.direct_loop
    p = res.pairing
    return PlotData(
        mode_index=res.mode_index, f0_hz=res.f0_hz, omega0=res.omega0, alpha=res.alpha,
        q=res.q, q_neg=res.q_neg, tip=res.tip, tip_velocity=res.tip_velocity,
        f_hz=res.f_hz,
        zeta=res.zeta, f_hz_masing=res.f_hz_masing, zeta_masing=res.zeta_masing,
        zeta_loop=res.zeta_loop, dissipation_method=res.dissipation_method,
        flags=tuple(res.flags),
        loops={k: _loop_curve(lp) for k, lp in res.loops.items()},
        direct_loop=None if dl is None else DirectCurve(
            dl.q, dl.alpha, dl.dissipation, dl.dissipation_masing, dl.success),
        pairing=PairsView(p.x, p.area, p.frames),
        preload=ContactView(res.preload.lam, res.preload.status),
        states=ContactView(res.states.lam, res.states.status),
        model=ModelView(res.model.dim), units=res.units, amplitude=amplitude)


# -- Every figure of a run -----------------------------------------------------------------

def figure_files(dim) -> dict:
    """The figures of a run of a ``dim``-dimensional model: name -> (file name,
    drawing function ``f(res) -> Figure``), in the order they are drawn."""
    interface = (("interface.png", draw_interface) if dim == 2
                 else ("interface_map.png", draw_interface_map))
    return {"backbone": ("backbone.png", draw_backbone),
            "loops": ("loops.png", draw_loops),
            "damping": ("damping_frequency.png", draw_damping_frequency),
            "interface": interface}


def write_plots(res, out, amplitude=None) -> dict:
    """Every figure of a run into folder ``out``: backbone.png, loops.png,
    damping_frequency.png and interface.png (2D) or interface_map.png (3D), drawn from
    :func:`plot_data` of ``res``.

    Returns
    -------
    dict
        figure name -> path written.
    """
    data = plot_data(res, amplitude)
    out = Path(out)
    return {name: save_png(draw(data), out / file)
            for name, (file, draw) in figure_files(data.model.dim).items()}


def figure_pngs(res, names=None, amplitude=None) -> dict:
    """The PNG bytes of the figures ``names`` (default all, :func:`figure_files`) of
    ``res`` (a result or its :class:`PlotData`), nothing written: name -> bytes, the
    same bytes :func:`write_plots` writes."""
    data = plot_data(res, amplitude)
    figures = figure_files(data.model.dim)
    names = list(figures) if names is None else names
    return {name: png_bytes(figures[name][1](data)) for name in names}
