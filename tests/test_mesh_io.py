"""Mesh files with named sets (qsma.model.io): round trips, hand-written files, files
made by Gmsh, and malformed files."""
import re
import subprocess
from pathlib import Path

import meshio
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st
from skfem import MeshTet

from qsma.errors import InputError, MeshFileError
from qsma.examples import sandwich_2d
from qsma.mesh.generate import structured_mesh
from qsma.mesh.io import MESH_FORMATS, read_mesh, write_mesh
from qsma.mesh.mesh import Mesh, boundary_facets
from helpers import QUAD_GRID, needs_ccx

DATA = Path(__file__).parent / "data"
#: (file name, gmsh_version) of every format and version written
WRITTEN = [("mesh.msh", "4.1"), ("mesh.msh", "2.2"), ("mesh.inp", "4.1")]
WRITTEN_IDS = ["msh4.1", "msh2.2", "inp"]


# --- helpers -------------------------------------------------------------------------

def facet_keys(rows) -> set:
    return {tuple(sorted(r)) for r in np.asarray(rows).tolist()}


def assert_same_mesh(read: Mesh, mesh: Mesh):
    """Same points (to round-off), cells in the same order, the same sets, and the same
    element formulation (a Gmsh file names none: only the default, CPE/C3D with full
    integration, may come back as None)."""
    assert read.cell_type == mesh.cell_type
    default = lambda e: e is None or re.fullmatch(r"(CPE|C3D)\d+", e)
    assert read.element == mesh.element or (default(read.element) and default(mesh.element))
    assert read.points.shape == mesh.points.shape
    scale = np.abs(mesh.points).max()
    np.testing.assert_allclose(read.points, mesh.points, rtol=0, atol=1e-14 * scale)
    np.testing.assert_array_equal(read.cells, mesh.cells)
    assert {k: v.tolist() for k, v in read.node_sets.items()} == \
        {k: np.unique(v).tolist() for k, v in mesh.node_sets.items()}
    assert {k: facet_keys(v) for k, v in read.facet_sets.items()} == \
        {k: facet_keys(v) for k, v in mesh.facet_sets.items()}
    assert {k: v.tolist() for k, v in read.cell_sets.items()} == \
        {k: np.unique(v).tolist() for k, v in mesh.cell_sets.items()}


def assert_outward(mesh: Mesh):
    """Facets read from files come in the orientation of boundary_facets."""
    oriented = {tuple(r) for r in boundary_facets(mesh).tolist()}
    for rows in mesh.facet_sets.values():
        assert {tuple(r) for r in rows.tolist()} <= oriented


def write_text(folder: Path, name: str, text: str) -> Path:
    path = folder / name
    path.write_text(text)
    return path


def hex_mesh() -> Mesh:
    m = structured_mesh(np.linspace(0.0, 3.0, 4), np.linspace(0.0, 1.0, 3),
                        np.array([0.0, 0.5, 2.0]))
    eps = 1e-9
    return m.with_sets(
        node_sets={"origin": [0], "x0": np.flatnonzero(m.points[:, 0] < eps)},
        facet_sets={"x0": m.boundary_facets_where(lambda p: p[:, 0] < eps),
                    "z top": m.boundary_facets_where(lambda p: p[:, 2] > 2.0 - eps),
                    "corner faces": m.boundary_facets_where(
                        lambda p: (p[:, 0] < 1.0 + eps) & (p[:, 2] > 0.5 - eps))},
        cell_sets={"first": [0, 1, 2], "odd": np.arange(1, 12, 2), "all": np.arange(12)})


def tetra_mesh() -> Mesh:
    sk = MeshTet.init_tensor(np.linspace(0, 1, 3), np.linspace(0, 2, 3), np.linspace(0, 1, 2))
    cells = sk.t.T.copy()
    x = sk.p.T[cells]
    inverted = np.linalg.det(x[:, 1:] - x[:, :1]) < 0        # scikit-fem mixes orientations
    cells[inverted] = cells[inverted][:, [0, 2, 1, 3]]
    m = Mesh(sk.p.T, cells, "tetra")
    return m.with_sets(node_sets={"top": np.flatnonzero(m.points[:, 2] > 0.5)},
                       facet_sets={"y0": m.boundary_facets_where(lambda p: p[:, 1] < 1e-9),
                                   "y2": m.boundary_facets_where(lambda p: p[:, 1] > 2 - 1e-9)},
                       cell_sets={"some": [3, 5, 7]})


def triangle_mesh() -> Mesh:
    q = structured_mesh(np.linspace(-1.0, 1.0, 5), np.linspace(0.0, 0.3, 3))
    cells = np.concatenate([q.cells[:, [0, 1, 2]], q.cells[:, [0, 2, 3]]])
    m = Mesh(q.points, cells, "triangle")
    return m.with_sets(node_sets={"left": np.flatnonzero(m.points[:, 0] < -1 + 1e-9)},
                       facet_sets={"top": m.boundary_facets_where(lambda p: p[:, 1] > 0.3 - 1e-9),
                                   "right": m.boundary_facets_where(lambda p: p[:, 0] > 1 - 1e-9)},
                       cell_sets={"upper": np.arange(8, 16)})


# --- round trips ---------------------------------------------------------------------

@pytest.mark.parametrize("name,version", WRITTEN, ids=WRITTEN_IDS)
@pytest.mark.parametrize("body", [0, 1])
def test_sandwich_body_round_trip(tmp_path, name, version, body):
    mesh = sandwich_2d().bodies[body].mesh
    read = read_mesh(write_mesh(tmp_path / name, mesh, gmsh_version=version))
    assert_same_mesh(read, mesh)
    assert read.points.shape[1] == 2
    assert sorted(read.facet_sets) == ["bolt", "end", "interface", "outer"]
    assert_outward(read)


@pytest.mark.parametrize("name,version", WRITTEN, ids=WRITTEN_IDS)
@pytest.mark.parametrize("make", [hex_mesh, tetra_mesh, triangle_mesh])
def test_round_trip_with_sets(tmp_path, name, version, make):
    mesh = make()
    read = read_mesh(write_mesh(tmp_path / name, mesh, gmsh_version=version),
                     cell_type=mesh.cell_type)
    assert_same_mesh(read, mesh)
    assert_outward(read)


@pytest.mark.parametrize("name,version", WRITTEN, ids=WRITTEN_IDS)
def test_round_trip_keeps_empty_sets_and_odd_names(tmp_path, name, version):
    m = structured_mesh(np.linspace(0, 1, 3), np.linspace(0, 1, 2))
    mesh = m.with_sets(node_sets={"nothing": [], "with space": [1], "7": [2]},
                       facet_sets={"no facets": np.zeros((0, 2), int),
                                   "bottom-edge": m.boundary_facets_where(lambda p: p[:, 1] < .5)},
                       cell_sets={"no cells": [], "Ünïcode": [1]})
    assert_same_mesh(read_mesh(write_mesh(tmp_path / name, mesh, gmsh_version=version)), mesh)


@pytest.mark.parametrize("name,version", WRITTEN, ids=WRITTEN_IDS)
def test_windows_line_endings_and_latin1_comment(tmp_path, name, version):
    mesh = hex_mesh()
    text = write_mesh(tmp_path / name, mesh, gmsh_version=version).read_text()
    if name.endswith(".inp"):
        text = "** Pr\xfcfk\xf6rper\n" + text           # a latin-1 comment
    (tmp_path / name).write_bytes(text.replace("\n", "\r\n").encode("latin-1"))
    assert_same_mesh(read_mesh(tmp_path / name), mesh)


@settings(max_examples=25, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data(), three_d=st.booleans(), which=st.sampled_from(range(len(WRITTEN))))
def test_random_sets_round_trip(tmp_path, data, three_d, which):
    axes = [np.linspace(0, 1, 3), np.linspace(0, 2, 4)] + ([np.linspace(0, 1, 2)] if three_d else [])
    m = structured_mesh(*axes)
    facets = boundary_facets(m)
    subset = lambda n: np.array(data.draw(st.lists(st.integers(0, n - 1), max_size=n)), dtype=int)
    mesh = m.with_sets(node_sets={"n": subset(m.n_nodes)},
                       facet_sets={"f": facets[subset(len(facets))],
                                   "g": facets[subset(len(facets))]},
                       cell_sets={"c": subset(len(m.cells)), "d": subset(len(m.cells))})
    name, version = WRITTEN[which]
    assert_same_mesh(read_mesh(write_mesh(tmp_path / name, mesh, gmsh_version=version)), mesh)


def test_write_is_atomic_and_replaces(tmp_path):
    mesh = hex_mesh()
    path = tmp_path / "m.inp"
    path.write_text("old content")
    write_mesh(path, mesh)
    assert read_mesh(path).n_nodes == mesh.n_nodes
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.inp"]
    bad = mesh.with_sets(facet_sets={"inner": [[1, 5, 17, 13]]})   # an interior face
    before = path.read_bytes()
    with pytest.raises(InputError, match="inner"):
        write_mesh(path, bad)
    assert path.read_bytes() == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.inp"]


def test_write_rejects_what_cannot_be_written(tmp_path):
    mesh = structured_mesh(np.linspace(0, 1, 2), np.linspace(0, 1, 2))
    with pytest.raises(InputError, match="quot|'\"'"):
        write_mesh(tmp_path / "m.msh", mesh.with_sets(node_sets={'a"b': [0]}))
    with pytest.raises(InputError, match="case"):
        write_mesh(tmp_path / "m.inp", mesh.with_sets(node_sets={"Top": [0], "top": [1]}))
    with pytest.raises(InputError, match="gmsh_version"):
        write_mesh(tmp_path / "m.msh", mesh, gmsh_version="3.0")
    with pytest.raises(MeshFileError, match=r"m\.vtk.*\.msh"):
        write_mesh(tmp_path / "m.vtk", mesh)
    with pytest.raises(MeshFileError, match="no_folder"):
        write_mesh(tmp_path / "no_folder" / "m.inp", mesh)
    with pytest.raises(InputError, match="no cells"):
        write_mesh(tmp_path / "m.inp", Mesh(np.zeros((3, 2)), np.zeros((0, 3), int), "triangle"))
    assert sorted(MESH_FORMATS) == [".inp", ".msh"]


def test_other_readers_accept_our_files(tmp_path):
    """meshio (hence scikit-fem) reads our Gmsh 2.2 and 3D Abaqus files."""
    mesh = hex_mesh()
    for name, version in [("m.msh", "2.2"), ("m.inp", "4.1")]:
        other = meshio.read(write_mesh(tmp_path / name, mesh, gmsh_version=version))
        np.testing.assert_allclose(other.points, mesh.points)
        assert len(other.cells_dict["hexahedron"]) >= len(mesh.cells)


@needs_ccx
@pytest.mark.parametrize("make,clamp,load,force", [
    (hex_mesh, "x0", "x_end", (2.0, 0, 0)),          # face x = 3 of 1 x 2
    (tetra_mesh, "y0", "y2", (0, 1.0, 0)),           # face y = 2 of 1 x 1
    (lambda: sandwich_2d().bodies[0].mesh, "clamp", "end", (0.00635, 0)),
    (triangle_mesh, "left", "right", (0.3, 0)),
])
def test_calculix_applies_pressure_on_our_surfaces(tmp_path, make, clamp, load, force):
    """CalculiX reads our .inp and loads the faces we meant: with a pressure p on a
    facet set away from the clamp, the clamp reaction is p times the area (depth 1)."""
    mesh = make()
    if load not in mesh.facet_sets:
        mesh = mesh.with_sets(facet_sets={load: mesh.boundary_facets_where(
            lambda p: p[:, 0] > p[:, 0].max() - 1e-9)})
    p = mesh.points[mesh.cells]
    if mesh.cell_type == "tetra":          # CalculiX wants positive volumes
        a, b, c = (p[:, k] - p[:, 0] for k in (1, 2, 3))
        cells = mesh.cells.copy()
        flip = np.einsum("ij,ij->i", np.cross(a, b), c) < 0
        cells[flip] = cells[flip][:, [0, 2, 1, 3]]
        mesh = Mesh(mesh.points, cells, "tetra", mesh.node_sets, mesh.facet_sets)
    mesh = mesh.with_sets(node_sets={clamp: mesh.nodes(clamp)},
                          cell_sets={"every": np.arange(len(mesh.cells))})
    path = write_mesh(tmp_path / "job.inp", mesh)
    path.write_text(path.read_text() + f"""*MATERIAL, NAME=STEEL
*ELASTIC
200e9, 0.3
*SOLID SECTION, ELSET=every, MATERIAL=STEEL
{'1.' if mesh.dim == 2 else ''}
*STEP
*STATIC
*BOUNDARY
{clamp}, 1, {mesh.dim}, 0.
*DSLOAD
{load}, P, 1000.
*NODE PRINT, NSET={clamp}, TOTALS=ONLY
RF
*END STEP
""")
    subprocess.run(["ccx", "job"], cwd=tmp_path, capture_output=True, check=True, timeout=120)
    totals = re.findall(r"total force.*\n\s*\n?\s*(.*)", (tmp_path / "job.dat").read_text())
    reaction = np.array(totals[-1].split(), dtype=float)[:len(force)]
    np.testing.assert_allclose(reaction, 1000.0 * np.array(force), rtol=1e-9, atol=1e-6)


def full_digit_mesh(cell_type="hexahedron") -> Mesh:
    """A distorted box in metres of millimetre size whose coordinates need 16-17
    significant digits: ``repr`` of those near zero (order 1e-5, written with an exponent)
    has 21 to 23 characters."""
    m = structured_mesh(np.linspace(0, 3, 4), np.linspace(0, 1, 3), np.array([0, .5, 2.]),
                        cell_type=cell_type)
    rng = np.random.default_rng(1)
    points = (m.points + 0.01 * rng.standard_normal(m.points.shape)) * 1.234567e-3
    return Mesh(points, m.cells, cell_type).with_sets(cell_sets={"every": np.arange(len(m.cells))})


@pytest.mark.parametrize("cell_type", ["hexahedron", "hexahedron20"])
def test_inp_fields_fit_calculix(tmp_path, cell_type):
    """Coordinates are written in at most 20 characters (CalculiX reads no more of a
    field) to 13 significant digits or more; lines hold at most 16 entries (a C3D20 row
    of 21 continues on the next line)."""
    from qsma.mesh.io.abaqus import CALCULIX_ENTRIES, CALCULIX_FIELD
    mesh = full_digit_mesh(cell_type)
    path = write_mesh(tmp_path / "m.inp", mesh)
    lines = path.read_text().splitlines()
    nodes = lines[lines.index("*NODE") + 1:lines.index(next(t for t in lines
                                                            if t.startswith("*ELEMENT")))]
    assert len(nodes) == mesh.n_nodes
    assert max(len(f.strip()) for t in nodes for f in t.split(",")[1:]) <= CALCULIX_FIELD
    assert max(len(t.split(",")) - t.endswith(",") for t in lines) <= CALCULIX_ENTRIES
    read = read_mesh(path)
    np.testing.assert_allclose(read.points, mesh.points, rtol=5e-14, atol=0)
    np.testing.assert_array_equal(read.cells, mesh.cells)


@needs_ccx
@pytest.mark.parametrize("cell_type", ["hexahedron", "hexahedron20"])
def test_calculix_reads_our_coordinates(tmp_path, cell_type):
    """CalculiX reads every coordinate of our .inp as written: the volume of each element
    it prints (EVOL, 7 digits) is the one qsma computes (its mass matrix at rho = 1)."""
    from qsma.fe import assemble_body
    from qsma.model import Body, Material
    mesh = full_digit_mesh(cell_type)
    path = write_mesh(tmp_path / "job.inp", mesh)
    path.write_text(path.read_text() + """*MATERIAL, NAME=STEEL
*ELASTIC
200e9, 0.3
*SOLID SECTION, ELSET=every, MATERIAL=STEEL
*STEP
*STATIC
*EL PRINT, ELSET=every
EVOL
*END STEP
""")
    run = subprocess.run(["ccx", "job"], cwd=tmp_path, capture_output=True, text=True,
                         timeout=120)
    assert run.returncode == 0 and "ERROR" not in run.stdout, run.stdout[-400:]
    rows = re.findall(r"^\s+(\d+)\s+(\S+E[-+]\d+)\s*$", (tmp_path / "job.dat").read_text(),
                      re.M)
    ccx = np.array([float(v) for _, v in rows])
    n = mesh.cells.shape[1]
    volume = [assemble_body(Body("c", Mesh(mesh.points[c], np.arange(n)[None], cell_type),
                                 Material(1.0, 0.3, 1.0))).M[0::3, 0::3].sum()
              for c in mesh.cells]
    assert len(ccx) == len(mesh.cells)
    np.testing.assert_allclose(ccx, volume, rtol=1e-6)


# --- hand-written Abaqus input --------------------------------------------------------

TWO_QUADS = """\
** nodes in two blocks, ids not contiguous, lower-case keywords
*heading
 two quadrilaterals
*node, nset=first
 10, 0.0, 0.0
 20, 1.0, 0.0
**  a comment between the blocks
*Node
 40, 0.0, 1.0
 30, 1.0, 1.0
 50, 2.0, 0.0, 0.0
 60, 2.d0, 1.0
*element, type=cpe4r, elset=plate
 100, 10, 20, 30, 40
 200, 20, 50, 60, 30
*nset, nset=gen, generate
 20, 60, 20
*Elset, Elset=Second
 200,
*NSET, NSET=Ref
 first, 50
*NSET, NSET=on_second, ELSET=second
*material, name=steel
*elastic
 210e9, 0.3
"""


def test_inp_nodes_blocks_generate_comments_lower_case(tmp_path):
    m = read_mesh(write_text(tmp_path, "two.inp", TWO_QUADS))
    # nodes in id order: 10, 20, 30, 40, 50, 60 -> 0..5
    np.testing.assert_array_equal(m.points, [[0, 0], [1, 0], [1, 1], [0, 1], [2, 0], [2, 1]])
    np.testing.assert_array_equal(m.cells, [[0, 1, 2, 3], [1, 4, 5, 2]])
    assert {k: v.tolist() for k, v in m.node_sets.items()} == \
        {"first": [0, 1], "gen": [1, 3, 5], "Ref": [0, 1, 4], "on_second": [1, 2, 4, 5]}
    assert {k: v.tolist() for k, v in m.cell_sets.items()} == {"plate": [0, 1], "Second": [1]}

def test_inp_surfaces_s1_to_s4_on_cpe4(tmp_path):
    m = read_mesh(write_text(tmp_path, "grid.inp", QUAD_GRID))
    ids = lambda *pairs: {tuple(sorted(i - 1 for i in p)) for p in pairs}
    # Abaqus CPE4 faces: S1 = nodes 1-2, S2 = 2-3, S3 = 3-4, S4 = 4-1 of the element
    assert facet_keys(m.facet_sets["s1"]) == ids((1, 2))
    assert facet_keys(m.facet_sets["s2"]) == ids((3, 6))
    assert facet_keys(m.facet_sets["s3"]) == ids((5, 4))
    assert facet_keys(m.facet_sets["s4"]) == ids((4, 1))
    assert sorted(m.cell_sets) == ["ALL"]          # internal sets stay internal
    assert_outward(m)


@pytest.mark.parametrize("etype,nodes,faces", [
    ("C3D8R", [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0),
               (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)],
     # Abaqus element library, C3D8 face numbering
     [(1, 2, 3, 4), (5, 8, 7, 6), (1, 5, 6, 2), (2, 6, 7, 3), (3, 7, 8, 4), (4, 8, 5, 1)]),
    ("C3D4", [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)],
     [(1, 2, 3), (1, 4, 2), (2, 4, 3), (3, 4, 1)]),
    ("CPS3", [(0, 0), (1, 0), (0, 1)], [(1, 2), (2, 3), (3, 1)]),
])
def test_inp_face_numbering(tmp_path, etype, nodes, faces):
    lines = ["*NODE"] + [f"{i}, " + ", ".join(map(str, p)) for i, p in enumerate(nodes, 1)]
    lines += [f"*ELEMENT, TYPE={etype}", "7, " + ", ".join(str(i) for i in range(1, len(nodes) + 1))]
    for k in range(1, len(faces) + 1):
        lines += [f"*SURFACE, NAME=f{k}", f"7, S{k}"]
    m = read_mesh(write_text(tmp_path, "one.inp", "\n".join(lines) + "\n"))
    for k, face in enumerate(faces, 1):
        assert facet_keys(m.facet_sets[f"f{k}"]) == {tuple(sorted(i - 1 for i in face))}


CUBE_ELEMENT = """\
*NODE
1, 0, 0, 0
2, 1, 0, 0
3, 1, 1, 0
4, 0, 1, 0
5, 0, 0, 1
6, 1, 0, 1
7, 1, 1, 1
8, 0, 1, 1
*ELEMENT, TYPE=C3D8,
 ELSET=cube
1, 1, 2, 3,
 4, 5, 6, 7, 8
*SURFACE, NAME=skin
cube
*SURFACE, TYPE=NODE, NAME=pins
1
8
"""


def test_inp_continuation_lines_free_faces_and_node_surface(tmp_path):
    m = read_mesh(write_text(tmp_path, "cube.inp", CUBE_ELEMENT))
    np.testing.assert_array_equal(m.cells, [np.arange(8)])
    assert m.cell_sets["cube"].tolist() == [0]
    assert facet_keys(m.facet_sets["skin"]) == facet_keys(boundary_facets(m))
    assert m.node_sets["pins"].tolist() == [0, 7]


def test_inp_include_and_facet_elements(tmp_path):
    write_text(tmp_path, "nodes.inc", "\n".join(
        f"{i + 1}, {x}, {y}" for i, (x, y) in enumerate([(0, 0), (1, 0), (1, 1), (0, 1)]))
        + "\n")
    path = write_text(tmp_path, "main.inp", """\
*NODE
*INCLUDE, INPUT=nodes.inc
*ELEMENT, TYPE=CPS3, ELSET=body
1, 1, 2, 3
2, 1, 3, 4
*ELEMENT, TYPE=T3D2, ELSET=edge
3, 2, 1
*ELEMENT, TYPE=T2D2
4, 4, 3
*ELSET, ELSET=edges
3, 4
""")
    m = read_mesh(path)
    assert m.cell_type == "triangle" and len(m.cells) == 2
    assert sorted(m.cell_sets) == ["body"]
    assert facet_keys(m.facet_sets["edge"]) == {(0, 1)}
    assert facet_keys(m.facet_sets["edges"]) == {(0, 1), (2, 3)}
    assert_outward(m)


CAE_STYLE = """\
*Heading
*Part, name=Beam
*Node
      1,           0.,           0.
      2,           1.,           0.
      3,           2.,           0.
      4,           0.,           1.
      5,           1.,           1.
      6,           2.,           1.
*Element, type=CPS4R
1, 1, 2, 5, 4
2, 2, 3, 6, 5
*Nset, nset=Set-1
 1, 4
*Elset, elset=_Surf-1_S4, internal
 1,
*Surface, type=ELEMENT, name=Surf-1
_Surf-1_S4, S4
*End Part
*Assembly, name=Assembly
*Instance, name=Beam-1, part=Beam
*End Instance
*Node
      1,           5.,           5.,           0.
*Nset, nset=RP
 1,
*Nset, nset=Fixed, instance=Beam-1
 3, 6
*Elset, elset=_Load_S3, internal, instance=Beam-1
 1, 2
*Surface, type=ELEMENT, name=Load
_Load_S3, S3
*Surface, type=ELEMENT, name=Left
Beam-1._Surf-1_S4, S4
*End Assembly
*Material, name=Steel
*Elastic
210000., 0.3
*Step, name=Step-1
*Static
*End Step
"""


def test_inp_one_part_one_instance(tmp_path):
    m = read_mesh(write_text(tmp_path, "cae.inp", CAE_STYLE))
    assert m.n_nodes == 6                               # the reference point is not the mesh
    assert {k: v.tolist() for k, v in m.node_sets.items()} == {"Set-1": [0, 3], "Fixed": [2, 5]}
    assert facet_keys(m.facet_sets["Surf-1"]) == {(0, 3)}
    assert facet_keys(m.facet_sets["Load"]) == {(3, 4), (4, 5)}
    assert facet_keys(m.facet_sets["Left"]) == {(0, 3)}
    assert m.cell_sets == {}


# --- files made by Gmsh (tests/data/make_gmsh_fixtures.py) ------------------------------

@pytest.mark.parametrize("name", ["gmsh_rect_v41.msh", "gmsh_rect_v41_binary.msh",
                                  "gmsh_rect_v40.msh", "gmsh_rect_v22.msh",
                                  "gmsh_rect_v22_binary.msh"])
def test_gmsh_files(name):
    m = read_mesh(DATA / name)
    assert (m.cell_type, m.points.shape, len(m.cells)) == ("triangle", (71, 2), 112)
    assert m.cell_sets["plate"].tolist() == list(range(112))
    assert sorted(m.facet_sets) == ["9", "bottom and left", "left"]
    x, y = m.points[:, 0], m.points[:, 1]
    assert np.all(x[m.facet_sets["left"]] == 0) and len(m.facet_sets["left"]) == 5
    assert np.all(y[m.facet_sets["9"]] == 0) and len(m.facet_sets["9"]) == 9
    assert facet_keys(m.facet_sets["bottom and left"]) == \
        facet_keys(m.facet_sets["left"]) | facet_keys(m.facet_sets["9"])
    np.testing.assert_array_equal(m.points[m.node_sets["origin"]], [[0.0, 0.0]])
    assert_outward(m)
    reference = read_mesh(DATA / "gmsh_rect_v41.msh")    # ASCII: 16 digits, binary: exact
    np.testing.assert_allclose(m.points, reference.points, rtol=0, atol=1e-15)
    np.testing.assert_array_equal(m.cells, reference.cells)


def test_gmsh_abaqus_export_matches_msh():
    m, reference = read_mesh(DATA / "gmsh_rect.inp"), read_mesh(DATA / "gmsh_rect_v41.msh")
    np.testing.assert_allclose(m.points, reference.points, atol=1e-13)
    np.testing.assert_array_equal(m.cells, reference.cells)
    assert facet_keys(m.facet_sets["left"]) == facet_keys(reference.facet_sets["left"])
    assert facet_keys(m.facet_sets["bottom_and_left"]) == \
        facet_keys(reference.facet_sets["bottom and left"])
    assert m.node_sets["origin"].tolist() == reference.node_sets["origin"].tolist()
    assert m.cell_sets["plate"].tolist() == list(range(112))


def test_gmsh_tetrahedra():
    m = read_mesh(DATA / "gmsh_box_v41.msh", cell_type="tetra")
    z = m.points[:, 2]
    assert m.cell_sets["solid"].tolist() == list(range(len(m.cells)))
    assert facet_keys(m.facet_sets["bottom"]) == \
        facet_keys(m.boundary_facets_where(lambda p: p[:, 2] == 0))
    assert facet_keys(m.facet_sets["top"]) == \
        facet_keys(m.boundary_facets_where(lambda p: p[:, 2] == 1))
    np.testing.assert_array_equal(m.points[m.node_sets["corner"]], [[0, 0, 0]])
    assert np.all(z >= 0)


SQUARE_V22 = """\
$MeshFormat
2.2 0 8
$EndMeshFormat
$PhysicalNames
3
0 1 "corner"
1 2 "bottom"
2 2 "square"
$EndPhysicalNames
$Nodes
4
11 0 0 0
12 1 0 0
13 1 1 0
14 0 1 0
$EndNodes
$Elements
6
1 15 2 1 1 11
2 1 2 2 1 11 12
3 1 2 5 3 14 13
4 2 2 2 1 11 12 13
5 2 2 2 1 11 13 14
6 2 2 0 1 11 13 14
$EndElements
"""


def test_hand_written_gmsh_22(tmp_path):
    m = read_mesh(write_text(tmp_path, "square.msh", SQUARE_V22))
    np.testing.assert_array_equal(m.cells, [[0, 1, 2], [0, 2, 3]])   # the repeat merged
    assert m.node_sets["corner"].tolist() == [0]
    assert facet_keys(m.facet_sets["bottom"]) == {(0, 1)}
    assert facet_keys(m.facet_sets["5"]) == {(2, 3)}                  # unnamed group
    assert m.cell_sets["square"].tolist() == [0, 1]    # tag 2 of dimension 2, not "bottom"


SQUARE_V41 = """\
$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
3
1 1 "bottom"
1 2 "boundary"
2 1 "square"
$EndPhysicalNames
$Entities
0 2 1 0
1 0 0 0 1 0 0 2 1 2 0
2 0 0 0 1 1 0 0 0
1 0 0 0 1 1 0 1 1 0
$EndEntities
$Nodes
1 4 1 4
2 1 0 4
1
2
3
4
0 0 0
1 0 0
1 1 0
0 1 0
$EndNodes
$Elements
3 4 1 4
2 1 2 2
1 1 2 3
2 1 3 4
1 1 1 1
3 1 2
1 2 1 1
4 2 3
$EndElements
"""


def test_hand_written_gmsh_41_entity_in_two_groups_and_one_in_none(tmp_path):
    # meshio 5.3.5 fails on this file (an entity without physical group) and keeps one
    # of the two groups of curve 1: our reader keeps both
    m = read_mesh(write_text(tmp_path, "square.msh", SQUARE_V41))
    assert facet_keys(m.facet_sets["bottom"]) == {(0, 1)}
    assert facet_keys(m.facet_sets["boundary"]) == {(0, 1)}
    assert m.cell_sets["square"].tolist() == [0, 1]
    assert len(m.facet_sets) == 2


def test_gmsh_41_nodes_come_in_tag_order(tmp_path):
    shuffled = SQUARE_V41.replace("""$Nodes
1 4 1 4
2 1 0 4
1
2
3
4
0 0 0
1 0 0
1 1 0
0 1 0
$EndNodes""", """$Nodes
2 4 1 4
1 1 0 2
4
3
0 1 0
1 1 0
1 2 0 2
2
1
1 0 0
0 0 0
$EndNodes""")
    m = read_mesh(write_text(tmp_path, "shuffled.msh", shuffled))
    reference = read_mesh(write_text(tmp_path, "square.msh", SQUARE_V41))
    np.testing.assert_array_equal(m.points, [[0, 0], [1, 0], [1, 1], [0, 1]])
    np.testing.assert_array_equal(m.cells, reference.cells)
    assert facet_keys(m.facet_sets["bottom"]) == {(0, 1)}


# --- malformed files -----------------------------------------------------------------

def inp_error(tmp_path, text, name="bad.inp") -> str:
    path = write_text(tmp_path, name, text)
    with pytest.raises(MeshFileError) as info:
        read_mesh(path)
    message = str(info.value)
    assert name in message
    return message


@pytest.mark.parametrize("text,line,words", [
    (QUAD_GRID.replace("2, 2, 3, 6, 5", "2, 2, 3, 6"), 10, "3 node ids"),
    (QUAD_GRID.replace("TYPE=CPE4", "TYPE=C3D15"), 8, "C3D15"),        # wedges: never read
    (TWO_QUADS.replace(" first, 50", " first, 55"), 21, "node 55"),
    (TWO_QUADS.replace(" 20, 60, 20", " 60, 20"), 17, "GENERATE"),
    (TWO_QUADS.replace("Second\n 200,", "Second\n 201,"), 19, "element 201"),
    (QUAD_GRID.replace("2, 2, 3, 6, 5", "2, 2, 3, 6, 7"), 10, "node 7"),
    (QUAD_GRID.replace("6, 2, 1", "5, 2, 1"), 7, "twice"),
    (QUAD_GRID.replace("2, S2", "2, S5"), 16, "S5"),
    (QUAD_GRID.replace("_first, s3", "_second, s3"), 18, "_second"),
    (QUAD_GRID.replace("1, 0, 0\n", "1, zero, 0\n"), 2, "node row"),
    ("1, 2, 3\n*NODE\n", 1, "before any keyword"),
    (CAE_STYLE.replace("*End Assembly", "*Instance, name=B2, part=Beam\n*End Assembly"), 35,
     "no *END INSTANCE"),
    (CAE_STYLE.replace("*End Assembly", "*Instance, name=B2, part=Beam\n*End Instance\n"
                                        "*End Assembly"), 35, "second *INSTANCE"),
    (CAE_STYLE.replace("*Instance, name=Beam-1, part=Beam", "*Instance, name=Beam-1, part=Beam"
                       "\n 1., 0., 0."), 22, "translated"),
])
def test_inp_errors_name_file_and_line(tmp_path, text, line, words):
    message = inp_error(tmp_path, text)
    assert f"line {line}:" in message and words in message


@pytest.mark.parametrize("text,words", [
    ("** nothing here\n*HEADING\n", "no nodes"),
    ("*NODE\n1, 0, 0\n2, 1, 0\n", "no elements"),
    (QUAD_GRID.replace("2, 2, 3, 6, 5", "2, 2, 3, 6, 5\n*ELEMENT, TYPE=CPE6\n3, 1, 2, 3, 4, 5, 6"),
     "a mix qsma does not support"),
    (QUAD_GRID.replace("3, 2, 0", "3, 2, 0, 0.5"), "non-zero z"),
    (QUAD_GRID.replace("1, S1", "1, S2"), "not boundary facets"),
    (QUAD_GRID.replace("TYPE=CPE4", "TYPE=S4R"), "no continuum elements"),
])
def test_inp_mesh_errors(tmp_path, text, words):
    assert words in inp_error(tmp_path, text)


def test_unsupported_mix_names_the_types(tmp_path):
    """quad + triangle6 do not share a facet type (line / line3): refused, naming both
    (supported mixes: tests/test_mixed.py)."""
    text = QUAD_GRID.replace("2, 2, 3, 6, 5",
                             "2, 2, 3, 6, 5\n*ELEMENT, TYPE=CPE6\n3, 1, 2, 3, 4, 5, 6")
    message = inp_error(tmp_path, text)
    assert "quad" in message and "triangle6" in message


def test_cell_type_must_match(tmp_path):
    with pytest.raises(MeshFileError, match="cell_type='hexahedron'"):
        read_mesh(write_text(tmp_path, "g.inp", QUAD_GRID), cell_type="hexahedron")
    with pytest.raises(InputError, match="cell_type"):
        read_mesh(write_text(tmp_path, "g.inp", QUAD_GRID), cell_type="wedge")


@pytest.mark.parametrize("name", ["missing.msh", "missing.inp"])
def test_missing_file(tmp_path, name):
    with pytest.raises(MeshFileError, match=f"{name}: no such file"):
        read_mesh(tmp_path / name)


@pytest.mark.parametrize("name", ["garbage.msh", "garbage.inp"])
def test_garbage_bytes(tmp_path, name):
    path = tmp_path / name
    path.write_bytes(np.random.default_rng(1).integers(0, 256, 3000, dtype=np.uint8).tobytes())
    with pytest.raises(MeshFileError, match=name):
        read_mesh(path)


def test_unknown_extension(tmp_path):
    with pytest.raises(MeshFileError, match=r"mesh\.stl.*\.msh.*\.inp"):
        read_mesh(write_text(tmp_path, "mesh.stl", "solid"))


@pytest.mark.parametrize("version", ["4.1", "2.2"])
def test_truncated_gmsh_file(tmp_path, version):
    text = write_mesh(tmp_path / "full.msh", hex_mesh(), gmsh_version=version).read_text()
    cut = write_text(tmp_path, "cut.msh", text[:len(text) // 2])
    with pytest.raises(MeshFileError, match=r"cut\.msh.*(truncated|not closed)"):
        read_mesh(cut)


def test_truncated_binary_gmsh_file(tmp_path):
    data = (DATA / "gmsh_rect_v41_binary.msh").read_bytes()
    path = tmp_path / "cut.msh"
    path.write_bytes(data[:len(data) * 2 // 3])
    with pytest.raises(MeshFileError, match=r"cut\.msh.*truncated"):
        read_mesh(path)


@pytest.mark.parametrize("text,words", [
    (SQUARE_V22.replace("$Elements\n6\n", "$Elements\n3\n").replace(
        "4 2 2 2 1 11 12 13\n5 2 2 2 1 11 13 14\n6 2 2 0 1 11 13 14\n", ""),
     "holds only"),
    (SQUARE_V41.replace("1 1 1 1\n3 1 2", "1 1 1 1\n3 1 3"), "not boundary facets"),
    (SQUARE_V41.replace("2 1 3 4\n", "2 1 3 9\n"), "node tag 9"),
    (SQUARE_V41.replace("2 1 2 2\n", "2 1 11 2\n"), "tetra10"),
    (SQUARE_V41.replace("2 1 2 2\n", "2 1 99 2\n"), "type number 99"),
    (SQUARE_V41.replace("1 1 0\n0 1 0", "1 1 0.25\n0 1 0"), "non-zero z"),
    ("$MeshFormat\n3.0 0 8\n$EndMeshFormat\n", "version 3.0"),
    ("$MeshFormat\n4 1 8\n\x01\x00\x00\x00\n$EndMeshFormat\n", "binary Gmsh 4.0"),
])
def test_gmsh_errors(tmp_path, text, words):
    path = write_text(tmp_path, "bad.msh", text)
    with pytest.raises(MeshFileError, match="bad.msh") as info:
        read_mesh(path)
    assert words in str(info.value)


@settings(max_examples=40, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(which=st.sampled_from(["4.1", "2.2", "inp"]), data=st.data())
def test_damaged_files_raise_only_mesh_file_errors(tmp_path, which, data):
    """Cut a file short, or drop or garble a line: the reader returns a mesh or raises
    MeshFileError, never a bare KeyError/IndexError/ValueError."""
    name = "m.inp" if which == "inp" else "m.msh"
    lines = write_mesh(tmp_path / name, tetra_mesh(), gmsh_version=which.replace("inp", "4.1")
                       ).read_text().splitlines()
    k = data.draw(st.integers(0, len(lines) - 1))
    action = data.draw(st.sampled_from(["cut", "drop", "garble"]))
    if action == "cut":
        lines = lines[:k]
    elif action == "drop":
        del lines[k]
    else:
        lines[k] = data.draw(st.sampled_from(["", "x", "1", "-1 2", "$Nodes", "*NODE", "1e999"]))
    path = write_text(tmp_path, name, "\n".join(lines) + "\n")
    try:
        read_mesh(path)
    except MeshFileError as exc:
        assert name in str(exc)


@pytest.mark.parametrize("make", [hex_mesh, tetra_mesh, triangle_mesh,
                                  lambda: structured_mesh(np.linspace(0, 1, 4),
                                                          np.linspace(0, 2, 3))])
def test_facet_index_finds_boundary_facets_in_any_node_order(make):
    """One facet index per mesh: rows = boundary_facets, owner cell and local face agree
    with the cell type's facets, find() ignores node order and answers -1 for internal
    facets."""
    from qsma.mesh.celltypes import CELL_TYPES
    from qsma.mesh.mesh import facet_index
    m = make()
    index = facet_index(m)
    assert facet_index(m) is index                                # built once
    np.testing.assert_array_equal(index.rows, boundary_facets(m))
    local = np.array(CELL_TYPES[m.cell_type].facets)
    np.testing.assert_array_equal(index.rows, m.cells[index.cell[:, None],
                                                      local[index.local_face]])
    rng = np.random.default_rng(0)
    shuffled = rng.permuted(index.rows, axis=1)
    order = rng.permutation(len(index.rows))
    np.testing.assert_array_equal(index.find(shuffled[order]), order)
    every = np.concatenate([m.cells[:, list(f)] for f in CELL_TYPES[m.cell_type].facets])
    internal = every[index.find(every) < 0]
    assert len(internal) == len(every) - len(index.rows)          # all the others
    assert len(internal) > 0 and (index.find(internal) == -1).all()
    assert index.find(np.zeros((0, local.shape[1]), dtype=int)).shape == (0,)


# --- element formulation named by the file (issue 13, reader side) ------------------

@pytest.mark.parametrize("etype", ["CPE4", "CPS4", "cax4", "CPE4I", "cpe4r", "CPS4R"])
def test_inp_element_type_is_recorded(tmp_path, etype):
    m = read_mesh(write_text(tmp_path, "q.inp", QUAD_GRID.replace("TYPE=CPE4", f"TYPE={etype}")))
    assert m.element == etype.upper()
    assert m.with_sets(node_sets={"n": [0]}).element == etype.upper()
    again = read_mesh(write_mesh(tmp_path / "again.inp", m))      # written as read
    assert again.element == etype.upper()


def test_gmsh_and_generated_meshes_name_no_element(tmp_path):
    assert read_mesh(DATA / "gmsh_rect_v41.msh").element is None
    assert hex_mesh().element is None
    assert read_mesh(write_mesh(tmp_path / "h.inp", hex_mesh())).element == "C3D8"


def test_inp_two_element_types_for_one_cell_type_are_refused(tmp_path):
    text = QUAD_GRID.replace("2, 2, 3, 6, 5", "*ELEMENT, TYPE=CPE4R, ELSET=ALL\n2, 2, 3, 6, 5")
    message = inp_error(tmp_path, text)
    assert "CPE4R" in message and "CPE4" in message and "line 11:" in message


def test_write_refuses_an_element_of_another_cell_type(tmp_path):
    m = hex_mesh()
    wrong = Mesh(m.points, m.cells, m.cell_type, element="CPE4")
    with pytest.raises(InputError, match="not an Abaqus continuum element type of hexahedron"):
        write_mesh(tmp_path / "w.inp", wrong)
    with pytest.raises(InputError, match="element must be"):
        Mesh(m.points, m.cells, m.cell_type, element="")


# --- quadratic cells (read when CELL_TYPES has them) ---------------------------------

#: meshio/VTK order of the nodes after the corners, as the corners each is the middle of
#: (VTK classes vtkQuadraticQuad, vtkQuadraticTetra, vtkQuadraticHexahedron,
#: vtkTriQuadraticHexahedron); written out here independently of qsma.model.validate
_VTK_HEX_EDGES = [(0, 1), (1, 2), (2, 3), (3, 0), (4, 5), (5, 6), (6, 7), (7, 4),
                  (0, 4), (1, 5), (2, 6), (3, 7)]
VTK_HIGHER = {
    "quad8": (4, [(0, 1), (1, 2), (2, 3), (3, 0)]),
    "tetra10": (4, [(0, 1), (1, 2), (2, 0), (0, 3), (1, 3), (2, 3)]),
    "hexahedron20": (8, _VTK_HEX_EDGES),
    "hexahedron27": (8, _VTK_HEX_EDGES + [(0, 3, 7, 4), (1, 2, 6, 5), (0, 1, 5, 4),
                                          (3, 2, 6, 7), (0, 1, 2, 3), (4, 5, 6, 7),
                                          tuple(range(8))]),
}
QUADRATIC = [("quadratic_box_tet10.msh", "tetra10", None),
             ("quadratic_box_tet10.inp", "tetra10", "C3D10"),
             ("quadratic_box_hex20.msh", "hexahedron20", None),
             ("quadratic_box_hex20.inp", "hexahedron20", "C3D20"),
             ("quadratic_box_hex27.msh", "hexahedron27", None),
             ("quadratic_rect_quad8.msh", "quad8", None)]


@pytest.mark.parametrize("name,cell_type,element", QUADRATIC)
def test_quadratic_files_read_in_meshio_node_order(name, cell_type, element, tmp_path):
    """Straight-edged Gmsh meshes (tests/data/make_quadratic_fixtures.py): in meshio order
    every further node is the mean of its corners; Gmsh's own Abaqus export gives the
    same cells; round trips keep cells and facet sets."""
    from qsma.mesh.validate import scaled_jacobians
    m = read_mesh(DATA / name)
    assert (m.cell_type, m.element) == (cell_type, element)
    nc, groups = VTK_HIGHER[cell_type]
    x = m.points[m.cells]
    for k, corners in enumerate(groups):
        np.testing.assert_allclose(x[:, nc + k], x[:, list(corners)].mean(axis=1), atol=1e-12)
    assert (scaled_jacobians(m) > 0.2).all()
    bottom = m.facet_sets["bottom"]
    assert len(bottom) and np.allclose(m.points[bottom][..., -1], 0.0)
    if name.endswith(".inp"):
        twin = read_mesh(DATA / name.replace(".inp", ".msh"))
        np.testing.assert_array_equal(m.cells, twin.cells)
    versions = ["4.1", "2.2"] + (["inp"] if cell_type != "hexahedron27" else [])
    for version in versions:
        path = tmp_path / ("w.inp" if version == "inp" else "w.msh")
        again = read_mesh(write_mesh(path, m, gmsh_version="4.1" if version == "inp"
                                     else version))
        assert_same_mesh(again, m)


def test_abaqus_c3d27_is_refused_with_its_reason(tmp_path):
    text = QUAD_GRID.replace("TYPE=CPE4", "TYPE=C3D27")
    assert "use C3D20" in inp_error(tmp_path, text)


def test_hexahedron27_cannot_be_written_to_inp(tmp_path):
    m = read_mesh(DATA / "quadratic_box_hex27.msh")
    with pytest.raises(InputError, match="hexahedron27 cells cannot be written to an .inp"):
        write_mesh(tmp_path / "h.inp", m)


def test_gmsh_writer_refuses_a_formulation_it_cannot_keep(tmp_path):
    """A CPS4I (plane stress, incompatible modes) mesh written to .msh would come back
    as plane strain Q1: refused; the .inp writer keeps it."""
    m = structured_mesh(np.linspace(0, 1, 3), np.linspace(0, 1, 3))
    m = Mesh(m.points, m.cells, m.cell_type, element="CPS4I")
    with pytest.raises(InputError, match="cannot be kept in a Gmsh file"):
        write_mesh(tmp_path / "a.msh", m)
    write_mesh(tmp_path / "a.inp", m)
    assert read_mesh(tmp_path / "a.inp").element == "CPS4I"
