"""Figures a person can read: no overlapping tick labels, a unit on every axis, every
plotted curve inside its axes, on the 2D and 3D examples.

The figures are captured as they are saved (``qsma.plots._save``) and inspected
through matplotlib's own text extents after a draw, so the test measures what the PNG
shows.
"""
import re

import numpy as np
import pytest

import qsma
import qsma.plots as plots
from qsma.examples import lap_2d, lap_3d, sandwich_2d
from qsma.levels import Levels, spec_levels

#: An axis label names its unit in brackets, e.g. "modal amplitude q [kg$^{1/2}$ m]";
#: a dimensionless quantity says "[-]".
UNIT = re.compile(r"\[[^\]]+\]")


def _capture(res, tmp_path, monkeypatch):
    figures = {}
    save = plots._save

    def keep(fig, path):
        figures[str(path).rsplit("/", 1)[-1]] = fig
        return save(fig, path)

    monkeypatch.setattr(plots, "_save", keep)
    plots.write_plots(res, tmp_path)
    return figures


def _overlaps(boxes):
    """Pairs of boxes (matplotlib Bbox) that overlap by more than a pixel."""
    bad = []
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            a, b = boxes[i], boxes[j]
            w = min(a.x1, b.x1) - max(a.x0, b.x0)
            h = min(a.y1, b.y1) - max(a.y0, b.y0)
            if w > 1 and h > 1:
                bad.append((i, j))
    return bad


def _drawn_ticklabels(axis):
    """The tick labels matplotlib draws: visible, non-empty, inside the view interval
    (the locator also returns ticks beyond the limits, which are not drawn)."""
    lo, hi = sorted(axis.get_view_interval())
    slack = 1e-9 * abs(hi - lo)
    return [t for t in axis.get_ticklabels() if t.get_visible() and t.get_text()
            and lo - slack <= (t.get_position()[0] if axis.axis_name == "x"
                               else t.get_position()[1]) <= hi + slack]


def _tick_boxes(axis, renderer):
    return [t.get_window_extent(renderer) for t in _drawn_ticklabels(axis)]


def _check_figure(name, fig):
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    problems = []
    for ax in fig.axes:
        if not ax.get_visible() or ax.get_label() == "<colorbar>":
            continue
        for which, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            bad = _overlaps(_tick_boxes(axis, renderer))
            if bad:
                texts = [t.get_text() for t in axis.get_ticklabels()]
                problems.append(f"{name}: overlapping {which} tick labels {texts}")
        for which, axis, label in (("x", ax.xaxis, ax.get_xlabel()),
                                   ("y", ax.yaxis, ax.get_ylabel())):
            shows_ticks = any(t.get_visible() and t.get_text()
                              for t in axis.get_ticklabels())
            if shows_ticks and not UNIT.search(label):   # (shared axes show them once)
                problems.append(f"{name}: {which} axis label {label!r} has no [unit]")
        page = fig.bbox
        texts = [ax.xaxis.label, ax.yaxis.label, ax.title] + \
            _drawn_ticklabels(ax.xaxis) + _drawn_ticklabels(ax.yaxis)
        for t in texts:
            if not t.get_text():
                continue
            box = t.get_window_extent(renderer)
            if (box.x0 < page.x0 - 1 or box.x1 > page.x1 + 1 or box.y0 < page.y0 - 1
                    or box.y1 > page.y1 + 1):
                problems.append(f"{name}: text {t.get_text()!r} is cut by the page edge")
        x0, x1 = sorted(ax.get_xlim())
        y0, y1 = sorted(ax.get_ylim())
        for line in ax.get_lines():
            x, y = (np.asarray(v, float) for v in line.get_data())
            ok = np.isfinite(x) & np.isfinite(y)
            if line.get_label().startswith("_") and not ok.any():
                continue
            inside = ok & (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)
            if not inside.any():
                problems.append(f"{name}: curve {line.get_label()!r} is outside its axes")
    return problems


@pytest.fixture(scope="module")
def results():
    # every sixth of the default levels: the same range as the figures users see
    full = spec_levels()
    levels = Levels(full.kind, full.values[::6])
    return {"sandwich-2d": qsma.run(sandwich_2d(), levels=levels),
            "lap-2d": qsma.run(lap_2d(), levels=levels),
            "lap-3d": qsma.run(lap_3d(), levels=levels)}


@pytest.mark.parametrize("case", ["sandwich-2d", "lap-2d", "lap-3d"])
def test_figures_are_readable(results, case, tmp_path, monkeypatch):
    res = results[case]
    assert res.n_levels > 3
    figures = _capture(res, tmp_path, monkeypatch)
    assert figures, "no figure was written"
    problems = [p for name, fig in figures.items() for p in _check_figure(name, fig)]
    assert not problems, "\n".join(problems)


def test_checker_sees_crowded_ticks_and_missing_units():
    """The checks above can fail: a crowded axis without units is caught."""
    fig, ax = plots._figure(figsize=(2, 2))
    ax.plot([0, 1], [0, 1])
    ax.set_xticks(np.linspace(0, 1, 40), [f"{x:.6f}" for x in np.linspace(0, 1, 40)])
    ax.set_xlabel("no unit here")
    ax.set_ylabel("y [m]")
    problems = _check_figure("crowded", fig)
    assert any("overlapping x tick labels" in p for p in problems)
    assert any("has no [unit]" in p for p in problems)


def test_log_axes_have_a_1_2_5_minor_grid(results, tmp_path, monkeypatch):
    """Minor ticks of the logarithmic axes only at 2 and 5 times a power of ten (what
    keeps the figures cheap to draw, docs/performance.md), and some of them drawn."""
    figures = _capture(results["sandwich-2d"], tmp_path, monkeypatch)
    seen = 0
    for fig in figures.values():
        fig.canvas.draw()
        for ax in fig.axes:
            for axis in (ax.xaxis, ax.yaxis):
                if axis.get_scale() != "log":
                    continue
                lo, hi = sorted(axis.get_view_interval())
                ticks = [t for t in axis.get_minorticklocs() if lo <= t <= hi]
                mantissa = np.round(np.asarray(ticks) / 10.0 ** np.floor(np.log10(ticks)), 9)
                assert set(mantissa) <= {2.0, 5.0}, (fig, mantissa)
                seen += len(ticks)
    assert seen >= 4


def test_figures_hold_the_plotted_data(results, tmp_path, monkeypatch):
    """Each figure draws the result's own numbers (not a resampled or truncated copy):
    the backbone (q, alpha) and the tied line, the loops at the three levels, the
    secant frequency and damping against the peak tip velocity, the preload pressure
    along the interface."""
    from qsma.masing import masing_loop
    res = results["sandwich-2d"]
    figures = _capture(res, tmp_path, monkeypatch)

    def data(line):
        return tuple(np.asarray(v, float) for v in line.get_data())

    backbone = figures["backbone.png"].axes[0].get_lines()
    np.testing.assert_array_equal(data(backbone[0]), (res.q, res.alpha))
    np.testing.assert_allclose(data(backbone[1])[1], res.q * res.omega0 ** 2)
    n, k0 = res.n_levels, res.omega0 ** 2
    loops = figures["loops.png"].axes[0].get_lines()
    for line, k in zip(loops, sorted({n // 2, (3 * n) // 4, n - 1})):
        assert line.get_label().endswith(f"level {k}")
        lp = res.loops.get(k)
        if lp is not None and lp.success:
            q, f = lp.q, lp.alpha
        else:
            q, f = masing_loop(res.alpha, res.q, k)
        np.testing.assert_allclose(data(line)[1], f - k0 * q)
    top, bottom = figures["damping_frequency.png"].axes
    v = np.abs(res.tip_velocity)
    np.testing.assert_array_equal(data(top.get_lines()[0]), (v, res.f_hz))
    np.testing.assert_array_equal(data(bottom.get_lines()[0]), (v, res.zeta))
    pressure = figures["interface.png"].axes[0].get_lines()[0]
    p = res.pairing
    np.testing.assert_allclose(data(pressure), (p.x[:, 0], res.preload.lam[:, -1] / p.area
                                                / 1e6))


def test_a_level_whose_loop_failed_stays_in_the_figures(results, tmp_path, monkeypatch):
    """A level without a used frequency (its loop failed: f, zeta and the velocity are
    NaN) is drawn with its Masing values at Masing's velocity and marked, not dropped;
    loops.png says why a level shows Masing's construction."""
    from dataclasses import replace
    from types import SimpleNamespace
    res = results["sandwich-2d"]
    n = res.n_levels
    k = n - 1                                   # a level loops.png shows
    nan_at = lambda a: np.where(np.arange(n) == k, np.nan, a)
    failed = SimpleNamespace(success=False)     # what the figures read of a failed Loop
    bad = replace(res, f_hz=nan_at(res.f_hz), zeta=nan_at(res.zeta),
                  tip_velocity=nan_at(res.tip_velocity),
                  dissipation_method=np.where(np.arange(n) == k, "loop",
                                              res.dissipation_method),
                  loops={**res.loops, k: failed})
    figures = _capture(bad, tmp_path, monkeypatch)
    v_masing = 2 * np.pi * res.f_hz_masing[k] * abs(res.tip[k])
    for ax, y in zip(figures["damping_frequency.png"].axes,
                     (res.f_hz_masing[k], res.zeta_masing[k])):
        marked = [l for l in ax.get_lines() if l.get_label().startswith("loop failed")]
        assert len(marked) == 1
        np.testing.assert_allclose(np.asarray(marked[0].get_data(), float).ravel(),
                                   [v_masing, y])
        masing = [l for l in ax.get_lines() if l.get_label() == "Masing"][0]
        assert np.isfinite(np.asarray(masing.get_xdata(), float)).all()
    labels = [l.get_label() for l in figures["loops.png"].axes[0].get_lines()]
    assert f"Masing, level {k} (its computed loop failed)" in labels
    for name, fig in figures.items():
        assert not _check_figure(name, fig)


def test_a_masing_level_without_values_is_not_called_a_failed_loop(results, tmp_path,
                                                                    monkeypatch):
    """Only a level that computed a loop can be marked 'loop failed'."""
    from dataclasses import replace
    res = results["sandwich-2d"]
    n = res.n_levels
    nan_at = lambda a: np.where(np.arange(n) == 1, np.nan, a)
    bad = replace(res, f_hz=nan_at(res.f_hz), zeta=nan_at(res.zeta),
                  f_hz_masing=nan_at(res.f_hz_masing), zeta_masing=nan_at(res.zeta_masing),
                  tip_velocity=nan_at(res.tip_velocity),
                  dissipation_method=np.full(n, "masing", dtype=object), loops={})
    figures = _capture(bad, tmp_path, monkeypatch)
    for ax in figures["damping_frequency.png"].axes:
        assert not [l for l in ax.get_lines() if l.get_label().startswith("loop failed")]
