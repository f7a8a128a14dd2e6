"""The command line, end to end in temporary folders."""
import csv
import json
import os
import sys

import meshio
import numpy as np
import pytest

from qsma.cli import main


def test_modes_json(capsys):
    assert main(["modes", "--example", "sandwich-2d", "--tie", "all", "--json", "-n", "3"]) == 0
    out = json.loads(capsys.readouterr().out)
    f = out["f_hz"]
    assert len(f) == 3 and 142.7 < f[0] < 285.3 and f == sorted(f)


def test_modes_tie_preload_is_softer_than_all(capsys):
    main(["modes", "--example", "sandwich-2d", "--tie", "preload", "--json", "-n", "1"])
    f_pre = json.loads(capsys.readouterr().out)["f_hz"][0]
    main(["modes", "--example", "sandwich-2d", "--tie", "all", "--json", "-n", "1"])
    f_all = json.loads(capsys.readouterr().out)["f_hz"][0]
    assert f_pre < f_all


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "sandwich"
    code = main(["run", "--example", "sandwich-2d", "--out", str(out), "--quiet",
                 "--direct-loop"])
    assert code == 0
    return out


def test_results_json_schema(run_dir):
    data = json.loads((run_dir / "results.json").read_text())
    assert set(data["model"]) >= {"n_nodes", "n_dofs", "n_pairs", "mu"}
    assert data["model"]["n_nodes"] == 2250 and data["model"]["n_pairs"] == 65
    assert set(data["mode"]) >= {"index", "f0_hz"}
    levels = data["levels"]
    keys = ["alpha", "tip_lin", "q", "tip", "f_hz", "zeta", "dissipation", "tip_velocity",
            "n_stuck", "n_slip", "n_open", "iterations"]
    assert all(len(levels[k]) == 51 for k in keys)
    assert set(data["timings_s"]) == {"model", "assembly", "modal", "condensation",
                                      "contact", "hysteresis", "postprocess", "total"}
    assert len(levels["flags"]) == 51 and set(levels["dissipation_method"]) == {"masing"}
    assert set(data["solver"]) >= {"method", "tol"}
    if sys.platform.startswith("linux"):           # VmHWM: this process's peak RSS
        assert data["resources"]["peak_memory_mb"] > 50     # numpy + scipy alone
    assert data["resources"]["cpu_s"] > 0
    assert data["qsma_version"]
    assert data["direct_loop"]["dissipation"] > 0


def test_results_csv_matches_json(run_dir):
    data = json.loads((run_dir / "results.json").read_text())
    rows = list(csv.DictReader((run_dir / "results.csv").open()))
    assert len(rows) == 51
    assert np.allclose([float(r["zeta [-]"]) for r in rows], data["levels"]["zeta"], rtol=1e-9,
                       atol=1e-15)


def test_plots_are_png(run_dir):
    for name in ("backbone", "loops", "damping_frequency", "interface"):
        head = (run_dir / f"{name}.png").read_bytes()[:8]
        assert head == b"\x89PNG\r\n\x1a\n"


def test_vtu_reads_back(run_dir):
    m = meshio.read(run_dir / "fields.vtu")
    assert len(m.points) == 2250
    assert m.cells[0].type == "quad" and len(m.cells[0].data) == 2 * 124 * 8
    assert "u_level50" in m.point_data and "von_mises_level50" in m.point_data
    p = m.point_data["contact_pressure_level50"]
    assert np.isfinite(p).all() and p.max() > 1e6          # MPa-level bolt pressure


def test_no_temporary_files_left(run_dir):
    assert not [p for p in run_dir.iterdir() if p.name.startswith(".")]


def test_bad_input_exit_code_2_without_traceback(tmp_path, capsys):
    assert main(["run", "--example", "nope", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "unknown example" in err and "sandwich-2d" in err and "Traceback" not in err
    assert main(["run", "--example", "sandwich-2d", "--out", str(tmp_path),
                 "--method", "magic"]) == 2
    assert "valid" in capsys.readouterr().err


def test_levels_option(tmp_path, capsys):
    out = tmp_path / "lv"
    assert main(["run", "--example", "sandwich-2d", "--out", str(out), "--quiet", "--no-plots",
                 "--no-vtu", "--levels", "alpha:list:10,100,1000", "--mode", "0"]) == 0
    data = json.loads((out / "results.json").read_text())
    assert data["levels"]["alpha"] == [10.0, 100.0, 1000.0]
    assert main(["run", "--example", "sandwich-2d", "--out", str(out), "--levels",
                 "tip:cubic:1:2:3"]) == 2
    assert "spacing must be" in capsys.readouterr().err
    assert main(["run", "--example", "sandwich-2d", "--out", str(out), "--levels", "x"]) == 2
    assert "expected KIND" in capsys.readouterr().err


def test_locking_warning_is_printed(tmp_path, capsys):
    """nu close to 0.5: the run goes on, the CLI prints our warning (once for the two
    bodies of equal material)."""
    import shutil
    from pathlib import Path
    from qsma.examples import example_dir
    examples = example_dir()
    for name in ("sandwich-2d-bottom.inp", "sandwich-2d-top.msh"):
        shutil.copy(examples / name, tmp_path / name)
    text = (examples / "sandwich-2d.toml").read_text().replace("nu = 0.285", "nu = 0.49")
    (tmp_path / "c.toml").write_text(text)
    assert main(["modes", str(tmp_path / "c.toml"), "-n", "1", "--json"]) == 0
    captured = capsys.readouterr()
    assert captured.err.count("qsma: warning: Poisson's ratio nu = 0.49 is close to 0.5") == 1
    assert "incompatible-mode element" in captured.err
    assert json.loads(captured.out)["f_hz"][0] > 0


def test_run_process_leaves_with_its_exit_code_and_all_its_output(tmp_path):
    """``qsma run`` as a process ends by ``os._exit`` after the run (no interpreter
    teardown): the exit code is the run's, stdout and stderr are complete (flushed
    before leaving), the result folder is whole; bad input still exits 2."""
    import subprocess
    out = tmp_path / "run"
    proc = subprocess.run([sys.executable, "-m", "qsma", "run", "--example", "sandwich-2d",
                           "--levels", "tip:log:1e-6:1e-4:3", "--no-plots", "--no-vtu",
                           "--out", str(out)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    last = proc.stdout.rstrip().splitlines()[-1]
    assert last.startswith("results: ") and last.endswith("manifest.json")
    assert json.loads((out / "results.json").read_text())["success"] is True
    bad = subprocess.run([sys.executable, "-m", "qsma", "run", "--example", "sandwich-2d",
                          "--levels", "tip:nonsense", "--out", str(tmp_path / "bad")],
                         capture_output=True, text=True)
    assert bad.returncode == 2
    assert "--levels 'tip:nonsense'" in bad.stderr


def test_busy_folder_names_the_owner_that_is_still_writing_its_name(tmp_path):
    """Two runs started together: the second may find the lock taken before the first
    wrote its pid into the lock file; it waits for the name instead of calling the
    owner unknown (tests/test_adversarial.py saw that race)."""
    import fcntl
    import os
    import threading
    from qsma.errors import OutputFolderBusy
    from qsma.output.folders import RunFolder
    fd = os.open(tmp_path / ".out.qsma-lock", os.O_RDWR | os.O_CREAT, 0o666)
    fcntl.flock(fd, fcntl.LOCK_EX)
    info = json.dumps({"pid": 4242, "host": "elsewhere", "run_id": "r1"}).encode()
    threading.Timer(0.05, os.pwrite, (fd, info, 0)).start()
    try:
        with pytest.raises(OutputFolderBusy, match="pid 4242 on elsewhere"):
            with RunFolder(tmp_path / "out"):
                pass
    finally:
        os.close(fd)


#: Modules a ``qsma run`` of a built-in example never needs: parameter studies, fits
#: and reduced-order models (all in ``qsma.study``), the mesh-file readers, Dask,
#: pyplot (figures are drawn on matplotlib's Figure + Agg), scipy's interpolation and
#: optimisation (a 2D gap field and the fits need them; importing them costs a run's
#: start 0.1-0.2 s). meshio writes the VTU files: a run with ``--no-vtu`` does not
#: import it.
NOT_IMPORTED_BY_A_RUN = ("qsma.study", "qsma.model.io", "dask", "distributed",
                         "matplotlib.pyplot", "scipy.interpolate", "scipy.optimize")


@pytest.mark.parametrize("plots", [False, True])
def test_a_run_imports_only_what_it_needs(tmp_path, plots):
    """In a fresh process: ``qsma run --no-plots`` never imports matplotlib (nor
    Pillow), ``--no-vtu`` never meshio, and no run imports the modules of
    :data:`NOT_IMPORTED_BY_A_RUN`; the run still writes its files (with the figures,
    report.html and the VTU files when plotting). The
    figures are drawn in this process here (``QSMA_PLOT_WORKER=0``); with the worker
    the qsma process imports no matplotlib at all (tests/test_plot_worker.py)."""
    import subprocess
    code = ("import json, sys\nfrom qsma.cli import main\ncode = main(sys.argv[1:])\n"
            "print(json.dumps([code, sorted(sys.modules)]))")
    out = tmp_path / "run"
    args = ["run", "--example", "sandwich-2d", "--levels", "tip:log:1e-6:1e-4:3",
            "--quiet", "--out", str(out)] + ([] if plots else ["--no-plots", "--no-vtu"])
    proc = subprocess.run([sys.executable, "-c", code, *args], capture_output=True,
                          text=True, env=dict(os.environ, QSMA_PLOT_WORKER="0"))
    assert proc.returncode == 0, proc.stderr
    exit_code, modules = json.loads(proc.stdout.splitlines()[-1])
    assert exit_code == 0
    loaded = {m for m in modules if m.split(".")[0] in ("qsma", "meshio", "dask",
                                                       "distributed", "matplotlib",
                                                       "PIL", "scipy")}
    unwanted = [m for m in loaded
                if any(m == n or m.startswith(n + ".") for n in NOT_IMPORTED_BY_A_RUN)]
    assert unwanted == []
    assert ("matplotlib" in loaded) == plots and ("PIL" in loaded) == plots
    assert ("meshio" in loaded) == plots
    assert "qsma.analysis" in loaded                     # the check sees imports at all
    files = {p.name for p in out.iterdir()}
    assert {"results.json", "results.csv", "manifest.json"} <= files
    assert ({"report.html", "backbone.png", "interface.png", "fields.vtu",
             "fields.pvd"} <= files) == plots


def test_a_level_whose_loop_failed_is_written_as_null_beside_its_flag(tmp_path):
    """A level flagged loop_not_stabilised (or not_finite, loop_failed) has no f and
    zeta: results.json/csv write null / empty there and keep every other level (seen
    on stack-2d, whose whole output used to be refused); a NaN that no flag explains
    is still refused."""
    import dataclasses

    import qsma
    from qsma.errors import AnalysisError
    from qsma.examples import sandwich_2d
    from qsma.analysis.levels import Levels
    from qsma.output.files import results_dict, write_csv

    res = qsma.run(sandwich_2d(1), levels=Levels.log("tip", 1e-6, 1e-4, 4),
                   refine_levels=False)
    nan_at_1 = dict(f_hz=res.f_hz.copy(), zeta=res.zeta.copy())
    for v in nan_at_1.values():
        v[1] = np.nan
    flags = list(res.flags)
    flags[1] = tuple(flags[1]) + ("loop_not_stabilised",)
    flagged = dataclasses.replace(res, flags=tuple(flags), **nan_at_1)
    levels = results_dict(flagged)["levels"]
    assert levels["f_hz"][1] is None and levels["zeta"][1] is None
    assert levels["f_hz"][0] == pytest.approx(res.f_hz[0], rel=1e-15)
    assert levels["zeta"][2:] == pytest.approx(list(res.zeta[2:]), rel=1e-15)
    write_csv(flagged, tmp_path / "r.csv")
    rows = list(csv.DictReader(open(tmp_path / "r.csv")))
    assert rows[1]["f_hz [Hz]"] == "" and rows[1]["zeta [-]"] == "" \
        and rows[0]["f_hz [Hz]"] != ""
    with pytest.raises(AnalysisError, match="non-finite value in results.levels.f_hz"):
        results_dict(dataclasses.replace(res, **nan_at_1))
    q = res.q.copy()
    q[1] = np.nan                       # the backbone is never excused by a loop's flag
    with pytest.raises(AnalysisError, match="non-finite value in results.levels.q"):
        results_dict(dataclasses.replace(flagged, q=q))


@pytest.mark.parametrize("keep_going", [False, True])
def test_a_level_whose_loop_failed_fails_the_run_even_with_continue(tmp_path, capsys,
                                                                   monkeypatch, keep_going):
    """Loops that cannot stabilise (one cycle allowed, no repeat or agreement counts,
    no extension): every file is written, the levels are flagged, and the CLI exits 1
    with or without --continue (which covers failed contact solves only)."""
    from qsma.hysteresis import cycles as driver, refinement
    cycles = driver._cycles
    monkeypatch.setattr(driver, "CONTRACTION", 0.0)
    monkeypatch.setattr(driver, "_same", lambda *args: False)
    monkeypatch.setattr(refinement, "_cycles",
                        lambda step, modal, A, start, u, k_ref, max_cycles, rtol, atol,
                        closings=None:
                        cycles(step, modal, A, start, u, k_ref, 1, 0.0, 0.0, closings))
    argv = ["run", "--example", "sandwich-2d", "--out", str(tmp_path), "--no-plots",
            "--no-vtu", "--dissipation", "loop", "--levels", "tip:log:1e-4:1e-3:3"]
    code = main(argv + (["--continue"] if keep_going else []))
    err = capsys.readouterr().err
    data = json.loads((tmp_path / "results.json").read_text())
    flagged = [k for k, f in enumerate(data["levels"]["flags"]) if "loop_not_stabilised" in f]
    assert code == 1 and flagged and "analysis failed" in err
    assert all(data["levels"]["zeta"][k] is None for k in flagged)
    assert data["success"] is False and len(data["levels"]["alpha"]) == 3
