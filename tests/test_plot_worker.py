"""The figures drawn by a forked process beside the analysis (qsma.output.plotworker): the
same files as drawn in the qsma process, the result folder protocol kept when the
worker raises, dies or is switched off, and no worker where forking is not possible.
"""
import io
import json
import logging
import os
import signal
import subprocess
import sys

import numpy as np
import pytest

import qsma
import qsma.output.plotworker as pw
import qsma.output.plots as plots
from qsma.errors import InputError
from qsma.examples import lap_3d, sandwich_2d
from qsma.analysis.levels import Levels, spec_levels
from qsma.output.files import write_all
from qsma.output.folders import verify_run_folder

from qsma._infra.forked import parallel_available

needs_fork = pytest.mark.skipif(not parallel_available(),
                                reason="no fork start method (Windows)")


@pytest.fixture(autouse=True)
def worker_on(monkeypatch):
    """The worker switched on, whatever the environment of the test run."""
    monkeypatch.setenv(pw.ENV, "1")


@pytest.fixture(scope="module")
def results():
    full = spec_levels()
    levels = Levels(full.kind, full.values[::6])
    return {"sandwich-2d": qsma.run(sandwich_2d(), levels=levels),
            "lap-3d": qsma.run(lap_3d(), levels=levels)}


def _pixels(png: bytes) -> np.ndarray:
    from matplotlib.image import imread
    return imread(io.BytesIO(png), format="png")


def _worker_pngs(res):
    worker = pw.PlotWorker.start()
    assert worker is not None
    try:
        worker.submit(res)
        return worker.collect()
    finally:
        worker.close()


@needs_fork
@pytest.mark.parametrize("case", ["sandwich-2d", "lap-3d"])
def test_the_worker_draws_the_figures_of_the_qsma_process(results, case, tmp_path,
                                                          monkeypatch):
    """The PNG files drawn in the worker (split over two processes, as on two cores)
    equal those of write_plots in this process, byte for byte and so pixel for pixel."""
    monkeypatch.setattr(pw, "usable_cores", lambda: 2)
    res = results[case]
    here = plots.write_plots(res, tmp_path)
    there = _worker_pngs(res)
    assert set(there) == set(here) == set(plots.figure_files(res.model.dim))
    for name, path in here.items():
        ours = path.read_bytes()
        a, b = _pixels(ours), _pixels(there[name])
        assert a.shape == b.shape and a.shape[0] > 100
        np.testing.assert_array_equal(a, b)
        assert ours == there[name]


@needs_fork
def test_a_worker_on_one_core_draws_every_figure_itself(results, monkeypatch):
    monkeypatch.setattr(pw, "usable_cores", lambda: 1)
    monkeypatch.setattr(pw, "_draw_split", _raises)   # no second drawing process
    res = results["sandwich-2d"]
    assert _worker_pngs(res) == plots.figure_pngs(res)


def _folder_pngs(out):
    return {p.name: p.read_bytes() for p in sorted(out.iterdir()) if p.suffix == ".png"}


@pytest.fixture(scope="module")
def reference(results, tmp_path_factory):
    """The figures of write_all drawn in this process (no worker)."""
    out = tmp_path_factory.mktemp("reference") / "out"
    write_all(results["sandwich-2d"], out)
    return _folder_pngs(out)


@needs_fork
def test_write_all_with_a_worker_writes_the_same_complete_run(results, reference,
                                                              tmp_path):
    worker = pw.PlotWorker.start()
    try:
        paths = write_all(results["sandwich-2d"], tmp_path / "out", plot_worker=worker)
    finally:
        worker.close()
    manifest = verify_run_folder(tmp_path / "out")
    assert {"backbone.png", "loops.png", "damping_frequency.png", "interface.png",
            "report.html"} <= set(manifest["files"])
    assert _folder_pngs(tmp_path / "out") == reference
    assert paths["interface"] == tmp_path.resolve() / "out" / "interface.png"
    report = (tmp_path / "out" / "report.html").read_text()
    assert report.count("data:image/png;base64") == 4       # the four figures embedded


def _raises(data, conn):
    raise RuntimeError("drawing broke")


def _exits(data, conn):
    os._exit(3)


def _killed(data, conn):
    os.kill(os.getpid(), signal.SIGKILL)


@needs_fork
@pytest.mark.parametrize("broken, why", [(_raises, "RuntimeError: drawing broke"),
                                         (_exits, "exit code 3"),
                                         (_killed, f"exit code {-signal.SIGKILL}")])
def test_a_failing_worker_leaves_the_figures_to_this_process(results, reference, tmp_path,
                                                             monkeypatch, caplog, broken,
                                                             why):
    """A worker that raises, exits abnormally or is killed delivers nothing: this
    process draws the figures itself (the same files, a complete manifest) and logs
    why. The worker never writes into the result folder, so nothing of it is left."""
    monkeypatch.setattr(pw, "_draw", broken)        # inherited by the fork
    worker = pw.PlotWorker.start()
    try:
        with caplog.at_level(logging.WARNING, logger="qsma.output.plotworker"):
            write_all(results["sandwich-2d"], tmp_path / "out", plot_worker=worker)
    finally:
        worker.close()
    verify_run_folder(tmp_path / "out")
    assert _folder_pngs(tmp_path / "out") == reference
    assert [r for r in caplog.records if why in r.getMessage()
            and "figures drawn in the qsma process instead" in r.getMessage()]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@needs_fork
def test_a_failing_second_drawing_process_leaves_its_figures_to_the_worker(
        results, monkeypatch):
    """The half of the figures drawn by the worker's own child, which dies, are drawn
    by the worker: every figure arrives, the same bytes."""
    res = results["sandwich-2d"]
    expected = plots.figure_pngs(res)
    test_pid = os.getpid()
    draw = plots.figure_pngs

    def dies_in_the_grandchild(data, names=None):
        if os.getppid() != test_pid and os.getpid() != test_pid:
            os._exit(5)
        return draw(data, names)

    monkeypatch.setattr(pw, "usable_cores", lambda: 2)
    monkeypatch.setattr(plots, "figure_pngs", dies_in_the_grandchild)
    assert _worker_pngs(res) == expected


@needs_fork
def test_drawing_that_fails_everywhere_fails_the_run_and_keeps_the_folder(
        results, tmp_path, monkeypatch):
    """The worker's failure is not hidden: drawn again here, the figure fails as it
    would without a worker, and the result folder keeps its previous run."""
    write_all(results["sandwich-2d"], tmp_path / "out", plots=False)
    before = verify_run_folder(tmp_path / "out")

    def broken(fig):
        raise RuntimeError("no PNG today")

    monkeypatch.setattr(plots, "png_bytes", broken)
    worker = pw.PlotWorker.start()
    try:
        with pytest.raises(RuntimeError, match="no PNG today"):
            write_all(results["sandwich-2d"], tmp_path / "out", plot_worker=worker)
    finally:
        worker.close()
    assert verify_run_folder(tmp_path / "out") == before


@needs_fork
def test_a_worker_whose_parent_goes_away_ends(results):
    """The worker waits for its job on a pipe; when the qsma process ends (its end of
    the pipe closes) the worker leaves without drawing."""
    worker = pw.PlotWorker.start()
    process = worker._process
    worker._conn.close()
    process.join(timeout=120)               # a guard against a hang, not a timing
    assert process.exitcode == 0
    worker.close()


def test_no_worker_where_it_may_not_fork(monkeypatch):
    monkeypatch.setenv(pw.ENV, "0")
    assert pw.why_not_fork().startswith(f"{pw.ENV}=0")
    monkeypatch.delenv(pw.ENV)
    assert pw.why_not_fork().startswith(f"{pw.ENV}=unset")   # off by default
    assert pw.PlotWorker.start() is None
    monkeypatch.setenv(pw.ENV, "1")
    monkeypatch.setattr(pw.multiprocessing, "get_all_start_methods", lambda: ["spawn"])
    assert pw.why_not_fork() == "the fork start method is not available"
    assert pw.PlotWorker.start() is None


@pytest.mark.parametrize("value", ["yes", "2", "off"])
def test_a_bad_worker_setting_is_refused(monkeypatch, value):
    monkeypatch.setenv(pw.ENV, value)
    with pytest.raises(InputError, match=f"{pw.ENV} must be 0 .* or 1 .*got '{value}'"):
        pw.why_not_fork()


def test_write_all_without_a_worker_draws_here(results, reference, tmp_path):
    """The path of Windows and QSMA_PLOT_WORKER=0: write_all draws the figures."""
    write_all(results["sandwich-2d"], tmp_path / "out", plot_worker=None)
    verify_run_folder(tmp_path / "out")
    assert _folder_pngs(tmp_path / "out") == reference


@pytest.mark.parametrize("worker", [
    pytest.param("1", marks=needs_fork), "0"])
def test_qsma_run_draws_in_the_worker_or_here(tmp_path, worker):
    """In a fresh process, with the worker and without it (QSMA_PLOT_WORKER=0, as on
    Windows), ``qsma run`` writes the same figure files. The qsma process imports
    matplotlib either way: report.html's mesh drawing is made there (matplotlib), the
    four figures by the worker when it runs."""
    code = ("import json, sys\nfrom qsma.cli import main\ncode = main(sys.argv[1:])\n"
            "print(json.dumps([code, 'matplotlib' in sys.modules]))")
    out = tmp_path / "run"
    args = ["run", "--example", "sandwich-2d", "--levels", "tip:log:1e-6:1e-4:3",
            "--quiet", "--out", str(out)]
    env = dict(os.environ, **{pw.ENV: worker})
    proc = subprocess.run([sys.executable, "-c", code, *args], capture_output=True,
                          text=True, env=env)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == ""
    exit_code, matplotlib_here = json.loads(proc.stdout.splitlines()[-1])
    assert exit_code == 0 and matplotlib_here
    manifest = verify_run_folder(out)
    assert {"backbone.png", "loops.png", "damping_frequency.png", "interface.png",
            "report.html"} <= set(manifest["files"])


def test_no_plots_starts_no_worker(tmp_path, monkeypatch):
    """``qsma run --no-plots`` forks nothing (and so never imports matplotlib)."""
    from qsma.cli import main

    def refuse():
        raise AssertionError("a plot worker was started")

    monkeypatch.setattr(pw.PlotWorker, "start", staticmethod(refuse))
    out = tmp_path / "run"
    assert main(["run", "--example", "sandwich-2d", "--levels", "tip:log:1e-6:1e-4:3",
                 "--quiet", "--no-plots", "--out", str(out)]) == 0
    assert not any(p.suffix == ".png" for p in out.iterdir())
