"""Mesh files with named sets: Gmsh ``.msh`` and Abaqus/CalculiX ``.inp``.

:func:`read_mesh` and :func:`write_mesh` choose the format from the file
extension through the registry :data:`MESH_FORMATS`. Both formats map onto a
:class:`~qsma.model.mesh.Mesh` the same way:

==============  =======================================  ==========================================
Mesh            Gmsh (physical groups)                    Abaqus / CalculiX
==============  =======================================  ==========================================
``cell_sets``   groups of the mesh dimension              ``*ELSET`` of volume elements
``facet_sets``  groups of dimension - 1 (facet elements)  ``*SURFACE, TYPE=ELEMENT`` (faces S1..S6),
                                                          ``*ELSET`` of surface/line elements
``node_sets``   groups of dimension 0 (point elements)    ``*NSET``
==============  =======================================  ==========================================

Facets read from a file are matched to the boundary facets of the volume mesh
and returned in the orientation of :func:`~qsma.model.mesh.boundary_facets`
(outward), whatever their node order in the file. ``docs/mesh-io.md`` lists
the conventions, the face numbering and the known limits.
"""
from __future__ import annotations

import contextlib
import io
import os
import re
import secrets
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable

import numpy as np

from ..errors import InputError, MeshFileError
from .mesh import CELL_FACETS, CELL_TYPES, Mesh

__all__ = ["read_mesh", "write_mesh", "MESH_FORMATS", "ABAQUS_FACES", "ABAQUS_ELEMENT_TYPES",
           "GMSH_VERSIONS"]

#: Abaqus face numbering: face ``S<k>`` of an element is ``ABAQUS_FACES[type][k - 1]``
#: (0-based local nodes), from the Abaqus element library ("face 1: 1-2-3-4,
#: face 2: 5-8-7-6, face 3: 1-5-6-2, ..." for C3D8; "1-2-3, 1-4-2, 2-4-3, 3-4-1" for C3D4;
#: edges 1-2, 2-3, 3-4, 4-1 for CPE4). Linear Abaqus and meshio node orders coincide.
ABAQUS_FACES = {
    "triangle": [(0, 1), (1, 2), (2, 0)],
    "quad": [(0, 1), (1, 2), (2, 3), (3, 0)],
    "tetra": [(0, 1, 2), (0, 3, 1), (1, 3, 2), (2, 3, 0)],
    "hexahedron": [(0, 1, 2, 3), (4, 7, 6, 5), (0, 4, 5, 1), (1, 5, 6, 2), (2, 6, 7, 3),
                   (3, 7, 4, 0)],
}

#: Abaqus/CalculiX element types read, without the letters R, I, H, T that mark reduced
#: integration, incompatible modes, hybrid and coupled temperature variants (so C3D8R,
#: CPE4I, CPS4R, ... are read too). Continuum elements are the cells of a mesh; shell,
#: membrane, rigid, surface, truss and beam elements only ever carry sets (facets, nodes).
ABAQUS_ELEMENT_TYPES = {
    "C3D8": "hexahedron", "C3D4": "tetra",
    "CPE4": "quad", "CPS4": "quad", "CAX4": "quad", "CPEG4": "quad",
    "CPE3": "triangle", "CPS3": "triangle", "CAX3": "triangle", "CPEG3": "triangle",
    "S4": "quad", "M3D4": "quad", "R3D4": "quad", "SFM3D4": "quad",
    "S3": "triangle", "M3D3": "triangle", "R3D3": "triangle", "SFM3D3": "triangle",
    "T2D2": "line", "T3D2": "line", "B21": "line", "B31": "line", "R2D2": "line",
}
#: element type written to .inp files (plane strain in 2D)
_ABAQUS_WRITE_TYPE = {"quad": "CPE4", "triangle": "CPE3", "hexahedron": "C3D8", "tetra": "C3D4"}

#: Gmsh element type number -> (meshio name, nodes per element, topological dimension)
_GMSH_TYPES = {
    1: ("line", 2, 1), 2: ("triangle", 3, 2), 3: ("quad", 4, 2), 4: ("tetra", 4, 3),
    5: ("hexahedron", 8, 3), 6: ("wedge", 6, 3), 7: ("pyramid", 5, 3), 8: ("line3", 3, 1),
    9: ("triangle6", 6, 2), 10: ("quad9", 9, 2), 11: ("tetra10", 10, 3),
    12: ("hexahedron27", 27, 3), 13: ("wedge18", 18, 3), 14: ("pyramid14", 14, 3),
    15: ("vertex", 1, 0), 16: ("quad8", 8, 2), 17: ("hexahedron20", 20, 3),
    18: ("wedge15", 15, 3), 19: ("pyramid13", 13, 3),
}
_GMSH_TYPE_NUMBER = {name: number for number, (name, _, _) in _GMSH_TYPES.items()}
#: element types a file may hold besides the cells: (name -> topological dimension)
_SET_ELEMENT_DIM = {"vertex": 0, "line": 1, "triangle": 2, "quad": 2}
#: topological dimension and nodes of the linear types
_TOPO_DIM = {**_SET_ELEMENT_DIM, "tetra": 3, "hexahedron": 3}
_N_NODES = {"vertex": 1, "line": 2, "triangle": 3, "quad": 4, "tetra": 4, "hexahedron": 8}
#: Gmsh file versions write_mesh can produce
GMSH_VERSIONS = ("4.1", "2.2")

#: largest node or element id accepted (ids are stored as int64)
_MAX_ID = 2**62
#: most ids one GENERATE row may produce
_MAX_GENERATED = 10**8
_BINARY_BYTES = re.compile(rb"[\x00-\x08\x0b\x0e-\x1f\x7f]")
_PLAIN_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_\-]*")


# --------------------------------------------------------------------------------------
# public functions

def read_mesh(path, *, cell_type: str | None = None) -> Mesh:
    """Read a mesh and its named sets from a Gmsh ``.msh`` or Abaqus ``.inp`` file.

    Parameters
    ----------
    path : str or os.PathLike
        The file; its extension (case-insensitive) selects the format in
        :data:`MESH_FORMATS`.
    cell_type : str, optional
        The cell type the caller expects (one of ``CELL_TYPES``). The cells of a
        mesh are always the elements of the highest dimension in the file; when
        ``cell_type`` is given and they are of another type, the file is rejected.

    Returns
    -------
    Mesh
        Nodes in the order of their ids (Gmsh tags, Abaqus node numbers), remapped
        to 0-based indices; cells of one type in file order; the sets (see the module
        docstring). 2D meshes (triangles, quads) must lie in the plane z = 0 and come
        back with 2D points.

    Raises
    ------
    MeshFileError
        The file is missing, unreadable, truncated or malformed, holds mixed or
        unsupported cell types, or a set that cannot be resolved. The message
        names the file, the line where known, and what to fix.
    """
    path = Path(path)
    if cell_type is not None and cell_type not in CELL_TYPES:
        raise InputError(f"cell_type must be one of {sorted(CELL_TYPES)} or None, "
                         f"got {cell_type!r}")
    return _format_of(path).read(path, cell_type)


def write_mesh(path, mesh: Mesh, *, gmsh_version: str = "4.1") -> Path:
    """Write ``mesh`` with its sets to a Gmsh ``.msh`` or Abaqus ``.inp`` file.

    The file is written to a temporary file in the same folder and moved into
    place with :func:`os.replace`, so a reader never sees half a file.

    Parameters
    ----------
    path : str or os.PathLike
        The file; its extension selects the format in :data:`MESH_FORMATS`.
    mesh : Mesh
        The mesh; every facet of its facet sets must be a boundary facet.
    gmsh_version : {"4.1", "2.2"}
        Version of the ASCII ``.msh`` format (ignored for other formats).

    Returns
    -------
    Path
        The file written.
    """
    path = Path(path)
    fmt = _format_of(path)
    if gmsh_version not in GMSH_VERSIONS:
        raise InputError(f"gmsh_version must be one of {GMSH_VERSIONS}, got {gmsh_version!r}")
    if not isinstance(mesh, Mesh):
        raise InputError(f"write_mesh needs a qsma Mesh, got {type(mesh).__name__}")
    if len(mesh.cells) == 0:
        raise InputError(f"cannot write {path}: the mesh has no cells")
    _write_atomically(path, fmt.format(mesh, gmsh_version))
    return path


@dataclass(frozen=True)
class MeshFormat:
    """A mesh file format: a reader ``(path, cell_type) -> Mesh`` and a formatter
    ``(mesh, gmsh_version) -> file text``."""

    name: str
    read: Callable
    format: Callable


def _format_of(path: Path) -> MeshFormat:
    fmt = MESH_FORMATS.get(path.suffix.lower())
    if fmt is None:
        known = ", ".join(f"{ext} ({f.name})" for ext, f in MESH_FORMATS.items())
        raise MeshFileError(f"{path}: unknown mesh file extension {path.suffix!r}; "
                            f"use one of {known}")
    return fmt


def _write_atomically(path: Path, text: str) -> None:
    """Write ``text`` to a temporary file beside ``path``, then rename it to ``path``."""
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(6)}.tmp")
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)  # umask applies
    except OSError as exc:
        raise MeshFileError(f"cannot write {path}: {exc.strerror}; check that the folder "
                            f"{path.parent} exists and is writable") from exc
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
        raise


# --------------------------------------------------------------------------------------
# from what a file holds to a Mesh (shared by the readers)

@dataclass
class _FileMesh:
    """What a reader found, before it becomes a :class:`Mesh`.

    ``blocks`` are ``(type, dimension, (k, nodes) node indices, may be cells)``: shell,
    membrane and rigid elements may only carry sets. "Global element indices" count the
    rows of all blocks in order. Set values are lists of index arrays, merged when the
    mesh is built.
    """

    source: str
    points: np.ndarray                  # (n, 3)
    labels: np.ndarray                  # node ids of the file, for messages
    blocks: list
    element_sets: dict = field(default_factory=dict)   # name -> [global element indices]
    node_sets: dict = field(default_factory=dict)      # name -> [node indices]
    facet_rows: dict = field(default_factory=dict)     # name -> [(k, nf) node indices]
    free_faces: dict = field(default_factory=dict)     # name -> [global element indices]
    empty_sets: dict = field(default_factory=dict)     # name -> "cell" | "facet" | "node"


class _Elements:
    """Global element indices (rows of all blocks, in order) and their blocks."""

    def __init__(self, blocks: list):
        sizes = [len(conn) for _, _, conn, _ in blocks]
        self.blocks = blocks
        self.offsets = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        self.block_of = np.repeat(np.arange(len(blocks)), sizes)

    def by_block(self, members: np.ndarray):
        """``(block, rows within the block)`` of global element indices ``members``."""
        for b in np.unique(self.block_of[members]):
            yield int(b), members[self.block_of[members] == b] - self.offsets[b]


def _cell_type_of(source: str, blocks: list, requested: str | None) -> str:
    """The cell type of a file: the type of the highest-dimensional elements that may be
    cells (one type only)."""
    types = {t: d for t, d, conn, cell in blocks if len(conn) and cell}
    if not types and any(len(conn) for *_, conn, _ in blocks):
        found = sorted({t for t, _, conn, _ in blocks if len(conn)})
        raise MeshFileError(f"{source}: no continuum elements, only shell/surface/line "
                            f"elements ({', '.join(found)}); a mesh needs continuum cells "
                            f"such as CPE4, CPS3, C3D8 or C3D4")
    if not types:
        raise MeshFileError(f"{source}: the file holds no elements (empty mesh); a mesh "
                            f"needs triangle, quad, tetra or hexahedron cells")
    dim = max(types.values())
    if dim < 2:
        raise MeshFileError(f"{source}: the file holds only {', '.join(sorted(types))} "
                            f"elements; a mesh needs 2D (triangle, quad) or 3D (tetra, "
                            f"hexahedron) cells")
    top = sorted(t for t, d in types.items() if d == dim)
    if len(top) > 1:
        raise MeshFileError(f"{source}: mixed meshes are not supported yet: the file holds "
                            f"{dim}D cells of types {', '.join(top)}; mesh with a single cell "
                            f"type (e.g. all {top[0]})")
    vtype = top[0]
    if vtype not in CELL_TYPES:
        raise MeshFileError(f"{source}: {vtype} cells are not supported; qsma reads linear "
                            f"meshes of one of {', '.join(sorted(CELL_TYPES))}")
    other = sorted(t for t in types if t != vtype and t not in _SET_ELEMENT_DIM)
    if other:
        raise MeshFileError(f"{source}: {', '.join(other)} elements are not supported beside "
                            f"the {vtype} cells; remove them or use linear elements")
    if requested is not None and requested != vtype:
        raise MeshFileError(f"{source}: the cells are {vtype}, but cell_type={requested!r} "
                            f"was requested")
    return vtype


class _Boundary:
    """Boundary facets of a mesh (as :func:`boundary_facets`) with their owner cells."""

    def __init__(self, mesh: Mesh):
        local = CELL_FACETS[mesh.cell_type]
        n = len(mesh.cells)
        every = np.concatenate([mesh.cells[:, list(f)] for f in local])
        _, inverse, counts = _unique_rows(np.sort(every, axis=1))
        at = np.flatnonzero(counts[inverse] == 1)
        self.rows = every[at]
        self.cell = at % n
        self.local_face = at // n
        self._index = {k: i for i, k in enumerate(map(tuple, np.sort(self.rows, axis=1).tolist()))}

    def find(self, rows: np.ndarray) -> np.ndarray:
        """Boundary facet index of each facet row (any node order), -1 where none."""
        keys = map(tuple, np.sort(np.asarray(rows, dtype=np.int64), axis=1).tolist())
        return np.array([self._index.get(k, -1) for k in keys], dtype=np.int64)


def _unique_rows(rows: np.ndarray):
    """``(first, inverse, counts)`` of the distinct rows, like ``np.unique(axis=0)`` with
    ``return_index``, ``return_inverse`` and ``return_counts`` (but faster)."""
    rows = np.asarray(rows).reshape(len(rows), -1)
    order = np.lexsort(rows.T[::-1])
    ordered = rows[order]
    new = np.ones(len(rows), dtype=bool)
    new[1:] = np.any(ordered[1:] != ordered[:-1], axis=1)
    starts = np.flatnonzero(new)
    inverse = np.empty(len(rows), dtype=np.int64)
    inverse[order] = np.cumsum(new) - 1
    first = np.minimum.reduceat(order, starts) if len(rows) else order
    return first, inverse, np.diff(np.append(starts, len(rows)))


def _first_appearance(values: np.ndarray) -> np.ndarray:
    _, first = np.unique(values, return_index=True)
    return values[np.sort(first)]


def _plane_points(source: str, points: np.ndarray, vtype: str) -> np.ndarray:
    if CELL_TYPES[vtype][0] == 3:
        return points
    scale = max(1.0, float(np.abs(points[:, :2]).max(initial=0.0)))
    z = np.abs(points[:, 2]).max(initial=0.0)
    if z > 1e-12 * scale:
        raise MeshFileError(f"{source}: the {vtype} cells are 2D but nodes have non-zero z "
                            f"(largest |z| = {z:g}); qsma reads 2D meshes in the plane z = 0")
    return np.ascontiguousarray(points[:, :2])


def _to_mesh(fm: _FileMesh, vtype: str) -> Mesh:
    """Build the Mesh: cells of ``vtype``, sets split by element dimension, facets
    matched to boundary facets."""
    src = fm.source
    dim = CELL_TYPES[vtype][0]
    elements = _Elements(fm.blocks)
    volume = [b for b, (t, _, _, cell) in enumerate(fm.blocks) if t == vtype and cell]
    rows = np.concatenate([fm.blocks[b][2] for b in volume])
    where = np.concatenate([np.arange(*elements.offsets[b:b + 2]) for b in volume])
    # one cell per set of nodes: Gmsh 2.2 repeats an element once per physical group
    first, inverse, _ = _unique_rows(np.sort(rows, axis=1))
    rank = np.empty(len(first), dtype=np.int64)
    rank[np.argsort(first)] = np.arange(len(first))
    cells = rows[np.sort(first)]
    element_cell = np.full(elements.offsets[-1], -1, dtype=np.int64)
    element_cell[where] = rank[inverse]
    points = _plane_points(src, fm.points, vtype)
    try:
        bare = Mesh(points, cells, vtype)
    except InputError as exc:
        raise MeshFileError(f"{src}: {exc}") from exc
    boundary = _Boundary(bare)

    cell_sets: dict = {}
    node_sets = {k: list(v) for k, v in fm.node_sets.items()}
    facet_rows = {k: list(v) for k, v in fm.facet_rows.items()}
    for name, parts in fm.element_sets.items():
        for b, mine in elements.by_block(np.unique(_joined(parts, (0,)))):
            etype, edim, conn, cell = fm.blocks[b]
            if etype == vtype and cell:
                cell_sets.setdefault(name, []).append(element_cell[elements.offsets[b] + mine])
            elif edim >= dim:
                raise MeshFileError(f"{src}: set {name!r} holds {edim}D {etype} elements that "
                                    f"are neither cells nor facets of the {vtype} mesh; remove "
                                    f"them from the set")
            elif edim == dim - 1:
                if etype != bare.facet_type:
                    raise MeshFileError(
                        f"{src}: set {name!r} holds {etype} elements, but the facets of a "
                        f"{vtype} mesh are {bare.facet_type}s; remove them from the set")
                facet_rows.setdefault(name, []).append(conn[mine])
            else:
                node_sets.setdefault(name, []).append(conn[mine].ravel())
    for name, parts in fm.free_faces.items():
        cells_in = np.unique(element_cell[np.concatenate(parts)])
        on = np.isin(boundary.cell, cells_in)
        facet_rows.setdefault(name, []).append(boundary.rows[on])

    nf = len(CELL_FACETS[vtype][0])
    facet_sets = {name: _match_facets(src, name, _joined(parts, (0, nf)), boundary,
                                      fm.labels, bare)
                  for name, parts in facet_rows.items()}
    node_sets = {k: np.unique(_joined(v, (0,))) for k, v in node_sets.items()}
    cell_sets = {k: np.unique(_joined(v, (0,))) for k, v in cell_sets.items()}
    empty = {"cell": (cell_sets, np.zeros(0, np.int64)),
             "node": (node_sets, np.zeros(0, np.int64)),
             "facet": (facet_sets, np.zeros((0, nf), np.int64))}
    for name, kind in fm.empty_sets.items():
        sets, value = empty[kind]
        sets.setdefault(name, value)
    try:
        return Mesh(points, cells, vtype, node_sets, facet_sets, cell_sets)
    except InputError as exc:
        raise MeshFileError(f"{src}: {exc}") from exc


def _joined(parts: list, empty_shape: tuple) -> np.ndarray:
    return np.concatenate(parts) if parts else np.zeros(empty_shape, dtype=np.int64)


def _match_facets(src, name, rows, boundary: _Boundary, labels, mesh: Mesh) -> np.ndarray:
    """The boundary facets (outward orientation) of the facet rows of set ``name``."""
    if len(rows) == 0:
        return np.zeros((0, len(CELL_FACETS[mesh.cell_type][0])), dtype=np.int64)
    found = boundary.find(rows)
    missing = np.flatnonzero(found < 0)
    if missing.size:
        ids = ", ".join(str(labels[i]) for i in rows[missing[0]])
        raise MeshFileError(
            f"{src}: facet set {name!r} holds {missing.size} facet(s) that are not boundary "
            f"facets of the {mesh.cell_type} mesh, e.g. the facet of nodes {ids}; facet sets "
            f"must lie on the outer boundary (internal faces and faces of other meshes are "
            f"not supported): remove these facets from the set or fix their nodes")
    return boundary.rows[_first_appearance(found)]


# --------------------------------------------------------------------------------------
# reading files

def _read_bytes(path: Path) -> bytes:
    try:
        return path.read_bytes()
    except FileNotFoundError:
        raise MeshFileError(f"{path}: no such file; check the path (relative paths start "
                            f"in {os.getcwd()})") from None
    except IsADirectoryError:
        raise MeshFileError(f"{path}: is a folder, not a mesh file") from None
    except OSError as exc:
        raise MeshFileError(f"{path}: cannot be read ({exc.strerror})") from exc


def _line_of(data: bytes, offset: int) -> int:
    return data.count(b"\n", 0, offset) + 1


class _IdLookup:
    """File ids -> 0-based indices (in order of definition)."""

    def __init__(self, ids: np.ndarray):
        self.order = np.argsort(ids, kind="stable")
        self.sorted = ids[self.order]
        dup = np.flatnonzero(self.sorted[1:] == self.sorted[:-1])
        #: index of the second definition of a repeated id, or None
        self.duplicate = int(self.order[dup[0] + 1]) if dup.size else None

    def __call__(self, ids) -> np.ndarray:
        ids = np.asarray(ids, dtype=np.int64)
        if len(self.sorted) == 0:
            return np.full(ids.shape, -1, dtype=np.int64)
        pos = np.minimum(np.searchsorted(self.sorted, ids), len(self.sorted) - 1)
        return np.where(self.sorted[pos] == ids, self.order[pos], -1)


# ----- Gmsh ---------------------------------------------------------------------------

def _read_gmsh(path: Path, cell_type: str | None) -> Mesh:
    raw = _read_bytes(path)
    src = str(path)
    version, is_ascii, size_t = _gmsh_header(raw, src)
    if version in ("4", "4.0") and not is_ascii:
        raise MeshFileError(f"{src}: binary Gmsh 4.0 files are not supported; save the mesh "
                            f"as version 4.1 (Gmsh: Mesh.MshFileVersion = 4.1)")
    if version in ("4", "4.0", "4.1"):    # Gmsh writes format 4.0 as version "4"
        fm, dims = _Gmsh4(raw, src, is_ascii, size_t, version == "4.1").file_mesh()
    elif version in ("2", "2.0", "2.1", "2.2"):
        fm, dims = _gmsh_with_meshio(path, raw, src, version, is_ascii)
    else:
        raise MeshFileError(f"{src}: Gmsh format version {version} is not supported; save "
                            f"the mesh as version 4.1 or 2.2 (Gmsh: Mesh.MshFileVersion)")
    vtype = _cell_type_of(src, fm.blocks, cell_type)
    dim = CELL_TYPES[vtype][0]
    kinds = {dim: "cell", dim - 1: "facet"}
    for name, gdim in dims.items():
        if name not in fm.element_sets:
            fm.empty_sets[name] = kinds.get(gdim, "node")
    return _to_mesh(fm, vtype)


def _gmsh_header(raw: bytes, src: str):
    m = re.match(rb"\s*(?:\$Comments.*?\$EndComments\s*)*\$MeshFormat[ \t]*\r?\n"
                 rb"[ \t]*(\S+)[ \t]+(\S+)[ \t]+(\S+)[ \t]*\r?\n", raw, re.S)
    if m is None:
        raise MeshFileError(f"{src}: not a Gmsh mesh file (no $MeshFormat header at the "
                            f"start); check that the file is a .msh file saved by Gmsh")
    try:
        version, file_type, size_t = m.group(1).decode(), int(m.group(2)), int(m.group(3))
    except ValueError:
        raise MeshFileError(f"{src}, line 2: malformed $MeshFormat line "
                            f"{m.group(0).splitlines()[-1]!r}; expected "
                            f"'version file-type data-size'") from None
    if file_type not in (0, 1) or size_t not in (4, 8):
        raise MeshFileError(f"{src}, line 2: unexpected file type {file_type} or data size "
                            f"{size_t} in $MeshFormat; expected 0 or 1, and 4 or 8")
    if file_type == 1 and raw[m.end():m.end() + 4] != np.array(1, np.int32).tobytes():
        raise MeshFileError(f"{src}: binary Gmsh file of another byte order or damaged "
                            f"header; save it as ASCII (Gmsh: Mesh.Binary = 0)")
    return version, file_type == 0, size_t


def _gmsh_physical_names(text: bytes, src: str, first_line: int) -> dict:
    """``(dim, tag) -> name`` from the body of a $PhysicalNames section."""
    lines = text.decode("utf-8", errors="replace").splitlines()
    names = {}
    for number, line in enumerate(lines[1:], start=first_line + 1):
        if not line.strip():
            continue
        m = re.fullmatch(r'\s*(\d+)\s+(-?\d+)\s+"(.*)"\s*', line)
        if m is None:
            raise MeshFileError(f"{src}, line {number}: malformed physical name {line!r}; "
                                f"expected 'dimension tag \"name\"'")
        names[(int(m.group(1)), int(m.group(2)))] = m.group(3)
    return names


def _gmsh_sections(raw: bytes, src: str, is_ascii: bool, parsers: dict):
    """Walk the ``$Name ... $EndName`` sections, calling ``parsers[name](body, start)``.

    For ASCII files ``body`` is the section text; for binary ones the parser gets the
    whole file and returns the offset where its data ends.
    """
    pos = raw.find(b"$EndMeshFormat") + len(b"$EndMeshFormat")
    while True:
        while pos < len(raw) and raw[pos:pos + 1].isspace():
            pos += 1
        if pos >= len(raw):
            return
        eol = raw.find(b"\n", pos)
        eol = len(raw) if eol < 0 else eol
        header = raw[pos:eol].strip()
        if not header.startswith(b"$"):
            raise MeshFileError(f"{src}, line {_line_of(raw, pos)}: expected a section "
                                f"header such as $Nodes, found {header[:40]!r}; the file is "
                                f"damaged or not a Gmsh file")
        name = header[1:].decode("ascii", errors="replace")
        start = eol + 1
        parse = parsers.get(name)
        if parse is not None and not (is_ascii or name == "PhysicalNames"):
            start = parse(raw, start)
        end = raw.find(b"$End" + name.encode(), start)
        if end < 0:
            raise MeshFileError(f"{src}, line {_line_of(raw, pos)}: section ${name} is not "
                                f"closed by $End{name}: the file is truncated or damaged; "
                                f"save it again from Gmsh")
        if parse is not None and (is_ascii or name == "PhysicalNames"):
            parse(raw[start:end], start)
        pos = end + len(name) + 4


class _Stream:
    """Values of a Gmsh section, read in order: ASCII tokens or binary words."""

    def __init__(self, gmsh, data: bytes, start: int, section: str):
        self.src, self.raw, self.ascii = gmsh.src, gmsh.raw, gmsh.is_ascii
        self.size_t = np.dtype(f"u{gmsh.size_t}")
        self.section, self.start = section, start
        if self.ascii:
            lines = data.decode("ascii", errors="replace").splitlines()
            self.tokens = " ".join(lines).split()
            counts = [len(line.split()) for line in lines]
            self.token_line = np.repeat(np.arange(len(lines)), counts)
            self.line0 = _line_of(self.raw, start)
        self.pos = 0 if self.ascii else start

    def where(self) -> str:
        """File and line (ASCII) or byte offset (binary) of the next value."""
        if not self.ascii:
            return f"{self.src}, byte {self.pos}"
        k = min(self.pos, len(self.tokens) - 1)
        return f"{self.src}, line {self.line0 + (int(self.token_line[k]) if k >= 0 else 0)}"

    def _take(self, n: int, dtype) -> np.ndarray:
        n = int(n)
        if n < 0:
            raise MeshFileError(f"{self.where()}: negative count in ${self.section}; the "
                                f"file is damaged")
        if n == 0:
            return np.zeros(0, dtype=float if dtype == "d" else np.int64)
        if self.ascii:
            if n > len(self.tokens) - self.pos:
                raise self.truncated()
            chunk = self.tokens[self.pos:self.pos + n]
            try:
                values = np.array(chunk, dtype=float if dtype == "d" else np.int64)
            except (ValueError, OverflowError):
                raise MeshFileError(f"{self.where()}: unexpected value in ${self.section} "
                                    f"(expected {'numbers' if dtype == 'd' else 'integers'}); "
                                    f"the file is damaged") from None
            self.pos += n
            return values
        dt = {"i": np.dtype("i4"), "d": np.dtype("f8"), "z": self.size_t}[dtype]
        if n * dt.itemsize > len(self.raw) - self.pos:
            raise self.truncated()
        values = np.frombuffer(self.raw, dtype=dt, count=n, offset=self.pos)
        self.pos += n * dt.itemsize
        return values.astype(float if dtype == "d" else np.int64)

    def ints(self, n):
        return self._take(n, "i")

    def sizes(self, n):
        return self._take(n, "z")

    def doubles(self, n):
        return self._take(n, "d")

    def truncated(self) -> MeshFileError:
        return MeshFileError(f"{self.where()}: section ${self.section} ends before all its "
                             f"data was read: the file is truncated or damaged; save it again "
                             f"from Gmsh")


class _Gmsh4:
    """Reader of Gmsh 4.1 (ASCII and binary) and 4.0 (ASCII) files that keeps every
    physical group.

    meshio 5.3.5 keeps only the first physical tag of an entity unless it is named,
    merges names of different dimensions, fails on 4.1 files where some entities have no
    physical group, and reads Gmsh's version "4" (format 4.0) as 4.1; hence this reader.
    """

    def __init__(self, raw: bytes, src: str, is_ascii: bool, size_t: int, v41: bool):
        self.raw, self.src, self.is_ascii, self.size_t = raw, src, is_ascii, size_t
        self.v41 = v41
        self.names, self.entity_groups = {}, {}
        self.node_tags, self.node_xyz, self.blocks = [], [], []
        self.saw_nodes = self.saw_elements = False

    def file_mesh(self):
        _gmsh_sections(self.raw, self.src, self.is_ascii, {
            "PhysicalNames": lambda body, start: self.names.update(
                _gmsh_physical_names(body, self.src, _line_of(self.raw, start))),
            "Entities": self._entities, "Nodes": self._nodes, "Elements": self._elements})
        if not self.saw_nodes or not self.saw_elements:
            raise MeshFileError(f"{self.src}: no ${'Nodes' if not self.saw_nodes else 'Elements'}"
                                f" section: the file is truncated or holds no mesh; mesh the "
                                f"geometry in Gmsh before saving")
        tags = np.concatenate(self.node_tags) if self.node_tags else np.zeros(0, np.int64)
        points = np.concatenate(self.node_xyz) if self.node_xyz else np.zeros((0, 3))
        lookup = _IdLookup(tags)
        if lookup.duplicate is not None:
            raise MeshFileError(f"{self.src}: node tag {tags[lookup.duplicate]} is defined "
                                f"twice in $Nodes; the file is damaged")
        tags, points = tags[lookup.order], points[lookup.order]     # nodes in tag order
        lookup = _IdLookup(tags)
        blocks, element_sets = [], {}
        first = 0
        for dim, entity, etype, conn_tags, where in self.blocks:
            conn = lookup(conn_tags)
            if (conn < 0).any():
                bad = conn_tags[conn < 0][0]
                raise MeshFileError(f"{where}: an element refers to node tag {bad}, which is "
                                    f"not in $Nodes; the file is damaged")
            blocks.append((etype, _GMSH_TYPES[_GMSH_TYPE_NUMBER[etype]][2], conn, True))
            for group in self.entity_groups.get((dim, entity), ()):
                name = self.names.get((dim, group), str(group))
                element_sets.setdefault(name, []).append(first + np.arange(len(conn)))
            first += len(conn)
        fm = _FileMesh(self.src, points, tags, blocks, element_sets=element_sets)
        return fm, {name: dim for (dim, _), name in self.names.items()}

    def _stream(self, data, start, section):
        return _Stream(self, data, start, section)

    def _entities(self, data, start):
        s = self._stream(data, start, "Entities")
        counts = s.sizes(4)
        for dim in range(4):
            for _ in range(int(counts[dim])):
                tag = int(s.ints(1)[0])
                s.doubles(3 if dim == 0 and self.v41 else 6)
                groups = s.ints(int(s.sizes(1)[0]))
                if dim > 0:
                    s.ints(int(s.sizes(1)[0]))   # bounding entities
                self.entity_groups[(dim, tag)] = tuple(int(g) for g in groups)
        return s.pos

    def _nodes(self, data, start):
        s = self._stream(data, start, "Nodes")
        n_blocks = int(s.sizes(4 if self.v41 else 2)[0])
        for _ in range(n_blocks):
            where = s.where()
            first, second, parametric = (int(v) for v in s.ints(3))
            dim = first if self.v41 else second         # 4.0: entity tag, then dimension
            if not 0 <= dim <= 3 or parametric not in (0, 1):
                raise MeshFileError(f"{where}: node block of dimension {dim} with parametric "
                                    f"flag {parametric}; the file is damaged")
            n = int(s.sizes(1)[0])
            width = 3 + (dim if parametric else 0)
            if self.v41:                                # tags, then coordinates
                self.node_tags.append(s.sizes(n))
                self.node_xyz.append(s.doubles(n * width).reshape(n, width)[:, :3])
            else:                                       # tag x y z per node (ASCII)
                table = s.doubles(n * (1 + width)).reshape(n, 1 + width)
                if not np.all(np.abs(table[:, 0]) < _MAX_ID) or np.any(table[:, 0] % 1):
                    raise MeshFileError(f"{where}: node tags that are not integers; the "
                                        f"file is damaged")
                self.node_tags.append(table[:, 0].astype(np.int64))
                self.node_xyz.append(table[:, 1:4])
        self.saw_nodes = True
        return s.pos

    def _elements(self, data, start):
        s = self._stream(data, start, "Elements")
        n_blocks = int(s.sizes(4 if self.v41 else 2)[0])
        for _ in range(n_blocks):
            where = s.where()
            first, second, number = (int(v) for v in s.ints(3))
            dim, entity = (first, second) if self.v41 else (second, first)
            if number not in _GMSH_TYPES:
                raise MeshFileError(f"{where}: unknown Gmsh element type number {number}; "
                                    f"qsma reads linear meshes (Gmsh types 1-5 and 15)")
            etype, nv, _ = _GMSH_TYPES[number]
            n = int(s.sizes(1)[0])
            rows = (s.sizes if self.v41 else s.ints)(n * (1 + nv)).reshape(n, 1 + nv)
            self.blocks.append((dim, entity, etype, rows[:, 1:], where))
        self.saw_elements = True
        return s.pos


def _gmsh_with_meshio(path: Path, raw: bytes, src: str, version: str, is_ascii: bool):
    """Gmsh 2.x files through meshio, with names and checks of our own."""
    import meshio

    names = {}

    def read_names(body, start):
        names.update(_gmsh_physical_names(body, src, _line_of(raw, start)))

    _gmsh_sections(raw, src, is_ascii, {"PhysicalNames": read_names})
    notes = io.StringIO()
    try:
        # meshio prints its warnings to stderr (rich); keep them to report them here
        with contextlib.redirect_stderr(notes), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            m = meshio.gmsh.read(path)
    except Exception as exc:  # meshio raises ReadError, ValueError, KeyError, IndexError...
        raise MeshFileError(f"{src}: cannot be read as a Gmsh {version} file "
                            f"({type(exc).__name__}: {exc}); check that the file is complete "
                            f"and saved by Gmsh") from exc
    problems = [str(w.message) for w in caught
                if not issubclass(w.category, (DeprecationWarning, FutureWarning))
                or "could not be read" in str(w.message)]
    problems += [p.strip() for p in notes.getvalue().split("\n")     # partition tags: fine
                 if p.strip() and "tag data that couldn't be processed" not in p]
    if problems:
        raise MeshFileError(f"{src}: the Gmsh reader reported: {'; '.join(problems)}; the "
                            f"file is damaged or uses features qsma does not read")
    n = len(m.points)
    physical = m.cell_data.get("gmsh:physical")
    blocks, element_sets = [], {}
    first = 0
    for k, block in enumerate(m.cells):
        conn = np.asarray(block.data, dtype=np.int64).reshape(len(block.data), -1)
        if conn.size and (conn.min() < 0 or conn.max() >= n):
            raise MeshFileError(f"{src}: {block.type} elements refer to nodes missing from "
                                f"$Nodes; the file is damaged")
        blocks.append((block.type, block.dim, conn, True))
        tags = None if physical is None else np.asarray(physical[k])
        if tags is not None and len(tags) != len(conn):
            raise MeshFileError(f"{src}: some elements have no physical tag; save the mesh "
                                f"with physical and elementary tags for every element")
        for tag in np.unique(tags) if tags is not None else ():
            if tag > 0:
                name = names.get((block.dim, int(tag)), str(int(tag)))
                element_sets.setdefault(name, []).append(first + np.flatnonzero(tags == tag))
        first += len(conn)
    labels = np.arange(1, n + 1)
    fm = _FileMesh(src, np.asarray(m.points, dtype=float), labels, blocks,
                   element_sets=element_sets)
    return fm, {name: dim for (dim, _), name in names.items()}


# ----- Abaqus / CalculiX --------------------------------------------------------------

@dataclass
class _Card:
    """A keyword line (upper-case keyword, parameters) and its data lines."""

    keyword: str
    params: dict
    where: tuple            # (file, line)
    data: list              # [(file, line, text)]


def _at(where) -> str:
    return f"{where[0]}, line {where[1]}"


def _inp_error(where, problem: str, fix: str) -> MeshFileError:
    return MeshFileError(f"{_at(where)}: {problem}; {fix}")


def _split_fields(text: str) -> list:
    """Split on commas outside double quotes."""
    if '"' not in text:
        return text.split(",")
    fields, current, quoted = [], [], False
    for ch in text:
        if ch == '"':
            quoted = not quoted
        if ch == "," and not quoted:
            fields.append("".join(current))
            current = []
        else:
            current.append(ch)
    fields.append("".join(current))
    return fields


def _unquote(text: str) -> str:
    text = text.strip()
    return text[1:-1] if len(text) >= 2 and text[0] == text[-1] == '"' else text


def _parse_keyword(line: str, where) -> tuple:
    fields = _split_fields(line[1:])
    keyword = " ".join(fields[0].split()).upper()
    if not keyword:
        raise _inp_error(where, f"empty keyword line {line!r}", "write the keyword after '*'")
    params = {}
    for item in fields[1:]:
        if item.strip():
            key, eq, value = item.partition("=")
            params[" ".join(key.split()).upper()] = _unquote(value) if eq else True
    return keyword, params


def _read_inp_text(path: Path, where=None) -> str:
    if where is not None and not path.is_file():
        raise _inp_error(where, f"included file {str(path)!r} not found",
                         "check the INPUT= path (relative to the including file)")
    data = _read_bytes(path)
    bad = _BINARY_BYTES.search(data)
    if bad:
        raise MeshFileError(f"{path}, line {_line_of(data, bad.start())}: binary data "
                            f"(byte 0x{data[bad.start()]:02x}); an .inp file is plain text: "
                            f"check that this is an Abaqus/CalculiX input file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def _inp_lines(path: Path, stack=(), where=None):
    """(file, line number, text) of the lines that are not blank or comments, with
    ``*INCLUDE`` expanded."""
    text = _read_inp_text(path, where)
    here = path.resolve()
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("**"):
            continue
        if line.startswith("*") and line[1:].split(",")[0].strip().upper() == "INCLUDE":
            _, params = _parse_keyword(line, (str(path), number))
            target = params.get("INPUT")
            if not isinstance(target, str) or not target:
                raise _inp_error((str(path), number), "*INCLUDE without INPUT=file",
                                 "name the included file with INPUT=")
            included = path.parent / target
            if included.resolve() in stack + (here,):
                raise _inp_error((str(path), number), f"{target!r} includes itself",
                                 "remove the circular *INCLUDE")
            yield from _inp_lines(included, stack + (here,), (str(path), number))
            continue
        yield str(path), number, line


def _inp_cards(path: Path) -> list:
    items = list(_inp_lines(path))
    cards, i = [], 0
    while i < len(items):
        file, number, line = items[i]
        i += 1
        if not line.startswith("*"):
            raise _inp_error((file, number), f"data line {line[:40]!r} before any keyword",
                             "an .inp file starts with keyword lines such as *HEADING or "
                             "*NODE: check that this is an Abaqus/CalculiX input file")
        # a keyword line ending with a comma continues on the next line
        while (line.endswith(",") and i < len(items) and not items[i][2].startswith("*")
               and items[i][2][:1].isalpha() and "=" in items[i][2]):
            line += items[i][2]
            i += 1
        keyword, params = _parse_keyword(line, (file, number))
        start = i
        while i < len(items) and not items[i][2].startswith("*"):
            i += 1
        cards.append(_Card(keyword, params, (file, number), items[start:i]))
    return cards


def _rows(card: _Card):
    """((file, line), tokens) of the data lines; a trailing comma adds no token."""
    for file, number, text in card.data:
        if '"' in text:
            tokens = [_unquote(t) for t in _split_fields(text)]
        else:
            tokens = [t.strip() for t in text.split(",")]
        if tokens and tokens[-1] == "" and len(tokens) > 1:
            tokens.pop()
        yield (file, number), tokens, text


def _integer(token: str) -> int:
    """An id or count of an .inp file (ValueError if it is none or out of range)."""
    value = int(token)
    if abs(value) >= _MAX_ID:
        raise ValueError(f"{token} is out of range")
    return value


def _abaqus_float(token: str) -> float:
    token = token.strip()
    return float(token.replace("D", "E").replace("d", "e")) if token else 0.0


def _abaqus_cell_type(name: str):
    """meshio type of an Abaqus element type, or None."""
    base = name.upper()
    while base not in ABAQUS_ELEMENT_TYPES and len(base) > 2 and base[-1] in "RIHT":
        base = base[:-1]
    return ABAQUS_ELEMENT_TYPES.get(base)


@dataclass
class _InpSet:
    name: str
    internal: bool
    chunks: list = field(default_factory=list)   # (ids array, where) or ("elset", key)


@dataclass
class _InpBlock:
    cell_type: str
    abaqus_type: str
    ids: np.ndarray             # element ids
    conn: np.ndarray            # (k, nodes) node ids
    where: list                 # (file, line) of each row


class _InpReader:
    """State of an .inp file being read; the handlers in ``_INP_KEYWORDS`` fill it."""

    def __init__(self, path: Path):
        self.source = str(path)
        self.node_ids, self.node_xyz, self.node_where = [], [], []
        self.blocks = []
        self.sets = {"NSET": {}, "ELSET": {}}
        self.surfaces = {}          # key -> (name, [(reference, face or None, where)])
        self.node_surfaces = {}     # key -> _InpSet
        self.scope = "model"        # model | part | assembly | instance
        self.parts = self.instances = 0

    def skips(self, card: _Card) -> bool:
        """Definitions at assembly level (reference points, connectors) are not the mesh."""
        return self.scope == "assembly" and "INSTANCE" not in card.params

    def named_set(self, kind: str, name: str, internal: bool) -> _InpSet:
        s = self.sets[kind].setdefault(name.upper(), _InpSet(name, internal))
        s.internal = s.internal and internal
        return s

    def find_set(self, kind: str, name: str, where) -> _InpSet:
        sets = self.sets[kind]
        key = name.upper()
        if key not in sets and "." in key:        # instance.set
            key = key.rsplit(".", 1)[1]
        if key not in sets:
            raise _inp_error(where, f"unknown {'node' if kind == 'NSET' else 'element'} set "
                             f"{name!r}", f"define it with *{kind} before it is used")
        return sets[key]

    # --- after the last card -----------------------------------------------------------
    def file_mesh(self, cell_type):
        """What the file holds (nodes in id order), and its cell type."""
        node_ids, xyz = self._nodes()
        nodes = _IdLookup(node_ids)
        blocks = [(b.cell_type, _TOPO_DIM[b.cell_type], self._connectivity(b, nodes),
                   _is_continuum(b.abaqus_type)) for b in self.blocks]
        vtype = _cell_type_of(self.source, blocks, cell_type)
        elements = self._element_lookup()
        index = _Elements(blocks)
        elsets = {k: self._element_indices(s, elements) for k, s in self.sets["ELSET"].items()}
        fm = _FileMesh(self.source, xyz, node_ids, blocks)
        for s in self.sets["NSET"].values():
            if not s.internal:
                fm.node_sets[s.name] = [self._node_indices(s, nodes, elsets, index)]
        for s in self.node_surfaces.values():
            fm.node_sets.setdefault(s.name, []).append(
                self._node_indices(s, nodes, elsets, index))
        for key, s in self.sets["ELSET"].items():
            if not s.internal and len(elsets[key]):
                fm.element_sets[s.name] = [elsets[key]]
            elif not s.internal:
                fm.empty_sets[s.name] = "cell"
        for name, rows in self.surfaces.values():
            self._surface(fm, name, rows, vtype, elements, elsets, index)
        return fm, vtype

    def _nodes(self):
        if not sum(len(ids) for ids in self.node_ids):
            raise MeshFileError(f"{self.source}: no nodes (no *NODE data lines); an empty "
                                f"mesh cannot be read: check that this is the model's input "
                                f"file")
        ids = np.concatenate(self.node_ids)
        lookup = _IdLookup(ids)
        if lookup.duplicate is not None:
            raise _inp_error(self.node_where[lookup.duplicate],
                             f"node {ids[lookup.duplicate]} is defined twice",
                             "give every node a distinct id")
        return ids[lookup.order], np.concatenate(self.node_xyz)[lookup.order]

    @staticmethod
    def _connectivity(block: _InpBlock, nodes: _IdLookup) -> np.ndarray:
        conn = nodes(block.conn)
        if (conn < 0).any():
            row, col = np.argwhere(conn < 0)[0]
            raise _inp_error(block.where[row], f"element {block.ids[row]} refers to node "
                             f"{block.conn[row, col]}, which no *NODE defines",
                             "define the node or correct the element row")
        return conn

    def _element_lookup(self) -> _IdLookup:
        ids = np.concatenate([b.ids for b in self.blocks] + [np.zeros(0, np.int64)])
        lookup = _IdLookup(ids)
        if lookup.duplicate is not None:
            where = [w for b in self.blocks for w in b.where][lookup.duplicate]
            raise _inp_error(where, f"element {ids[lookup.duplicate]} is defined twice",
                             "give every element a distinct id")
        return lookup

    @staticmethod
    def _element_indices(s: _InpSet, elements: _IdLookup) -> np.ndarray:
        parts = [np.zeros(0, np.int64)]
        for ids, where in s.chunks:
            idx = elements(ids)
            if (idx < 0).any():
                raise _inp_error(where, f"element set {s.name!r} refers to element "
                                 f"{ids[idx < 0][0]}, which no *ELEMENT defines",
                                 "correct the id or define the element")
            parts.append(idx)
        return np.unique(np.concatenate(parts))

    @staticmethod
    def _node_indices(s: _InpSet, nodes: _IdLookup, elsets: dict, index: _Elements):
        parts = [np.zeros(0, np.int64)]
        for chunk in s.chunks:
            if isinstance(chunk[0], str):           # *NSET, ELSET=...: nodes of elements
                parts += [index.blocks[b][2][rows].ravel()
                          for b, rows in index.by_block(elsets[chunk[1]])]
                continue
            ids, where = chunk
            idx = nodes(ids)
            if (idx < 0).any():
                raise _inp_error(where, f"node set {s.name!r} refers to node "
                                 f"{ids[idx < 0][0]}, which no *NODE defines",
                                 "correct the id or define the node")
            parts.append(idx)
        return np.unique(np.concatenate(parts))

    def _surface(self, fm, name, rows, vtype, elements, elsets, index: _Elements):
        """Facets of an element-based surface: ``(element or set, face)`` rows."""
        faces = ABAQUS_FACES[vtype]
        if not rows:
            fm.empty_sets.setdefault(name, "facet")
        for reference, face, where in rows:
            if re.fullmatch(r"[+-]?\d{1,18}", reference):
                members = elements(np.array([int(reference)]))
                if members[0] < 0:
                    raise _inp_error(where, f"surface {name!r} refers to element {reference}, "
                                     f"which no *ELEMENT defines", "correct the element id")
            else:
                members = elsets[self.find_set("ELSET", reference, where).name.upper()]
            by_block = list(index.by_block(members))
            wrong = [b for b, _ in by_block if fm.blocks[b][0] != vtype or not fm.blocks[b][3]]
            if wrong:
                raise _inp_error(where, f"surface {name!r} uses faces of "
                                 f"{fm.blocks[wrong[0]][0]} elements", f"a surface is made "
                                 f"of faces of the {vtype} cells; refer to those")
            if face is None:                            # every boundary face
                fm.free_faces.setdefault(name, []).append(members)
                continue
            m = re.fullmatch(r"S(\d)", face.upper())
            if m is None or not 1 <= int(m.group(1)) <= len(faces):
                raise _inp_error(where, f"face {face!r} does not exist on {vtype} elements",
                                 f"use S1..S{len(faces)} (Abaqus face numbering)")
            local = list(faces[int(m.group(1)) - 1])
            fm.facet_rows.setdefault(name, []).extend(
                fm.blocks[b][2][rows][:, local] for b, rows in by_block)


def _is_continuum(abaqus_type: str) -> bool:
    return abaqus_type.upper().startswith(("C3D", "CPE", "CPS", "CAX"))


def _inp_node(r: _InpReader, card: _Card):
    if r.skips(card):
        return
    system = str(card.params.get("SYSTEM", "R")).upper()
    if system != "R":
        raise _inp_error(card.where, f"nodes given in SYSTEM={system}",
                         "give node coordinates in the rectangular system (SYSTEM=R)")
    if "INPUT" in card.params:
        raise _inp_error(card.where, "INPUT= on *NODE is not supported",
                         "put the data lines in the file or use *INCLUDE, INPUT=")
    rows = list(_rows(card))
    try:      # fast path: plain numbers in every row
        ids = np.array([tokens[0] for _, tokens, _ in rows], dtype=np.int64)
        xyz = np.array([(tokens + ["0", "0", "0"])[1:4] for _, tokens, _ in rows],
                       dtype=float).reshape(len(rows), 3)
        if np.abs(ids).max(initial=0) >= _MAX_ID:
            raise ValueError("id out of range")
    except (ValueError, OverflowError):
        ids, xyz = _node_rows(rows)
    bad = np.flatnonzero(~np.isfinite(xyz).all(axis=1))
    if bad.size:
        raise _inp_error(rows[bad[0]][0], f"node {ids[bad[0]]} has a non-finite coordinate",
                         "give finite coordinates")
    r.node_ids.append(ids)
    r.node_xyz.append(xyz)
    r.node_where += [where for where, _, _ in rows]
    name = card.params.get("NSET")
    if isinstance(name, str) and name:
        r.named_set("NSET", name, False).chunks.append((ids, card.where))


def _node_rows(rows) -> tuple:
    """Node ids and coordinates row by row (Fortran exponents, empty fields), with the
    line of the first row that cannot be read."""
    ids, xyz = [], []
    for where, tokens, text in rows:
        try:
            ids.append(_integer(tokens[0]))
            xyz.append([_abaqus_float(t) for t in (tokens + ["", "", ""])[1:4]])
        except ValueError:
            raise _inp_error(where, f"cannot read the node row {text!r}",
                             "expected 'node id, x, y[, z]' with an integer id") from None
    return np.array(ids, dtype=np.int64), np.array(xyz, dtype=float).reshape(-1, 3)


def _inp_element(r: _InpReader, card: _Card):
    if r.skips(card):
        return
    etype = card.params.get("TYPE")
    if not isinstance(etype, str) or not etype:
        raise _inp_error(card.where, "*ELEMENT without TYPE=", "give the element type")
    cell_type = _abaqus_cell_type(etype)
    if cell_type is None:
        raise _inp_error(card.where, f"unknown or unsupported element type {etype!r}",
                         f"qsma reads the linear types {', '.join(ABAQUS_ELEMENT_TYPES)} "
                         f"(with R/I/H/T variants); convert the mesh to one of them")
    nv = _N_NODES[cell_type]
    rows, starts, texts = [], [], []
    pending, start = [], None
    for where, tokens, text in _rows(card):
        if not pending:
            start = where
        pending += tokens
        if len(pending) < 1 + nv and text.rstrip().endswith(","):
            continue                                   # the row continues on the next line
        if len(pending) != 1 + nv:
            raise _inp_error(start, f"element row with {len(pending) - 1} node ids, but "
                             f"{etype} elements have {nv}", f"give 'element id' and {nv} "
                             f"node ids (continue a long row by ending the line with a comma)")
        rows.append(pending)
        starts.append(start)
        texts.append(text)
        pending = []
    if pending:
        raise _inp_error(start, "the last element row is incomplete",
                         f"give {nv} node ids for each {etype} element")
    try:
        table = np.array(rows, dtype=np.int64).reshape(len(rows), 1 + nv)
        if np.abs(table).max(initial=0) >= _MAX_ID:
            raise ValueError("id out of range")
    except (ValueError, OverflowError):
        for row, where, text in zip(rows, starts, texts):
            try:
                [_integer(t) for t in row]
            except ValueError:
                raise _inp_error(where, f"cannot read the element row {text!r}",
                                 "expected integer element and node ids") from None
        raise _inp_error(card.where, "cannot read the element rows",
                         "expected integer element and node ids") from None
    r.blocks.append(_InpBlock(cell_type, etype, table[:, 0], table[:, 1:], starts))
    name = card.params.get("ELSET")
    if isinstance(name, str) and name:
        r.named_set("ELSET", name, False).chunks.append((table[:, 0], card.where))


def _inp_set(kind: str):
    def handler(r: _InpReader, card: _Card):
        if r.skips(card):
            return
        name = card.params.get(kind)
        if not isinstance(name, str) or not name:
            raise _inp_error(card.where, f"*{kind} without {kind}=name", "name the set")
        s = r.named_set(kind, name, card.params.get("INTERNAL") is True)
        from_elset = card.params.get("ELSET") if kind == "NSET" else None
        if isinstance(from_elset, str):
            s.chunks.append(("elset", r.find_set("ELSET", from_elset, card.where).name.upper()))
        generate = card.params.get("GENERATE") is True
        for where, tokens, text in _rows(card):
            s.chunks.append((_set_row(r, kind, s, tokens, text, where, generate), where))
    return handler


def _set_row(r, kind, s, tokens, text, where, generate) -> np.ndarray:
    if generate:
        try:
            values = [_integer(t) for t in tokens]
        except ValueError:
            values = []
        if (len(values) not in (2, 3) or values[1] < values[0]
                or (len(values) == 3 and values[2] < 1)
                or (values[1] - values[0]) // (values[2] if len(values) == 3 else 1)
                >= _MAX_GENERATED):
            raise _inp_error(where, f"cannot read the GENERATE row {text!r}",
                             "expected 'first, last[, increment]' with first <= last, a "
                             f"positive increment and fewer than {_MAX_GENERATED} ids")
        return np.arange(values[0], values[1] + 1, values[2] if len(values) == 3 else 1)
    ids = []
    for token in tokens:
        if not token:
            continue
        if re.fullmatch(r"[+-]?\d+", token):
            try:
                ids.append(_integer(token))
            except ValueError:
                raise _inp_error(where, f"id {token} is out of range",
                                 f"use ids below {_MAX_ID}") from None
        else:   # the name of another set of the same kind
            s.chunks.extend(r.find_set(kind, token, where).chunks)
    return np.array(ids, dtype=np.int64)


def _inp_surface(r: _InpReader, card: _Card):
    name = card.params.get("NAME")
    if not isinstance(name, str) or not name:
        raise _inp_error(card.where, "*SURFACE without NAME=", "name the surface")
    stype = str(card.params.get("TYPE", "ELEMENT")).upper()
    if stype == "NODE":
        s = r.node_surfaces.setdefault(name.upper(), _InpSet(name, False))
        for where, tokens, text in _rows(card):
            s.chunks.append((_set_row(r, "NSET", s, tokens[:1], text, where, False), where))
        return
    if stype != "ELEMENT":
        return    # analytical and cutting surfaces are not sets of the mesh
    _, rows = r.surfaces.setdefault(name.upper(), (name, []))
    for where, tokens, text in _rows(card):
        if not tokens[0]:
            raise _inp_error(where, f"cannot read the surface row {text!r}",
                             "expected 'element set or element id, face (S1, S2, ...)'")
        rows.append((tokens[0], tokens[1] if len(tokens) > 1 and tokens[1] else None, where))


def _inp_scope(scope: str):
    def handler(r: _InpReader, card: _Card):
        if scope == "part":
            r.parts += 1
            if r.parts > 1:
                raise _inp_error(card.where, "a second *PART",
                                 "qsma reads one part per file: write each part to its own "
                                 "file or export a flat input file")
        if scope == "instance":
            r.instances += 1
            if r.instances > 1:
                raise _inp_error(card.where, "a second *INSTANCE",
                                 "qsma reads one instance per file: write each instance "
                                 "to its own file or export a flat input file")
            for where, tokens, text in _rows(card):
                try:
                    moved = any(_abaqus_float(t) != 0.0 for t in tokens)
                except ValueError:
                    moved = True
                if moved:
                    raise _inp_error(where, "the instance is translated or rotated",
                                     "export the mesh in its final position (no instance "
                                     "transformation)")
        r.scope = scope
    return handler


#: keyword -> handler; other keywords (materials, steps, loads, ...) are skipped
_INP_KEYWORDS = {
    "NODE": _inp_node, "ELEMENT": _inp_element, "NSET": _inp_set("NSET"),
    "ELSET": _inp_set("ELSET"), "SURFACE": _inp_surface,
    "PART": _inp_scope("part"), "END PART": _inp_scope("model"),
    "ASSEMBLY": _inp_scope("assembly"), "END ASSEMBLY": _inp_scope("model"),
    "INSTANCE": _inp_scope("instance"), "END INSTANCE": _inp_scope("assembly"),
}


def _read_abaqus(path: Path, cell_type: str | None) -> Mesh:
    reader = _InpReader(path)
    for card in _inp_cards(path):
        handler = _INP_KEYWORDS.get(card.keyword)
        if handler is not None:
            handler(reader, card)
    fm, vtype = reader.file_mesh(cell_type)
    return _to_mesh(fm, vtype)


# --------------------------------------------------------------------------------------
# writing files

def _check_names(mesh: Mesh, forbidden: str, fmt: str):
    for kind, sets in (("node", mesh.node_sets), ("facet", mesh.facet_sets),
                       ("cell", mesh.cell_sets)):
        for name in sets:
            if not isinstance(name, str) or not name or any(c in name for c in forbidden):
                raise InputError(f"{kind} set name {name!r} cannot be written to a {fmt} "
                                 f"file: use a non-empty name without "
                                 f"{' or '.join(repr(c) for c in forbidden)}")


def _boundary_of_sets(mesh: Mesh, boundary: _Boundary) -> dict:
    """name -> boundary facet indices of each facet set (InputError if not on the boundary)."""
    found = {}
    for name, rows in mesh.facet_sets.items():
        idx = boundary.find(rows)
        if (idx < 0).any():
            bad = rows[np.flatnonzero(idx < 0)[0]]
            raise InputError(f"facet set {name!r} holds a facet of nodes {bad.tolist()} that "
                             f"is not a boundary facet of the mesh; only boundary facets can "
                             f"be written")
        found[name] = _first_appearance(idx)
    return found


def _number(x: float) -> str:
    return repr(float(x))


def _gmsh_blocks(mesh: Mesh):
    """Physical groups ``(dim, tag, name)`` and element blocks ``(dim, entity, Gmsh type,
    rows, groups)``: one entity per run of cells with the same groups, one per distinct
    combination of facet sets, one point entity per node of a node set."""
    _check_names(mesh, '"\n\r', "Gmsh")
    d = mesh.dim
    groups = []

    def group(dim, name):
        groups.append((dim, len(groups) + 1, name))
        return len(groups)

    cell_groups = [[] for _ in range(len(mesh.cells))]
    for name, idx in mesh.cell_sets.items():
        tag = group(d, name)
        for i in idx.tolist():
            cell_groups[i].append(tag)
    boundary = _Boundary(mesh)
    facet_groups = {}
    for name, idx in _boundary_of_sets(mesh, boundary).items():
        tag = group(d - 1, name)
        for i in idx.tolist():
            facet_groups.setdefault(i, []).append(tag)
    node_groups = {}
    for name, idx in mesh.node_sets.items():
        tag = group(0, name)
        for i in idx.tolist():
            node_groups.setdefault(i, []).append(tag)
    runs = []                                   # [groups, first cell, end]
    for i, g in enumerate(map(tuple, cell_groups)):
        if runs and runs[-1][0] == g:
            runs[-1][2] = i + 1
        else:
            runs.append([g, i, i + 1])
    blocks = [(d, k, _GMSH_TYPE_NUMBER[mesh.cell_type], mesh.cells[a:b], g)
              for k, (g, a, b) in enumerate(runs, start=1)]
    by_groups = {}
    for i, g in facet_groups.items():
        by_groups.setdefault(tuple(g), []).append(i)
    blocks += [(d - 1, k, _GMSH_TYPE_NUMBER[mesh.facet_type], boundary.rows[members], g)
               for k, (g, members) in enumerate(by_groups.items(), start=1)]
    blocks += [(0, k, 15, np.array([[node]]), tuple(g))
               for k, (node, g) in enumerate(sorted(node_groups.items()), start=1)]
    return groups, blocks


def _physical_names(groups) -> list:
    return (["$PhysicalNames", str(len(groups))]
            + [f'{dim} {tag} "{name}"' for dim, tag, name in groups] + ["$EndPhysicalNames"])


def _xyz(mesh: Mesh) -> np.ndarray:
    return np.column_stack([mesh.points, np.zeros((mesh.n_nodes, 3 - mesh.dim))])


def _rows_text(first_label: int, rows: np.ndarray) -> list:
    labels = np.arange(first_label, first_label + len(rows))
    return [" ".join(map(str, r)) for r in np.column_stack([labels, rows + 1]).tolist()]


def _format_gmsh(mesh: Mesh, version: str) -> str:
    return (_format_gmsh41 if version == "4.1" else _format_gmsh22)(mesh)


def _format_gmsh41(mesh: Mesh) -> str:
    """Gmsh 4.1 ASCII; the entities carry the physical groups (see ``_gmsh_blocks``)."""
    groups, blocks = _gmsh_blocks(mesh)
    xyz, n = _xyz(mesh), mesh.n_nodes
    entities = [[] for _ in range(4)]
    for dim, entity, _, rows, g in blocks:
        p = xyz[rows.ravel()]
        where = p[0] if dim == 0 else np.concatenate([p.min(axis=0), p.max(axis=0)])
        bounded_by = "" if dim == 0 else " 0"
        entities[dim].append(f"{entity} {' '.join(map(_number, where))} "
                             f"{' '.join(map(str, [len(g), *g]))}{bounded_by}")
    n_elements = sum(len(rows) for *_, rows, _ in blocks)
    out = ["$MeshFormat", "4.1 0 8", "$EndMeshFormat", *_physical_names(groups),
           "$Entities", " ".join(str(len(e)) for e in entities), *sum(entities, []),
           "$EndEntities", "$Nodes", f"1 {n} 1 {n}", f"{mesh.dim} 1 0 {n}"]
    out += [str(i) for i in range(1, n + 1)]
    out += [" ".join(map(_number, p)) for p in xyz.tolist()]
    out += ["$EndNodes", "$Elements", f"{len(blocks)} {n_elements} 1 {n_elements}"]
    label = 1
    for dim, entity, number, rows, _ in blocks:
        out.append(f"{dim} {entity} {number} {len(rows)}")
        out += _rows_text(label, rows)
        label += len(rows)
    out.append("$EndElements")
    return "\n".join(out) + "\n"


def _format_gmsh22(mesh: Mesh) -> str:
    """Gmsh 2.2 ASCII: an element is written once per physical group it belongs to (as
    Gmsh does), elements without a group once with physical tag 0; the elementary tags
    are the entities of ``_gmsh_blocks``. The first copies come first, in cell order."""
    groups, blocks = _gmsh_blocks(mesh)
    first = [(number, g[0] if g else 0, entity, rows) for _, entity, number, rows, g in blocks]
    again = [(number, tag, entity, rows) for _, entity, number, rows, g in blocks
             for tag in g[1:]]
    out = ["$MeshFormat", "2.2 0 8", "$EndMeshFormat", *_physical_names(groups),
           "$Nodes", str(mesh.n_nodes)]
    out += [f"{i} {' '.join(map(_number, p))}" for i, p in enumerate(_xyz(mesh).tolist(), 1)]
    out += ["$EndNodes", "$Elements", str(sum(len(rows) for *_, rows in first + again))]
    label = 1
    for number, tag, entity, rows in first + again:
        out += [f"{label + k} {number} 2 {tag} {entity} {' '.join(map(str, r))}"
                for k, r in enumerate((rows + 1).tolist())]
        label += len(rows)
    out.append("$EndElements")
    return "\n".join(out) + "\n"


def _inp_name(name: str) -> str:
    return name if _PLAIN_NAME.fullmatch(name) else f'"{name}"'


def _id_lines(ids: np.ndarray) -> list:
    """Set data lines, 16 ids per line (the Abaqus limit)."""
    ids = (np.asarray(ids) + 1).tolist()
    return [", ".join(map(str, ids[k:k + 16])) for k in range(0, len(ids), 16)]


def _format_abaqus(mesh: Mesh, _version=None) -> str:
    """Abaqus/CalculiX input: *NODE, *ELEMENT, *NSET, *ELSET and one *SURFACE per facet
    set, whose faces are listed through internal element sets ``_<set>_S<k>``."""
    _check_names(mesh, '"\n\r,', "Abaqus .inp")
    for kind, sets in (("node", mesh.node_sets), ("cell", mesh.cell_sets),
                       ("facet", mesh.facet_sets)):
        upper = [name.upper() for name in sets]
        if len(set(upper)) < len(upper):
            raise InputError(f"{kind} set names {sorted(sets)} differ only in case; Abaqus "
                             f"names are case-insensitive: rename them")
    boundary = _Boundary(mesh)
    on_boundary = _boundary_of_sets(mesh, boundary)
    etype = _ABAQUS_WRITE_TYPE[mesh.cell_type]
    # local facet of CELL_FACETS -> Abaqus face number
    face_number = [1 + [sorted(f) for f in ABAQUS_FACES[mesh.cell_type]].index(sorted(local))
                   for local in CELL_FACETS[mesh.cell_type]]
    out = ["*HEADING", f"qsma mesh: {mesh.n_nodes} nodes, {len(mesh.cells)} {etype} elements",
           "** written by qsma.model.io.write_mesh; facet sets are *SURFACE definitions over",
           "** the internal element sets _<set>_S<face> (Abaqus face numbering)", "*NODE"]
    out += [", ".join([str(i)] + [_number(v) for v in p])
            for i, p in enumerate(mesh.points.tolist(), 1)]
    out.append(f"*ELEMENT, TYPE={etype}")
    out += [", ".join(map(str, r)) for r in
            np.column_stack([np.arange(1, len(mesh.cells) + 1), mesh.cells + 1]).tolist()]
    for name, idx in mesh.node_sets.items():
        out += [f"*NSET, NSET={_inp_name(name)}", *_id_lines(idx)]
    for name, idx in mesh.cell_sets.items():
        out += [f"*ELSET, ELSET={_inp_name(name)}", *_id_lines(idx)]
    taken = {name.upper() for name in mesh.cell_sets}
    for k, (name, idx) in enumerate(on_boundary.items()):
        faces = np.array(face_number)[boundary.local_face[idx]]
        surface = []
        for face in np.unique(faces).tolist():
            elset = f"_{name}_S{face}"
            if len(elset) > 80 or not _PLAIN_NAME.fullmatch(elset[1:]):
                elset = f"_SURFACE{k + 1}_S{face}"
            while elset.upper() in taken:                  # a cell set of that name
                elset = f"_{elset}"
            taken.add(elset.upper())
            out += [f"*ELSET, ELSET={elset}, INTERNAL",
                    *_id_lines(np.sort(boundary.cell[idx[faces == face]]))]
            surface.append(f"{elset}, S{face}")
        out += [f"*SURFACE, TYPE=ELEMENT, NAME={_inp_name(name)}", *surface]
    return "\n".join(out) + "\n"


#: file extension -> format; read_mesh and write_mesh dispatch through this registry
MESH_FORMATS = {
    ".msh": MeshFormat("Gmsh", _read_gmsh, _format_gmsh),
    ".inp": MeshFormat("Abaqus/CalculiX", _read_abaqus, _format_abaqus),
}
