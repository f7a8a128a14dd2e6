"""Parameter studies: the grid, sharing of the preparation, equality with separate runs,
Dask against serial, failures, resumption, the command line, and several modes per
run (one preparation, one backbone per mode)."""
from dataclasses import replace
import json
import pickle

import numpy as np
import pytest

import qsma
from qsma.analysis import prepare, run_prepared
from qsma.cli import main
from qsma.errors import InputError
from qsma.examples import sandwich_2d
from qsma.model import Material, Pressure
from qsma.study import grid, parse_values, read_table, sweep
from qsma.reduction.condensation import RefactorisedEE
from qsma.study.runners import done_path

from helpers import in_forked_child

#: 5 levels over the spec's range of linear tied tip deflection (1 um .. 1 mm): small
#: enough for a test, wide enough to cross from stuck to gross slip on sandwich-2d.
LEVELS = qsma.Levels.log("tip", 1e-6, 1e-3, 5)
OPTIONS = qsma.RunOptions(levels=LEVELS)
#: Columns that are round-off by construction, with their absolute tolerance: the
#: asymmetry (q + q_neg) / q is ~1e-10 on sandwich-2d (contact tol 1e-10), a residual
#: is below the contact tolerance (qsma.contact.DEFAULT_TOL = 1e-10).
ROUND_OFF = {"asymmetry": 1e-9, "residual": 1e-10}
#: The fields compared between a sweep case and a separate run.
COMPARED = ("alpha", "q", "tip", "f_hz", "zeta", "dissipation", "n_stuck", "n_slip")


def scaled(model, s):
    """The model with every preload pressure multiplied by ``s`` (assembled anew)."""
    return replace(model, bodies=tuple(replace(b, pressures=tuple(
        Pressure(p.set, p.p * s, p.load) for p in b.pressures)) for b in model.bodies))


#: A damping ratio of a stuck level is round-off (~1e-11 on sandwich-2d; the analysis
#: calls |zeta| < qsma.analysis.ZETA_ZERO = 1e-8 zero): compared absolutely to this.
ZETA_ROUND_OFF = 1e-10
#: Dissipation and damping are differences of integrals of the backbone: they amplify
#: the round-off of the condensed model (its welded force W is exact to ~2e-10
#: relative: metis_superlu, splu and superlu_schur differ by that much) near gross
#: slip. Measured on the mu = 0.6, preload 1.5 case of this module: zeta and the
#: dissipation change by up to 1.1e-9 between Schur backends (separate runs), and by
#: 1.7e-9 between a prepared case and a separate run when the two beams share one
#: factorisation (qsma.reduction.congruence); with the contact tolerance at 1e-13 instead of
#: 1e-10 the numbers do not move.
INTEGRAL_RTOL = 5e-9


def _tol(name):
    """(rtol, atol) of the comparison of column ``name``."""
    if name in ("zeta", "dissipation"):
        return INTEGRAL_RTOL, ZETA_ROUND_OFF if name == "zeta" else 0.0
    return 1e-10, 0.0


def assert_close(a, b, rtol=1e-10, atol=0.0):
    """Equal to ``rtol`` relative to the largest magnitude of the column (plus ``atol``)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    scale = max(np.max(np.abs(a)), np.max(np.abs(b)), 1e-300)
    assert np.max(np.abs(a - b)) <= rtol * scale + atol, (a, b)


@pytest.fixture(scope="module")
def model():
    return sandwich_2d(1)


@pytest.fixture(scope="module")
def serial(model, tmp_path_factory):
    out = tmp_path_factory.mktemp("serial")
    return sweep(model, {"mu": [0.3, 0.6], "preload": [1.5]}, OPTIONS, out=out,
                 scheduler="serial", plots=False), out


# ------------------------------------------------------------------------------ grid

def test_grid_is_the_cartesian_product_last_fastest():
    cases = grid({"mu": "0.2:0.8:4", "preload": "0.5,1.5"})
    assert len(cases) == 8
    assert [c.as_dict()["preload"] for c in cases[:2]] == [0.5, 1.5]
    assert [c.as_dict()["mu"] for c in cases[::2]] == pytest.approx([0.2, 0.4, 0.6, 0.8])
    assert [c.name for c in cases[:2]] == ["case-0000", "case-0001"]


def test_values_of_options_are_typed():
    assert parse_values("mode", "0:2:3") == [0, 1, 2]
    assert parse_values("method", "basket,active_set") == ["basket", "active_set"]
    lv = parse_values("levels", [LEVELS, qsma.Levels("tip", (1e-5, 1e-4))])
    assert [len(v.values) for v in lv] == [5, 2]
    with pytest.raises(InputError, match="qsma.Levels"):
        parse_values("levels", "tip:log:1e-6:1e-3:5")


@pytest.mark.parametrize("name, spec, words", [
    ("friction", "0.1,0.2", "unknown sweep parameter"),
    ("mu", "0.1:0.2", "START:STOP:N"),
    ("mu", "a,b", "needs numbers"),
    ("E:middle", "1e9", "no body 'middle'"),
])
def test_bad_parameters_are_named(model, tmp_path, name, spec, words):
    with pytest.raises(InputError, match=words):
        sweep(model, {name: spec}, OPTIONS, out=tmp_path, scheduler="serial")


# ------------------------------------------------------------------ shared preparation

def test_prepared_case_equals_a_separate_run_for_mu_and_preload_scale(model, serial):
    res, out = serial
    assert res.success, res.message
    for case in res.cases:
        mu, s = case.params["mu"], case.params["preload"]
        ref = qsma.run(scaled(replace(model, mu=mu), s), OPTIONS)
        rows = [i for i, c in enumerate(res.table["case"]) if c == case.index]
        assert len(rows) == ref.n_levels == 5
        for name in COMPARED:
            assert_close([res.table[name][i] for i in rows], getattr(ref, name),
                         *_tol(name))
        info = json.loads((out / f"case-{case.index:04d}" / "results.json").read_text())
        assert info["model"]["mu"] == mu


def test_a_different_mu_changes_the_damping(serial):
    """The comparison above could pass with mu ignored: the two cases must differ."""
    res, _ = serial
    z = np.array(res.table["zeta"], float).reshape(2, 5)
    assert abs(z[0, -1] - z[1, -1]) > 1e-3 * abs(z[1, -1])


def test_tied_modes_are_reused_while_the_closed_set_is_the_same(model):
    prep = prepare(model, OPTIONS)
    run_prepared(prep.with_mu(0.3), OPTIONS)
    run_prepared(prep.with_mu(0.5), OPTIONS)
    modes = [k for k in prep.cache if k[0] == "mode"]
    preloads = [k for k in prep.cache if k[0] == "preload"]
    assert len(preloads) == 2
    assert len(modes) == 1       # sandwich-2d: mu does not change the pairs the bolt closes


def test_prepared_survives_pickling_with_its_preload_scale(model):
    prep = prepare(model, OPTIONS).with_mu(0.4).with_preload_scale(1.5)
    back = pickle.loads(pickle.dumps(prep))
    assert back.preload_scale == 1.5 and back.model.mu == 0.4
    assert back.model.bodies[0].pressures == prep.model.bodies[0].pressures
    assert_close(back.reduced.W, prep.reduced.W, 1e-12)


def test_shipped_preparation_arrives_condensed_and_runs_as_the_original(model, monkeypatch):
    """What Dask workers receive (and pass on to one another): the condensed model as
    computed (bit for bit, never condensed again, however often it is pickled), each
    body's K_EE factorised only when a solve asks for it, and a case run from it equal
    to the same case run from the original preparation."""
    import qsma.analysis
    prep = prepare(model, OPTIONS)

    def condensing(*args, **kwargs):
        raise AssertionError("condensed again")

    monkeypatch.setattr(qsma.analysis.prepared, "_condense", condensing)
    monkeypatch.setattr(qsma.analysis.stages, "_condense", condensing)
    monkeypatch.setattr(qsma.analysis.stages, "reduce_two_bodies", condensing)
    back = pickle.loads(pickle.dumps(prep))
    again = pickle.loads(pickle.dumps(back.with_mu(0.4)))        # worker to worker
    assert again.model.mu == 0.4 and np.array_equal(again.reduced.K, prep.reduced.K)
    assert type(back) is type(prep) and back.cache == {}
    for name in ("K", "W"):
        assert np.array_equal(getattr(back.reduced, name), getattr(prep.reduced, name))
    for b0, b1 in zip(prep.reduced.bodies, back.reduced.bodies):
        assert np.array_equal(b1.Kc, b0.Kc) and np.array_equal(b1.E, b0.E)
        own = getattr(b1.solve_EE, "base", b1.solve_EE)   # the top beam solves through
        assert isinstance(own, RefactorisedEE) and not own.factorised   # the bottom's
    case = dict(mu=0.4, preload=1.5)
    ref = run_prepared(prep.with_mu(0.4).with_preload_scale(1.5), OPTIONS)
    got = run_prepared(back.with_mu(0.4).with_preload_scale(1.5), OPTIONS)
    assert got.success and ref.success, case
    assert all(getattr(b.solve_EE, "base", b.solve_EE).factorised   # the tied modes
               for b in back.reduced.bodies)
    assert got.n_levels == ref.n_levels
    for name in COMPARED:
        assert_close(getattr(got, name), getattr(ref, name), *_tol(name))


@pytest.mark.parametrize("example", ["sandwich-2d", "stack-2d", "lap-2d-bolted",
                                     "lap-2d-free"])
def test_refactorised_K_EE_solves_as_the_condensation_factor(example):
    """Two bodies, several interfaces, bolts, a body held only by the joint: the
    factor remade from the assembled body inverts the condensation's K_EE (same
    operator to round-off: measured 1e-14 to 2e-13 relative)."""
    from qsma.examples import EXAMPLES
    prep = prepare(EXAMPLES[example](), OPTIONS)
    back = pickle.loads(pickle.dumps(prep))
    rng = np.random.default_rng(7)
    for b0, b1 in zip(prep.reduced.bodies, back.reduced.bodies):
        x = rng.standard_normal((b1.solve_EE.n, 2))
        assert_close(b1.solve_EE(x), b0.solve_EE(x), 1e-11)
        assert_close(b1.solve_EE(x[:, 0]), b0.solve_EE(x[:, 0]), 1e-11)
        assert b1.solve_EE(x[:, :0]).shape == (b1.solve_EE.n, 0)
        with pytest.raises(InputError, match="right-hand side"):
            b1.solve_EE(x[:-1])


def test_material_of_one_body_reassembles_that_body_only(model, tmp_path):
    res = sweep(model, {"E:bottom": [150e9]}, OPTIONS, out=tmp_path, scheduler="serial",
                plots=False)
    bottom = model.bodies[0]
    changed = replace(model, bodies=(replace(bottom, material=Material(
        150e9, bottom.material.nu, bottom.material.rho)), model.bodies[1]))
    ref = qsma.run(changed, OPTIONS)
    for name in ("q", "f_hz", "zeta"):
        assert_close(res.table[name], getattr(ref, name), *_tol(name))


# ------------------------------------------------------------- failures and resumption

def test_a_failing_case_is_recorded_and_the_others_go_on(model, tmp_path):
    res = sweep(model, {"mode": [7, 0]}, OPTIONS.replace(n_modes=6), out=tmp_path,
                scheduler="serial", plots=False, files=("rom",))
    assert not res.success and res.n_failed == 1
    bad, good = res.cases
    assert bad.status == "failed" and "mode index 7" in bad.message
    assert good.status == "ok"
    table = read_table(tmp_path / "study.csv")
    assert table["status"].count("failed") == 1 and table["level"][0] == ""
    assert len(table["case"]) == 1 + 5
    assert json.loads(done_path(tmp_path / "case-0000").read_text())["status"] == "failed"
    assert (tmp_path / "case-0001.rom.json").exists()
    assert not (tmp_path / "case-0000.rom.json").exists()


def test_an_interrupted_study_resumes_with_the_cases_not_done(model, serial, tmp_path):
    res, out = serial
    import shutil
    shutil.copytree(out, tmp_path, dirs_exist_ok=True)
    done_path(tmp_path / "case-0001").unlink()        # as if killed during case 1
    again = sweep(model, {"mu": [0.3, 0.6], "preload": [1.5]}, OPTIONS, out=tmp_path,
                  scheduler="serial", plots=False)
    assert [c.skipped for c in again.cases] == [True, False]
    for name in COMPARED:
        assert_close(again.table[name], res.table[name], 1e-10)
    with pytest.raises(InputError, match="another study"):
        sweep(model, {"mu": [0.2]}, OPTIONS, out=tmp_path, scheduler="serial")
    # the same cases with other levels would mix two studies' results: refused
    with pytest.raises(InputError, match="other run options"):
        sweep(model, {"mu": [0.3, 0.6], "preload": [1.5]},
              OPTIONS.replace(levels=qsma.Levels.log("tip", 1e-6, 1e-3, 3)), out=tmp_path,
              scheduler="serial")


def test_a_failed_case_is_retried_on_resume(model, tmp_path):
    """A failure may pass (a full disk): resuming runs a failed case again."""
    first = sweep(model, {"mode": [7]}, OPTIONS.replace(n_modes=6), out=tmp_path,
                  scheduler="serial", plots=False)
    again = sweep(model, {"mode": [7]}, OPTIONS.replace(n_modes=6), out=tmp_path,
                  scheduler="serial", plots=False)
    assert first.cases[0].status == again.cases[0].status == "failed"
    assert not again.cases[0].skipped


# ------------------------------------------------------------------------------ Dask

def test_two_dask_workers_give_the_serial_table(model, serial, tmp_path):
    """A two-worker local cluster of processes, reached by address as with
    ``--scheduler tcp://host:port`` (the sweep connects its own client): the serial
    table. In a forked child: a Dask client leaves its IO loop thread behind, which
    would keep the rest of the session from forking (the -alpha ramp's child)."""
    distributed = pytest.importorskip("distributed")
    import logging
    res, _ = serial

    def body():
        with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                      dashboard_address=None,
                                      silence_logs=logging.ERROR) as cluster, \
                distributed.Client(cluster) as client:
            par = sweep(model, {"mu": [0.3, 0.6], "preload": [1.5]}, OPTIONS,
                        out=tmp_path, scheduler=cluster.scheduler_address, plots=False)
            assert par.success, par.message
            assert len(client.scheduler_info()["workers"]) == 2
        assert list(par.table) == list(res.table)
        for name, col in res.table.items():
            if name in ROUND_OFF:
                assert np.allclose(par.table[name], col, rtol=0, atol=ROUND_OFF[name]), name
            elif isinstance(col[0], (float, int)) and not isinstance(col[0], bool):
                assert_close(par.table[name], col, 1e-10)
            else:
                assert par.table[name] == col, name
    in_forked_child(body)


# ----------------------------------------------------------------------- command line

def test_cli_sweep_writes_the_table_and_figures(tmp_path):
    out = tmp_path / "study"
    rc = main(["sweep", "--example", "sandwich-2d", "--vary", "mu=0.3,0.6",
               "--levels", "tip:log:1e-6:1e-3:3", "--workers", "0", "--out", str(out), "-q"])
    assert rc == 0
    table = read_table(out / "study.csv")
    assert table["mu"] == ["0.3"] * 3 + ["0.6"] * 3
    assert (out / "sweep_mu.png").stat().st_size > 0
    assert (out / "case-0001" / "results.json").exists()


def test_cli_levels_as_a_varied_parameter(tmp_path):
    out = tmp_path / "study"
    rc = main(["sweep", "--example", "sandwich-2d", "--vary",
               "levels=tip:log:1e-6:1e-3:3;tip:list:1e-6,1e-3", "--workers", "0",
               "--no-plots", "--out", str(out), "-q"])
    assert rc == 0
    table = read_table(out / "study.csv")
    assert table["case"] == ["0"] * 3 + ["1"] * 2
    assert table["tip_lin"][-1] == table["tip_lin"][2] == "0.001"


def test_cli_names_a_bad_vary(tmp_path, capsys):
    rc = main(["sweep", "--example", "sandwich-2d", "--vary", "mu", "--out", str(tmp_path)])
    assert rc == 2
    assert "expected NAME=VALUES" in capsys.readouterr().err


# ------------------------------------------------------------- several modes per run

def test_run_modes_equal_separate_runs_and_write_the_shapes(tmp_path):
    """Modes 0 and 1 from one preparation equal separate runs of each mode; the VTU
    holds the tied mode shapes of the results, mass-normalised."""
    import meshio
    from qsma.study.modes import run_modes
    model = sandwich_2d(1)
    out = run_modes(model, [0, 1], OPTIONS, out=tmp_path, plots=False, vtu=False)
    assert out.success and set(out.results) == {0, 1}
    for m in (0, 1):
        alone = qsma.run(model, OPTIONS, mode=m)
        res = out.results[m]
        assert res.mode_index == m
        for name in COMPARED:
            assert_close(getattr(res, name), getattr(alone, name), *_tol(name))
        assert json.loads((tmp_path / f"mode-{m}" / "results.json").read_text())[
            "mode"]["index"] == m
    summary = json.loads((tmp_path / "modes.json").read_text())
    assert [e["mode"] for e in summary["modes"]] == [0, 1]
    mesh = meshio.read(tmp_path / "modes.vtu")
    shapes = out.results[0].modes.shapes
    for k in range(shapes.shape[1]):
        np.testing.assert_array_equal(mesh.point_data[f"mode_{k:02d}"][:, :2],
                                      shapes[:, k].reshape(-1, 2))
    assert out.results[0].modes.f_hz[1] == pytest.approx(out.results[1].f0_hz, rel=1e-12)


def test_cli_run_modes_records_a_mode_that_cannot_run(tmp_path, capsys):
    """Mode 2 of sandwich-2d is axial (no tip deflection): recorded with its message,
    mode 0 is written, exit code 1."""
    code = main(["run", "--example", "sandwich-2d", "--modes", "0,2", "--levels",
                 "tip:log:1e-6:1e-3:3", "--no-plots", "--no-vtu", "--out",
                 str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert code == 1 and "mode 2" in err and "no tip deflection" in err
    summary = json.loads((tmp_path / "r" / "modes.json").read_text())["modes"]
    assert [e["success"] for e in summary] == [True, False]
    assert (tmp_path / "r" / "mode-0" / "results.json").exists()
    assert not (tmp_path / "r" / "mode-2").exists()
    assert main(["run", "--example", "sandwich-2d", "--modes", "0,0", "--out",
                 str(tmp_path / "x")]) == 2


def test_cli_modes_out_writes_vtu_and_json(tmp_path, capsys):
    import meshio
    assert main(["modes", "--example", "sandwich-2d", "-n", "3", "--json", "--out",
                 str(tmp_path)]) == 0
    printed = json.loads(capsys.readouterr().out)
    written = json.loads((tmp_path / "modes.json").read_text())
    assert written["f_hz"] == printed["f_hz"] and len(written["f_hz"]) == 3
    assert sorted(k for k in meshio.read(tmp_path / "modes.vtu").point_data
                  if k.startswith("mode_")) == ["mode_00", "mode_01", "mode_02"]


def test_the_fingerprint_ignores_loop_workers_only():
    """A study resumes whatever the number of loop workers (they change no result),
    but not after a change of an option that does."""
    from qsma.examples import sandwich_2d
    from qsma.analysis.options import RunOptions
    from qsma.study.sweep import _fingerprint
    model = sandwich_2d()
    base = _fingerprint(model, RunOptions())
    assert _fingerprint(model, RunOptions(loop_workers=2)) == base
    assert _fingerprint(model, RunOptions(loop_scheduler="tcp://host:8786")) == base
    assert _fingerprint(model, RunOptions(dissipation_rtol=1e-3)) != base


def test_the_execution_options_are_one_record_left_out_of_fingerprint_and_sweep():
    """The options that change no result are named once (EXECUTION_FIELDS, read as an
    Execution record); the fingerprint and the sweep leave out exactly those (and the
    sweep the BLAS threads and the condensation backend it fixes), and every other
    option is fingerprinted."""
    import importlib
    from qsma.analysis.options import EXECUTION_FIELDS, Execution, RunOptions
    from qsma.study.cases import NOT_SWEPT
    sweep_module = importlib.import_module("qsma.study.sweep")
    assert EXECUTION_FIELDS == ("loop_workers", "loop_scheduler", "parallel_ramps")
    assert sweep_module.NOT_FINGERPRINTED == EXECUTION_FIELDS
    assert set(NOT_SWEPT) == set(EXECUTION_FIELDS) | {"blas_threads", "schur_backend"}
    opts = RunOptions(loop_workers=2, parallel_ramps=False)
    assert opts.execution == Execution(loop_workers=2, parallel_ramps=False)
    assert opts.loop_worker_count == 2
    assert set(opts.results_options()) == set(opts.as_dict()) - set(EXECUTION_FIELDS)
    with pytest.raises(InputError, match="parallel_ramps must be true or false"):
        RunOptions(parallel_ramps="yes")


def test_a_case_computes_its_loops_itself_whatever_the_loop_scheduler():
    """The study's workers are its parallel part: a case on one of them that handed its
    loops to the same scheduler could wait for workers that all wait for loops."""
    from qsma.analysis.options import RunOptions
    from qsma.study.cases import case_inputs
    _, opts = case_inputs(object(), {"mode": 1},
                          RunOptions(loop_scheduler="tcp://host:8786"))
    assert opts.loop_scheduler is None and opts.mode == 1


def test_the_fingerprint_of_auto_is_the_method_it_runs_in_2d():
    """``method="auto"`` (the default) runs ``basket`` in 2D, the default of earlier
    versions, so their 2D studies still resume; in 3D the choice depends on the pair
    count, so auto is fingerprinted as itself and differs from an explicit method."""
    from qsma.examples import lap_3d, sandwich_2d
    from qsma.analysis.options import RunOptions
    from qsma.study.sweep import _fingerprint
    flat = sandwich_2d()
    assert _fingerprint(flat, RunOptions()) == _fingerprint(flat, RunOptions(method="basket"))
    assert _fingerprint(flat, RunOptions()) != _fingerprint(flat,
                                                            RunOptions(method="active_set"))
    solid = lap_3d()
    assert _fingerprint(solid, RunOptions()) != _fingerprint(solid,
                                                             RunOptions(method="basket"))
