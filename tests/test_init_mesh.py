"""`qsma init model.msh`: the configuration of a mesh file with physical groups, what a
mesh gives (bodies, sets, facing surfaces) written out, what it cannot give marked
REQUIRED so the file refuses to run until each is decided."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import qsma
from qsma.cli import main
from qsma.analysis.config import load_config
from qsma.deck.skeleton import facing_surfaces
from qsma.examples import sandwich_2d
from qsma.analysis.levels import Levels
from qsma.model import write_mesh
from helpers import bodies_in_one_mesh

LEVELS = Levels("alpha", (20.0, 200.0, 2000.0))
#: What the sandwich-2d example sets and a mesh cannot say: the REQUIRED lines filled.
FILLED = {
    "# E = 2.0e11": "E = 2.0e11",
    "# nu = 0.3": "nu = 0.285",
    "# rho = 7850.0": "rho = 6600.0",
    "# mu = 0.6": "mu = 0.6",
}


def _fill(text):
    out = []
    for line in text.splitlines():
        for old, new in FILLED.items():
            if line.startswith(old):
                line = new
        if line.startswith("# clamps = "):
            line = line[2:]
        if line.startswith("# pressures = "):
            line = line[2:].replace("p = 0.0", "p = 17.554e6")
        if line.startswith("# points = "):
            line = 'sets = [["bottom", "bottom_tip"], ["top", "top_tip"]]'
        if line.startswith("# direction = "):
            line = "direction = [0.0, 1.0]"
        out.append(line)
    return "\n".join(out) + "\n"


def test_mesh_skeleton_filled_in_runs_as_the_example(tmp_path, capsys):
    """sandwich-2d written as one Gmsh file (a physical group per body): the skeleton
    names both bodies by their groups, lists their sets, proposes the two interface
    surfaces (and not the outer boundaries that hold them) and refuses to run while E
    is missing; with the REQUIRED lines filled as the example sets them it gives the
    example's f0 and damping (the coordinates went through the .msh file)."""
    example = sandwich_2d(1)
    write_mesh(tmp_path / "lap.msh", bodies_in_one_mesh(example.bodies))
    assert main(["init", str(tmp_path / "lap.msh")]) == 0
    text = (tmp_path / "lap.toml").read_text()
    assert 'cells = "bottom"' in text and 'cells = "top"' in text
    assert text.count("[[interfaces]]") == 1
    assert 'set1 = "bottom_interface"' in text and 'set2 = "top_interface"' in text
    assert '# clamps = [{ set = "bottom_clamp"' in text
    assert main(["run", str(tmp_path / "lap.toml"), "--out", str(tmp_path / "o")]) == 2
    assert "missing required key 'E'" in capsys.readouterr().err
    (tmp_path / "lap.toml").write_text(_fill(text))
    model = load_config(tmp_path / "lap.toml").model
    got = qsma.run(model, levels=LEVELS)
    want = qsma.run(example, levels=LEVELS)
    assert got.f0_hz == pytest.approx(want.f0_hz, rel=1e-9)
    assert np.allclose(got.zeta, want.zeta, rtol=1e-6, atol=1e-12)


def test_surfaces_face_only_where_normals_oppose():
    """Two unit squares stacked (facing at y = 1) and a third apart: only the facing
    pair is proposed; surfaces of one body or with normals in the same sense are not
    interfaces."""
    from qsma.mesh.generate import box_facets, structured_mesh
    grid = np.linspace(0.0, 1.0, 5)
    base = structured_mesh(grid, grid)

    def square(dx, dy):
        m = dataclasses.replace(base, points=base.points + [dx, dy])
        return m.with_sets(facet_sets={
            "top": box_facets(m, lambda x: np.isclose(x[:, 1], dy + 1.0)),
            "bottom": box_facets(m, lambda x: np.isclose(x[:, 1], dy))})
    low, high, far = square(0.0, 0.0), square(0.0, 1.0), square(5.0, 0.0)
    found = facing_surfaces(["low", "high", "far"], [low, high, far])
    assert [(f[0], f[1], f[2], f[3]) for f in found] == [("low", "top", "high", "bottom")]
    assert found[0][4] == pytest.approx(1.0)


def test_init_of_a_mesh_refuses_deck_options(tmp_path, capsys):
    write_mesh(tmp_path / "lap.msh", bodies_in_one_mesh(sandwich_2d(1).bodies))
    assert main(["init", str(tmp_path / "lap.msh"), "--density", "7850"]) == 2
    assert "--density apply to a deck" in capsys.readouterr().err
    assert main(["init", str(tmp_path / "x.toml")]) == 2
    assert "or a Gmsh mesh (.msh)" in capsys.readouterr().err


def test_a_mesh_without_contact_groups_proposes_the_bodies_that_touch(tmp_path):
    """sandwich-2d written as one Gmsh file without its interface groups: no named
    surfaces face each other, so the skeleton proposes the two beams, which touch,
    with touching = true; filled in, it runs on the faces where they touch (their
    whole overlap)."""
    example = sandwich_2d(1)
    bodies = [dataclasses.replace(b, mesh=dataclasses.replace(b.mesh, facet_sets={
        k: v for k, v in b.mesh.facet_sets.items() if k != "interface"}))
        for b in example.bodies]
    write_mesh(tmp_path / "lap.msh", bodies_in_one_mesh(bodies))
    assert main(["init", str(tmp_path / "lap.msh")]) == 0
    text = (tmp_path / "lap.toml").read_text()
    assert text.count("[[interfaces]]") == 1 and "touching = true" in text
    assert "bottom and top touch over 124 and 124 facets" in text
    (tmp_path / "lap.toml").write_text(_fill(text))
    model = load_config(tmp_path / "lap.toml").model
    assert model.interface_list[0].set1 == "touching:top"
    assert len(model.body("bottom").mesh.facet_sets["touching:top"]) == 124
