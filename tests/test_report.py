"""report.html of a run and of a study: self-contained (no network), complete, and
shown by a real headless browser without console errors and with every figure."""
import base64
from dataclasses import replace
import re
import shutil
import sys
import xml.etree.ElementTree as ET

import numpy as np
import pytest

import qsma
from qsma.examples import sandwich_2d
import qsma.report
from qsma.report import REPORT_NAME, mesh_svg, nice_ticks, run_report_html, tick_labels

LEVELS = qsma.Levels.log("tip", 1e-6, 1e-3, 5)
#: Debian's chromium and its driver (apt-get install chromium chromium-driver; .ci/run
#: installs them as best effort). Only the browser checks skip without them.
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
CHROMEDRIVER = shutil.which("chromedriver")
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def run_result():
    res = qsma.run(sandwich_2d(1), levels=LEVELS)
    assert res.success
    return res


@pytest.fixture(scope="module")
def run_report(run_result, tmp_path_factory):
    out = tmp_path_factory.mktemp("run")
    paths = qsma.write_all(run_result, out, vtu=False)
    assert paths["report"] == out / REPORT_NAME
    return out / REPORT_NAME


@pytest.fixture(scope="module")
def study_report(tmp_path_factory):
    out = tmp_path_factory.mktemp("study")
    res = qsma.sweep(sandwich_2d(1), {"mu": [0.4, 0.6]}, qsma.RunOptions(levels=LEVELS),
                     out=out, scheduler="serial")
    assert res.success
    return res.paths["report"]


def images(html):
    return re.findall(r'<img[^>]*src="([^"]*)"', html)


def test_run_report_is_self_contained_and_complete(run_report, run_result):
    html = run_report.read_text()
    # nothing to fetch: every src/href is a data: URI (no http, no file reference)
    refs = re.findall(r'(?:src|href)="([^"]*)"', html)
    assert refs and all(r.startswith(("data:image/png;base64,",
                                      "data:image/svg+xml;base64,")) for r in refs)
    assert "<script" not in html
    srcs = images(html)
    assert len(srcs) == 5          # mesh (SVG) + backbone, loops, damping, interface
    assert srcs[0].startswith("data:image/svg+xml;base64,")
    assert ET.fromstring(base64.b64decode(srcs[0].split(",", 1)[1])).tag.endswith("svg")
    for s in srcs[1:]:
        assert base64.b64decode(s.split(",", 1)[1]).startswith(PNG_MAGIC)
    for text in ("sandwich-2d", "Solver statistics", "Timings", "Levels", "Warnings",
                 f"{run_result.f0_hz:.4f}"):
        assert text in html
    level_rows = re.findall(r"<tr><td>(\d+)</td>", html)
    assert level_rows == [str(k) for k in range(run_result.n_levels)]


SVG = "{http://www.w3.org/2000/svg}"


def test_mesh_figure_shows_every_cell_and_pair_where_it_is(run_result):
    """The 2D mesh figure (SVG written by qsma): the whole-model panel outlines every
    cell of each body, one dot per interface pair in the colour of its state after the
    preload (counts as in the result), dots placed by one map x -> a + s x,
    y -> b - s y (the same scale s on both axes: the drawing is not distorted)."""
    res = run_result
    root = ET.fromstring(mesh_svg(res))
    paths = root.findall(f".//{SVG}path[@class='cells']")
    assert len(paths) == 2 * len(res.model.bodies)          # whole model + interface
    for path, body in zip(paths, res.model.bodies):         # whole model first
        assert path.get("d").count("M") == len(body.mesh.cells)
        assert path.get("d").count("Z") == len(body.mesh.cells)
    pre = res.preload
    for name, count in (("stuck", pre.n_stuck), ("slipping", pre.n_slipping),
                        ("open", pre.n_open)):
        dots = root.findall(f".//{SVG}circle[@class='pair-{name}']")
        assert len(dots) == count
    assert pre.n_stuck and pre.n_open        # both colours are exercised here
    order = np.concatenate([np.flatnonzero(pre.status == s) for s in (0, 1, 2)])
    dots = root.findall(f".//{SVG}circle[@class]")
    cx = np.array([float(c.get("cx")) for c in dots])
    cy = np.array([float(c.get("cy")) for c in dots])
    x, y = res.pairing.x[order, 0], res.pairing.x[order, 1]
    scale, offset = np.polyfit(x, cx, 1)
    assert scale > 0 and np.max(np.abs(offset + scale * x - cx)) < 0.06   # 0.1 px rounding
    if np.ptp(y) > 0:
        assert np.allclose(np.polyfit(y, cy, 1)[0], -scale, rtol=1e-3)
    else:                                    # a straight interface: one row of dots
        assert np.ptp(cy) < 0.06
    legend = "".join(root.itertext())
    assert f"interface pair, stuck after preload ({pre.n_stuck})" in legend
    assert f"{res.model.n_nodes} nodes, {res.pairing.n_pairs} interface pairs" in legend


def test_every_cell_of_a_mixed_mesh_is_drawn():
    """A body meshed with a quadrilateral and two triangles (two cell blocks) draws
    three cells in each panel (found in review: only the first block was drawn), and
    its outline is the strip's rectangle: 6 edges."""
    from types import SimpleNamespace as NS

    from qsma.model.mesh import CellBlock, Mesh
    pts = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], float)
    mesh = Mesh(pts, np.array([[0, 1, 4, 3]]), "quad",
                extra_blocks=(CellBlock("triangle", np.array([[1, 2, 5], [1, 5, 4]]),
                                        None),))
    model = NS(bodies=[NS(mesh=mesh, name="strip")], name="mixed", n_nodes=6, dim=2)
    res = NS(model=model, pairing=NS(x=np.array([[0.5, 0.0], [1.5, 0.0]]), n_pairs=2),
             preload=NS(status=np.array([0, 2])))
    paths = ET.fromstring(mesh_svg(res)).iter("{http://www.w3.org/2000/svg}path")
    drawn = [p.get("d").count("M") for p in paths if p.get("class") == "cells"]
    assert drawn == [3, 3]
    assert len(qsma.report._outline_edges(qsma.report._body_corner_blocks(mesh))) == 6


def test_a_fine_mesh_is_drawn_by_its_outline(run_result, monkeypatch):
    """Beyond MAX_SVG_CELLS cells a body is drawn by the edges of one cell only: on a
    structured grid of nx x ny cells the 2 (nx + ny) edges of its rectangle."""
    nx, ny = 3, 2
    node = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    cells = np.array([[node[j, i], node[j, i + 1], node[j + 1, i + 1], node[j + 1, i]]
                      for j in range(ny) for i in range(nx)])
    edges = qsma.report._outline_edges([cells])
    assert len(edges) == 2 * (nx + ny)
    rows, cols = np.divmod(edges, nx + 1)
    on_side = ((rows == 0).all(1) | (rows == ny).all(1) | (cols == 0).all(1)
               | (cols == nx).all(1))
    assert on_side.all()
    every_cell = mesh_svg(run_result)
    monkeypatch.setattr(qsma.report, "MAX_SVG_CELLS", 100)
    outline = mesh_svg(run_result)
    root = ET.fromstring(outline)
    assert root.findall(f".//{SVG}path[@class='cells']") == []
    assert len(root.findall(f".//{SVG}path[@class='outline']")) == \
        2 * len(run_result.model.bodies)
    assert len(outline) < len(every_cell) / 3


def test_2d_report_needs_no_matplotlib(run_result, monkeypatch):
    """A 2D run's report without figures draws its mesh figure without matplotlib
    (any import of it fails here)."""
    for name in [m for m in sys.modules if m.split(".")[0] in ("matplotlib", "mpl_toolkits")]:
        monkeypatch.delitem(sys.modules, name)
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    html = run_report_html(run_result, figures={})
    assert len(images(html)) == 1 and "data:image/svg+xml;base64," in html


def test_3d_mesh_figure_is_a_png_with_every_pair_state():
    """A 3D model's mesh figure stays a matplotlib PNG (nodes in a 3D projection),
    with a legend entry per pair state that occurs after the preload."""
    from qsma.examples import lap_3d
    res = qsma.run(lap_3d(), levels=qsma.Levels.log("tip", 1e-6, 1e-4, 2))
    mime, png = qsma.report.mesh_figure(res)
    assert mime == "image/png" and png.startswith(PNG_MAGIC)
    states = qsma.report._pair_states(res.preload.status)    # every pair in one state
    assert sum(int(sel.sum()) for *_, sel in states) == res.pairing.n_pairs
    html = run_report_html(res, figures={})
    assert images(html)[0].startswith("data:image/png;base64,")


@pytest.mark.parametrize("lo, hi, n, expected", [
    (0.0, 0.2032, 5, [0.0, 0.05, 0.1, 0.15, 0.2]),      # step 0.05 >= 0.2032 / 5
    (0.0, 0.2032, 4, [0.0, 0.1, 0.2]),                  # 0.05 < 0.0508: step 0.1
    (-3.3e-3, 3.3e-3, 4, [-2e-3, 0.0, 2e-3]),
    (0.00635, 0.0127, 4, [0.008, 0.01, 0.012]),
    (175.0, 215.0, 4, [180.0, 190.0, 200.0, 210.0])])
def test_nice_ticks_are_1_2_5_steps_inside_the_interval(lo, hi, n, expected):
    """The smallest step of 1, 2 or 5 times a power of ten that is at least
    ``(hi - lo) / n``; its multiples inside ``[lo, hi]``."""
    assert np.allclose(nice_ticks(lo, hi, n), expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("lo, hi, expected", [
    (123456.0, 123458.0, ["123456.0", "123456.5", "123457.0", "123457.5", "123458.0"]),
    (1e6, 1e6 + 1.0, ["1000000.0", "1000000.2", "1000000.4", "1000000.6", "1000000.8",
                      "1000001.0"]),
    (0.0, 0.2032, ["0.00", "0.05", "0.10", "0.15", "0.20"]),
    (175.0, 215.0, ["180", "190", "200", "210"])])
def test_tick_labels_keep_the_digits_their_step_needs(lo, hi, expected):
    """Labels of a mesh far from the origin stay distinct (six significant digits,
    the general format, printed 123456 for every tick of a two-metre span there)."""
    labels = tick_labels(nice_ticks(lo, hi, 5 if hi - lo < 10 else 4))
    assert labels == expected and len(set(labels)) == len(labels)
    assert tick_labels(nice_ticks(0.0031, 0.0052, 2)) == ["0.004"]   # a lone tick


def test_report_names_the_warnings(run_result):
    flags = ((),) * (run_result.n_levels - 1) + (("negative_dissipation",),)
    bad = replace(run_result, success=False, message="level 4 holds a negative "
                  "dissipation", flags=flags)
    html = run_report_html(bad, figures={})
    assert "NOT successful" in html
    assert "failure: negative_dissipation at level(s) [4]" in html
    assert "level 4 holds a negative dissipation" in html


def test_a_level_without_f_and_zeta_shows_dashes(run_result):
    """A level whose loop did not stabilise has no f and zeta: the levels table shows
    a dash there (not "nan") and the flag in the same row."""
    f, zeta = run_result.f_hz.copy(), run_result.zeta.copy()
    f[1] = zeta[1] = np.nan
    flags = list(run_result.flags)
    flags[1] = ("loop_not_stabilised",)
    html = run_report_html(replace(run_result, f_hz=f, zeta=zeta, flags=tuple(flags),
                                   success=False), figures={})
    levels = html[html.index("<h2>Levels</h2>"):]
    row = levels[levels.index("<tr><td>1</td>"):]
    row = row[:row.index("</tr>")]
    assert row.count("\u2014") == 2 and "loop_not_stabilised" in row
    assert "nan" not in levels[:levels.index("</table>")]


def test_study_report_lists_the_cases(study_report):
    html = study_report.read_text()
    assert "2 of 2 cases ok" in html
    assert len(images(html)) == 1                 # sweep_mu.png
    assert re.findall(r"<tr><td>(\d)</td><td>(0\.\d)</td>", html) == [("0", "0.4"),
                                                                         ("1", "0.6")]


# ------------------------------------------------------------------ real browser

@pytest.fixture(scope="module")
def browser():
    if not (CHROMIUM and CHROMEDRIVER):
        pytest.skip("Debian's chromium and chromium-driver are not installed "
                    "(apt-get install chromium chromium-driver): browser check skipped")
    webdriver = pytest.importorskip("selenium.webdriver",
                                    reason="selenium (the 'test' extra) is not installed")
    from selenium.webdriver.chrome.service import Service
    opts = webdriver.ChromeOptions()
    opts.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu",
                "--disable-dev-shm-usage"):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)
    yield driver
    driver.quit()


def show(driver, path):
    """(console messages of level SEVERE, naturalWidth of every image) of the page."""
    driver.get(path.as_uri())
    driver.execute_async_script(
        "const done = arguments[arguments.length - 1];"
        "Promise.all(Array.from(document.images).map(i => i.decode().catch(() => null)))"
        ".then(() => done(null));")
    widths = driver.execute_script(
        "return Array.from(document.images).map(i => i.naturalWidth);")
    errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    return errors, widths


def test_browser_check_catches_a_broken_page(browser, tmp_path):
    """The check itself: a console error and an undecodable image are seen."""
    bad = tmp_path / "bad.html"
    bad.write_text('<!DOCTYPE html><html><body><img src="data:image/png;base64,AAAA">'
                   '<script>console.error("broken on purpose")</script></body></html>')
    errors, widths = show(browser, bad)
    assert any("broken on purpose" in e["message"] for e in errors)
    assert widths == [0]


@pytest.mark.parametrize("which", ["run_report", "study_report"])
def test_report_shows_in_a_browser(browser, which, request):
    path = request.getfixturevalue(which)
    errors, widths = show(browser, path)
    assert errors == []
    assert widths and all(w > 100 for w in widths), widths
