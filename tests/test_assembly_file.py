"""Assemblies in one mesh file: bodies chosen by cell set, several interfaces in TOML."""
import numpy as np
import pytest
import scipy.sparse.linalg as spla

import qsma
from qsma.cli import main
from qsma.analysis.config import load_config
from qsma.errors import InputError, MeshFileError
from qsma.examples import STACK_2D, sandwich_2d, stack_2d
from qsma.fe import assemble_body
from qsma.modal import linear_modes
from qsma.model import make_pairing
from qsma.mesh.io import read_assembly
from helpers import (STACK_INTERFACES, body_toml as _body_toml, one_file as _one_file,
                     stack_toml as _stack_toml)

LEVELS = qsma.Levels.log("tip", 1e-6, 1e-4, 4)


@pytest.mark.parametrize("ext", ["msh", "inp"])
def test_two_plates_from_one_file_give_the_sandwich_answers(ext, tmp_path):
    """sandwich-2d with both plates in one Gmsh / Abaqus file, each body a cell set: the
    same meshes, and the run gives the example's f0, q and zeta (same arithmetic)."""
    ref = sandwich_2d(1)
    _one_file(ref.bodies, tmp_path / f"both.{ext}")
    toml = "".join(_body_toml(b.name, f"both.{ext}") for b in ref.bodies) + (
        '[interface]\nbody1 = "bottom"\nset1 = "bottom_interface"\nbody2 = "top"\n'
        'set2 = "top_interface"\nmu = 0.6\n'
        '[tip]\nsets = [["bottom", "bottom_tip"], ["top", "top_tip"]]\n'
        'direction = [0.0, 1.0]\n')
    (tmp_path / "c.toml").write_text(toml)
    model = load_config(tmp_path / "c.toml").model
    for b, r in zip(model.bodies, ref.bodies):
        # .inp coordinates fit CalculiX's 20-character fields: 0.0025399999999999997 is
        # written as 0.00254, one unit in the last place away (docs/mesh-io.md)
        np.testing.assert_allclose(b.mesh.points, r.mesh.points, rtol=5e-14, atol=0)
        assert ext == "inp" or np.array_equal(b.mesh.points, r.mesh.points)
        assert np.array_equal(b.mesh.cells, r.mesh.cells)
        assert set(b.mesh.cell_sets) == {b.name}       # the other body's set is left out
    a, b = qsma.run(model, levels=LEVELS), qsma.run(ref, levels=LEVELS)
    # the same arithmetic from a .msh; from an .inp, coordinates moved by up to 5e-14
    # and the eigensolver converged from another start (relative 1e-10 seen on f0)
    rtol = 1e-12 if ext == "msh" else 1e-8
    assert a.success and a.f0_hz == pytest.approx(b.f0_hz, rel=rtol)
    assert np.allclose(a.q, b.q, rtol=max(rtol, 1e-10))
    assert np.allclose(a.zeta, b.zeta, rtol=rtol, atol=1e-12)


def test_two_bodies_read_whole_from_one_file_point_to_cells(tmp_path):
    """Two bodies of one file, neither with ``cells``: each would be the whole mesh; the
    message names ``cells`` and the file's cell sets."""
    ref = sandwich_2d(1)
    _one_file(ref.bodies, tmp_path / "both.msh")
    toml = "".join(_body_toml(b.name, "both.msh").replace(f'cells = "{b.name}"\n', "")
                   for b in ref.bodies) + (
        '[interface]\nbody1 = "bottom"\nset1 = "bottom_interface"\nbody2 = "top"\n'
        'set2 = "top_interface"\nmu = 0.6\n'
        '[tip]\nsets = [["bottom", "bottom_tip"]]\ndirection = [0.0, 1.0]\n')
    (tmp_path / "c.toml").write_text(toml)
    with pytest.raises(InputError, match=r"bodies \['bottom', 'top'\] all read .*both.msh "
                       r"whole.*'cells'.*cell sets of the file: \['bottom', 'top'\]"):
        load_config(tmp_path / "c.toml")


def test_a_conforming_file_read_whole_points_to_cells(tmp_path):
    """A file of two bodies sharing nodes, read whole as one body: its contact surfaces are
    inside the mesh; the message says first that the file holds several cell sets and
    that ``cells`` takes one body out of it."""
    _conforming_inp(tmp_path / "blocks.inp")
    (tmp_path / "c.toml").write_text(
        '[[bodies]]\nname = "lower"\nmesh = "blocks.inp"\nE = 2e11\nnu = 0.3\nrho = 7800.0\n'
        '[[bodies]]\nname = "upper"\nmesh = "blocks.inp"\ncells = "UPPER"\nE = 2e11\n'
        'nu = 0.3\nrho = 7800.0\n[interface]\nbody1 = "lower"\nset1 = "LOWER_TOP"\n'
        'body2 = "upper"\nset2 = "UPPER_BOTTOM"\nmu = 0.6\n'
        '[tip]\nsets = [["upper", "TIP"]]\ndirection = [0.0, 1.0]\n')
    with pytest.raises(InputError, match=r"bodies\[0\] \('lower'\): .*blocks.inp holds \d "
                       r"cell sets .*'LOWER'.*'UPPER'.*cells = '.*'\. Reading it whole gave: "
                       r".*not boundary facets"):
        load_config(tmp_path / "c.toml")


def test_pressure_on_an_element_set_says_that_it_needs_faces(tmp_path):
    """A pressure named by an element set (as an Abaqus *DLOAD, ELSET may be) is refused
    with what a pressure needs: a facet set (*SURFACE of element faces)."""
    mesh = read_assembly(_conforming_inp(tmp_path / "blocks.inp")).body_mesh("LOWER")
    steel = qsma.model.Material(200e9, 0.3, 7800.0)
    with pytest.raises(InputError, match=r"pressure on '_L_TOP', which is a cell set "
                       r"\(elements.*\*SURFACE, TYPE=ELEMENT of the loaded faces \(rows "
                       r"'element set, S1'..'S4'\).*available facet sets: \['LOWER_TOP'"):
        qsma.model.Body("lower", mesh, steel, pressures=(qsma.model.Pressure("_L_TOP", 1e6),))


def _conforming_inp(path, nx=8, ny=2, L=0.1, h=0.01):
    """Two blocks of CPE4 sharing their nodes along y = h (one mesh made in one go): the
    contact surfaces are the top faces (S3) of the lower block and the bottom faces (S1)
    of the upper block, interior to the file."""
    xs = np.linspace(0, L, nx + 1)
    ys = np.linspace(0, 2 * h, 2 * ny + 1)
    node = lambda i, j: 1 + i + (nx + 1) * j
    lines = ["*NODE"] + [f"{node(i, j)}, {float(x)!r}, {float(y)!r}" for j, y in enumerate(ys)
                         for i, x in enumerate(xs)]
    lines.append("*ELEMENT, TYPE=CPE4")
    eid, lower, upper = 0, [], []
    for j in range(2 * ny):
        for i in range(nx):
            eid += 1
            lines.append(f"{eid}, {node(i, j)}, {node(i + 1, j)}, {node(i + 1, j + 1)}, "
                         f"{node(i, j + 1)}")
            (lower if j < ny else upper).append(eid)
    top_row = [e for e in lower if (e - 1) // nx == ny - 1]
    bottom_row = [e for e in upper if (e - 1) // nx == ny]
    ids = lambda v: [", ".join(map(str, v[k:k + 16])) for k in range(0, len(v), 16)]
    lines += ["*ELSET, ELSET=LOWER", *ids(lower), "*ELSET, ELSET=UPPER", *ids(upper),
              "*ELSET, ELSET=_L_TOP", *ids(top_row), "*ELSET, ELSET=_U_BOT", *ids(bottom_row),
              "*SURFACE, NAME=LOWER_TOP", "_L_TOP, S3", "*SURFACE, NAME=UPPER_BOTTOM",
              "_U_BOT, S1",
              "*NSET, NSET=CLAMP", *ids([node(0, j) for j in range(2 * ny + 1)]),
              "*NSET, NSET=TIP", *ids([node(nx, j) for j in range(2 * ny + 1)])]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_conforming_bodies_in_one_file_are_split_and_tied_back(tmp_path):
    """An interface interior to the file (shared nodes) is a boundary of each body: both
    bodies get their own copy of the shared nodes, the pairing is node-to-node, and the
    tied pair has the modes of the whole block (the same finite element space), 1e-9."""
    path = _conforming_inp(tmp_path / "blocks.inp")
    with pytest.raises(MeshFileError, match="not boundary facets"):
        qsma.model.read_mesh(path)                         # one body: refused as before
    asm = read_assembly(path)
    assert {"LOWER", "UPPER"} <= set(asm.cell_sets)
    lo, up = asm.body_mesh("LOWER"), asm.body_mesh("UPPER")
    assert lo.n_nodes == up.n_nodes == 9 * 3
    assert "UPPER_BOTTOM" in up.facet_sets and "LOWER_TOP" in lo.facet_sets
    steel = qsma.model.Material(200e9, 0.3, 7800.0)
    clamp = (qsma.model.Clamp("CLAMP"),)
    bodies = (qsma.model.Body("lower", lo, steel, clamp),
              qsma.model.Body("upper", up, steel, clamp))
    model = qsma.model.Model(bodies, qsma.model.Interface("lower", "LOWER_TOP", "upper",
                                                          "UPPER_BOTTOM"))
    pairing = make_pairing(model)
    assert pairing.coupling == "node" and pairing.n_pairs == 9
    tied = linear_modes(model, [assemble_body(b) for b in bodies], pairing, n_modes=3)
    ab = assemble_body(qsma.model.Body("block", _whole_block(), steel, clamp))
    K = ab.K.tocsc()[ab.free][:, ab.free]
    M = ab.M.tocsc()[ab.free][:, ab.free]
    w2 = np.sort(spla.eigsh(K, k=3, M=M, sigma=0, which="LM")[0])
    assert np.allclose(tied.omega, np.sqrt(w2), rtol=1e-9)


def _whole_block(nx=8, ny=2, L=0.1, h=0.01):
    from qsma.mesh.generate import structured_mesh
    m = structured_mesh(np.linspace(0, L, nx + 1), np.linspace(0, 2 * h, 2 * ny + 1))
    return m.with_sets(node_sets={"CLAMP": np.flatnonzero(m.points[:, 0] < 1e-12)})


def test_unknown_cell_set_names_the_cell_sets(tmp_path):
    asm = read_assembly(_conforming_inp(tmp_path / "blocks.inp"))
    with pytest.raises(InputError, match=r"no cell set named 'MIDDLE'.*'LOWER', 'UPPER'"):
        asm.body_mesh("MIDDLE")


def test_stack_in_one_file_with_a_list_of_interfaces(tmp_path):
    """stack-2d from one Gmsh file and [[interfaces]]: the model of stack_2d(mu=(0.6,
    0.3)) (same meshes, interfaces and mu), hence the same condensed problem."""
    path, ref = _stack_toml(tmp_path, STACK_INTERFACES)
    model = load_config(path).model
    assert model.interface is None and len(model.interface_list) == 2
    assert [i.mu for i in model.interface_list] == [0.6, 0.3]
    for b, r in zip(model.bodies, ref.bodies):
        assert np.array_equal(b.mesh.points, r.mesh.points)
    assert STACK_2D["n_fine_middle"] != STACK_2D["n_fine"]   # both interfaces mortar


@pytest.mark.parametrize("extra, match", [
    ('[[interfaces]]\nbody1 = "middle"\nset1 = "middle_lower"\nbody2 = "bottom"\n'
     'set2 = "bottom_upper"\nmu = 0.6\n', "listed twice"),
    ('[interface]\nbody1 = "bottom"\nset1 = "bottom_upper"\nbody2 = "middle"\n'
     'set2 = "middle_lower"\nmu = 0.6\n', "exactly one of the two"),
])
def test_bad_interface_lists_exit_2_from_the_cli(tmp_path, capsys, extra, match):
    path, _ = _stack_toml(tmp_path, STACK_INTERFACES + extra)
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    assert match in capsys.readouterr().err


def test_a_body_in_no_interface_exits_2_from_the_cli(tmp_path, capsys):
    first = STACK_INTERFACES[:STACK_INTERFACES.index("[[interfaces]]", 1)]
    path, _ = _stack_toml(tmp_path, first)
    assert main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "body 'top' belongs to no interface" in err and "Fix" in err


def _two_cubes_deck(path):
    """Two unit-cube blocks of C3D8 (2x2x2 each) stacked along z, meshed apart, in one
    flat deck: a node-based slave surface on the lower block's top, an element-based
    master surface on the upper block's bottom, a *CONTACT PAIR whose names differ in
    case from their definitions, a friction coefficient and a clamp."""
    from qsma.mesh.generate import structured_mesh
    from qsma.model import Body, Material
    steel = Material(200e9, 0.3, 7800.0)
    bodies = []
    for k, name in enumerate(("lower", "upper")):
        m = structured_mesh(*(np.linspace(0, 1, 3),) * 2, np.linspace(k, k + 1, 3))
        on = lambda z: (lambda p: np.abs(p[:, 2] - z) < 1e-9)
        m = m.with_sets(node_sets={"clamp": np.flatnonzero(on(0)(m.points)),
                                   "top_nodes": np.flatnonzero(on(k + 1)(m.points))},
                        facet_sets={"bottom": m.boundary_facets_where(on(k))})
        bodies.append(Body(name, m, steel))
    _one_file(bodies, path)
    with open(path, "a") as f:
        f.write("*SURFACE, NAME=SLAVE_TOP, TYPE=NODE\nlower_top_nodes\n"
                "*CONTACT PAIR, INTERACTION=si1, TYPE=SURFACE TO SURFACE\n"
                "slave_top, UPPER_BOTTOM\n"
                "*SURFACE INTERACTION, NAME=SI1\n*FRICTION\n0.25, 1e5\n"
                "*BOUNDARY\nlower_clamp, 1, 3\nupper_top_nodes, 3, 3, 0.001\n")
    return path


def test_contact_pairs_and_connected_bodies_of_a_flat_deck(tmp_path):
    """What a CalculiX-style deck holds: the contact pair (names as defined, the mu of
    its interaction), the homogeneous clamp (a prescribed displacement is not a clamp),
    the connected parts as bodies, a node-based surface as the facets it spans; the two
    bodies and the pair make a model whose interface is coupled and tied."""
    asm = read_assembly(_two_cubes_deck(tmp_path / "cubes.inp"))
    (pair,) = asm.contact_pairs
    assert (pair.slave, pair.master, pair.mu) == ("SLAVE_TOP", "upper_bottom", 0.25)
    assert asm.file_mesh.boundaries == [("lower_clamp", 1, 3)]
    lower, upper = asm.component_meshes()
    assert lower.n_nodes == upper.n_nodes == 27
    assert len(lower.facets("SLAVE_TOP")) == 4 and "SLAVE_TOP" not in upper.facet_sets
    steel = qsma.model.Material(200e9, 0.3, 7800.0)
    bodies = (qsma.model.Body("lower", lower, steel, (qsma.model.Clamp("lower_clamp"),)),
              qsma.model.Body("upper", upper, steel))
    itf = qsma.model.Interface("upper", pair.master, "lower", pair.slave, mu=pair.mu)
    model = qsma.model.Model(bodies, itf)
    p = make_pairing(model)
    assert p.coupling == "node" and p.n_pairs == 9
    assert np.allclose(p.normals, [0, 0, -1])          # from body 1 (upper) into lower
    modes = linear_modes(model, [assemble_body(b) for b in bodies], p, n_modes=1)
    assert modes.f_hz[0] > 0


PARTS_DECK = """\
*Heading
*Part, name=Beam
*Node
      1,           0.,           0.
      2,           1.,           0.
      3,           2.,           0.
      4,           0.,           1.
      5,           1.,           1.
      6,           2.,           1.
*Element, type=CPS4
1, 1, 2, 5, 4
2, 2, 3, 6, 5
*Nset, nset=Set-1
 1, 4
*Elset, elset=_Surf-1_S1, internal
 1, 2
*Surface, type=ELEMENT, name=Bottom
_Surf-1_S1, S1
*Elset, elset=_Surf-2_S3, internal
 1, 2
*Surface, type=ELEMENT, name=Top
_Surf-2_S3, S3
*End Part
*Assembly, name=Assembly
*Instance, name=Lower, part=Beam
*End Instance
*Instance, name=Upper, part=Beam
 0., 1., 0.
*End Instance
*Instance, name=Turned, part=Beam
 0., 0., 0.
 0., 0., 0., 0., 0., 1., 90.
*End Instance
*Nset, nset=Fixed, instance=Upper
 3, 6
*Surface, type=ELEMENT, name=Left
Upper._Surf-1_S1, S1
*End Assembly
*Contact Pair, interaction=IntProp-1
Upper.Bottom, Lower.Top
"""


def test_parts_and_placed_instances_become_bodies(tmp_path):
    """One part placed three times (as is, translated by (0, 1), turned by 90 degrees
    about z): each instance is a body with its nodes moved, its sets named
    <instance>.<set>, assembly sets and the contact pair in instance terms; the
    translated instance touches the first one node-to-node. read_mesh still refuses
    the file (it reads one body)."""
    path = tmp_path / "parts.inp"
    path.write_text(PARTS_DECK)
    with pytest.raises(MeshFileError, match="second \\*PART|second \\*INSTANCE|translated"):
        qsma.model.read_mesh(path)
    asm = read_assembly(path)
    assert asm.cell_sets == ["Lower", "Turned", "Upper"]
    (pair,) = asm.contact_pairs
    assert (pair.slave, pair.master) == ("Upper.Bottom", "Lower.Top")
    lower, upper, turned = (asm.body_mesh(n) for n in ("Lower", "Upper", "Turned"))
    assert np.allclose(upper.points, lower.points + [0.0, 1.0])
    assert np.allclose(turned.points, lower.points[:, ::-1] * [-1.0, 1.0])   # x, y -> -y, x
    assert set(upper.node_sets) == {"Upper.Set-1", "Fixed"}
    assert upper.nodes("Fixed").tolist() == [2, 5]
    assert set(upper.facet_sets) == {"Upper.Bottom", "Upper.Top", "Left"}
    steel = qsma.model.Material(200e9, 0.3, 7800.0)
    model = qsma.model.Model((qsma.model.Body("lower", lower, steel),
                              qsma.model.Body("upper", upper, steel)),
                             qsma.model.Interface("lower", pair.master, "upper", pair.slave))
    p = make_pairing(model)
    assert p.coupling == "node" and p.n_pairs == 3
    assert np.allclose(p.normals, [0, 1])
