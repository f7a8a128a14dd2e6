"""Bodies of different cell types in one file: a trilinear block under a quadratic
(C3D20) block, meshed apart, each body of one cell type. The file is read body by body
(each body's mesh one cell type, or a mix one mesh holds); a body whose own cells mix
types that share no facet type is refused naming its element sets."""
from __future__ import annotations

import numpy as np
import pytest

import qsma
from qsma.analysis.config import parse_config
from qsma.analysis.levels import Levels
from qsma.deck import read_deck
from qsma.errors import InputError, MeshFileError
from qsma.mesh.generate import structured_mesh
from qsma.mesh.io import read_assembly, read_mesh
from helpers import load_benchmark, needs_ccx

#: uniform pressure on the upper block's top face (Pa), over its area 1 m^2
PRESSURE = 1e6


def _nodes_and_elements(mesh, first_node, first_element, element, elset):
    nodes = [f"{first_node + i}, " + ", ".join(f"{x:.17g}" for x in xyz)
             for i, xyz in enumerate(mesh.points)]
    rows = []
    for k, cell in enumerate(mesh.cells):      # at most 16 entries per line
        ids = [str(first_node + int(n)) for n in cell]
        rows.append(f"{first_element + k}, " + ", ".join(ids[:15])
                    + (",\n" + ", ".join(ids[15:]) if len(ids) > 15 else ""))
    return "\n".join(nodes), f"*ELEMENT, TYPE={element}, ELSET={elset}\n" + "\n".join(rows)


def mixed_deck(path, extra="", upper_cells=3, shift=0.0, pair="UPPER_BOTTOM, LOWER_TOP"):
    """The deck: LOWER (2 x 2 x 1 C3D8, z in [0, 0.5]) clamped at its bottom, UPPER
    (``upper_cells`` x ``upper_cells`` x 1 C3D20, z in [0.5, 1], moved by ``shift`` along
    x) pressed onto it, held in x and y at its top; hard contact, mu = 0.3, the upper
    block the slave (``pair``: the *CONTACT PAIR row)."""
    lower = structured_mesh(*[np.linspace(0, 1, 3)] * 2, np.linspace(0, 0.5, 2))
    upper = structured_mesh(np.linspace(0, 1, upper_cells + 1) + shift,
                            np.linspace(0, 1, upper_cells + 1), np.linspace(0.5, 1, 2),
                            cell_type="hexahedron20")
    n = lower.n_nodes
    nodes_l, cells_l = _nodes_and_elements(lower, 1, 1, "C3D8", "LOWER")
    nodes_u, cells_u = _nodes_and_elements(upper, n + 1, 101, "C3D20", "UPPER")
    bottom = 1 + np.flatnonzero(lower.points[:, 2] == 0.0)
    top = n + 1 + np.flatnonzero(upper.points[:, 2] == 1.0)
    path.write_text(f"""*NODE
{nodes_l}
{nodes_u}
{cells_l}
{cells_u}
*NSET, NSET=BOTTOM
{", ".join(map(str, bottom))}
*NSET, NSET=TOP
{", ".join(map(str, top[:16]))}
{", ".join(map(str, top[16:])) or ""}
{extra}*SURFACE, NAME=LOWER_TOP
LOWER, S2
*SURFACE, NAME=UPPER_BOTTOM
UPPER, S1
*SURFACE, NAME=UPPER_TOP
UPPER, S2
*MATERIAL, NAME=STEEL
*ELASTIC
200e9, 0.3
*DENSITY
7800.
*SOLID SECTION, ELSET=LOWER, MATERIAL=STEEL
*SOLID SECTION, ELSET=UPPER, MATERIAL=STEEL
*SURFACE INTERACTION, NAME=JOINT
*FRICTION
0.3
*CONTACT PAIR, INTERACTION=JOINT, TYPE=SURFACE TO SURFACE
{pair}
*BOUNDARY
BOTTOM, 1, 3
TOP, 1, 2
*STEP
*STATIC
*DSLOAD
UPPER_TOP, P, {PRESSURE:g}
*END STEP
*STEP
*FREQUENCY
4
*END STEP
""")
    return path


def test_each_body_of_a_file_is_one_cell_type(tmp_path):
    """The file holds C3D8 and C3D20 cells: read as one mesh it is refused (one mesh
    cannot mix them), read as an assembly each body is its own type, by cell set and by
    connected part."""
    path = mixed_deck(tmp_path / "mixed.inp")
    with pytest.raises(MeshFileError, match="hexahedron, hexahedron20, a mix"):
        read_mesh(path)
    asm = read_assembly(path)
    lower, upper = asm.body_mesh("LOWER"), asm.body_mesh("UPPER")
    assert (lower.cell_type, lower.element, lower.n_cells) == ("hexahedron", "C3D8", 4)
    assert (upper.cell_type, upper.element, upper.n_cells) == ("hexahedron20", "C3D20", 9)
    assert upper.facet_sets["UPPER_BOTTOM"].shape == (9, 8)      # quad8 faces
    assert lower.facet_sets["LOWER_TOP"].shape == (4, 4)
    parts = asm.component_meshes()
    assert [m.cell_type for m in parts] == ["hexahedron", "hexahedron20"]
    np.testing.assert_array_equal(parts[1].points, upper.points)


def test_a_body_mixing_cell_types_is_refused_naming_its_element_sets(tmp_path):
    """One element set over both blocks taken as one body: the message names each
    type's element name and sets, and the fix (a body per type, joined by an
    interface)."""
    path = mixed_deck(tmp_path / "mixed.inp", extra="*ELSET, ELSET=BOTH\nLOWER, UPPER\n")
    with pytest.raises(MeshFileError) as err:
        read_assembly(path).body_mesh("BOTH")
    text = str(err.value)
    assert "4 C3D8 (hexahedron) cell(s) in element set(s) LOWER, BOTH" in text
    assert "9 C3D20 (hexahedron20) cell(s) in element set(s) UPPER, BOTH" in text
    assert "a body of its own" in text and "*CONTACT PAIR" in text


def test_the_deck_runs_and_its_preload_carries_the_pressure(tmp_path):
    """qsma run's model of the deck: a trilinear and a quadratic body, mortar between
    quad8 slave facets and bilinear master facets; the preload's contact forces carry
    the pressure's resultant (equilibrium), and the levels are solved."""
    deck = read_deck(mixed_deck(tmp_path / "mixed.inp"))
    model = parse_config(deck.config, base=tmp_path).model
    assert [b.mesh.cell_type for b in model.bodies] == ["hexahedron", "hexahedron20"]
    res = qsma.run(model, levels=Levels("alpha", (1.0, 10.0, 100.0)), method="basket")
    assert res.success and len(res.alpha) == 3 and np.all(np.isfinite(res.f_hz))
    assert res.preload.lam[:, -1].sum() == pytest.approx(PRESSURE, rel=1e-9)


@needs_ccx
def test_calculix_agrees_on_the_tied_frequency_and_the_contact_resultant(tmp_path):
    """The model exported to CalculiX (`qsma export --calculix --tied`): the tied f0
    equals qsma's to the 7 digits ccx prints (measured 1324.4993 against 1324.499 Hz),
    and the preload's total contact force the pressure's resultant (ccx: 999999.76 N
    of 1e6 at the default penalty). The nodal forces are not compared: on quad8 slave
    faces CalculiX's node-to-surface forces are the consistent nodal forces of the
    pressure (negative at the corners), qsma's those of its mixed basis."""
    deck = read_deck(mixed_deck(tmp_path / "mixed.inp"))
    model = parse_config(deck.config, base=tmp_path).model
    r = load_benchmark("bench_export_calculix").compare(model, tmp_path)
    assert r["f0_tied"] == pytest.approx(r["f0_qsma"], rel=1e-6)
    assert r["total_qsma"] == pytest.approx(PRESSURE, rel=1e-9)
    assert r["total_ccx"] == pytest.approx(PRESSURE, rel=1e-6)


def test_a_quadratic_slave_the_master_covers_only_in_part_names_the_swap(tmp_path):
    """One C3D20 slave face half over the master (as in CalculiX's beamcontact deck): on
    the covered half the quad8 facet's mixed shape functions of the nodes off the master
    integrate to almost nothing, so no facet can be coupled; the message says so (not
    that the surfaces do not face each other) and names the swap, with which the deck
    runs (the linear face the slave, half of it covered) and carries the pressure."""
    levels = Levels("alpha", (1.0, 10.0))
    with pytest.raises(InputError, match=r"every one of the 1 quad8 slave facet\(s\) is "
                       r"only partly covered by the master \(at most 50.0 %.*swap the "
                       r"surfaces of the \*CONTACT PAIR row"):
        read_deck(mixed_deck(tmp_path / "half.inp", upper_cells=1, shift=0.5))
    deck = read_deck(mixed_deck(tmp_path / "swap.inp", upper_cells=1, shift=0.5,
                                pair="LOWER_TOP, UPPER_BOTTOM"))
    res = qsma.run(parse_config(deck.config, base=tmp_path).model, levels=levels,
                   method="basket")
    assert res.success
    assert res.preload.lam[:, -1].sum() == pytest.approx(PRESSURE, rel=1e-9)
