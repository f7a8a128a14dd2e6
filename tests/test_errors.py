"""Bad input and physical edge cases: clear errors, never a silent wrong answer."""
import dataclasses
import json
import os
import signal
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import pytest

import qsma
from qsma.cli import main
from qsma.errors import AnalysisError, ContactConvergenceWarning, InputError
from qsma.examples import sandwich_2d
from qsma.analysis.levels import Levels
from qsma.model import Body, Clamp, Interface, Material, Mesh, Model, Pressure


def _replace_body(model, k, **changes):
    bodies = list(model.bodies)
    bodies[k] = dataclasses.replace(bodies[k], **changes)
    return dataclasses.replace(model, bodies=tuple(bodies))


def test_non_matching_interface_names_nodes_and_distance():
    m = sandwich_2d(1)
    mesh = m.bodies[1].mesh
    pts = mesh.points.copy()
    node = int(mesh.nodes("interface")[5])
    pts[node, 0] += 2e-4
    moved = Mesh(pts, mesh.cells, mesh.cell_type, mesh.node_sets, mesh.facet_sets)
    bad = _replace_body(m, 1, mesh=moved)
    node_to_node = dataclasses.replace(bad, interface=dataclasses.replace(
        bad.interface, coupling="node"))
    with pytest.raises(InputError) as exc:
        qsma.run(node_to_node)
    msg = str(exc.value)
    assert f"node {node}" in msg and "no partner" in msg and "e-04" in msg
    assert "mortar" in msg                          # the message points to the coupling
    from qsma.model import make_pairing              # the default couples it instead
    assert make_pairing(bad).coupling == "mortar"


def test_interface_set_on_wrong_body():
    m = sandwich_2d(1)
    bad = dataclasses.replace(m, interface=Interface("bottom", "interface", "top", "bolt"))
    with pytest.raises(InputError, match="no partner|not covered|cover|normal"):
        qsma.run(bad)
    with pytest.raises(InputError, match="no facet set named 'nope'"):
        qsma.run(dataclasses.replace(m, interface=Interface("bottom", "nope", "top",
                                                            "interface")))


def test_interface_set_inside_its_body_is_refused():
    """A facet set that runs through the inside of a body (two cells share each facet)
    cannot be a contact surface: the message names the body, the set and a facet."""
    m = sandwich_2d(1)
    bottom = m.bodies[m.body_index("bottom")]
    cells = bottom.mesh.cells
    shared = {}
    for c in cells.tolist():
        for a, b in zip(c, c[1:] + c[:1]):
            shared.setdefault(frozenset((a, b)), []).append(c)
    inner = np.array([sorted(k) for k, v in shared.items() if len(v) == 2][:3])
    body = dataclasses.replace(bottom, mesh=bottom.mesh.with_sets(
        facet_sets={"interface": np.vstack([bottom.mesh.facet_sets["interface"], inner])}))
    bodies = tuple(body if b.name == "bottom" else b for b in m.bodies)
    with pytest.raises(InputError, match=r"body 'bottom': facet set 'interface' contains "
                                         r"3 facet\(s\) not on the boundary"):
        qsma.run(dataclasses.replace(m, bodies=bodies))


@pytest.mark.parametrize("clamps", [(), (Clamp("clamp", (0,)),)])
def test_body_held_only_through_the_joint_is_accepted(clamps):
    """Issue 12: a body whose clamps leave rigid motions free is held by the joint; the
    condensation keeps those motions (tests/test_freefree.py runs such models)."""
    from qsma.reduction.two_bodies import reduce_two_bodies
    from qsma.fe import assemble_body
    from qsma.model import make_pairing
    m = _replace_body(sandwich_2d(1), 1, clamps=clamps)
    red = reduce_two_bodies(*[assemble_body(b) for b in m.bodies], make_pairing(m))
    assert red.bodies[1].rigid.shape[1] == (3 if not clamps else 1)   # 1: translation y
    assert red.ghost is not None and red.gauge is None


@pytest.mark.parametrize("kw, match", [(dict(E=0.0), "E must be > 0"),
                                       (dict(E=-1.0), "E must be > 0"),
                                       (dict(rho=0.0), "rho must be > 0"),
                                       (dict(nu=0.5), r"nu must lie in \(-1, 0.5\)"),
                                       (dict(nu=-1.0), "nu must lie"),
                                       (dict(E=float("nan")), "must be finite")])
def test_bad_material(kw, match):
    args = dict(E=200e9, nu=0.3, rho=7800.0)
    args.update(kw)
    with pytest.raises(InputError, match=match):
        Material(**args)


def test_bad_friction_and_nan_inputs():
    with pytest.raises(InputError, match="mu must be >= 0"):
        sandwich_2d(1, mu=-0.1)
    with pytest.raises(InputError, match="finite"):
        sandwich_2d(1, mu=float("nan"))
    with pytest.raises(InputError, match="finite"):
        Pressure("bolt", float("inf"))
    with pytest.raises(InputError, match="NaN"):
        Mesh(np.array([[0.0, 0.0], [1.0, np.nan], [0.0, 1.0]]), [[0, 1, 2]], "triangle")


def test_mode_index_beyond_computed_modes():
    with pytest.raises(InputError, match="beyond the 6 computed modes"):
        qsma.run(sandwich_2d(1), mode=6, n_modes=6)


def test_preload_that_separates_the_bodies():
    m = sandwich_2d(1)
    pulled = m
    for k in (0, 1):
        pulled = _replace_body(pulled, k, pressures=(Pressure("bolt", -17.554e6),))
    with pytest.raises(AnalysisError, match="no interface pair in contact"):
        qsma.run(pulled)


def test_levels_must_increase():
    with pytest.raises(InputError, match="increase strictly"):
        Levels("tip", (1e-6, 1e-5, 1e-5))
    with pytest.raises(InputError, match="> 0"):
        Levels("alpha", (0.0, 1.0))


def test_gross_slip_is_solved_and_reported():
    res = qsma.run(sandwich_2d(1), levels=Levels.log("tip", 1e-6, 3e-3, 12))
    assert res.success
    g = res.gross_slip_level
    assert g is not None and res.n_stuck[g] == 0 and res.n_stuck[g - 1] > 0
    assert np.all(np.diff(res.f_hz) <= 1e-8 * res.f0_hz)


def test_zero_friction_is_elastic_no_dissipation():
    res = qsma.run(sandwich_2d(1, mu=0.0), levels=Levels.log("tip", 1e-6, 1e-4, 5))
    assert res.success
    assert np.all(res.n_stuck == 0)                     # nothing can stick without friction
    assert np.all(res.f_hz < res.f0_hz * 0.99)          # softer than the tied structure
    # frictionless contact stores energy but dissipates none (Masing on a linear backbone)
    assert np.all(np.abs(res.zeta) < 1e-8)


@pytest.fixture
def starved_solver(monkeypatch):
    """Fault injection: the preload solves normally, every later level gets one
    iteration of the nodal Gauss-Seidel, which cannot converge on this problem."""
    import qsma.analysis as analysis
    import qsma.contact.zone as zone
    real = analysis.solves.contact_solve
    calls = {"n": 0}

    def starved(problem, lam_w, state=None, **kw):
        calls["n"] += 1
        if calls["n"] > 1:
            kw.update(method="nodal_gs", maxiter=1)
        return real(problem, lam_w, state, **kw)
    monkeypatch.setattr(analysis.solves, "contact_solve", starved)
    monkeypatch.setattr(zone, "solve", starved)       # the ramp solves on the zone
    return calls


def test_non_convergence_is_flagged_and_stops(starved_solver):
    levels = Levels.log("tip", 1e-4, 1e-3, 4)
    with pytest.warns(ContactConvergenceWarning, match="load level 0"):
        res = qsma.run(sandwich_2d(1), levels=levels)
    assert not res.success and "load level 0" in res.message and "residual" in res.message
    assert res.n_levels == 0                       # nothing unconverged is kept


def test_continue_keeps_going_and_flags(starved_solver):
    levels = Levels.log("tip", 1e-4, 1e-3, 3)
    with pytest.warns(ContactConvergenceWarning):
        res = qsma.run(sandwich_2d(1), levels=levels, continue_on_failure=True)
    assert not res.success and res.n_levels == 3
    assert np.all(res.states.residual > 1e-8)


def test_cli_exit_1_names_the_level(starved_solver, tmp_path, capsys):
    code = main(["run", "--example", "sandwich-2d", "--out", str(tmp_path), "--quiet",
                 "--no-plots", "--no-vtu"])
    assert code == 1
    err = capsys.readouterr().err
    assert "contact solve failed at load level" in err and "Traceback" not in err
    import re
    k = int(re.search(r"load level (\d+)", err).group(1))
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["success"] is False and len(data["levels"]["alpha"]) == k   # levels before


def test_unwritable_output_folder_fails_before_computing(tmp_path, capsys, monkeypatch):
    import qsma.analysis
    def must_not_run(*a, **k):
        raise AssertionError("the analysis started although --out cannot be written")
    monkeypatch.setattr(qsma.analysis, "run", must_not_run)
    monkeypatch.setattr(qsma.examples.sandwich, "sandwich_2d", must_not_run)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    assert main(["run", "--example", "sandwich-2d", "--out", str(blocker / "sub")]) == 2
    err = capsys.readouterr().err
    assert "cannot be written" in err and "--out" in err


def test_killed_run_leaves_no_partial_results(tmp_path):
    """SIGKILL at several moments of a first run: the folder is absent or holds the
    complete run (its manifest checks); a later run removes the killed runs' staging
    folders and leaves nothing hidden beside the result folder."""
    from qsma.output.folders import verify_run_folder
    out = tmp_path / "out"
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    cmd = [sys.executable, "-m", "qsma", "run", "--example", "sandwich-2d", "--out",
           str(out), "--quiet"]
    for delay in (0.5, 1.5, 2.5, 3.5):
        proc = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL,
                                stderr=subprocess.DEVNULL)
        time.sleep(delay)
        proc.send_signal(signal.SIGKILL)
        proc.wait()
        if out.exists():
            assert len(verify_run_folder(out)["files"]) >= 2
            data = json.loads((out / "results.json").read_text())
            assert len(data["levels"]["alpha"]) == 51
    assert main(["run", "--example", "sandwich-2d", "--out", str(out), "--quiet",
                 "--no-plots", "--no-vtu"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    assert set(verify_run_folder(out)["files"]) == {"results.json", "results.csv", "qsma.log"}


def test_sigterm_cleans_up(tmp_path):
    """SIGTERM during the analysis: exit 130, no staging folder left, no result folder."""
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "qsma", "run", "--example", "sandwich-2d",
                             "--refine", "2", "--direct-loop", "--out", str(out), "--quiet"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    lock = tmp_path / ".out.qsma-lock"           # taken once the handler is set
    t0 = time.time()
    while not lock.exists() and time.time() - t0 < 60:
        time.sleep(0.02)
    time.sleep(0.3)                                     # inside the analysis (about 2 s)
    proc.send_signal(signal.SIGTERM)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130 and b"interrupted" in err, err
    assert list(tmp_path.iterdir()) == []


def test_pressure_of_another_load_pattern_is_rejected():
    m = _replace_body(sandwich_2d(1), 0, pressures=(Pressure("bolt", 17.554e6, load="bolt"),))
    with pytest.raises(InputError, match="load pattern 'bolt' is not used"):
        qsma.run(m)


def test_tip_probe_is_validated():
    from qsma.model import Probe
    m = sandwich_2d(1)
    for probe, match in [(Probe((), (0.0, 1.0)), "at least one"),
                         (Probe((("top", "tip"),), (0.0, 0.0)), "not all zero"),
                         (Probe((("top", "tip"),), (0.0, 1.0, 0.0)), "2 finite numbers"),
                         (Probe((("top", "nope"),), (0.0, 1.0)), "no node or facet set")]:
        with pytest.raises(InputError, match=match):
            dataclasses.replace(m, tip=probe)


def test_interface_of_a_body_with_itself():
    with pytest.raises(InputError, match="to itself"):
        dataclasses.replace(sandwich_2d(1),
                            interface=Interface("bottom", "interface", "bottom", "interface"))


def test_mode_without_tip_motion():
    # an axial mode of the 2-beam sandwich moves the tip along x, not y: probe along y only
    m = sandwich_2d(1)
    from qsma.model import Probe
    sideways = dataclasses.replace(m, tip=Probe((("bottom", "tip"), ("top", "tip")),
                                                (1.0, 0.0)))
    with pytest.raises(InputError, match="no tip deflection"):
        qsma.run(sideways, mode=0)        # first bending: no mean x motion of the tip


def test_failed_preload_is_an_analysis_error():
    with pytest.warns(ContactConvergenceWarning):
        with pytest.raises(AnalysisError, match="preload contact solve failed"):
            qsma.run(sandwich_2d(1), method="nodal_gs", maxiter=2)


def test_mixed_cell_types_write_vtu(tmp_path):
    """Bottom beam in triangles, top in quadrilaterals: analysis and every file."""
    m = sandwich_2d(1)
    q = m.bodies[0].mesh
    tri = np.concatenate([q.cells[:, [0, 1, 2]], q.cells[:, [0, 2, 3]]])
    tmesh = Mesh(q.points, tri, "triangle", q.node_sets, q.facet_sets)
    mixed = _replace_body(m, 0, mesh=tmesh)
    res = qsma.run(mixed, levels=Levels.log("tip", 1e-5, 1e-3, 4))
    assert res.success
    from qsma.output.files import write_all
    import meshio
    write_all(res, tmp_path / "mixed", plots=False)
    vtu = meshio.read(tmp_path / "mixed" / "fields.vtu")
    assert {c.type for c in vtu.cells} == {"triangle", "quad"}


def test_continue_exits_zero_with_warning(starved_solver, tmp_path, capsys):
    code = main(["run", "--example", "sandwich-2d", "--out", str(tmp_path), "--quiet",
                 "--no-plots", "--no-vtu", "--continue", "--levels", "tip:log:1e-4:1e-3:3"])
    assert code == 0
    assert "warning" in capsys.readouterr().err
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["success"] is False and len(data["levels"]["alpha"]) == 3


def test_refine_with_config_is_rejected(tmp_path, capsys):
    from qsma.examples import example_file
    toml = example_file("sandwich-2d.toml")
    assert main(["run", str(toml), "--refine", "2", "--out", str(tmp_path)]) == 2
    assert "--refine applies to --example" in capsys.readouterr().err


def test_direct_loop_failure_is_not_an_answer(monkeypatch, tmp_path, capsys):
    """A contact failure inside the direct loop stops it: no area is reported, the
    backbone is kept, results.json says why, the CLI exits 1."""
    import qsma.analysis as analysis
    real = analysis._Solver.__call__

    def failing_in_loop(self, alpha, state, where, closing=None):
        if where.startswith("direct loop") and alpha < 0:     # starve the reloading half
            return analysis._solve(self.problem, self.reduced, alpha, state, "nodal_gs",
                                   {"maxiter": 1}, where, None)[0]
        return real(self, alpha, state, where, closing)
    monkeypatch.setattr(analysis._Solver, "__call__", failing_in_loop)
    levels = Levels.log("tip", 1e-5, 1e-3, 6)
    with pytest.warns(ContactConvergenceWarning, match="direct loop"):
        res = qsma.run(sandwich_2d(1), levels=levels, direct_loop=True)
    dl = res.direct_loop
    assert res.success and res.n_levels == 6
    assert not dl.success and dl.dissipation is None and "stopped at alpha" in dl.message
    assert np.all(dl.alpha >= 0) and len(dl.q) == len(dl.alpha)
    code = main(["run", "--example", "sandwich-2d", "--out", str(tmp_path), "--quiet",
                 "--no-vtu", "--direct-loop", "--levels", "tip:log:1e-5:1e-3:6"])
    assert code == 1 and "direct loop stopped" in capsys.readouterr().err
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["direct_loop"]["dissipation"] is None and not data["direct_loop"]["success"]


# ---- input limits and relative rigid-body checks ----------------------------------------

def _material_everywhere(model, nu=None, E_top=None):
    from qsma.model import Material
    bodies = []
    for k, b in enumerate(model.bodies):
        m = b.material
        bodies.append(dataclasses.replace(b, material=Material(
            E_top if (E_top is not None and k == 1) else m.E, m.nu if nu is None else nu,
            m.rho)))
    return dataclasses.replace(model, bodies=tuple(bodies))


def _first_modes(model, tied="all", n_modes=3):
    from qsma.fe import assemble_body
    from qsma.modal import linear_modes
    from qsma.model import make_pairing
    p = make_pairing(model)
    tie = np.ones(p.n_pairs, bool) if tied == "all" else np.zeros(p.n_pairs, bool)
    return linear_modes(model, [assemble_body(b) for b in model.bodies], p, tied=tie,
                        n_modes=n_modes)


@pytest.mark.parametrize("kw", [dict(nu=0.4999999999), dict(E_top=1e3)],
                         ids=["nu-0.4999999999", "top-E-1e3"])
def test_soft_or_incompressible_body_is_not_a_rigid_body_mode(kw):
    """Both gave "rigid-body mode" with the old threshold 1e-12 x max(K_ii) / max(M_ii)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")                 # the locking warning (nu)
        model = _material_everywhere(sandwich_2d(1), **kw)
        f = _first_modes(model).f_hz
    assert np.all(f > 0) and np.all(np.diff(f) >= 0)
    if "E_top" in kw:                                   # the soft top beam's own bending:
        assert f[0] < 212.544 * np.sqrt(1e3 / 200e9) * 10   # far below the steel f0


def test_unclamped_body_is_still_caught():
    free_top = _replace_body(sandwich_2d(1), 1, clamps=())
    with pytest.raises(InputError, match="rigid-body"):
        _first_modes(free_top, tied="none")


def test_rigid_mode_check_is_kinematic():
    """A rigid motion of one body is refused whatever its eigenvalue; the elastic first
    mode is not."""
    from qsma.reduction.rigid import rigid_body_modes
    from qsma.fe import assemble_body
    from qsma.modal import RIGID_TOL, nonrigid_part, tie_transform
    from qsma.modal.tied import _check_rigid
    from qsma.model import make_pairing
    m = _replace_body(sandwich_2d(1), 1, clamps=())
    p = make_pairing(m)
    A = [assemble_body(b) for b in m.bodies]
    T = tie_transform(m, A, p, np.zeros(p.n_pairs, bool))   # a selection: T.T T = I
    u = np.zeros(m.n_dofs)
    off = m.dof_offsets()
    u[off[1]:off[2]] = rigid_body_modes(m.bodies[1].mesh.points)[:, 2]   # top rotates
    vec = (T.T @ u)[:, None]
    with pytest.raises(InputError, match="rigid-body mode.*'top'"):
        _check_rigid(np.array([123.0]), m, A, T, vec)
    mode = _first_modes(sandwich_2d(1), tied="none", n_modes=1).shapes[:, 0]
    assert nonrigid_part(m, A, mode) > 100 * RIGID_TOL


@pytest.mark.parametrize("scale", [1e-10, 1.0, 1e6])
def test_clamp_check_is_independent_of_units(scale):
    """Coordinates in any unit: a clamped body has no free rigid motion, a body clamped
    in x along its end keeps the y translation free (the old absolute tolerance 1e-9
    called every body smaller than about 1e-9 m free)."""
    from qsma.fe import assemble_body
    from qsma.reduction.rigid import free_motions
    m = sandwich_2d(1)
    b = m.bodies[1]
    mesh = b.mesh
    scaled = Mesh(mesh.points * scale, mesh.cells, mesh.cell_type, mesh.node_sets,
                  mesh.facet_sets)
    held = assemble_body(dataclasses.replace(b, mesh=scaled))
    assert free_motions(scaled.points, held.fixed).shape[1] == 0
    loose = assemble_body(dataclasses.replace(b, mesh=scaled, clamps=(Clamp("clamp", (0,)),)))
    free = free_motions(scaled.points, loose.fixed)
    assert free.shape[1] == 1
    u = free[:, 0].reshape(-1, 2)
    assert np.abs(u[:, 0]).max() < 1e-9 * np.abs(u[:, 1]).max()      # no x part
    assert np.ptp(u[:, 1]) < 1e-9 * np.abs(u[:, 1]).max()            # uniform in y


def test_level_and_mode_counts_are_bounded():
    from qsma.analysis.levels import MAX_LEVELS
    from qsma.modal import MAX_MODES, check_n_modes
    with pytest.raises(InputError, match=f"at most {MAX_LEVELS}"):
        Levels.log("tip", 1e-6, 1e-3, 10_000_000_000)     # used to allocate 74.5 GiB
    with pytest.raises(InputError, match=f"at most {MAX_LEVELS}"):
        Levels("alpha", tuple(range(1, MAX_LEVELS + 2)))
    assert len(Levels.linear("alpha", 1.0, 2.0, MAX_LEVELS).values) == MAX_LEVELS
    with pytest.raises(InputError, match=f"at most {MAX_MODES}"):
        check_n_modes(100_000)
    with pytest.raises(InputError, match="11 free DOFs"):
        check_n_modes(10, n_free=11)
    with pytest.raises(InputError, match="positive integer"):
        check_n_modes(True)
    check_n_modes(MAX_MODES, n_free=4500)
    with pytest.raises(InputError, match="at most 200"):
        qsma.run(sandwich_2d(1), n_modes=100_000, levels=Levels("tip", (1e-6,)))


def test_nearly_incompressible_material_warns():
    from qsma.errors import NearlyIncompressibleWarning
    from qsma.model.body import NU_LOCKING
    with pytest.warns(NearlyIncompressibleWarning, match="mixed .* or incompatible-mode"):
        Material(200e9, 0.49, 7800.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        Material(200e9, NU_LOCKING, 7800.0)              # at the limit: silent


def test_a_friction_coefficient_past_no_slip_is_refused_with_the_fix():
    """mu above 1e4 (a deck's 1e20 for 'no slip') changes no answer but costs the contact
    solve its digits (a CalculiX test deck with mu = 1e20 failed its solve at level 29
    and runs with 1e4): refused with the value to give, on the model and per interface;
    at 1e4 a joint runs and its stuck levels are those of any large mu."""
    import dataclasses
    import qsma
    from qsma.analysis.levels import Levels
    with pytest.raises(InputError, match="mu = 1e\\+20 is above 10000.*give mu = 10000"):
        sandwich_2d(1, mu=1e20)
    model = sandwich_2d(1)
    with pytest.raises(InputError, match="interface .*mu = 1e\\+06 is above 10000"):
        dataclasses.replace(model.interface, mu=1e6)
    levels = Levels("alpha", (20.0, 2000.0))
    sticky = qsma.run(sandwich_2d(1, mu=1e4), levels=levels)
    assert sticky.success and np.all(sticky.zeta <= 1e-12)
    assert sticky.f0_hz == pytest.approx(qsma.run(sandwich_2d(1, mu=1e3), levels=levels).f0_hz,
                                         rel=1e-12)
