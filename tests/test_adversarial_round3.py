"""An adversarial user of the newer surfaces: several bodies and interfaces, parts and
instances, sweeps, fits and the folders of every command.

Each test is one way a wrong answer could be reported as success, a folder left
inconsistent, an internal error, or a bad input refused only after computing.
"""
from dataclasses import replace
from pathlib import Path
import re

import numpy as np
import pytest

import qsma
from qsma.cli import main
from qsma.analysis.config import load_config
from qsma.errors import AnalysisError, InputError
from qsma.examples import stack_2d
from qsma.model import Pressure
from qsma.output.folders import verify_run_folder
from qsma.examples import example_dir

from helpers import STACK_INTERFACES, stack_toml

EXAMPLES = example_dir()        # the example files shipped with qsma
STACK_LEVELS = qsma.Levels.log("tip", 1e-6, 1e-4, 3)


# ---- wrong answers reported as success --------------------------------------------

def test_a_stack_whose_second_interface_opens_is_refused():
    """The top plate's bolt pressure pulls (negative): the preload opens every pair of
    the second interface and the top plate vibrates alone. Refused as the two-body
    path refuses a preload that opens the whole interface."""
    model = stack_2d(1)
    top = model.bodies[2]
    pulled = replace(top, pressures=(Pressure("bolt", -top.pressures[0].p),))
    model = replace(model, bodies=model.bodies[:2] + (pulled,))
    with pytest.raises(AnalysisError, match="no pair of interface middle.upper / top.lower"):
        qsma.run(model, levels=STACK_LEVELS)


@pytest.fixture
def stack_config(tmp_path):
    """stack-2d as a configuration whose two [[interfaces]] set their own mu (0.6, 0.3)."""
    path, _ = stack_toml(tmp_path, STACK_INTERFACES)
    return path


def _no_case_computed(monkeypatch):
    """Make any computation of the model fail the test: refusals must come first."""
    import qsma.analysis as analysis

    def computed(*a, **k):
        raise AssertionError("computed before refusing")
    monkeypatch.setattr(analysis, "prepare", computed)
    monkeypatch.setattr(analysis, "run", computed)


@pytest.mark.parametrize("argv", [
    ["run", "--mu", "0.1"],
    ["sweep", "--vary", "mu=0.2,0.4", "--workers", "0"],
    ["fit", "--params", "mu", "--measured", "MEASURED"],
], ids=["run --mu", "sweep --vary mu", "fit --params mu"])
def test_a_model_wide_mu_is_refused_where_the_interfaces_set_their_own(
        stack_config, tmp_path, capsys, monkeypatch, argv):
    """--mu (and a study of mu) on a model whose interfaces set their own mu: the
    model's mu would reach no interface, so the numbers would be those without it.
    Refused with the fix before anything is computed."""
    measured = tmp_path / "m.csv"
    measured.write_text("tip_m,f_hz\n1e-6,200\n1e-5,199\n")
    argv = [str(measured) if a == "MEASURED" else a for a in argv]
    _no_case_computed(monkeypatch)
    code = main([argv[0], str(stack_config), *argv[1:], "--out", str(tmp_path / "out"),
                 "--quiet"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "bottom.bottom_upper / middle.middle_lower sets its own mu = 0.6" in err
    assert "Fix:" in err
    assert not (tmp_path / "out").exists()


def _example_config(folder):
    """The example sandwich-2d.toml and its meshes copied to ``folder`` (levels and the
    direct loop trimmed for speed); returns the configuration's path."""
    import shutil
    for name in ("sandwich-2d.toml", "sandwich-2d-bottom.inp", "sandwich-2d-top.msh"):
        shutil.copy(EXAMPLES / name, folder / name)
    path = folder / "sandwich-2d.toml"
    text = path.read_text().replace("direct_loop = true", "direct_loop = false")
    path.write_text(text.replace("n = 51", "n = 3").replace("stop = 1e-3", "stop = 1e-5"))
    return path


@pytest.mark.parametrize("edit", [
    ("*NSET, NSET=clamp\n1, 126, 251, 376, 501, 626, 751, 876, 1001\n",
     "*NSET, NSET=clamp\n1, 126, 251, 376, 501, 626, 751, 876\n"),
    ("*ELSET, ELSET=_bolt_S1, INTERNAL\n", None),
], ids=["clamp nodes", "bolt surface halved"])
def test_a_study_of_an_edited_model_is_not_resumed(tmp_path, capsys, edit):
    """A sweep resumed after editing the contents of a set (names unchanged) must not
    take the old cases as done: the fingerprint covers what the model is."""
    config = _example_config(tmp_path)
    argv = ["sweep", str(config), "--vary", "mu=0.5", "--workers", "0", "--no-plots",
            "--out", str(tmp_path / "study"), "--quiet"]
    assert main(argv) == 0
    inp = tmp_path / "sandwich-2d-bottom.inp"
    text = inp.read_text()
    old, new = edit
    if new is None:                      # keep the first half of the bolt's facet rows
        start = text.index(old) + len(old)
        rows = text[start:text.index("*", start)].split("\n")[:-1]
        ids = ", ".join(rows).split(", ")
        new = old + ", ".join(ids[:len(ids) // 2]) + "\n"
        old = old + "\n".join(rows) + "\n"
    assert old in text
    inp.write_text(text.replace(old, new))
    assert main(argv) == 2
    assert "another model" in capsys.readouterr().err


@pytest.mark.parametrize("cut_after", [
    "*NSET, NSET=clamp\n1, 126, 251, 37",            # mid-row in the clamp's node set
    "*ELSET, ELSET=_outer_S1, INTERNAL\n1, 2, 3, 4, 5, 6, 7",     # mid-row in an *ELSET
], ids=["mid-nset", "mid-elset"])
def test_a_truncated_abaqus_file_is_refused(tmp_path, cut_after):
    """An .inp file cut off inside a data row (an interrupted copy): the clamp silently
    lost nodes (f0 = 216.55 Hz instead of 212.54). The unterminated last row says so."""
    from qsma.errors import MeshFileError
    from qsma.model import read_mesh
    text = (EXAMPLES / "sandwich-2d-bottom.inp").read_text()
    assert cut_after in text
    path = tmp_path / "cut.inp"
    path.write_text(text[:text.index(cut_after) + len(cut_after)])
    with pytest.raises(MeshFileError, match=r"cut\.inp, line \d+: the file ends inside the "
                                            r"data line .*cut off"):
        read_mesh(path)


def test_a_node_row_short_of_the_cells_dimension_is_refused(tmp_path):
    """A node row with one coordinate in a 2D mesh (a row cut short) would put the node
    at y = 0 silently."""
    from qsma.errors import MeshFileError
    from qsma.model import read_mesh
    text = (EXAMPLES / "sandwich-2d-bottom.inp").read_text()
    row = next(line for line in text.splitlines() if line.startswith("130,"))
    path = tmp_path / "short.inp"
    path.write_text(text.replace(row + "\n", row[:row.rindex(",")] + "\n", 1))
    with pytest.raises(MeshFileError, match=r"short\.inp, line 135: node row '130, .*' gives "
                                            r"1 coordinate\(s\), but the cells are 2D"):
        read_mesh(path)


@pytest.mark.parametrize("mu", [0.0, 1e4], ids=["mu=0", "mu=1e4"])
def test_a_cycle_in_which_no_pair_rubs_dissipates_exactly_nothing(mu):
    """mu = 0 (every pair slips, without friction) and mu = 1e4 (every pair sticks): no
    pair dissipates, so D and zeta are exactly 0, not round-off of either sign
    (-3.2e-13 was reported as a successful damping ratio)."""
    from qsma.examples import sandwich_2d
    res = qsma.run(sandwich_2d(1, mu=mu), levels=qsma.Levels.log("tip", 1e-6, 1e-3, 7))
    assert res.success, res.message
    assert np.all(res.dissipation == 0.0) and np.all(res.zeta == 0.0)
    assert np.all(res.dissipation_masing == 0.0)


def _level_columns(D, err, use_loop=False, n=1):
    """The :class:`qsma.analysis.Dissipation` :func:`qsma.analysis._flags` reads, for
    one dissipation."""
    from qsma.analysis import Dissipation
    col = lambda v: np.full(n, v, float)
    return Dissipation(use_loop=np.full(n, use_loop), f_hz_loop=col(np.nan),
                       f_hz_masing=col(0.9), zeta_loop=col(np.nan),
                       zeta_masing=col(D / (2 * np.pi)), loop_error=col(np.nan),
                       masing_error=col(err), dissipation_loop=col(np.nan),
                       dissipation_masing=col(D), dissipation_first_cycle=col(np.nan),
                       loop_cycles=np.zeros(n, int), method_reason=np.full(n, "", object),
                       shakedown=np.zeros(n, bool), no_slip=np.zeros(n, bool),
                       linear=np.zeros(n, bool))


def test_negative_dissipation_beyond_round_off_fails_whatever_its_error_estimate():
    """A negative D beyond the round-off bound (zeta < -1e-8) is a failure even when the
    error estimate exceeds |D| (a middle body with E = 1e300 gave D = -9790 J with only
    information flags), unless that estimate is negligible as a damping ratio
    (test_lap.py::test_a_negligible_negative_loop_within_its_estimate_is_zero_not_a_failure);
    one within the round-off bound is reported as exactly 0."""
    from qsma.analysis import _flags, _settle_dissipation
    from qsma.analysis.options import RunOptions
    args = (np.ones(1), np.ones(1), np.ones(1))          # alpha, q, tip: energy scale 1
    real = _level_columns(D=-1e-4, err=1e-3)
    flags = _flags(*args, real, 2 * np.pi, RunOptions())
    assert "negative_dissipation" in flags[0]
    _settle_dissipation(real, flags, np.ones(1), np.ones(1))
    assert real.dissipation_masing[0] == -1e-4          # kept beside its flag
    noise = _level_columns(D=-3e-13, err=1e-14)
    flags = _flags(*args, noise, 2 * np.pi, RunOptions())
    assert "negative_dissipation" not in flags[0]
    _settle_dissipation(noise, flags, np.ones(1), np.ones(1))
    assert noise.dissipation_masing[0] == 0.0 and noise.zeta_masing[0] == 0.0


def test_a_loop_where_no_pair_with_friction_slipped_is_elastic_whatever_its_quadrature():
    """Where no pair with friction slipped on either ramp (a frictionless joint whose
    pairs open and close: the public CalculiX decks hueeber1 and hueeber3 gave
    D = -3e-8 J with an estimate of 3e-7 J and failed the run), the cycle is elastic:
    D, zeta and the error are exactly 0, with neither a negative_dissipation nor an
    integration_error_above_rtol flag. The same value with a slipping pair keeps both."""
    from qsma.analysis import _flags, _settle_dissipation
    from qsma.analysis.options import RunOptions
    args = (np.ones(1), np.ones(1), np.ones(1))
    elastic = _level_columns(D=-1e-4, err=1e-3)
    elastic.no_slip[:] = True
    flags = _flags(*args, elastic, 2 * np.pi, RunOptions())
    assert not {"negative_dissipation", "integration_error_above_rtol"} & set(flags[0])
    _settle_dissipation(elastic, flags, np.ones(1), np.ones(1))
    assert elastic.dissipation_masing[0] == 0.0 and elastic.zeta_masing[0] == 0.0
    assert elastic.masing_error[0] == 0.0
    rubbing = _level_columns(D=-1e-4, err=1e-3)
    flags = _flags(*args, rubbing, 2 * np.pi, RunOptions())
    assert {"negative_dissipation", "integration_error_above_rtol"} <= set(flags[0])


def test_masing_needs_backbones_that_mirror_not_only_equal_dissipations():
    """Two straight backbones of different slopes (pairs left at the friction limit by a
    tangential preload slip one way only) both give a Masing dissipation of 0; they are
    no mirror images, so Masing's rules are not verified there."""
    from qsma.hysteresis import masing_checks
    alpha = np.linspace(1.0, 5.0, 5)
    q_pos, q_neg = 2.37 * alpha, -0.48 * 2.37 * alpha         # both straight lines
    P = np.ones((5, 3))
    shut = np.zeros((5, 3), bool)
    checks = masing_checks(alpha, q_pos, q_neg, P, P, P[0], shut, shut, shut[0], k_ref=1.0,
                           rtol=5e-3, atol=1e-12)
    assert not checks.valid.any()
    assert "peak modal amplitudes differ" in checks.reason[0]


def test_a_preload_that_leaves_every_pair_slipping_is_flagged_at_the_first_level(capsys):
    """A pressure on the bottom plate's end face shears the interface until every closed
    pair slips in the preload. The first loading then slides (tip 2.37 times the linear
    one) while the settled cycle is elastic (f = f0, zeta = 0): flagged as a shakedown,
    with a note from the command line, instead of three numbers that disagree."""
    from qsma.cli.run import _warn_flags
    from qsma.contact import SLIPPING
    from qsma.examples import sandwich_2d
    model = sandwich_2d(1)
    bottom = model.bodies[0]
    sheared = replace(bottom, pressures=bottom.pressures + (Pressure("end", 1e8),))
    model = replace(model, bodies=(sheared, model.bodies[1]))
    res = qsma.run(model, levels=qsma.Levels.log("tip", 1e-6, 1e-5, 3))
    closed = res.preload.status != 2
    assert np.all(res.preload.status[closed] == SLIPPING)
    assert res.tip[0] / res.tip_lin[0] > 2                # the first loading slides
    assert "shakedown" in res.flags[0]
    _warn_flags(res)
    assert "shakedown) at level(s) [0" in capsys.readouterr().err


def test_plane_stress_bottom_plate_is_not_a_stuck_level_misfire(tmp_path):
    """sandwich-2d with a CPS4 (plane stress) bottom plate is a valid, slightly
    asymmetric joint: its -alpha ramp starts slipping before the +alpha one, so the
    level where only that side slips dissipates. It was flagged stuck_not_linear (the
    untouched test read the +alpha states alone) and the run failed."""
    config = _example_config(tmp_path)
    inp = tmp_path / "sandwich-2d-bottom.inp"
    inp.write_text(inp.read_text().replace("TYPE=CPE4", "TYPE=CPS4"))
    cfg = load_config(config)
    res = qsma.run(cfg.model, cfg.options.replace(
        levels=qsma.Levels.log("tip", 1e-5, 1.6e-5, 4)))
    assert res.success, res.message
    # a level whose +alpha states are those of the preload dissipates on -alpha
    stuck_on_top = [k for k in range(res.n_levels) if np.all(res.states.status[k] ==
                                                              res.preload.status)]
    assert any(res.zeta[k] > 1e-6 for k in stuck_on_top)


def _tetrahedral_lap_3d():
    """lap-3d with each hexahedron split into six tetrahedra (the sets made again on
    the tetrahedral meshes, as the example makes them)."""
    from qsma.examples import lap_3d
    from qsma.examples.lap import LAP_3D, _sets
    from helpers import tetrahedra_of
    s, model = LAP_3D, lap_3d(1)
    L, c, t, b, a = s["L"], s["c"], s["t"], s["b"], s["a_washer"]
    patch = lambda p: ((np.abs(p[:, 0] - (L - c / 2)) <= a / 2 + 1e-9 * L)
                       & (np.abs(p[:, 2] - b / 2) <= a / 2 + 1e-9 * L))
    bodies = []
    for body, bottom in zip(model.bodies, (True, False)):
        mesh = _sets(tetrahedra_of(body.mesh), s, y_if=t, y_out=0.0 if bottom else 2 * t,
                     x_clamp=0.0 if bottom else 2 * L - c, patch=patch)
        bodies.append(replace(body, mesh=mesh))
    return replace(model, bodies=tuple(bodies))


#: the first three default levels of a run (tip:log:1e-6:1e-3:51)
FIRST_TIPS = tuple(10.0 ** (-6 + 3 * np.arange(3) / 50))


def test_a_slow_shakedown_of_a_tetrahedral_lap_joint_is_followed_to_its_end():
    """The tetrahedral lap-3d's loop at its third default level contracts by 0.78 to
    0.85 per cycle and repeats after about 27 cycles: no misfire of loop_not_stabilised
    (the run failed at 8 cycles, its message 'values the physics forbids')."""
    res = qsma.run(_tetrahedral_lap_3d(), levels=qsma.Levels("tip", FIRST_TIPS))
    assert res.success, res.message
    assert res.loop_cycles[2] > 16


def test_a_loop_stopped_by_max_cycles_says_which_max_cycles_would_do():
    """The run's message names the flag, its levels and what to change, the loop's own
    message with the max_cycles it needs."""
    res = qsma.run(_tetrahedral_lap_3d(), levels=qsma.Levels("tip", FIRST_TIPS),
                   max_cycles=4)
    assert not res.success
    assert "physics forbids" not in res.message
    m = re.search(r"loop_not_stabilised at level\(s\) \[2\]: .*raise max_cycles to (\d+)",
                  res.message)
    assert m, res.message
    again = qsma.run(_tetrahedral_lap_3d(), levels=qsma.Levels("tip", FIRST_TIPS),
                     max_cycles=int(m.group(1)))
    assert again.success, again.message


# ---- folders: one protocol for every command ------------------------------------------

QUICK = ["--example", "sandwich-2d", "--levels", "tip:log:1e-6:1e-4:3", "--no-plots"]


@pytest.fixture
def finished_run(tmp_path):
    """A result folder of one complete `qsma run`."""
    out = tmp_path / "run"
    assert main(["run", *QUICK, "--no-vtu", "--quiet", "--out", str(out)]) == 0
    return out, verify_run_folder(out)["run_id"]


@pytest.mark.parametrize("argv", [
    ["run", *QUICK, "--out", "{run}/sub"],
    ["run", *QUICK, "--out", "{run}/a/b"],
    ["run", *QUICK, "--modes", "0,1", "--out", "{run}"],
    ["run", *QUICK, "--modes", "0", "--out", "{run}/modes"],
    ["modes", "--example", "sandwich-2d", "--out", "{run}"],
    ["sweep", "--example", "sandwich-2d", "--vary", "mu=0.5", "--workers", "0",
     "--no-plots", "--out", "{run}"],
    ["sweep", "--example", "sandwich-2d", "--vary", "mu=0.5", "--workers", "0",
     "--no-plots", "--out", "{run}/study"],
    ["fit", "--example", "sandwich-2d", "--measured", "{csv}", "--params", "mu",
     "--out", "{run}"],
], ids=["run inside", "run two below", "run --modes over", "run --modes inside",
        "modes over", "sweep over", "sweep inside", "fit over"])
def test_no_command_writes_into_or_over_a_finished_run(finished_run, tmp_path, capsys,
                                                       monkeypatch, argv):
    """Every command refuses, before computing, a folder that is or lies inside the
    result folder of another command: the run folder keeps its manifest and files."""
    out, run_id = finished_run
    csv = tmp_path / "m.csv"
    csv.write_text("tip_m,f_hz\n1e-5,212\n2e-5,211\n")
    _no_case_computed(monkeypatch)
    argv = [a.format(run=out, csv=csv) for a in argv]
    assert main(argv + ["--quiet"] * (argv[0] != "modes")) == 2
    err = capsys.readouterr().err
    assert "lies inside" in err or "holds the result of qsma run" in err, err
    assert verify_run_folder(out)["run_id"] == run_id
    assert sorted(p.name for p in out.iterdir()) == ["manifest.json", "qsma.log",
                                                     "results.csv", "results.json"]


def test_every_command_leaves_a_locked_checked_manifest(tmp_path, capsys):
    """run --modes, modes and sweep write complete result folders of their kind; a
    later run of another kind into them is refused."""
    argv = {"run-modes": ["run", *QUICK, "--no-vtu", "--modes", "0,1"],
            "modes": ["modes", "--example", "sandwich-2d", "-n", "2"],
            "study": ["sweep", "--example", "sandwich-2d", "--vary", "mu=0.5,0.6",
                      "--levels", "tip:log:1e-6:1e-4:3", "--workers", "0", "--no-plots"]}
    for kind, args in argv.items():
        out = tmp_path / kind
        assert main(args + ["--out", str(out)]) == 0
        manifest = verify_run_folder(out)
        assert manifest["kind"] == kind
        assert main(["run", *QUICK, "--quiet", "--out", str(out)]) == 2
        assert f"not of qsma run" in capsys.readouterr().err
    assert verify_run_folder(tmp_path / "run-modes" / "mode-0")["kind"] == "run"


def test_fewer_modes_into_the_same_folder_leave_no_stale_mode_folder(tmp_path):
    """--modes 0,1 then --modes 1: the folder is replaced as a whole, mode-0 goes."""
    out = tmp_path / "m"
    assert main(["run", *QUICK, "--no-vtu", "--quiet", "--modes", "0,1", "--out",
                 str(out)]) == 0
    assert main(["run", *QUICK, "--no-vtu", "--quiet", "--modes", "1", "--out",
                 str(out)]) == 0
    assert not (out / "mode-0").exists() and (out / "mode-1").is_dir()
    assert verify_run_folder(out)["kind"] == "run-modes"


def test_a_second_study_on_a_folder_in_use_is_refused_before_computing(tmp_path, capsys,
                                                                       monkeypatch):
    """Two identical sweeps into one folder: the second is refused while the first
    holds the study's lock (every case ran twice, and the loser's table once marked a
    sound case failed)."""
    from qsma.output.folders import StudyFolder
    from qsma.study.sweep import _in_study
    _no_case_computed(monkeypatch)
    with StudyFolder(tmp_path / "study", allowed=_in_study):
        code = main(["sweep", "--example", "sandwich-2d", "--vary", "mu=0.5", "--workers",
                     "0", "--quiet", "--out", str(tmp_path / "study")])
    assert code == 2
    assert "in use by another qsma run" in capsys.readouterr().err


def test_a_sweep_into_a_folder_of_foreign_files_is_refused(tmp_path, capsys, monkeypatch):
    (tmp_path / "study").mkdir()
    (tmp_path / "study" / "notes.txt").write_text("mine")
    _no_case_computed(monkeypatch)
    assert main(["sweep", "--example", "sandwich-2d", "--vary", "mu=0.5", "--workers", "0",
                 "--quiet", "--out", str(tmp_path / "study")]) == 2
    assert "'notes.txt'" in capsys.readouterr().err
    assert (tmp_path / "study" / "notes.txt").read_text() == "mine"


@pytest.mark.parametrize("command", ["run", "fit"])
def test_an_output_that_cannot_be_a_folder_is_refused_before_computing(
        tmp_path, capsys, monkeypatch, command):
    """--out on a loop of symbolic links (the run computed, then exited 1), or on an
    existing file for qsma fit (refused only after every evaluation)."""
    import os
    loop = tmp_path / "loop"
    os.symlink(tmp_path / "other", loop)
    os.symlink(loop, tmp_path / "other")
    a_file = tmp_path / "a-file"
    a_file.write_text("x")
    csv = tmp_path / "m.csv"
    csv.write_text("tip_m,f_hz\n1e-5,212\n2e-5,211\n")
    _no_case_computed(monkeypatch)
    for out, match in ((loop, "leads nowhere"), (a_file, "is not a folder")):
        argv = (["run", *QUICK] if command == "run" else
                ["fit", "--example", "sandwich-2d", "--measured", str(csv), "--params",
                 "mu"])
        assert main(argv + ["--quiet", "--out", str(out)]) == 2
        assert match in capsys.readouterr().err


# ---- Abaqus parts and instances --------------------------------------------------------

PART_DECK = """\
*Part, name=Beam
*Node
1, 0., 0.
2, 1., 0.
3, 1., 1.
4, 0., 1.
*Element, type=CPS4
1, 1, 2, 3, 4
*End Part
*Assembly, name=Assembly
*Instance, name=Lower, part=Beam
*End Instance
*Instance, name=Upper, part=Beam
{placement}*End Instance
*End Assembly
"""


@pytest.mark.parametrize("placement, match", [
    ("a, b, c\n", r"line 14: cannot read the translation line 'a, b, c' of \*INSTANCE; "
                  r"expected numbers"),
    ("0., 1., 0., 7., 7.\n", r"line 14: the translation line .* has 5 values, it holds "
                             r"at most 3"),
    ("0., 0., 0.\n1., 1., 0., 1., 1., 0., 90.\n",
     r"line 15: the rotation of \*INSTANCE by 90 degrees is about an axis from a point to "
     r"itself"),
    ("0., 1., 0.\n0., 0., 0., 0., 0., 1., 90.\n1.\n", r"line 16: a third data line"),
], ids=["not numbers", "five values", "zero-length axis", "third line"])
def test_an_instance_placement_that_cannot_be_meant_is_refused(tmp_path, placement, match):
    """Each was an internal error ('a, b, c') or silently taken (the first three of five
    values; a rotation about no axis ignored)."""
    from qsma.errors import MeshFileError
    from qsma.mesh.io import read_assembly
    path = tmp_path / "deck.inp"
    path.write_text(PART_DECK.format(placement=placement))
    with pytest.raises(MeshFileError, match=match):
        read_assembly(path)


def test_an_instance_without_its_end_is_refused(tmp_path):
    """Without *END INSTANCE, every card up to the end of the assembly was taken as the
    instance's and dropped with it."""
    from qsma.errors import MeshFileError
    from qsma.mesh.io import read_assembly
    text = PART_DECK.format(placement="0., 1., 0.\n").replace(
        "*Instance, name=Lower, part=Beam\n*End Instance\n", "*Instance, name=Lower, "
        "part=Beam\n")
    path = tmp_path / "deck.inp"
    path.write_text(text)
    with pytest.raises(MeshFileError, match=r"line 11: \*INSTANCE 'Lower' has no \*END "
                                            r"INSTANCE before \*INSTANCE \(line 12\)"):
        read_assembly(path)


# ---- inputs that were internal errors -----------------------------------------------

def test_a_clamp_of_no_component_is_refused(tmp_path, capsys):
    """components = [] in a clamp table was an internal error (an empty index array)."""
    config = _example_config(tmp_path)
    config.write_text(config.read_text().replace(
        'clamps = [{ set = "clamp" }]  ', 'clamps = [{ set = "clamp", components = [] }]', 1))
    assert "components = []" in config.read_text()
    assert main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert "the clamp on 'clamp' holds no component" in capsys.readouterr().err


def test_a_scheduler_that_is_no_address_is_refused_before_the_study(tmp_path, capsys,
                                                                      monkeypatch):
    """--scheduler notanaddress was an internal error, after the study folder was made."""
    _no_case_computed(monkeypatch)
    assert main(["sweep", "--example", "sandwich-2d", "--vary", "mu=0.5", "--scheduler",
                 "notanaddress", "--quiet", "--out", str(tmp_path / "s")]) == 2
    assert "is not a Dask scheduler address" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


@pytest.mark.parametrize("vary", [["mu=0.1:0.9:10000000000"],
                                  ["mu=0.1:0.9:100000", "preload=0.5:1.5:100000"]],
                         ids=["1e10 values", "1e10-case grid"])
def test_a_study_too_large_to_hold_is_refused_before_allocating(tmp_path, capsys,
                                                                monkeypatch, vary):
    """10^10 values of one parameter (74.5 GiB asked) or a grid of 10^10 cases
    (MemoryError): refused from the count, before the values or cases are made."""
    import tracemalloc
    _no_case_computed(monkeypatch)
    argv = ["sweep", "--example", "sandwich-2d", "--quiet", "--out", str(tmp_path / "s")]
    for v in vary:
        argv += ["--vary", v]
    tracemalloc.start()
    try:
        assert main(argv) == 2
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 200 * 2**20                      # nothing of the cases was made
    assert "10000000000 cases, but this machine's free memory holds" in \
        capsys.readouterr().err


def test_max_cases_follows_the_free_memory(monkeypatch):
    """The limit is the cases whose records fit in half the free memory."""
    import qsma._infra.resources as resources
    from qsma.study.cases import CASE_BYTES, LEVEL_BYTES, max_cases
    monkeypatch.setattr(resources, "free_memory", lambda: 2**30)
    assert max_cases(51) == int(0.5 * 2**30 // (CASE_BYTES + 51 * LEVEL_BYTES))
    monkeypatch.setattr(resources, "free_memory", lambda: None)
    assert max_cases(51) == 100_000


@pytest.mark.parametrize("example, most", [("sandwich-2d", 9), ("sandwich-3d", 1)])
def test_a_refinement_beyond_the_free_memory_is_refused_before_meshing(
        capsys, monkeypatch, example, most):
    """--refine 100 allocated 4.7 and 29.7 GiB before failing. With 1 GiB free, the
    estimate (measured bytes per DOF) refuses it and names the largest refine that
    fits (sandwich-2d refine 8 peaked at 709 MiB, so 9 is about right in 2D)."""
    import qsma._infra.resources as resources
    from qsma.examples import EXAMPLES, run_bytes
    monkeypatch.setattr(resources, "free_memory", lambda: 2**30)
    assert main(["modes", "--example", example, "--refine", "100", "-n", "1"]) == 2
    assert f"use --refine {most} or less" in capsys.readouterr().err
    base = EXAMPLES[example](1)
    assert run_bytes(base.n_dofs * most ** base.dim, base.dim) <= 2**30 < \
        run_bytes(base.n_dofs * (most + 1) ** base.dim, base.dim)


@pytest.mark.parametrize("content, match", [
    ("tip_m,f_hz\n1e-5,212\n2e-5,211\n".encode("utf-16"), "encoded as UTF-16"),
    (b"# bei 20\xb0C\ntip_m,f_hz\n1e-5,212\n2e-5,211\n", r"line 1: byte 0xb0 is not UTF-8"),
    (b"tip_m,f_hz,f_hz\n1e-5,212,212\n2e-5,211,211\n", "column 'f_hz' appears twice"),
], ids=["utf-16", "latin-1", "duplicated column"])
def test_measured_data_that_cannot_be_read_is_refused_by_name(tmp_path, capsys, monkeypatch,
                                                              content, match):
    """Each was an internal error (a decoding error; arrays of two lengths)."""
    csv = tmp_path / "m.csv"
    csv.write_bytes(content)
    _no_case_computed(monkeypatch)
    assert main(["fit", "--example", "sandwich-2d", "--measured", str(csv), "--params",
                 "mu", "--quiet", "--out", str(tmp_path / "fit")]) == 2
    assert re.search(match, capsys.readouterr().err)


def test_a_fitted_material_of_no_body_is_refused_before_any_evaluation(tmp_path, capsys,
                                                                      monkeypatch):
    """--params E:nobody was an internal error (the start value of a body not there)."""
    csv = tmp_path / "m.csv"
    csv.write_text("tip_m,f_hz\n1e-5,212\n2e-5,211\n")
    _no_case_computed(monkeypatch)
    assert main(["fit", "--example", "sandwich-2d", "--measured", str(csv), "--params",
                 "E:nobody", "--quiet", "--out", str(tmp_path / "fit")]) == 2
    assert "parameter 'E:nobody': no body 'nobody'; bodies: ['bottom', 'top']" in \
        capsys.readouterr().err


@pytest.mark.parametrize("option", ["mesh", "config", "measured"])
def test_an_input_path_that_is_a_fifo_is_refused_not_read(tmp_path, capsys, option):
    """A FIFO that no program writes blocked the read forever; every input file is
    checked to be a regular file on the opened descriptor."""
    import os
    import threading
    fifo = tmp_path / ("fifo.inp" if option == "mesh" else "fifo")
    os.mkfifo(fifo)
    config = _example_config(tmp_path)
    argv = {"mesh": ["run", str(config)], "config": ["run", str(fifo)],
            "measured": ["fit", "--example", "sandwich-2d", "--measured", str(fifo),
                         "--params", "mu"]}[option]
    if option == "mesh":
        config.write_text(config.read_text().replace("sandwich-2d-bottom.inp", "fifo.inp"))
    done = []
    t = threading.Thread(target=lambda: done.append(
        main(argv + ["--quiet", "--out", str(tmp_path / "out")])), daemon=True)
    t.start()
    t.join(60)
    if t.is_alive():                       # unblock the reader so the thread can end
        with open(fifo, "wb"):
            pass
        pytest.fail("the read of a FIFO blocked")
    assert done == [2]
    assert "is not a regular file" in capsys.readouterr().err


# ---- refusals that came late or not at all -------------------------------------------

def test_a_model_without_bodies_is_refused_as_such(tmp_path, capsys):
    """bodies = [] said 'all bodies must have the same dimension, got []'."""
    from qsma.model import Model
    with pytest.raises(InputError, match="the model has no bodies"):
        Model(bodies=())
    config = _example_config(tmp_path)
    text = config.read_text()
    text = "bodies = []\n" + text[:text.index("[[bodies]]")] + text[text.index("[interface]"):]
    config.write_text(text)
    assert main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert "sandwich-2d.toml: bodies is empty; describe each body as a [[bodies]] table" \
        in capsys.readouterr().err


@pytest.mark.parametrize("levels, match", [
    ("kind = 'tip'\nspacing = 'log'\nstart = 1e-3\nstop = 1e-6\nn = 1\n",
     "one level \\(n = 1\\) from start=0.001 to stop=1e-06"),
    ("kind = 'tip'\nspacing = 'linear'\nstart = 1e-6\nstop = 1e-3\nn = 1\n",
     "the level would be start and stop ignored"),
    ("kind = 'tip'\nspacing = 'list'\nvalues = [1e-6, 1e-5]\nstart = 1e-6\nstop = 1e-3\n"
     "n = 51\n", "spacing 'list' takes its levels from 'values'; 'start', 'stop', 'n' given "
                 "too would be ignored"),
    ("kind = 'tip'\nspacing = 'log'\nstart = 1e-6\nstop = 1e-3\nn = 5\nvalues = [1e-6]\n",
     "'values' is given too"),
], ids=["n=1, start > stop", "n=1, start < stop", "list with a range", "range with values"])
def test_levels_whose_keys_contradict_each_other_are_refused(tmp_path, capsys, levels,
                                                             match):
    """A key that would be ignored (stop with n = 1; start, stop, n beside a list) is a
    contradiction the user should resolve, not a choice qsma makes silently."""
    config = _example_config(tmp_path)
    text = config.read_text()
    config.write_text(text[:text.index("[levels]")] + "[levels]\n" + levels)
    assert main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert re.search(match, capsys.readouterr().err)


def test_one_swept_value_from_a_range_is_refused(tmp_path, capsys, monkeypatch):
    _no_case_computed(monkeypatch)
    assert main(["sweep", "--example", "sandwich-2d", "--vary", "mu=0.8:0.2:1", "--quiet",
                 "--out", str(tmp_path / "s")]) == 2
    assert "one value from 0.8 to 0.2" in capsys.readouterr().err


def test_more_local_workers_than_cores_are_refused(tmp_path, capsys, monkeypatch):
    """--workers 6 on a 2-core machine started 7 processes without a word; with a
    scheduler the workers are the cluster's."""
    import qsma._infra.threads as threads
    monkeypatch.setattr(threads, "usable_cores", lambda: 2)
    _no_case_computed(monkeypatch)
    assert main(["sweep", "--example", "sandwich-2d", "--vary", "mu=0.5", "--workers", "6",
                 "--quiet", "--out", str(tmp_path / "s")]) == 2
    assert "--workers 6: this machine lets qsma use 2 core(s)" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()
    from qsma.study.runners import check_workers
    check_workers(2, None)
    check_workers(64, "tcp://cluster:8786")
