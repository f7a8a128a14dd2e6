"""Abaqus / CalculiX decks run as they are (qsma.model.io.deck): `qsma run deck.inp`,
`qsma init deck.inp`, what a deck holds that qsma does not use."""
from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest

import qsma
from qsma.cli import main
from qsma.analysis.config import load_config, parse_config, tomllib
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body
from qsma.analysis.levels import Levels
from qsma.model import write_mesh
from qsma.deck import read_deck
from helpers import bodies_in_one_mesh

#: the sandwich-2d bolt pressure (Pa) and the lap deck's friction
P_BOLT, MU = 17.554e6, 0.6
ALPHA = Levels("alpha", (20.0, 200.0, 2000.0))

STEPS = """*MATERIAL, NAME=STEEL
*ELASTIC
200e9, 0.285
*DENSITY
6600.
{sections}*SURFACE INTERACTION, NAME=JOINT
*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR
1e13, 0.
*FRICTION
0.6, 1e12
*CONTACT PAIR, INTERACTION=JOINT, TYPE=SURFACE TO SURFACE
top_interface, bottom_interface
*BOUNDARY
bottom_clamp, 1, 2
top_clamp, 1, 2
*STEP
*STATIC
{loads}*NODE PRINT, NSET=bottom_tip
U
*END STEP
*STEP
*FREQUENCY
6
*END STEP
"""
SECTIONS = """*SOLID SECTION, ELSET=bottom, MATERIAL=STEEL
1.
*SOLID SECTION, ELSET=top, MATERIAL=STEEL
1.
"""
DSLOAD = "*DSLOAD\nbottom_bolt, P, 17.554e6\ntop_bolt, P, 17.554e6\n"


def lap_deck(path, sections=SECTIONS, loads=DSLOAD, extra=""):
    """sandwich-2d as a CalculiX deck: both beams in one file (nodes apart), steel, the
    joint's *CONTACT PAIR with *FRICTION, clamps by *BOUNDARY, the bolt pressure by
    *DSLOAD in a *STATIC step, then a *FREQUENCY step."""
    write_mesh(path, bodies_in_one_mesh(sandwich_2d(1).bodies))
    path.write_text(path.read_text() + extra + STEPS.format(sections=sections, loads=loads))
    return path


#: The deck's *SURFACE BEHAVIOR (LINEAR, slope 1e13) and *FRICTION stick slope (1e12) as
#: the interface law's table.
LAW_TABLE = {"normal": "linear", "normal_stiffness": 1e13, "tangential": "elastic",
             "tangential_stiffness": 1e12}


def _with_law(model):
    import dataclasses
    from qsma.contact.laws import law_from_table
    return dataclasses.replace(model, interface=dataclasses.replace(
        model.interface, law=law_from_table(LAW_TABLE)))


def _run(config, base, levels=ALPHA):
    cfg = parse_config(config, base=base)
    return qsma.run(cfg.model, levels=levels, method="basket")


def test_deck_is_the_sandwich_model(tmp_path):
    """The lap deck runs as the sandwich-2d example with the deck's interface law (the
    linear pressure-overclosure slope and the stick slope): same bodies, clamps,
    pressures, interface, mu and law, hence the same f0 and damping at the same modal
    forces (the coordinates went through an .inp file: 5e-14 apart)."""
    deck = read_deck(lap_deck(tmp_path / "lap.inp"))
    assert not deck.refusals
    c = deck.config
    assert [b["name"] for b in c["bodies"]] == ["bottom", "top"]
    assert c["bodies"][0]["clamps"] == [{"set": "bottom_clamp", "dofs": [1, 2]}]
    assert c["bodies"][1]["pressures"] == [{"set": "top_bolt", "p": P_BOLT}]
    assert c["interface"] == {"body1": "bottom", "set1": "bottom_interface", "body2": "top",
                              "set2": "top_interface", "mu": MU, "coupling": "auto",
                              "slave": "top", "law": LAW_TABLE}
    assert deck.frequency_modes == 6
    a = _run(c, tmp_path)
    b = qsma.run(_with_law(sandwich_2d(1)), levels=ALPHA, method="basket")
    assert a.success and a.f0_hz == pytest.approx(b.f0_hz, rel=1e-9)
    np.testing.assert_allclose(a.zeta, b.zeta, rtol=1e-6, atol=1e-12)   # stuck: round-off
    np.testing.assert_allclose(a.f_hz, b.f_hz, rtol=1e-9)


def test_interaction_parameters_become_the_interface_law(tmp_path):
    """The stick slope and the *SURFACE BEHAVIOR law are kept on the interface record and
    become the interface's law; where qsma's law differs from CalculiX's (the tension
    of its node-to-surface springs) the note says so, with the line."""
    deck = read_deck(lap_deck(tmp_path / "lap.inp"))
    law = deck.interfaces[0].interaction
    assert (law.name, law.mu, law.stick_slope) == ("JOINT", MU, 1e12)
    assert law.pressure_overclosure == "LINEAR" and law.behavior == (1e13, 0.0)
    assert deck.config["interface"]["law"] == LAW_TABLE
    text = "\n".join(map(str, deck.notes))
    assert "lap.inp, line" in text and "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR" in text
    assert "tension" in text and not deck.refusals


@pytest.mark.parametrize("behavior, law", [
    ("*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=EXPONENTIAL\n2e-6, 1e7",
     {"normal": "exponential", "clearance": 2e-6, "pressure_at_zero": 1e7,
      "form": "calculix"}),
    ("*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=TABULAR\n0., -1e-6\n1e6, 0.\n5e6, 1e-6",
     {"normal": "tabular", "table": [[0.0, -1e-6], [1e6, 0.0], [5e6, 1e-6]]}),
])
def test_other_surface_behaviors_become_laws(tmp_path, behavior, law):
    text = lap_deck(tmp_path / "lap.inp").read_text().replace(
        "*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR\n1e13, 0.", behavior)
    (tmp_path / "lap.inp").write_text(text)
    deck = read_deck(tmp_path / "lap.inp")
    assert deck.config["interface"]["law"] == {**law, "tangential": "elastic",
                                               "tangential_stiffness": 1e12}
    from qsma.contact.laws import law_from_table
    law_from_table(deck.config["interface"]["law"])          # a valid law


def test_default_probe_is_the_node_of_largest_modal_displacement(tmp_path):
    """Without --tip-node the probe is the node of largest displacement in the loaded
    tied mode, along its largest component; --tip-node and --tip-direction choose."""
    from qsma.modal import linear_modes
    from qsma.model import make_pairing
    path = lap_deck(tmp_path / "lap.inp")
    deck = read_deck(path)
    model = parse_config(deck.config, base=tmp_path).model
    modes = linear_modes(model, [assemble_body(b) for b in model.bodies],
                         make_pairing(model), n_modes=1)
    u = modes.shapes[:, 0].reshape(-1, 2)
    x = np.vstack([b.mesh.points for b in model.bodies])
    k = int(np.argmax(np.linalg.norm(u, axis=1)))
    (body, point), = deck.config["tip"]["points"]
    assert point == x[k].tolist()
    assert deck.config["tip"]["direction"] == [0.0, 1.0]           # bending: y
    given = read_deck(path, tip_node=1, tip_direction=[1.0, 0.0])
    assert given.config["tip"] == {"points": [["bottom", [0.0, 0.0]]], "direction": [1.0, 0.0]}


def test_init_toml_runs_as_the_deck(tmp_path):
    """deck -> qsma run and deck -> qsma init -> qsma run: the same results, bit for bit
    (the TOML holds the deck's configuration exactly)."""
    path = lap_deck(tmp_path / "lap.inp")
    args = ["--levels", "alpha:list:20,2000", "--method", "basket", "-q", "--no-plots",
            "--no-vtu"]
    assert main(["run", str(path), "--out", str(tmp_path / "a"), *args]) == 0
    assert main(["init", str(path), "-o", str(tmp_path / "sub" / "lap.toml")]) == 2  # no folder
    (tmp_path / "sub").mkdir()
    assert main(["init", str(path), "-o", str(tmp_path / "sub" / "lap.toml")]) == 0
    text = (tmp_path / "sub" / "lap.toml").read_text()
    data = tomllib.loads(text)
    assert data["bodies"][0]["mesh"] == "../lap.inp"
    deck = read_deck(path)
    data["bodies"] = [dict(b, mesh="lap.inp") for b in data["bodies"]]
    assert {k: v for k, v in data.items() if k != "analysis"} == \
        {k: v for k, v in deck.config.items() if k != "analysis"}
    assert data["analysis"]["mode"] == 0 and data["analysis"]["method"] == "auto"
    assert "tol" not in data["analysis"] and "# tol =" in text
    assert main(["run", str(tmp_path / "sub" / "lap.toml"), "--out", str(tmp_path / "b"),
                 *args]) == 0
    a, b = (json.loads((tmp_path / f / "results.json").read_text()) for f in "ab")
    assert a["levels"] == b["levels"] and a["mode"] == b["mode"] and a["preload"] == b["preload"]
    assert main(["init", str(path), "-o", str(tmp_path / "sub" / "lap.toml")]) == 2  # exists


def test_cload_and_dload_faces_are_the_preload(tmp_path):
    """*DLOAD on the faces P<k> of an element set loads what the *DSLOAD on the surface
    of those faces loads (the same preload vector), and a *CLOAD puts its force on every
    node of a node set, or on the node it names by id."""
    base = lap_deck(tmp_path / "lap.inp")
    text = base.read_text()
    deck = read_deck(base)
    model = parse_config(deck.config, base=tmp_path).model
    bottom = model.bodies[0]
    bolt = bottom.mesh.facet_sets["bottom_bolt"]
    from qsma.mesh.mesh import facet_index
    index = facet_index(bottom.mesh)
    rows = index.find(bolt)
    cells = np.unique(index.cell[rows])
    faces = np.unique(index.local_face[rows])
    assert len(faces) == 1
    from qsma.mesh.celltypes import CELL_TYPES
    local = sorted(CELL_TYPES["quad"].facets[faces[0]])
    face = 1 + [sorted(f) for f in CELL_TYPES["quad"].abaqus_faces].index(local)
    ids = ", ".join(str(int(i) + 1) for i in cells)
    loads = (f"*DLOAD\nEBOLT, P{face}, 17.554e6\n*DSLOAD\ntop_bolt, P, 17.554e6\n"
             f"*CLOAD\nbottom_tip, 2, -5.\n2, 1, 7.\n")
    path = tmp_path / "dload.inp"
    path.write_text(text.replace("*MATERIAL", f"*ELSET, ELSET=EBOLT\n{ids}\n*MATERIAL", 1)
                    .replace(DSLOAD, loads))
    other = read_deck(path)
    b0 = other.config["bodies"][0]
    assert b0["pressures"] == [{"set": "EBOLT", "face": face, "p": P_BOLT}]
    assert b0["forces"] == [{"set": "bottom_tip", "force": [0.0, -5.0]},
                            {"set": "_N2", "force": [7.0, 0.0]}]
    m = parse_config(other.config, base=tmp_path).model
    f_dload = assemble_body(m.bodies[0]).loads["preload"].reshape(-1, 2)
    f_dsload = assemble_body(bottom).loads["preload"].reshape(-1, 2)
    tip = m.bodies[0].mesh.node_sets["bottom_tip"]
    f_dload[tip, 1] += 5.0
    f_dload[1, 0] -= 7.0                  # node id 2 is the bottom beam's second node
    np.testing.assert_allclose(f_dload, f_dsload, rtol=1e-12, atol=1e-6)


def test_bodies_without_their_own_element_set_are_connected_parts(tmp_path):
    """One section over both beams: the bodies are the mesh's connected parts
    (``part = k``) and the model is the same."""
    path = lap_deck(tmp_path / "lap.inp", sections="*ELSET, ELSET=EALL\nbottom, top\n"
                    "*SOLID SECTION, ELSET=EALL, MATERIAL=STEEL\n1.\n")
    deck = read_deck(path)
    assert [(b["name"], b["part"]) for b in deck.config["bodies"]] == [("part1", 1),
                                                                        ("part2", 2)]
    ref = read_deck(lap_deck(tmp_path / "ref.inp"))
    a = parse_config(deck.config, base=tmp_path).model
    b = parse_config(ref.config, base=tmp_path).model
    for x, y in zip(a.bodies, b.bodies):
        np.testing.assert_array_equal(x.mesh.points, y.mesh.points)
        np.testing.assert_array_equal(x.mesh.cells, y.mesh.cells)


REFUSED = """*EQUATION
2
1, 1, 1., 2, 1, -1.
"""


def test_what_would_change_the_answer_is_refused_line_by_line(tmp_path, capsys):
    """A deck with a constraint, a plastic material, gravity and an unknown keyword:
    qsma run names each with its line and exits 2 (a prescribed displacement beside
    them is read, not refused); qsma init writes the file with them as comments."""
    text = lap_deck(tmp_path / "base.inp").read_text()
    text = text.replace("*DENSITY\n6600.\n", "*DENSITY\n6600.\n*PLASTIC\n3e8, 0.\n")
    text = text.replace("*MATERIAL", REFUSED + "*WIBBLE\n*MATERIAL", 1)
    text = text.replace(DSLOAD, DSLOAD + "*DLOAD\nbottom, GRAV, 9.81, 0., -1.\n*BOUNDARY\n"
                        "top_clamp, 1, 1, 0.001\n")
    path = tmp_path / "bad.inp"
    path.write_text(text)
    deck = read_deck(path)
    found = {n.what.split(" ")[0] for n in deck.refusals}
    assert {"*EQUATION", "*PLASTIC", "*WIBBLE", "*DLOAD"} <= found, found
    assert "*BOUNDARY" not in found
    assert main(["run", str(path), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "cannot be run as it is: 4 thing(s)" in err
    for what in ("*EQUATION", "*PLASTIC of material 'STEEL'", "*WIBBLE is not a keyword",
                 "GRAV", "qsma init"):
        assert what in err, what
    assert all(f"bad.inp, line " in line for line in err.splitlines()[1:5])
    assert main(["init", str(path)]) == 0
    toml = (tmp_path / "bad.toml").read_text()
    assert "# NOT MODELLED" in toml and "*EQUATION" in toml
    load_config(tmp_path / "bad.toml")          # runs without them, as it says


def test_missing_density_and_one_connected_mesh_are_refused(tmp_path):
    text = lap_deck(tmp_path / "base.inp").read_text().replace("*DENSITY\n6600.\n", "")
    path = tmp_path / "light.inp"
    path.write_text(text)
    (note,) = read_deck(path).refusals
    assert "material 'STEEL' has no *DENSITY" in note.what and "a frequency needs mass" in note.fix


def test_probe_options_are_checked(tmp_path, capsys):
    path = lap_deck(tmp_path / "lap.inp")
    with pytest.raises(qsma.errors.InputError, match="lap.inp has no node 99999"):
        read_deck(path, tip_node=99999)
    with pytest.raises(qsma.errors.InputError, match="--tip-direction needs 2 numbers"):
        read_deck(path, tip_direction=[0.0, 0.0, 1.0])
    from qsma.examples import example_file
    toml = example_file("sandwich-2d.toml")
    assert main(["run", str(toml), "--tip-node", "3", "--out", str(tmp_path / "o")]) == 2
    assert "apply to .inp decks" in capsys.readouterr().err
    assert main(["init", str(toml)]) == 2
    assert "reads an Abaqus/CalculiX deck (.inp) or a Gmsh mesh" in capsys.readouterr().err


def test_tip_points_in_toml(tmp_path):
    """[tip] points: the body's node nearest to each point becomes the probe set; both
    or neither of sets and points, or a point off the body, are refused."""
    deck = read_deck(lap_deck(tmp_path / "lap.inp"))
    config = dict(deck.config, tip={"points": [["top", [0.2032, 0.0126]]],
                                    "direction": [0.0, 1.0]})
    model = parse_config(config, base=tmp_path).model
    top = model.body("top")
    (node,) = top.mesh.node_sets["_tip"]
    assert top.mesh.points[node].tolist() == [0.2032, 0.0127]
    assert model.tip.sets == (("top", "_tip"),)
    for tip, match in [({"sets": [["top", "top_tip"]], "points": [["top", [0.0, 0.0]]]},
                        "either sets"), ({}, "either sets"),
                       ({"points": [["top", [1.0, 0.0]]]},
                        r"point \[1.0, 0.0\] is 0.7968 from the nearest node of body .top."),
                       ({"points": [["nope", [0.0, 0.0]]]}, "naming bodies")]:
        with pytest.raises(qsma.errors.InputError, match=match):
            parse_config(dict(config, tip=dict(tip, direction=[0.0, 1.0])), base=tmp_path)


def test_part_is_checked(tmp_path):
    """``part`` beyond the connected parts or with ``cells``, a pressure face inside the
    body or out of range, a force on an unknown set or of the wrong length: refused by
    name."""
    deck = read_deck(lap_deck(tmp_path / "lap.inp"))
    c = deck.config
    E = qsma.errors.InputError

    def body(**changes):
        return dict(c, bodies=[dict(c["bodies"][0], **changes), c["bodies"][1]])
    by_part = {k: v for k, v in c["bodies"][0].items() if k != "cells"}
    with pytest.raises(E, match=r"part = 3: .*lap.inp has 2 connected part\(s\)"):
        parse_config(dict(c, bodies=[dict(by_part, part=3), c["bodies"][1]]), base=tmp_path)
    with pytest.raises(E, match="either cells .* or part"):
        parse_config(body(part=1), base=tmp_path)
    with pytest.raises(E, match=r"face 7 of cell set 'bottom': quad cells have faces 1..4"):
        parse_config(body(pressures=[{"set": "bottom", "face": 7, "p": 1.0}]), base=tmp_path)
    with pytest.raises(E, match=r"face S1 of \d+ cell\(s\) of 'bottom' is not on the boundary"):
        parse_config(body(pressures=[{"set": "bottom", "face": 1, "p": 1.0}]), base=tmp_path)
    with pytest.raises(E, match="force on unknown set 'nut'"):
        parse_config(body(forces=[{"set": "nut", "force": [0.0, 1.0]}]), base=tmp_path)
    with pytest.raises(E, match=r"force on 'bottom_tip' needs 2 components"):
        parse_config(body(forces=[{"set": "bottom_tip", "force": [0.0, 1.0, 0.0]}]),
                     base=tmp_path)
    with pytest.raises(E, match=r"force on 'bottom_tip' must be finite"):
        parse_config(body(forces=[{"set": "bottom_tip", "force": [0.0, float("nan")]}]),
                     base=tmp_path)


def test_amplitude_at_the_end_of_the_step_and_density_given(tmp_path):
    """A load with AMPLITUDE= counts with the tabular amplitude at the end of the preload
    step (step time 2 here: 0.5); --density gives mass to a material without *DENSITY
    (named as used), which is refused without it."""
    text = lap_deck(tmp_path / "base.inp").read_text()
    text = text.replace("*STATIC\n", "*STATIC\n0.1, 2.\n").replace(
        "*DSLOAD\n", "*DSLOAD, AMPLITUDE=RAMP\n").replace(
        "*MATERIAL", "*AMPLITUDE, NAME=RAMP\n0., 0., 4., 1.\n*MATERIAL", 1).replace(
        "*DENSITY\n6600.\n", "")
    path = tmp_path / "amp.inp"
    path.write_text(text)
    assert "has no *DENSITY" in read_deck(path).refusals[0].what
    deck = read_deck(path, density=6600.0)
    assert not deck.refusals
    assert deck.config["bodies"][0]["pressures"] == [{"set": "bottom_bolt", "p": 0.5 * P_BOLT}]
    assert deck.config["bodies"][0]["rho"] == 6600.0
    text = "\n".join(map(str, deck.notes))
    assert "AMPLITUDE=RAMP: the magnitudes times 0.5" in text and "--density" in text
    smooth = tmp_path / "smooth.inp"
    smooth.write_text(path.read_text().replace("NAME=RAMP", "NAME=RAMP, DEFINITION=SMOOTH STEP"))
    (note,) = read_deck(smooth, density=6600.0).refusals
    assert note.what == "*DSLOAD, AMPLITUDE=RAMP" and "tabular" in note.fix


def _mm_deck(path):
    """The lap deck in mm-N-s-tonne: coordinates in mm, E in MPa, rho in t/mm^3, the
    bolt pressure in MPa (the same structure)."""
    import dataclasses
    bodies = sandwich_2d(1).bodies
    mesh = bodies_in_one_mesh(bodies)
    write_mesh(path, dataclasses.replace(mesh, points=mesh.points * 1e3))
    steps = (STEPS.replace("200e9, 0.285", "200e3, 0.285").replace("6600.", "6.6e-9")
             .replace("1e13, 0.", "1e4, 0.").replace("0.6, 1e12", "0.6, 1e3"))
    path.write_text(path.read_text() + steps.format(
        sections=SECTIONS, loads=DSLOAD.replace("17.554e6", "17.554")))
    return path


def test_deck_units_follow_its_materials(tmp_path):
    """A deck states no units: one whose materials are solids only in mm-N-s-tonne
    (E = 200e3 MPa, rho = 6.6e-9 t/mm^3) is read in that system, with a note and the
    comment in its TOML; its tied frequency in Hz is the SI deck's (the same structure
    in consistent units, so f0 agrees to round-off), and the run's labels use mm.
    --units overrides; an SI deck stays SI."""
    mm = read_deck(_mm_deck(tmp_path / "mm.inp"))
    si = read_deck(lap_deck(tmp_path / "si.inp"))
    assert mm.config["units"] == "mm-N-s-tonne" and si.config["units"] == "SI"
    assert any("units: mm-N-s-tonne" in str(n) for n in mm.notes)
    assert not any(n.refuses for n in mm.notes)
    f = []
    for deck in (mm, si):
        model = parse_config(deck.config, base=tmp_path).model
        assert qsma.units.unit_mismatches(model) == []
        modes = qsma.modal.linear_modes(model, [assemble_body(b) for b in model.bodies],
                                        qsma.model.pairing.make_pairing(model), n_modes=1)
        f.append(modes.f_hz[0])
    assert f[0] == pytest.approx(f[1], rel=1e-9)
    forced = read_deck(tmp_path / "mm.inp", units="SI")
    assert forced.config["units"] == "SI"
    from qsma.deck import deck_toml
    assert "a deck states no units" in deck_toml(mm)


def test_deck_units_option(tmp_path, capsys):
    """--units is a deck option: checked against the systems qsma knows, refused with a
    TOML file (which declares `units` itself)."""
    path = _mm_deck(tmp_path / "mm.inp")
    assert main(["init", str(path), "--units", "furlongs"]) == 2
    assert "invalid choice" in capsys.readouterr().err
    from qsma.examples import example_file
    assert main(["run", str(example_file("sandwich-2d.toml")), "--units", "SI", "--out",
                 str(tmp_path / "o")]) == 2
    assert "`units` at its top" in capsys.readouterr().err
    assert main(["init", str(path), "--units", "SI", "--out", str(tmp_path / "mm.toml")]) == 0
    assert 'units = "SI"' in (tmp_path / "mm.toml").read_text()


def test_boundary_with_a_value_is_a_prescribed_displacement(tmp_path):
    """A step's `*BOUNDARY` row with a value moves its DOFs in the preload and holds
    them there; it modifies the model data's row on the same set and DOF (as in
    Abaqus and CalculiX), which keeps its other DOFs. The deck runs as the TOML of the
    same clamps."""
    path = lap_deck(tmp_path / "lap.inp",
                    loads=DSLOAD + "*BOUNDARY\ntop_clamp, 2, 2, -1e-5\n")
    deck = read_deck(path)
    assert not deck.refusals
    assert any("prescribes a displacement; read as part of the preload" in str(n)
               for n in deck.notes)
    top = next(b for b in deck.config["bodies"] if b["name"] == "top")
    assert top["clamps"] == [{"set": "top_clamp", "dofs": [1]},
                             {"set": "top_clamp", "dofs": [2], "displacement": [-1e-5]}]
    model = parse_config(deck.config, base=tmp_path).model
    res = qsma.run(model, levels=ALPHA, method="basket")
    body = model.body("top")
    u = res.fields(None)[1].reshape(-1, 2)[body.mesh.nodes("top_clamp")]
    assert np.allclose(u, [0.0, -1e-5], rtol=0, atol=1e-15)


def test_a_deck_friction_of_no_slip_is_taken_as_the_largest_mu(tmp_path):
    """A deck's *FRICTION mu = 1e20 (CalculiX's idiom for no slip) is read as
    qsma.model.friction.MU_NO_SLIP, named as a note."""
    from qsma.model.friction import MU_NO_SLIP
    path = lap_deck(tmp_path / "lap.inp")
    path.write_text(path.read_text().replace("*FRICTION\n0.6, 1e12", "*FRICTION\n1.E20, 1e12"))
    deck = read_deck(path)
    assert deck.config["interface"]["mu"] == MU_NO_SLIP
    assert any("mu = 1e+20" in str(n) and not n.refuses for n in deck.notes)


def _general(tmp_path, cards):
    """The lap deck with its *CONTACT PAIR replaced by ``cards`` (general contact)."""
    text = lap_deck(tmp_path / "base.inp").read_text()
    pair = re.search(r"\*CONTACT PAIR[^\n]*\n[^\n]+\n", text).group(0)
    path = tmp_path / "general.inp"
    path.write_text(text.replace(pair, cards))
    return path


def test_general_contact_all_exterior_runs_as_the_contact_pair(tmp_path):
    """Abaqus' general contact (*CONTACT, ALL EXTERIOR, one global property) instead of
    the *CONTACT PAIR: the interface is where the two beams touch, with the property's
    friction and law. sandwich-2d's beams touch along their whole overlap, beyond the
    bolted region the benchmark names: so the model equals sandwich-2d with that
    overlap as interface, and qsma init writes touching = true, read back the same."""
    path = _general(tmp_path, "*CONTACT\n*CONTACT INCLUSIONS, ALL EXTERIOR\n"
                              "*CONTACT PROPERTY ASSIGNMENT\n, , JOINT\n")
    deck = read_deck(path)
    assert not deck.refusals, deck.refusals
    itf = deck.config["interface"]
    assert itf["touching"] and "set1" not in itf and itf["mu"] == MU
    assert itf["law"] == LAW_TABLE
    model = parse_config(deck.config, base=tmp_path).model
    bottom, top = model.bodies
    n = [len(b.mesh.facet_sets[f"touching:{o.name}"]) for b, o in ((bottom, top),
                                                                  (top, bottom))]
    ref = sandwich_2d(1)
    named = [len(b.mesh.facet_sets["interface"]) for b in ref.bodies]
    assert n[0] == n[1] > named[0] == named[1]           # the whole overlap
    assert main(["init", str(path)]) == 0
    back = load_config(tmp_path / "general.toml").model
    assert back.interface.set1 == model.interface.set1 == "touching:top"


@pytest.mark.parametrize("cards, what", [
    ("*CONTACT\n*CONTACT INCLUSIONS\ntop_interface, bottom_interface\n",
     "*CONTACT INCLUSIONS of named surfaces"),
    ("*CONTACT\n*CONTACT INCLUSIONS, ALL EXTERIOR\n*CONTACT EXCLUSIONS\n"
     "top_clamp, bottom_clamp\n", "*CONTACT EXCLUSIONS"),
    ("*CONTACT\n*CONTACT INCLUSIONS, ALL EXTERIOR\n*CONTACT PROPERTY ASSIGNMENT\n"
     "top_interface, bottom_interface, JOINT\n", "*CONTACT PROPERTY ASSIGNMENT to surfaces"),
    ("*CONTACT\n*CONTACT INCLUSIONS, ALL EXTERIOR\n*CONTACT PROPERTY ASSIGNMENT\n"
     ", , NOPE\n", "names interaction 'NOPE'"),
])
def test_general_contact_qsma_cannot_read_is_refused_with_the_way(tmp_path, cards, what):
    """Narrower general contact (named inclusions, exclusions, properties per surface
    pair) or an undefined property: refused by line, naming the *CONTACT PAIR to
    write; the deck does not run."""
    deck = read_deck(_general(tmp_path, cards))
    (note,) = [n for n in deck.refusals if what in n.what]
    assert "*CONTACT PAIR" in note.fix or "*SURFACE INTERACTION" in note.fix
    assert main(["run", str(tmp_path / "general.inp"), "--out", str(tmp_path / "o")]) == 2


@pytest.mark.parametrize("adjust, expected", [("1e-5", 1e-5), ("TOP_INTERFACE", "top_interface")])
def test_contact_pair_adjust_is_the_interfaces_adjust(tmp_path, adjust, expected):
    """``*CONTACT PAIR, ADJUST=`` a distance or a node set of the slave (names ignore
    case) becomes the interface's ``adjust`` (the gaps it closes are zero), written by
    qsma init and read back; a set the slave does not hold is a note and the gaps stay
    as meshed."""
    text = lap_deck(tmp_path / "base.inp").read_text()
    path = tmp_path / "adjust.inp"
    path.write_text(text.replace("TYPE=SURFACE TO SURFACE",
                                 f"TYPE=SURFACE TO SURFACE, ADJUST={adjust}"))
    deck = read_deck(path)
    assert not deck.refusals
    itf = deck.config["interface"]
    assert itf["adjust"] == expected and itf["set2"] == "top_interface"
    assert not any("ADJUST" in n.what for n in deck.notes)
    assert main(["init", str(path)]) == 0
    model = load_config(tmp_path / "adjust.toml").model
    assert model.interface_list[0].adjust == expected
    if isinstance(expected, float):            # the export writes the distance back
        from qsma.deck import export_calculix
        (tmp_path / "export").mkdir()
        back = export_calculix(model, tmp_path / "export" / "back.inp").text
        assert re.search(r"\*CONTACT PAIR, [^\n]*, ADJUST=1e-0?5\n", back)
    path.write_text(text.replace("TYPE=SURFACE TO SURFACE",
                                 "TYPE=SURFACE TO SURFACE, ADJUST=BOTTOM_CLAMP"))
    deck = read_deck(path)
    assert "adjust" not in deck.config["interface"]
    assert any("ADJUST=BOTTOM_CLAMP" in n.what and not n.refuses for n in deck.notes)
