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
import qsma.output.report
from qsma.output.report import REPORT_NAME, run_report_html

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


def _pixels_per_unit(ax):
    """Pixels per data unit along x and along y of a drawn axes."""
    o, x, y = ax.transData.transform([(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)])
    return abs(x[0] - o[0]), abs(y[1] - o[1])


def test_mesh_figure_shows_every_cell_and_pair_where_it_is(run_result):
    """The 2D mesh figure (matplotlib, written as SVG): the whole-model panel draws
    every cell edge of each body once, the interface panel one dot per pair in the
    colour of its state after the preload (counts as in the result) at the pair's
    position, both panels at the same scale in x and y (the drawing is not
    distorted), axes labelled with the model's length unit."""
    from qsma.output.report import _body_corner_blocks, _cell_edges, draw_mesh_2d
    res = run_result
    fig = draw_mesh_2d(res)
    fig.canvas.draw()
    whole, zoom = fig.axes
    for ax in (whole, zoom):
        sx, sy = _pixels_per_unit(ax)
        assert sx == pytest.approx(sy, rel=1e-6)
        assert ax.get_xlabel() == "x [m]" and ax.get_ylabel() == "y [m]"
    for i, body in enumerate(res.model.bodies):
        patch = [p for p in whole.patches if p.get_gid() == f"cells-{i}"]
        assert len(patch) == 1
        edges = _cell_edges(_body_corner_blocks(body.mesh))
        assert len(patch[0].get_path().vertices) == 2 * len(edges)
        # quads: 2 n + (rows + columns) edges; each cell's four edges are among them
        assert len(edges) < 4 * len(body.mesh.cells)
    pre = res.preload
    for name, count in (("stuck", pre.n_stuck), ("slipping", pre.n_slipping),
                        ("open", pre.n_open)):
        dots = [c for c in zoom.collections if c.get_gid() == f"pairs-{name}"]
        if count == 0:
            assert dots == []
            continue
        np.testing.assert_array_equal(dots[0].get_offsets(),
                                      res.pairing.x[pre.status == {"stuck": 0,
                                                                   "slipping": 1,
                                                                   "open": 2}[name]])
    assert pre.n_stuck and pre.n_open        # both colours are exercised here
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert f"interface pair, stuck after preload ({pre.n_stuck})" in legend
    assert fig._suptitle.get_text().endswith(
        f"{res.model.n_nodes} nodes, {res.pairing.n_pairs} interface pairs")
    mime, svg = qsma.output.report.mesh_figure(res)
    root = ET.fromstring(svg)
    assert mime == "image/svg+xml" and root.tag.endswith("svg")
    assert root.find(".//*[@id='cells-0']") is not None


def test_every_cell_of_a_mixed_mesh_is_drawn():
    """A body meshed with a quadrilateral and two triangles (two cell blocks) draws the
    edges of all three cells (found in review: only the first block was drawn), and
    its outline is the strip's rectangle: 6 edges."""
    from qsma.mesh.mesh import CellBlock, Mesh
    from qsma.output.report import _body_corner_blocks, body_edges
    pts = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1]], float)
    mesh = Mesh(pts, np.array([[0, 1, 4, 3]]), "quad",
                extra_blocks=(CellBlock("triangle", np.array([[1, 2, 5], [1, 5, 4]]),
                                        None),))
    edges, kind = body_edges(mesh)
    assert kind == "cells"
    drawn = {tuple(e) for e in np.sort(edges, axis=1).tolist()}
    for cells in _body_corner_blocks(mesh):
        for cell in cells.tolist():
            for a, b in zip(cell, cell[1:] + cell[:1]):
                assert tuple(sorted((a, b))) in drawn
    assert len(drawn) == 8
    assert len(qsma.output.report._outline_edges(_body_corner_blocks(mesh))) == 6


def test_a_fine_mesh_is_drawn_by_its_outline(run_result, monkeypatch):
    """Beyond MAX_SVG_CELLS cells a body is drawn by the edges of one cell only: on a
    structured grid of nx x ny cells the 2 (nx + ny) edges of its rectangle; the SVG
    file is then much smaller."""
    nx, ny = 3, 2
    node = np.arange((nx + 1) * (ny + 1)).reshape(ny + 1, nx + 1)
    cells = np.array([[node[j, i], node[j, i + 1], node[j + 1, i + 1], node[j + 1, i]]
                      for j in range(ny) for i in range(nx)])
    edges = qsma.output.report._outline_edges([cells])
    assert len(edges) == 2 * (nx + ny)
    rows, cols = np.divmod(edges, nx + 1)
    on_side = ((rows == 0).all(1) | (rows == ny).all(1) | (cols == 0).all(1)
               | (cols == nx).all(1))
    assert on_side.all()
    every_cell = qsma.output.report.mesh_figure(run_result)[1]
    monkeypatch.setattr(qsma.output.report, "MAX_SVG_CELLS", 100)
    fig = qsma.output.report.draw_mesh_2d(run_result)
    gids = {p.get_gid() for p in fig.axes[0].patches}
    assert gids == {f"outline-{i}" for i in range(len(run_result.model.bodies))}
    outline = qsma.output.report.mesh_figure(run_result)[1]
    assert len(outline) < len(every_cell) / 2


def test_3d_mesh_figure_is_a_png_with_every_pair_state_at_equal_scales():
    """A 3D model's mesh figure is a PNG (nodes in a 3D projection) scaled equally
    along x, y and z (the box's sides in proportion to the model's extent), with a
    legend entry per pair state that occurs after the preload."""
    from qsma.examples import lap_3d
    res = qsma.run(lap_3d(), levels=qsma.Levels.log("tip", 1e-6, 1e-4, 2))
    mime, png = qsma.output.report.mesh_figure(res)
    assert mime == "image/png" and png.startswith(PNG_MAGIC)
    ax = qsma.output.report.draw_mesh_3d(res).axes[0]
    extent = np.ptp(np.vstack([b.mesh.points for b in res.model.bodies]), axis=0)
    box = np.asarray(ax.get_box_aspect())
    np.testing.assert_allclose(box / box[0], extent / extent[0], rtol=1e-9)
    states = qsma.output.report._pair_states(res.preload.status)    # every pair in one state
    assert sum(int(sel.sum()) for *_, sel in states) == res.pairing.n_pairs
    html = run_report_html(res, figures={})
    assert images(html)[0].startswith("data:image/png;base64,")


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


#: The window the layout is checked at: a laptop screen.
WINDOW = (1200, 900)
#: Smallest font size of the page's text [CSS px] and smallest scale at which a figure
#: is shown (its text, 8-10 pt at 100-120 dpi, then stays at 9 px or more).
MIN_FONT_PX = 12
MIN_FIGURE_SCALE = 0.7


def layout(driver, path):
    """Layout facts of the page at :data:`WINDOW`: header cells without text, the
    smallest font size of any text, how far the page overflows the window sideways,
    and per image its natural and shown width, right edge and top."""
    driver.set_window_size(*WINDOW)
    show(driver, path)
    return driver.execute_script("""
        const texts = Array.from(document.querySelectorAll(
            'p, td, th, figcaption, li, h1, h2')).filter(e => e.textContent.trim());
        const root = document.documentElement;
        return {
          empty_headers: Array.from(document.querySelectorAll('th'))
              .filter(t => !t.textContent.trim()).length,
          smallest_font: Math.min(...texts.map(e => parseFloat(getComputedStyle(e).fontSize))),
          overflow: root.scrollWidth - root.clientWidth,
          width: root.clientWidth,
          images: Array.from(document.images).map(i => {
              const r = i.getBoundingClientRect();
              return [i.naturalWidth, r.width, r.right, Math.round(r.top)]; }),
        };""")


def layout_problems(facts):
    """What makes the page hard to read (empty list: nothing)."""
    out = []
    if facts["empty_headers"]:
        out.append(f"{facts['empty_headers']} empty table header cell(s)")
    if facts["smallest_font"] < MIN_FONT_PX:
        out.append(f"text at {facts['smallest_font']} px")
    if facts["overflow"] > 0:
        out.append(f"the page is {facts['overflow']} px wider than the window")
    for natural, shown, right, _ in facts["images"]:
        if natural and shown < MIN_FIGURE_SCALE * natural:
            out.append(f"a figure {natural} px wide is shown at {shown:.0f} px")
        if right > facts["width"] + 1:
            out.append("a figure runs beyond the window")
    return out


def test_browser_check_catches_a_broken_page(browser, tmp_path):
    """The checks themselves: a console error, an undecodable image, an empty header
    cell, small text and a figure shrunk to a thumbnail are seen."""
    bad = tmp_path / "bad.html"
    bad.write_text('<!DOCTYPE html><html><body><img src="data:image/png;base64,AAAA">'
                   '<script>console.error("broken on purpose")</script></body></html>')
    errors, widths = show(browser, bad)
    assert any("broken on purpose" in e["message"] for e in errors)
    assert widths == [0]
    from qsma.output.plots import agg_figure, png_bytes
    png = base64.b64encode(png_bytes(agg_figure()[0])).decode()
    cramped = tmp_path / "cramped.html"
    cramped.write_text('<!DOCTYPE html><html><body><table><tr><th></th><th></th></tr>'
                       '<tr><td style="font-size: 9px">value</td><td>1</td></tr></table>'
                       f'<img style="max-width: 20em" src="data:image/png;base64,{png}">'
                       '</body></html>')
    problems = layout_problems(layout(browser, cramped))
    assert any("empty table header" in p for p in problems)
    assert any("text at 9 px" in p for p in problems)
    assert any("is shown at" in p for p in problems)


@pytest.mark.parametrize("which", ["run_report", "study_report"])
def test_report_shows_in_a_browser(browser, which, request):
    path = request.getfixturevalue(which)
    errors, widths = show(browser, path)
    assert errors == []
    assert widths and all(w > 100 for w in widths), widths


@pytest.mark.parametrize("which", ["run_report", "study_report"])
def test_report_layout_reads_on_a_laptop_screen(browser, which, request, tmp_path):
    """At 1200 x 900 pixels: no empty header row, no text below 12 px, nothing wider
    than the window, every figure shown at 70 % of its size or more; the run's
    figures two to a row where they fit. The screenshot is kept beside the test's
    temporary files for a person to look at."""
    path = request.getfixturevalue(which)
    facts = layout(browser, path)
    assert layout_problems(facts) == []
    if which == "run_report":
        tops = [top for *_, top in facts["images"]]
        assert len(tops) > len(set(tops))            # some figures side by side
    shot = tmp_path / f"{which}.png"
    browser.set_window_size(WINDOW[0], min(browser.execute_script(
        "return document.documentElement.scrollHeight"), 8000))
    assert browser.save_screenshot(str(shot)) and shot.read_bytes().startswith(PNG_MAGIC)
