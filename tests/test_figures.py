"""Figures a person can read: no overlapping tick labels, a unit on every axis, every
plotted curve inside its axes, on the 2D and 3D examples.

The figures are captured as they are saved (``qsma.output.plots.save_png``) and inspected
through matplotlib's own text extents after a draw, so the test measures what the PNG
shows.
"""
import re

import numpy as np
import pytest

import qsma
import qsma.output.plots as plots
from qsma.examples import lap_2d, lap_3d, sandwich_2d
from qsma.analysis.levels import Levels, spec_levels

#: An axis label names its unit in brackets, e.g. "modal amplitude q [kg$^{1/2}$ m]";
#: a dimensionless quantity says "[-]".
UNIT = re.compile(r"\[[^\]]+\]")


def _capture(res, tmp_path, monkeypatch):
    figures = {}
    save = plots.save_png

    def keep(fig, path):
        figures[str(path).rsplit("/", 1)[-1]] = fig
        return save(fig, path)

    monkeypatch.setattr(plots, "save_png", keep)
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
    fig, ax = plots.agg_figure(figsize=(2, 2))
    ax.plot([0, 1], [0, 1])
    ax.set_xticks(np.linspace(0, 1, 40), [f"{x:.6f}" for x in np.linspace(0, 1, 40)])
    ax.set_xlabel("no unit here")
    ax.set_ylabel("y [m]")
    problems = _check_figure("crowded", fig)
    assert any("overlapping x tick labels" in p for p in problems)
    assert any("has no [unit]" in p for p in problems)


def test_log_axes_have_a_1_2_5_minor_grid(results, tmp_path, monkeypatch):
    """Minor ticks of the logarithmic axes only at 2 and 5 times a power of ten (what
    keeps the figures cheap to draw, CHANGELOG.md "The small case"), and some of them drawn."""
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
    the backbone (q, alpha) and the tied line, the loops at their levels normalised by
    the amplitude, the secant frequency and damping against the peak tip deflection,
    the preload pressure along the interface."""
    res = results["sandwich-2d"]
    figures = _capture(res, tmp_path, monkeypatch)

    def data(line):
        return tuple(np.asarray(v, float) for v in line.get_data())

    backbone = figures["backbone.png"].axes[0].get_lines()
    np.testing.assert_array_equal(data(backbone[0]), (res.q, res.alpha))
    np.testing.assert_allclose(data(backbone[1])[1], res.q * res.omega0 ** 2)
    k0 = res.omega0 ** 2
    panels = [ax for ax in figures["loops.png"].axes if ax.get_visible()]
    levels = plots.loop_levels(res)
    assert len(panels) == len(levels) and levels[-1] == res.n_levels - 1
    for ax, k in zip(panels, levels):
        line = ax.get_lines()[0]
        assert line.get_label().endswith(f"level {k}")
        q, f, _ = plots.loop_curve(res, k)
        qa = abs(res.q[k])
        np.testing.assert_allclose(data(line), (q / qa, (f - k0 * q) / (k0 * qa)))
    top, bottom = figures["damping_frequency.png"].axes
    tip = np.abs(res.tip)
    np.testing.assert_array_equal(data(top.get_lines()[0]), (tip, res.f_hz))
    np.testing.assert_array_equal(data(bottom.get_lines()[0]), (tip, res.zeta))
    assert bottom.get_xlabel() == "peak tip deflection [m]"
    pressure = figures["interface.png"].axes[0].get_lines()[0]
    p = res.pairing
    np.testing.assert_allclose(data(pressure), (p.x[:, 0], res.preload.lam[:, -1] / p.area
                                                / 1e6))


def test_every_loop_drawn_fills_its_panel(results, tmp_path, monkeypatch):
    """Loops of very different size are each visible: every panel's loop spans at
    least half of its axes in both directions (on one shared axis the loop at the
    first dissipating level of sandwich-2d is a thousandth of the largest one)."""
    res = results["sandwich-2d"]
    figures = _capture(res, tmp_path, monkeypatch)
    fig = figures["loops.png"]
    fig.canvas.draw()
    heights = []
    for ax in (a for a in fig.axes if a.get_visible()):
        x, y = (np.asarray(v, float) for v in ax.get_lines()[0].get_data())
        (x0, x1), (y0, y1) = ax.get_xlim(), ax.get_ylim()
        assert np.ptp(x) > 0.5 * (x1 - x0) and np.ptp(y) > 0.5 * (y1 - y0)
        k = int(ax.get_lines()[0].get_label().rsplit(" ", 1)[1])
        heights.append(np.ptp(y) * abs(res.q[k]))      # the loop's height unnormalised
    assert max(heights) > 100 * min(heights)


def test_the_amplitude_measure_is_selectable_and_shared_with_studies(results, tmp_path,
                                                                    monkeypatch):
    """``amplitude`` picks what frequency and damping are drawn against, in a run's
    figures and in a study's alike (tip deflection by default in both)."""
    import qsma.study.plots as study_plots
    res = results["sandwich-2d"]
    table = {"case": [0] * res.n_levels, "level": list(range(res.n_levels)),
             "mu": [0.6] * res.n_levels, "tip": list(res.tip), "q": list(res.q),
             "tip_velocity": list(res.tip_velocity), "f_hz": list(res.f_hz),
             "zeta": list(res.zeta)}
    drawn = []
    monkeypatch.setattr(study_plots, "save_png", lambda fig, path: drawn.append(fig))
    for amplitude, field, label in (
            (None, "tip", "peak tip deflection [m]"),
            ("velocity", "tip_velocity", "peak tip velocity [m/s]"),
            ("q", "q", "peak modal amplitude q [\u221a(kg/m) m]")):
        run_ax = plots.draw_damping_frequency(plots.plot_data(res, amplitude)).axes[1]
        study_plots.plot_parameter(table, "mu", [], tmp_path / "s.png", "SI", 2, amplitude)
        study_ax = drawn[-1].axes[1]
        assert run_ax.get_xlabel() == study_ax.get_xlabel() == label
        for ax in (run_ax, study_ax):
            np.testing.assert_array_equal(ax.get_lines()[0].get_xdata(),
                                          np.abs(getattr(res, field)))
    with pytest.raises(qsma.errors.InputError, match="unknown amplitude measure"):
        plots.plot_data(res, "speed")


def test_the_interface_map_has_one_colour_scale_per_row(results, tmp_path, monkeypatch):
    """Pressure and shear keep their colours across the levels drawn: one norm per row,
    from 0 to the largest value of any level shown."""
    res = results["lap-3d"]
    fig = _capture(res, tmp_path, monkeypatch)["interface_map.png"]
    maps = [ax for ax in fig.axes if ax.collections and ax.get_label() != "<colorbar>"]
    rows = {}
    for ax in maps:
        coll = ax.collections[0]
        rows.setdefault(coll.cmap.name, []).append(coll)
    assert len(rows) == 3 and all(len(c) == 3 for c in rows.values())
    for name, colls in rows.items():
        assert len({(c.norm.vmin, c.norm.vmax) for c in colls}) == 1, name
        if name == "viridis":
            top = max(float(np.max(c.get_array())) for c in colls)
            assert colls[0].norm.vmin == 0 and colls[0].norm.vmax == pytest.approx(top)
    bars = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert len(bars) == 3                           # one per row


def test_a_level_whose_loop_failed_stays_in_the_figures(results, tmp_path, monkeypatch):
    """A level without a used frequency (its loop failed: f, zeta and the velocity are
    NaN) is drawn with its Masing values and marked, not dropped (against the velocity:
    at Masing's velocity); loops.png says why a level shows Masing's construction."""
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
    v_masing = 2 * np.pi * res.f_hz_masing[k] * abs(res.tip[k])
    for amplitude, x in (("tip", abs(res.tip[k])), ("velocity", v_masing)):
        fig = plots.draw_damping_frequency(plots.plot_data(bad, amplitude))
        for ax, y in zip(fig.axes, (res.f_hz_masing[k], res.zeta_masing[k])):
            marked = [l for l in ax.get_lines() if l.get_label().startswith("loop failed")]
            assert len(marked) == 1
            np.testing.assert_allclose(np.asarray(marked[0].get_data(), float).ravel(),
                                       [x, y])
            masing = [l for l in ax.get_lines() if l.get_label() == "Masing"][0]
            assert np.isfinite(np.asarray(masing.get_xdata(), float)).all()
    figures = _capture(bad, tmp_path, monkeypatch)
    labels = [l.get_label() for ax in figures["loops.png"].axes for l in ax.get_lines()]
    assert f"Masing (its computed loop failed), level {k}" in labels
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
