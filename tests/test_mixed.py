"""Mixed meshes: several cell types in one body (triangles left among quadrilaterals by
Gmsh's recombination, triangle6 among quad8 / quad9), read from Gmsh and Abaqus files,
assembled block by block, loaded, paired and in contact."""
import dataclasses

import numpy as np
import pytest

from qsma.errors import InputError, MeshFileError
from qsma.examples import sandwich_2d
from qsma.fe import assemble_body, pressure_load
from qsma.modal import linear_modes
from qsma.model import Body, Clamp, Material, Mesh, Pressure, make_pairing
from qsma.mesh.generate import structured_mesh
from qsma.mesh.io import read_mesh, write_mesh
from qsma.mesh.mesh import CellBlock, boundary_facets, mixed_mesh
from helpers import QUAD_GRID, check_patch, distorted_patch

STEEL = Material(200e9, 0.285, 7800.0)
A2 = np.array([[1e-3, 2e-4], [-5e-4, 3e-4]])

#: the diagonal split of a quad (meshio order) into two triangles, and of a quad9 into
#: two triangle6 (corners 0 1 2 / 0 2 3, midsides 01 12 20 / 02 23 30; the quad9 centre
#: node 8 is the middle of the diagonal 0-2 for straight-sided cells)
SPLIT = {"quad": ([0, 1, 2], [0, 2, 3]),
         "quad9": ([0, 1, 2, 4, 5, 8], [0, 2, 3, 8, 6, 7])}


def split_cells(mesh: Mesh, mask, keep="quad9") -> Mesh:
    """``mesh`` (quad or quad9 cells) with the cells of ``mask`` split into two triangles
    (triangle6); the other quad9 cells become ``keep`` (``"quad8"``: centre node dropped,
    unused nodes removed). Sets are kept: splitting adds no boundary facet."""
    mask = np.asarray(mask, dtype=bool)
    a, b = SPLIT[mesh.cell_type]
    tri = np.concatenate([mesh.cells[mask][:, a], mesh.cells[mask][:, b]])
    rest = mesh.cells[~mask]
    if mesh.cell_type == "quad":
        blocks = [("quad", rest), ("triangle", tri)]
    else:
        blocks = [(keep, rest[:, :8] if keep == "quad8" else rest), ("triangle6", tri)]
    used = np.unique(np.concatenate([c.ravel() for _, c in blocks]))
    new = np.full(mesh.n_nodes, -1)
    new[used] = np.arange(len(used))
    node_sets = {k: new[v][new[v] >= 0] for k, v in mesh.node_sets.items()}
    facet_sets = {k: new[v] for k, v in mesh.facet_sets.items()}
    return mixed_mesh(mesh.points[used], [CellBlock(t, new[c], mesh.element)
                                          for t, c in blocks], node_sets, facet_sets)


def checkerboard(mesh):
    return (np.arange(len(mesh.cells)) % 3) == 0


# ---------------------------------------------------------------- the mesh itself
def test_mixed_mesh_blocks_facets_and_sets():
    m = split_cells(structured_mesh(np.linspace(0, 1, 4), np.linspace(0, 1, 3)),
                    [True, False, False, True, False, False])
    assert m.is_mixed and m.n_cells == 4 + 4
    assert [b.cell_type for b in m.cell_blocks] == ["quad", "triangle"]
    bf = boundary_facets(m)
    assert len(bf) == 2 * 3 + 2 * 2                        # the square's 10 edges
    length = np.linalg.norm(np.diff(m.points[bf], axis=1), axis=2).sum()
    assert length == pytest.approx(2 * 1 + 2 * 1, rel=1e-14)
    # cell indices count the first block first
    m2 = m.with_sets(cell_sets={"tris": [4, 5, 6, 7]})
    assert m2.extra_blocks[0].cells.tolist() == m.extra_blocks[0].cells.tolist()
    assert m2.n_cells == 8


@pytest.mark.parametrize("first, other, words", [
    ("quad", "triangle6", "cannot be mixed"),
    ("hexahedron", "tetra", "3D mixes"),
    ("quad", "quad", "two cell blocks"),
])
def test_unsupported_mixes_are_refused(first, other, words):
    from qsma.mesh.celltypes import CELL_TYPES
    dim, nv = CELL_TYPES[first].dim, CELL_TYPES[first].n_nodes
    pts = np.random.default_rng(0).random((30, dim))
    cells = np.arange(nv)[None, :]
    with pytest.raises(InputError, match=words):
        mixed_mesh(pts, [(first, cells), (other, np.arange(CELL_TYPES[other].n_nodes)[None, :])])


# ---------------------------------------------------------------- assembly
@pytest.mark.parametrize("quads", ["CPE4", "CPE4I"])
def test_patch_test_on_distorted_mixed_triangle_quad_mesh(quads):
    """Uniform strain reproduced exactly: quads (full integration or incompatible
    modes) and triangles, each block with its own element, assembled into one matrix
    (and the stress of both blocks uniform)."""
    m = distorted_patch("quad")
    mixed = split_cells(m, checkerboard(m))
    blocks = [CellBlock("quad", mixed.cells, quads), CellBlock("triangle",
                                                               mixed.extra_blocks[0].cells)]
    a = check_patch(mixed_mesh(mixed.points, blocks), A2)
    assert a.M.sum() / 2 == pytest.approx(STEEL.rho, rel=1e-12)        # unit square
    assert a.formulation.startswith(f"mixed mesh: {quads}:") and "CPE3" in a.formulation


@pytest.mark.parametrize("keep", ["quad8", "quad9"])
def test_patch_test_on_curved_mixed_quadratic_mesh(keep):
    xs = np.linspace(0, 1, 5)
    m = split_cells(structured_mesh(xs, xs, cell_type="quad9"),
                    checkerboard(structured_mesh(xs, xs)), keep=keep)
    a = check_patch(_perturb_interior(m, 0.02), A2)
    assert a.M.sum() / 2 == pytest.approx(STEEL.rho, rel=1e-12)


def _perturb_interior(mesh: Mesh, amp, seed=1) -> Mesh:
    """Every node off the boundary moved (corner and midside nodes: curved edges)."""
    p = mesh.points.copy()
    inner = np.setdiff1d(np.arange(mesh.n_nodes), np.unique(boundary_facets(mesh)))
    p[inner] += np.random.default_rng(seed).uniform(-amp, amp, size=(len(inner), mesh.dim))
    return dataclasses.replace(mesh, points=p)


def test_rigid_motions_are_free_and_pressure_sums_to_its_resultant():
    """K annihilates the rigid motions of a mixed mesh; a uniform pressure on a facet set
    whose facets belong to triangles and quads gives the resultant p x length."""
    xs = np.linspace(0, 0.2, 9)
    m = structured_mesh(xs, np.linspace(0, 0.02, 3))
    bottom = m.boundary_facets_where(lambda p: p[:, 1] < 1e-12)
    m = split_cells(m.with_sets(facet_sets={"bottom": bottom}), checkerboard(m))
    body = Body("b", m, STEEL, pressures=(Pressure("bottom", 2e6),))
    a = assemble_body(body)
    x, y = m.points.T
    for rigid in (np.column_stack([np.ones_like(x), 0 * x]),
                  np.column_stack([0 * x, np.ones_like(x)]), np.column_stack([-y, x])):
        assert np.abs(a.K @ rigid.ravel()).max() < 1e-9 * abs(a.K).max() * 0.2
    f = pressure_load(body, "bottom", 2e6).reshape(-1, 2)
    assert f[:, 1].sum() == pytest.approx(2e6 * 0.2, rel=1e-13)   # into the body: +y
    assert abs(f[:, 0].sum()) < 1e-9 * 2e6 * 0.2


def _beam(cell_type, n_thick, mask_every=None, keep="quad9", nx=32, L=0.2, h=0.00625):
    m = structured_mesh(np.linspace(0, L, nx + 1), np.linspace(0, h, n_thick + 1),
                        cell_type=None if cell_type == "quad" else cell_type)
    m = m.with_sets(node_sets={"clamp": np.flatnonzero(m.points[:, 0] < 1e-12)})
    if mask_every is not None:
        lin = structured_mesh(np.linspace(0, L, nx + 1), np.linspace(0, h, n_thick + 1))
        m = split_cells(m, (np.arange(len(lin.cells)) % mask_every) == 0, keep=keep)
    return m


def _f1(mesh):
    from scipy.sparse.linalg import eigsh
    a = assemble_body(Body("beam", mesh, STEEL, clamps=(Clamp("clamp"),)))
    K, M = a.K[a.free][:, a.free], a.M[a.free][:, a.free]
    w2 = eigsh(K.tocsc(), k=1, M=M.tocsc(), sigma=0.0, which="LM")[0]
    return np.sqrt(w2[0]) / (2 * np.pi)


def test_mixed_cantilever_lies_between_its_uniform_meshes():
    """Same geometry, same nodes: the first bending frequency of a cantilever with every
    third quad split into triangles lies between the all-quad and all-triangle meshes
    (constant-strain triangles are stiffer in bending); likewise quad9 / triangle6."""
    f_quad = _f1(_beam("quad", 4))
    f_tri = _f1(_beam("quad", 4, mask_every=1))
    f_mix = _f1(_beam("quad", 4, mask_every=3))
    assert f_quad < f_mix < f_tri
    f_quad9 = _f1(_beam("quad9", 2, nx=32))
    f_tri6 = _f1(_beam("quad9", 2, mask_every=1, nx=32))
    assert f_quad9 < _f1(_beam("quad9", 2, mask_every=3, nx=32)) < f_tri6


@pytest.mark.parametrize("keep", ["quad8", "quad9"])
def test_mixed_quadratic_cantilever_converges_at_second_order(keep):
    """triangle6 with quad8 / quad9 (every third cell split), n cells through h and 16 n
    along, against uniform quad9 with 8 x 128 cells: the f1 error falls about 4x
    per halving of h, asserted 2.5x (measured: quad8 mix 4.9e-3, 1.3e-3, 3.8e-4; quad9 mix 4.9e-3,
    1.05e-3, 3.6e-4 for n = 1, 2, 4; uniform quad9 2.2e-3, 7.4e-4, 2.0e-4)."""
    ref = _f1(_beam("quad9", 8, nx=128))
    err = [abs(_f1(_beam("quad9", n, mask_every=3, keep=keep, nx=16 * n)) / ref - 1)
           for n in (1, 2, 4)]
    assert err[0] > 2.5 * err[1] and err[1] > 2.5 * err[2] and err[2] < 5e-4


# ---------------------------------------------------------------- files
GMSH41 = """$MeshFormat
4.1 0 8
$EndMeshFormat
$PhysicalNames
2
1 2 "left"
2 1 "body"
$EndPhysicalNames
$Entities
0 1 1 0
1 0 0 0 0 1 0 1 2 0
1 0 0 0 2 1 0 1 1 0
$EndEntities
$Nodes
1 6 1 6
2 1 0 6
1
2
3
4
5
6
0 0 0
1 0 0
2 0 0
0 1 0
1 1 0
2 1 0
$EndNodes
$Elements
3 4 1 4
2 1 3 1
1 1 2 5 4
2 1 2 2
2 2 3 6
3 2 6 5
1 1 1 1
4 1 4
$EndElements
"""

INP = QUAD_GRID.split("*ELEMENT")[0] + """*ELEMENT, TYPE=CPE4I, ELSET=QUADS
1, 1, 2, 5, 4
*ELEMENT, TYPE=CPE3, ELSET=TRIS
2, 2, 3, 6
3, 2, 6, 5
*ELSET, ELSET=BOTTOM
1, 2
*SURFACE, NAME=BOT
BOTTOM, S1
*NSET, NSET=LEFT
1, 4
"""


def _square_blocks(m):
    return [(b.cell_type, b.cells.tolist()) for b in m.cell_blocks]


def test_gmsh41_file_with_quads_and_triangles(tmp_path):
    """Gmsh's recombination leaves triangles among quads: read as one mixed body."""
    path = tmp_path / "mixed.msh"
    path.write_text(GMSH41)
    m = read_mesh(path)
    assert _square_blocks(m) == [("quad", [[0, 1, 4, 3]]), ("triangle", [[1, 2, 5],
                                                                         [1, 5, 4]])]
    assert m.element is None and m.facets("left").tolist() == [[3, 0]]
    assert m.cell_sets["body"].tolist() == [0, 1, 2]
    assert assemble_body(Body("b", m, STEEL)).M.sum() / 2 == pytest.approx(2 * STEEL.rho)
    with pytest.raises(InputError, match="mixed meshes"):
        write_mesh(tmp_path / "back.msh", m)


def test_gmsh22_file_written_by_meshio_with_quads_and_triangles(tmp_path):
    import meshio
    m = distorted_patch("quad")
    mixed = split_cells(m, checkerboard(m))
    left = mixed.boundary_facets_where(lambda p: p[:, 0] < 1e-12)
    blocks = [(b.cell_type, b.cells) for b in mixed.cell_blocks] + [("line", left)]
    tags = [np.full(len(c), 1 if t != "line" else 2) for t, c in blocks]
    path = tmp_path / "mixed22.msh"
    meshio.write(path, meshio.Mesh(np.column_stack([mixed.points, np.zeros(mixed.n_nodes)]),
                                   blocks, cell_data={"gmsh:physical": tags,
                                                      "gmsh:geometrical": tags},
                                   field_data={"body": np.array([1, 2]),
                                               "left": np.array([2, 1])}),
                 file_format="gmsh22", binary=False)
    r = read_mesh(path)
    assert [b.cell_type for b in r.cell_blocks] == ["quad", "triangle"]
    assert r.n_cells == mixed.n_cells and len(r.facets("left")) == len(left)
    ka = assemble_body(Body("a", mixed, STEEL)).K
    kb = assemble_body(Body("b", r, STEEL)).K
    assert abs(ka - kb).max() < 1e-12 * abs(ka).max()       # same nodes, same order


def test_abaqus_file_with_two_element_types_keeps_each_formulation(tmp_path):
    """CPE4I quads and CPE3 triangles: each block computed as its file says; a surface
    on an element set spanning both types uses each type's face numbering."""
    path = tmp_path / "mixed.inp"
    path.write_text(INP)
    m = read_mesh(path)
    assert [(b.cell_type, b.element) for b in m.cell_blocks] == [("quad", "CPE4I"),
                                                                 ("triangle", "CPE3")]
    assert m.facets("BOT").tolist() == [[0, 1], [1, 2]]
    assert m.cell_sets["TRIS"].tolist() == [1, 2]
    a = assemble_body(Body("b", m, STEEL))
    assert a.formulation.startswith("mixed mesh: CPE4I") and "CPE3" in a.formulation
    plane_stress = path.read_text().replace("CPE3", "CPS3")
    path.write_text(plane_stress)
    with pytest.raises(InputError, match="different kinematics"):
        assemble_body(Body("b", read_mesh(path), STEEL))


def test_mixed_quadratic_linear_file_is_refused(tmp_path):
    text = INP.replace("*ELEMENT, TYPE=CPE3, ELSET=TRIS\n2, 2, 3, 6\n3, 2, 6, 5\n",
                       "*ELEMENT, TYPE=CPE6, ELSET=TRIS\n2, 2, 3, 6, 1, 4, 5\n")
    path = tmp_path / "bad.inp"
    path.write_text(text)
    with pytest.raises(MeshFileError, match="a mix qsma does not support"):
        read_mesh(path)


# ---------------------------------------------------------------- contact
def _mixed_sandwich(mask_every):
    """sandwich-2d with every ``mask_every``-th quad of both beams split into triangles
    (the interface nodes are unchanged, so the beams still pair node to node)."""
    model = sandwich_2d(1)
    bodies = []
    for b in model.bodies:
        mask = (np.arange(len(b.mesh.cells)) % mask_every) == 0
        bodies.append(dataclasses.replace(b, mesh=split_cells(b.mesh, mask)))
    return dataclasses.replace(model, bodies=tuple(bodies))


def test_mixed_sandwich_pairs_preloads_and_lies_between_uniform_meshes():
    """Pairing, preload contact and the tied f0 on mixed bodies: 65 node pairs as on the
    quad mesh, the same preload contact state, and f0 between the all-quad
    (212.544 Hz, docs/validation.md) and all-triangle meshes of the same nodes."""
    from qsma.analysis import preload

    def f0(model):
        A = [assemble_body(b) for b in model.bodies]
        pairing = make_pairing(model)
        _, _, pre = preload(model, A, pairing)
        closed = pre.status != 2
        modes = linear_modes(model, A, pairing, n_modes=1, tied=closed)
        return pairing, pre, modes.f_hz[0]

    p_quad, pre_quad, f_quad = f0(sandwich_2d(1))
    p_mix, pre_mix, f_mix = f0(_mixed_sandwich(3))
    _, _, f_tri = f0(_mixed_sandwich(1))
    assert p_mix.n_pairs == p_quad.n_pairs == 65
    # interface resultant: the bolt force 111,467.9 N/m less what the clamps take
    # (measured: quad 111,492.89, mix 111,493.18, triangles 111,494.10 N/m; 17 pairs
    # closed on each)
    assert (pre_mix.status != 2).sum() == (pre_quad.status != 2).sum() == 17
    assert pre_mix.lam[:, -1].sum() == pytest.approx(pre_quad.lam[:, -1].sum(), rel=1e-5)
    assert f_quad < f_mix < f_tri


def test_qsma_run_on_mixed_bodies_writes_every_cell(tmp_path):
    """The whole analysis on mixed bodies, results.json naming both formulations and
    fields.vtu holding every cell of both blocks of both bodies."""
    import json
    import meshio
    import qsma
    from qsma.analysis.levels import Levels
    from qsma.output.files import write_all
    model = _mixed_sandwich(3)
    res = qsma.run(model, levels=Levels.log("tip", 1e-5, 1e-3, 4))
    assert res.success
    write_all(res, tmp_path / "out", plots=False)
    vtu = meshio.read(tmp_path / "out" / "fields.vtu")
    n_cells = sum(len(c.data) for c in vtu.cells)
    assert n_cells == sum(b.mesh.n_cells for b in model.bodies)
    assert {c.type for c in vtu.cells} == {"triangle", "quad"}
    text = json.dumps(json.loads((tmp_path / "out" / "results.json").read_text()))
    assert "mixed mesh: CPE4" in text and "CPE3" in text
