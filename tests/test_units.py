"""Unit systems: a model declares its units; every label, file and message follows
them, and a model whose numbers look like another system is warned about."""
import csv
import dataclasses
import json
import warnings

import meshio
import numpy as np
import pytest

import qsma
from qsma.cli import main
from qsma.errors import InputError, UnitSystemWarning
from qsma.examples import sandwich_2d
from qsma.analysis.levels import Levels
from qsma.model import Material, Pressure
from qsma.output.files import column_name, write_all
from qsma.units import (MM_N_S_TONNE, SI, check_model_units, quantity_unit,
                        unit_mismatches, unit_system)
from qsma.analysis.result import units_block

LEVELS_M = (1e-6, 1e-5, 3e-4, 1e-3)


def in_millimetres(model, declare="mm-N-s-tonne"):
    """``model`` (SI) with every number in mm, N, s, t: coordinates x 1e3, E and
    pressures / 1e6 (Pa -> MPa), densities / 1e12 (kg/m^3 -> t/mm^3)."""
    bodies = []
    for b in model.bodies:
        mesh = dataclasses.replace(b.mesh, points=b.mesh.points * 1e3)
        m = b.material
        bodies.append(dataclasses.replace(
            b, mesh=mesh, material=Material(m.E / 1e6, m.nu, m.rho / 1e12),
            pressures=tuple(Pressure(p.set, p.p / 1e6, p.load) for p in b.pressures)))
    return dataclasses.replace(model, bodies=tuple(bodies), units=declare)


@pytest.fixture(scope="module")
def si_and_mm():
    """The same sandwich-2d run in SI and in mm-N-s-tonne (levels in each system)."""
    model = sandwich_2d(1)
    si = qsma.run(model, levels=Levels("tip", LEVELS_M))
    mm = qsma.run(in_millimetres(model), levels=Levels("tip", tuple(1e3 * v
                                                                    for v in LEVELS_M)))
    return si, mm


def test_unknown_unit_system_is_refused_with_the_valid_names():
    with pytest.raises(InputError, match="mm-N-s-tonne"):
        unit_system("mm-kg-s")
    with pytest.raises(InputError, match="unknown unit system 'cgs'"):
        dataclasses.replace(sandwich_2d(1), units="cgs")


def test_units_of_the_quantities():
    assert quantity_unit("modal_amplitude", SI, 3) == "kg^0.5 m"
    assert quantity_unit("modal_force", SI, 3) == "N/kg^0.5"
    assert quantity_unit("energy", SI, 2) == "J/m"             # per unit depth in 2D
    assert quantity_unit("modal_amplitude", MM_N_S_TONNE, 2) == "(t/mm)^0.5 mm"
    assert quantity_unit("stress", MM_N_S_TONNE) == "MPa"
    assert quantity_unit("velocity", MM_N_S_TONNE) == "mm/s"
    assert quantity_unit("modal_amplitude", SI, 3, pretty=True) == "\u221akg m"
    # the factors to SI are those of the unit names
    assert MM_N_S_TONNE.stress_pa == pytest.approx(1e6)
    assert MM_N_S_TONNE.density_si == pytest.approx(1e12)


def test_a_millimetre_model_gives_the_same_physics_in_its_units(si_and_mm):
    """Nothing is converted: the same joint written in mm-N-s-tonne has the same
    frequencies and damping, tip deflections 1000 times larger and dissipations (mJ =
    N mm) 1000 times larger (per unit depth: / 1000 again, J/m -> mJ/mm)."""
    si, mm = si_and_mm
    assert mm.f0_hz == pytest.approx(si.f0_hz, rel=1e-8)
    assert np.allclose(mm.tip, 1e3 * si.tip, rtol=1e-6)
    assert np.allclose(mm.f_hz, si.f_hz, rtol=1e-6)
    assert np.allclose(mm.zeta, si.zeta, rtol=1e-5, atol=1e-12)
    # energy per depth: J/m -> mJ/mm is a factor 1e3 / 1e3 = 1
    assert np.allclose(mm.dissipation, si.dissipation, rtol=1e-5,
                       atol=1e-12 * np.max(si.dissipation))
    assert mm.units is MM_N_S_TONNE and si.units is SI
    assert not any("look like" in w for w in mm.warnings + si.warnings)


def test_files_and_messages_name_the_declared_units(si_and_mm, tmp_path):
    _, mm = si_and_mm
    paths = write_all(mm, tmp_path / "mm", plots=False, report=True)
    data = json.loads(paths["json"].read_text())
    assert data["units"]["system"] == "mm-N-s-tonne"
    assert data["units"]["levels"]["tip"] == "mm"
    assert data["units"]["levels"]["dissipation"] == "mJ/mm"
    assert data["units"]["stress"] == "MPa"
    assert data["units"] == units_block(MM_N_S_TONNE, 2)
    header = paths["csv"].read_text().splitlines()[0].split(",")
    assert "tip [mm]" in header and "f_hz [Hz]" in header and "zeta [-]" in header
    assert "flags" in header and [column_name(h) for h in header][1] == "alpha"
    vtu = meshio.read(paths["vtu"])
    units = json.loads(bytes(vtu.field_data["units"]).decode())
    assert units["system"] == "mm-N-s-tonne" and units["Points"] == "mm"
    assert units["u_level00"] == "mm" and units["contact_pressure_level00"] == "MPa"
    html = paths["report"].read_text()
    assert "peak tip [mm]" in html and "peak tip [m]" not in html
    assert "mm-N-s-tonne" in html


def test_cli_prints_the_tip_in_the_model_length_unit(tmp_path, capsys):
    """A millimetre model does not print "tip = 9.995e-01 m"."""
    deck = tmp_path / "mm.toml"
    src = (tmp_path / "src")
    src.mkdir()
    # the sandwich-2d example deck written in mm-N-s-tonne
    from qsma.model import write_mesh
    model = in_millimetres(sandwich_2d(1))
    for b in model.bodies:
        write_mesh(src / f"{b.name}.inp", b.mesh)
    deck.write_text(f"""units = "mm-N-s-tonne"
[[bodies]]
name = "bottom"
mesh = "src/bottom.inp"
E = 200e3
nu = 0.285
rho = 6.6e-9
clamps = [{{ set = "clamp" }}]
pressures = [{{ set = "bolt", p = 17.554 }}]
[[bodies]]
name = "top"
mesh = "src/top.inp"
E = 200e3
nu = 0.285
rho = 6.6e-9
clamps = [{{ set = "clamp" }}]
pressures = [{{ set = "bolt", p = 17.554 }}]
[interface]
body1 = "bottom"
set1 = "interface"
body2 = "top"
set2 = "interface"
mu = 0.6
[tip]
sets = [["bottom", "tip"], ["top", "tip"]]
direction = [0.0, 1.0]
""")
    assert main(["run", str(deck), "--out", str(tmp_path / "out"), "--no-plots",
                 "--no-vtu", "-v"]) == 0
    out = capsys.readouterr()
    assert "units mm-N-s-tonne" in out.out and "tip [mm]" in out.out
    last = [line for line in out.out.splitlines() if line.startswith("last level")][0]
    assert last.endswith(" mm") and "look like" not in out.err
    data = json.loads((tmp_path / "out" / "results.json").read_text())
    # the default levels are the spec's 1 um to 1 mm, in mm
    assert data["levels"]["tip_lin"][0] == pytest.approx(1e-3)
    assert data["levels"]["tip_lin"][-1] == pytest.approx(1.0)
    # the same deck declared as SI: warned, with the system its numbers look like
    deck.write_text(deck.read_text().replace('units = "mm-N-s-tonne"', 'units = "SI"'))
    main(["run", str(deck), "--out", str(tmp_path / "out2"), "--no-plots", "--no-vtu",
          "--levels", "tip:list:1e-3"])
    err = capsys.readouterr().err
    assert "qsma: warning: body 'bottom'" in err and "look like mm-N-s-tonne" in err


def test_numbers_of_another_system_are_warned_about():
    si = sandwich_2d(1)
    assert unit_mismatches(si) == []
    # SI numbers declared as mm-N-s-tonne, and mm numbers declared as SI
    for model, looks in ((dataclasses.replace(si, units="mm-N-s-tonne"), "SI"),
                         (in_millimetres(si, declare="SI"), "mm-N-s-tonne")):
        with pytest.warns(UnitSystemWarning, match=f"look like {looks} "):
            check_model_units(model)
    # numbers of no known system: said so, without a system to switch to
    odd = dataclasses.replace(si, bodies=tuple(
        dataclasses.replace(b, material=Material(1.0, 0.3, 1.0)) for b in si.bodies))
    assert all("nor in any other system" in m for m in unit_mismatches(odd))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_model_units(si)                                # consistent: silent


def test_toml_units_key_is_checked(tmp_path):
    from qsma.analysis.config import parse_config
    with pytest.raises(InputError, match="units: unknown unit system 'inch'"):
        parse_config({"units": "inch", "bodies": [], "tip": {}}, where="cfg")


def test_stuck_levels_have_exactly_zero_damping(tmp_path):
    """Where no pair has left its preload state, the dissipation and damping are 0, not
    the round-off of the Masing integral (+-1e-17) or of a loop's area; the other
    levels keep their computed values."""
    model = sandwich_2d(1)
    for dissipation in ("masing", "loop"):
        res = qsma.run(model, levels=Levels.log("tip", 1e-6, 3e-5, 5),
                       dissipation=dissipation)
        linear = np.array([r.startswith("linear") for r in res.method_reason]) \
            if dissipation == "masing" else res.n_slip == 0
        assert linear[:2].all() and not linear.all()
        kind = f"_{dissipation}"
        for name in ("zeta", "dissipation", "zeta" + kind, "dissipation" + kind):
            v = getattr(res, name)
            assert np.all(v[linear] == 0.0), (dissipation, name, v[linear])
            assert np.all(v[~linear] > 0), (dissipation, name)
        assert np.all(res.dissipation_error >= 0)
        assert res.success
    paths = write_all(res, tmp_path / "z", plots=False, vtu=False)
    rows = list(csv.reader(paths["csv"].open()))
    col = [column_name(h) for h in rows[0]].index("zeta")
    assert rows[1][col] == "0"


def test_vtu_integers_and_time_series(si_and_mm, tmp_path):
    si, _ = si_and_mm
    paths = write_all(si, tmp_path / "si", plots=False, report=False)
    vtu = meshio.read(paths["vtu"])
    assert vtu.point_data["body"].dtype.kind == "i"
    assert vtu.point_data["contact_state_level00"].dtype.kind == "i"
    assert set(np.unique(vtu.point_data["contact_state_level03"])) <= {-1, 0, 1, 2}
    assert vtu.point_data["u_level00"].dtype == np.float64
    units = json.loads(bytes(vtu.field_data["units"]).decode())
    assert units["von_mises_preload"] == "Pa" and "body" not in units
    # the levels as a ParaView time series: a PVD collection of one file per level,
    # each with the same array names
    import xml.etree.ElementTree as ET
    sets = ET.parse(paths["series"]).getroot().find("Collection").findall("DataSet")
    assert [int(d.get("timestep")) for d in sets] == [0, 2, 3]
    for d in sets:
        step = meshio.read(paths["series"].parent / d.get("file"))
        k = int(d.get("timestep"))
        assert np.array_equal(step.point_data["u"], vtu.point_data[f"u_level{k:02d}"])
        assert np.array_equal(step.point_data["contact_state"],
                              vtu.point_data[f"contact_state_level{k:02d}"])
