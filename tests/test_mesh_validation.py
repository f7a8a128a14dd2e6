"""Damaged meshes are refused (issue 18): inverted, degenerate and self-intersecting
cells, duplicate and unused nodes, and random mutations of real mesh files."""
import re
import warnings
from pathlib import Path

import numpy as np
import pytest

from qsma.errors import InputError, MeshFileError
from qsma.mesh.generate import structured_mesh
from qsma.mesh.io import read_mesh
from qsma.mesh.mesh import Mesh
from qsma.examples import example_dir
from qsma.mesh.validate import (DEGENERATE_SCALED_JACOBIAN, MeshQualityWarning, scaled_jacobians, validate_mesh)

DATA = Path(__file__).parent / "data"
EXAMPLES = example_dir()        # the example files shipped with qsma


def unit_square_quads():
    return structured_mesh(np.linspace(0, 2, 3), np.linspace(0, 1, 2))


# --- cells ----------------------------------------------------------------------------

def corner_measures(mesh: Mesh) -> np.ndarray:
    """Signed area (2D) or volume (3D) spanned at each corner by its two (three) edges
    in counter-clockwise order: all positive for a valid linear cell. Independent of
    qsma.model.validate (no shape functions)."""
    x = mesh.points[mesh.cells]
    if mesh.cell_type in ("triangle", "quad"):
        n = x.shape[1]
        nxt, prv = x[:, np.roll(np.arange(n), -1)] - x, x[:, np.roll(np.arange(n), 1)] - x
        return nxt[..., 0] * prv[..., 1] - nxt[..., 1] * prv[..., 0]
    if mesh.cell_type == "tetra":
        return np.linalg.det(x[:, 1:] - x[:, :1])[:, None]
    # hexahedron: at each corner its three neighbours along x, y, z of the reference cube
    neighbours = [(1, 3, 4), (2, 0, 5), (3, 1, 6), (0, 2, 7),
                  (7, 5, 0), (4, 6, 1), (5, 7, 2), (6, 4, 3)]
    return np.stack([np.linalg.det(np.stack([x[:, a] - x[:, c] for a in nb], axis=2))
                     for c, nb in enumerate(neighbours)], axis=1)


def test_scaled_jacobian_is_one_on_rectangles_of_any_aspect_ratio():
    m = structured_mesh(np.array([0.0, 1e-6, 1.0]), np.array([0.0, 1e3]))
    np.testing.assert_allclose(scaled_jacobians(m), 1.0, rtol=1e-12)
    h = structured_mesh(np.linspace(0, 1, 2), np.linspace(0, 1e-4, 2), np.linspace(0, 7, 2))
    np.testing.assert_allclose(scaled_jacobians(h), 1.0, rtol=1e-12)


@pytest.mark.parametrize("order,word", [
    ([0, 1, 3, 2], "self-intersecting"),        # bow-tie
    ([0, 3, 2, 1], "inverted"),                 # clockwise
])
def test_bad_quad_is_named_by_its_id(order, word):
    m = unit_square_quads()
    cells = m.cells.copy()
    cells[1] = cells[1][order]
    with pytest.raises(InputError, match=rf"quad element 2 \(nodes .*\) is {word}"):
        validate_mesh(Mesh(m.points, cells, "quad"))


def test_degenerate_quad_with_a_collapsed_edge():
    m = unit_square_quads()
    points = m.points.copy()
    points[m.cells[0, 3]] = points[m.cells[0, 2]] + [0.0, 1e-12]      # corners 2, 3 meet
    bad = Mesh(points, m.cells, "quad")
    assert scaled_jacobians(bad)[0].min() <= DEGENERATE_SCALED_JACOBIAN
    with pytest.raises(InputError, match="quad element 1 .* is degenerate"):
        validate_mesh(bad)
    with pytest.raises(InputError, match="element 11"):
        validate_mesh(bad, cell_ids=[11, 12])


def test_a_valid_but_badly_shaped_quad_passes_with_a_warning():
    """q = sin(0.57 degrees) ~ 0.01 > DEGENERATE_SCALED_JACOBIAN: accepted, warned below
    POOR_SCALED_JACOBIAN = 0.01, silent above."""
    for shear, warned in ((100.0, True), (50.0, False)):
        points = np.array([[0, 0], [1, 0], [1 + shear, 1], [shear, 1.0]])
        m = Mesh(points, [[0, 1, 2, 3]], "quad")
        assert 0.005 < scaled_jacobians(m).min() < 0.03
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            validate_mesh(m)
        assert [w.category for w in caught] == ([MeshQualityWarning] if warned else [])


def test_a_node_moved_off_the_surface_is_warned_about(tmp_path):
    """The mutation that moves a node of the sandwich top 0.3 m up keeps every cell
    valid (a spike); it is read, with a warning naming the element."""
    text = (EXAMPLES / "sandwich-2d-top.msh").read_text()
    assert "\n0.1905 0.0127 0.0\n" in text
    path = tmp_path / "spike.msh"
    path.write_text(text.replace("\n0.1905 0.0127 0.0\n", "\n0.1905 0.3127 0.0\n", 1))
    with pytest.warns(MeshQualityWarning, match=r"spike.msh: 2 quad element\(s\) are very "
                                                r"badly shaped .* the worst element \d+"):
        read_mesh(path)


def test_inverted_tetra_and_hexahedron():
    h = structured_mesh(np.linspace(0, 1, 3), np.linspace(0, 1, 2), np.linspace(0, 1, 2))
    cells = h.cells.copy()
    cells[0] = cells[0][[4, 5, 6, 7, 0, 1, 2, 3]]                     # upside down
    with pytest.raises(InputError, match="hexahedron element 1 .* inverted"):
        validate_mesh(Mesh(h.points, cells, "hexahedron"))
    tet = Mesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1.0]], [[0, 2, 1, 3]], "tetra")
    with pytest.raises(InputError, match="tetra element 1 .* inverted"):
        validate_mesh(tet)


def test_a_hexahedron_folded_at_one_corner_is_caught_at_that_corner():
    """A node pushed through the opposite face: the Jacobian is negative at that corner
    only, positive at the Gauss points nearest the others."""
    h = structured_mesh(np.linspace(0, 1, 2), np.linspace(0, 1, 2), np.linspace(0, 1, 2))
    points = h.points.copy()
    points[h.cells[0, 6]] = [0.3, 0.3, 0.3]     # corner (1, 1, 1) moved inside past centre
    bad = Mesh(points, h.cells, "hexahedron")
    q = scaled_jacobians(bad)
    assert q[0, 6] < 0 and q[0].max() > 0
    with pytest.raises(InputError, match="self-intersecting"):
        validate_mesh(bad)


# --- nodes ----------------------------------------------------------------------------

def test_duplicate_node_not_joined_is_refused_and_one_joined_is_a_degenerate_cell():
    m = unit_square_quads()                     # nodes 0..5, cells [0,1,4,3], [1,2,5,4]
    points = np.vstack([m.points, m.points[1] + [0, 1e-13]])        # node 7 on node 2
    cells = m.cells.copy()
    cells[1, 0] = 6                              # second cell uses the copy: a crack
    with pytest.raises(InputError, match="nodes 2 and 7 are at the same point"):
        validate_mesh(Mesh(points, cells, "quad"))
    with pytest.raises(MeshFileError, match=r"^f.msh: nodes 20 and 70"):
        validate_mesh(Mesh(points, cells, "quad"), source="f.msh",
                      node_ids=[10, 20, 30, 40, 50, 60, 70])


def test_unused_nodes_are_refused(tmp_path):
    m = unit_square_quads()
    points = np.vstack([m.points, [[5.0, 5.0]]])
    with pytest.raises(InputError, match=r"1 node\(s\) are used by no element, e.g. "
                                         r"node\(s\) 7; .* delete these nodes"):
        validate_mesh(Mesh(points, m.cells, "quad"))
    text = (DATA / "gmsh_rect.inp").read_text().replace("*ELEMENT", "999, 7.0, 7.0\n*ELEMENT", 1)
    path = tmp_path / "free.inp"
    path.write_text(text)
    with pytest.raises(MeshFileError, match=r"free.inp: 1 node\(s\) .* node\(s\) 999;"):
        read_mesh(path)


def test_valid_meshes_pass_without_warning():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for path in [DATA / "gmsh_box_v41.msh", DATA / "gmsh_rect.inp",
                     EXAMPLES / "sandwich-2d-top.msh", EXAMPLES / "sandwich-2d-bottom.inp"]:
            m = read_mesh(path)
            assert (corner_measures(m) > 0).all()
            validate_mesh(m)


def test_read_names_file_and_element_id(tmp_path):
    text = (DATA / "gmsh_rect.inp").read_text()
    rows = re.findall(r"^(\d+), (\d+), (\d+), (\d+)$", text.split("type=CPS3")[1], re.M)
    eid, a, b, c = rows[3]
    bad = text.replace(f"\n{eid}, {a}, {b}, {c}\n", f"\n{eid}, {a}, {c}, {b}\n")
    path = tmp_path / "flipped.inp"
    path.write_text(bad)
    with pytest.raises(MeshFileError, match=rf"flipped.inp: triangle element {eid} "
                                            rf"\(nodes {a}, {c}, {b}\) is inverted"):
        read_mesh(path)


# --- the cases: one line duplicated or two swapped ----------------------------

def test_duplicated_coordinate_line_in_gmsh_file_is_refused(tmp_path):
    lines = (EXAMPLES / "sandwich-2d-top.msh").read_text().splitlines()
    k = next(j for j in range(lines.index("$Nodes"), len(lines))
             if len(lines[j].split()) == 3 and "." in lines[j])
    path = tmp_path / "dup.msh"
    path.write_text("\n".join(lines[:k + 1] + lines[k:]) + "\n")
    with pytest.raises(MeshFileError, match=r"dup.msh, line \d+: section \$Nodes holds 3 "
                                            r"value\(s\) more than its counts declare"):
        read_mesh(path)


@pytest.mark.parametrize("name,words", [
    ("gmsh_rect_v22.msh", r"\$Nodes declares 71 lines but holds 72"),
    ("gmsh_rect_v40.msh", r"the header declares 71 nodes but its blocks hold 28"),
])
def test_duplicated_line_in_older_gmsh_versions(tmp_path, name, words):
    lines = (DATA / name).read_text().splitlines()
    k = lines.index("$Nodes") + 3
    path = tmp_path / name
    path.write_text("\n".join(lines[:k + 1] + lines[k:]) + "\n")
    with pytest.raises(MeshFileError, match=rf"{name}, line \d+: {words}"):
        read_mesh(path)


@pytest.mark.parametrize("name", ["gmsh_rect_v41_binary.msh", "gmsh_rect_v22_binary.msh"])
@pytest.mark.parametrize("section", ["Nodes", "Elements"])
def test_binary_section_with_bytes_left_over(tmp_path, name, section):
    raw = (DATA / name).read_bytes()
    path = tmp_path / "b.msh"
    end = f"$End{section}".encode()
    path.write_bytes(raw.replace(end, b"\x01\x02\x03\x04" + end, 1))
    with pytest.raises(MeshFileError, match=rf"b.msh, byte \d+: section \${section} holds "
                                            rf"5 bytes after the data its counts declare"):
        read_mesh(path)


def test_binary_gmsh22_element_group_that_does_not_fit(tmp_path):
    raw = (DATA / "gmsh_rect_v22_binary.msh").read_bytes()
    start = raw.index(b"\n", raw.index(b"$Elements\n") + 10) + 1     # first group header
    header = np.frombuffer(raw, np.int32, 3, start).copy()
    header[1] += 1000                                                 # more than declared
    path = tmp_path / "g.msh"
    path.write_bytes(raw[:start] + header.tobytes() + raw[start + 12:])
    with pytest.raises(MeshFileError, match=rf"g.msh, byte {start}: element group header"):
        read_mesh(path)


def test_inp_node_row_with_extra_fields(tmp_path):
    text = (DATA / "gmsh_rect.inp").read_text()
    row = re.search(r"^1, .*$", text, re.M).group(0)
    path = tmp_path / "n.inp"
    path.write_text(text.replace(row, row + ", 7.5", 1))
    with pytest.raises(MeshFileError, match=r"n.inp, line \d+: node row .* has 5 fields"):
        read_mesh(path)


# --- random mutations -----------------------------------------------------------------

MUTATED = [DATA / "gmsh_rect_v41.msh", DATA / "gmsh_rect_v40.msh", DATA / "gmsh_rect_v22.msh",
           DATA / "gmsh_rect.inp", DATA / "gmsh_box_v41.msh"]


def is_number(token: str) -> bool:
    try:
        float(token)
    except ValueError:
        return False
    return True


def mutate(lines: list, rng) -> list:
    """One random damage: a line duplicated, deleted, swapped with another, a number
    perturbed, or two node ids swapped in an element row."""
    lines = list(lines)
    k = int(rng.integers(len(lines)))
    kind = rng.integers(5)
    if kind == 0:
        lines.insert(k, lines[k])
    elif kind == 1:
        del lines[k]
    elif kind == 2:
        j = int(np.clip(k + rng.integers(-6, 7), 0, len(lines) - 1))
        lines[k], lines[j] = lines[j], lines[k]
    else:
        sep = "," if "," in lines[k] else " "
        tokens = lines[k].split(sep)
        numeric = [i for i, t in enumerate(tokens) if is_number(t)]
        if not numeric:
            return mutate(lines, rng)
        if kind == 3:
            i = numeric[int(rng.integers(len(numeric)))]
            value = float(tokens[i])
            tokens[i] = repr(float(value + rng.choice([-1, 1]) * rng.choice([1, 0.3, 1e-9])))
            if re.fullmatch(r"\s*-?\d+\s*", lines[k].split(sep)[i]):
                tokens[i] = str(int(round(float(tokens[i]))))
        else:
            if len(numeric) < 3:
                return mutate(lines, rng)
            a, b = rng.choice(numeric[1:], size=2, replace=False)
            tokens[a], tokens[b] = tokens[b], tokens[a]
        lines[k] = sep.join(tokens)
    return lines


def declared_nodes(text: str, suffix: str):
    """The node count the file itself declares (None: the .inp format declares none)."""
    if suffix == ".inp" or "$Nodes" not in text:
        return None
    header = text.split("$Nodes", 1)[1].split()
    version4 = re.search(r"^\$MeshFormat\s+4", text, re.M) is not None
    try:
        return int(header[1] if version4 else header[0])
    except (ValueError, IndexError):      # a damaged count: such a file must be refused
        return -1


def assert_refused_or_valid(target: Path, original: Mesh, n_nodes=None):
    """``target`` is refused with MeshFileError/InputError, or reads as a mesh whose
    every cell has positive corner measures, with ``n_nodes`` nodes (when the file
    declares a count) and, for Gmsh files, the cells of the original."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MeshQualityWarning)
            mesh = read_mesh(target)
    except (MeshFileError, InputError):
        return
    assert (corner_measures(mesh) > 0).all(), f"{target.name} accepted with a bad cell"
    assert n_nodes is None or mesh.n_nodes == n_nodes, f"{target.name}: node count"
    if target.suffix == ".msh":
        assert len(mesh.cells) == len(original.cells), f"{target.name}: cell count"


def check_mutants(path: Path, count: int, seed: int, tmp_path: Path):
    original = read_mesh(path)
    lines = path.read_text().splitlines()
    rng = np.random.default_rng(seed)
    for n in range(count):
        text = "\n".join(mutate(lines, rng)) + "\n"
        target = tmp_path / f"m{n}{path.suffix}"
        target.write_text(text)
        assert_refused_or_valid(target, original, declared_nodes(text, path.suffix))


@pytest.mark.parametrize("path", MUTATED, ids=lambda p: p.name)
def test_mutated_files_are_refused_or_valid(path, tmp_path):
    """40 mutants per file (seeded); each refused with MeshFileError/InputError or, if
    accepted, a mesh whose every cell has positive corner areas/volumes and the node and
    cell counts the file declares."""
    check_mutants(path, 40, seed=18, tmp_path=tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("path", MUTATED + [EXAMPLES / "sandwich-2d-top.msh",
                                            EXAMPLES / "sandwich-2d-bottom.inp"],
                         ids=lambda p: p.name)
def test_many_mutated_files_are_refused_or_valid(path, tmp_path):
    check_mutants(path, 400, seed=1800, tmp_path=tmp_path)


BINARY = [DATA / "gmsh_rect_v41_binary.msh", DATA / "gmsh_rect_v22_binary.msh"]


def check_binary_mutants(path: Path, count: int, seed: int, tmp_path: Path):
    """Bytes of the data overwritten, doubled or deleted (after the header)."""
    original = read_mesh(path)
    raw = path.read_bytes()
    start = raw.index(b"$EndMeshFormat")
    rng = np.random.default_rng(seed)
    for n in range(count):
        k = int(rng.integers(start, len(raw) - 8))
        width = int(rng.choice([1, 4, 8]))
        kind = rng.integers(3)
        if kind == 0:
            data = raw[:k] + bytes(rng.integers(0, 256, width, dtype=np.uint8)) + raw[k + width:]
        elif kind == 1:
            data = raw[:k] + raw[k:k + width] + raw[k:]
        else:
            data = raw[:k] + raw[k + width:]
        target = tmp_path / f"b{n}.msh"
        target.write_bytes(data)
        assert_refused_or_valid(target, original)


@pytest.mark.parametrize("path", BINARY, ids=lambda p: p.name)
def test_mutated_binary_files_are_refused_or_valid(path, tmp_path):
    check_binary_mutants(path, 40, seed=18, tmp_path=tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("path", BINARY, ids=lambda p: p.name)
def test_many_mutated_binary_files_are_refused_or_valid(path, tmp_path):
    check_binary_mutants(path, 400, seed=1800, tmp_path=tmp_path)


def test_gmsh41_element_tag_defined_twice(tmp_path):
    lines = (DATA / "gmsh_rect_v41.msh").read_text().splitlines()
    block = next(k for k in range(lines.index("$Elements") + 2, len(lines))
                 if lines[k].split()[:1] == ["2"])                # the triangles' block
    tag = lines[block + 1].split()[0]
    lines[block + 2] = " ".join([tag] + lines[block + 2].split()[1:])
    path = tmp_path / "tags.msh"
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(MeshFileError, match=rf"tags.msh: element tag {tag} is defined twice"):
        read_mesh(path)


def test_inp_surface_row_with_extra_fields(tmp_path):
    text = """*NODE
1, 0, 0
2, 1, 0
3, 1, 1
4, 0, 1
*ELEMENT, TYPE=CPE4
1, 1, 2, 3, 4
*SURFACE, NAME=s
1, S1, S2
"""
    path = tmp_path / "s.inp"
    path.write_text(text)
    with pytest.raises(MeshFileError, match=r"s.inp, line 9: cannot read the surface row"):
        read_mesh(path)


def test_gmsh22_node_tag_defined_twice(tmp_path):
    lines = (DATA / "gmsh_rect_v22.msh").read_text().splitlines()
    i = lines.index("$Nodes")
    tag = lines[i + 2].split()[0]
    damaged = lines[:i + 1] + [str(int(lines[i + 1]) + 1), f"{tag} 9 9 0"] + lines[i + 2:]
    path = tmp_path / "twice.msh"
    path.write_text("\n".join(damaged) + "\n")
    with pytest.raises(MeshFileError, match=rf"twice.msh, line {i + 4}: node tag {tag} is "
                                            rf"defined twice \(first on line {i + 3}\)"):
        read_mesh(path)


def damaged(tmp_path, name, old, new, out="damaged.msh"):
    text = (DATA / name).read_text()
    assert old in text
    path = tmp_path / out
    path.write_text(text.replace(old, new, 1))
    return path


@pytest.mark.parametrize("old,new,words", [
    ("$Nodes\n9 71 1 71\n", "$Nodes\n9 72 1 72\n", r"line \d+: the header declares 72 nodes "
                                                   r"but its blocks hold 71"),
    ("$Nodes\n9 71 1 71\n", "$Nodes\n9 71 2 71\n", r"node tags run from 1 to 71, outside the "
                                                   r"declared range 2..71"),
    ("$Elements\n4 127 1 127\n", "$Elements\n4 126 1 127\n",
     "the header declares 126 elements but its blocks hold 127"),
    ('$PhysicalNames\n4\n', '$PhysicalNames\n5\n', "line 5: \\$PhysicalNames declares 5 names "
                                                   "but holds 4"),
    ('0 5 "origin"\n1 3 "left"', '0 5 "origin"\n0 5 "left"', 'line 7: physical group 0 5 is '
                                                              'named twice'),
])
def test_gmsh41_counts_and_names(tmp_path, old, new, words):
    with pytest.raises(MeshFileError, match=rf"damaged.msh.*{words}"):
        read_mesh(damaged(tmp_path, "gmsh_rect_v41.msh", old, new))


@pytest.mark.parametrize("old,new,words", [
    ("$Elements\n141\n", "$Elements\n140\n", r"line \d+: \$Elements declares 140 lines but "
                                             r"holds 141"),
    ("\n2 1 2 4 1 1 5\n", "\n2 1 2 4 1 1 5 6\n", r"line \d+: 8 values on a \$Elements line, "
                                                 r"expected 7"),
])
def test_gmsh22_counts(tmp_path, old, new, words):
    with pytest.raises(MeshFileError, match=rf"damaged.msh, {words}"):
        read_mesh(damaged(tmp_path, "gmsh_rect_v22.msh", old, new))


@pytest.mark.parametrize("axes", [[[0, 1, 1, 2], [0, 1]], [[0, 1], [1, 0]],
                                  [[0, 1], [0, 1], [0, np.nan]], [[0], [0, 1]]])
def test_structured_mesh_refuses_axes_that_do_not_increase(axes):
    with pytest.raises(InputError, match="strictly increasing"):
        structured_mesh(*[np.array(a, dtype=float) for a in axes])


def test_generated_meshes_pass_validation():
    """structured_mesh checks its axes instead of calling validate_mesh; the two agree."""
    rng = np.random.default_rng(16)
    for dims in (2, 3, 2, 3):
        axes = [np.cumsum(rng.uniform(1e-3, 1.0, int(rng.integers(2, 6)))) for _ in range(dims)]
        m = structured_mesh(*axes)
        validate_mesh(m)
        assert (corner_measures(m) > 0).all()


def test_a_mirrored_mesh_gets_one_message(tmp_path):
    m = read_mesh(DATA / "gmsh_rect_v41.msh")
    mirrored = Mesh(m.points * [1, -1], m.cells, m.cell_type)
    with pytest.raises(InputError, match=r"every one of the \d+ triangle elements is inverted"
                                         r".*gmsh.model.mesh.reverse\(\)"):
        validate_mesh(mirrored)


def test_binary_gmsh22_node_tag_defined_twice(tmp_path):
    raw = (DATA / "gmsh_rect_v22_binary.msh").read_bytes()
    start = raw.index(b"\n", raw.index(b"$Nodes\n") + 7) + 1           # first node record
    second = start + 28
    path = tmp_path / "t.msh"
    path.write_bytes(raw[:second] + raw[start:start + 4] + raw[second + 4:])
    with pytest.raises(MeshFileError, match=rf"t.msh, byte {second}: node tag 1 is defined "
                                            rf"twice"):
        read_mesh(path)
