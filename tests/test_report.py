"""report.html of a run and of a study: self-contained (no network), complete, and
shown by a real headless browser without console errors and with every figure."""
import base64
from dataclasses import replace
import re
import shutil

import pytest

import qsma
from qsma.examples import sandwich_2d
from qsma.report import REPORT_NAME, run_report_html

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
    assert refs and all(r.startswith("data:image/png;base64,") for r in refs)
    assert "<script" not in html
    srcs = images(html)
    assert len(srcs) == 5          # mesh + backbone, loops, damping, interface
    for s in srcs:
        assert base64.b64decode(s.split(",", 1)[1]).startswith(PNG_MAGIC)
    for text in ("sandwich-2d", "Solver statistics", "Timings", "Levels", "Warnings",
                 f"{run_result.f0_hz:.4f}"):
        assert text in html
    level_rows = re.findall(r"<tr><td>(\d+)</td>", html)
    assert level_rows == [str(k) for k in range(run_result.n_levels)]


def test_report_names_the_warnings(run_result):
    flags = ((),) * (run_result.n_levels - 1) + (("negative_dissipation",),)
    bad = replace(run_result, success=False, message="level 4 holds a negative "
                  "dissipation", flags=flags)
    html = run_report_html(bad, figures={})
    assert "NOT successful" in html
    assert "failure: negative_dissipation at level(s) [4]" in html
    assert "level 4 holds a negative dissipation" in html


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
