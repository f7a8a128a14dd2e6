"""What the readers share: from what a mesh file holds to a :class:`Mesh`.

A reader fills a :class:`_FileMesh` (points, element blocks of every type, named
element, node and facet sets); :func:`_to_mesh` picks the cells (the elements of the
highest dimension), turns sets of lower-dimensional elements into facet and node sets,
and matches facets to the boundary facets of the cells. Also here: reading bytes with
messages that name the file, file ids to indices, and the atomic write of
:func:`~qsma.mesh.io.write_mesh`.
"""
from __future__ import annotations

import os
import stat
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ...errors import InputError, MeshFileError
from ..validate import validate_mesh
from ..._infra.files import atomic_write
from ..celltypes import CELL_TYPES, TYPES
from ..mesh import (MIXABLE, CellBlock, FacetIndex, Mesh, facet_index, mixed_mesh,
                    unique_rows)

_MAX_ID = 2**62

def _write_atomically(path: Path, text: str) -> None:
    """Write ``text`` atomically (:func:`qsma._infra.files.atomic_write`), an unwritable
    folder reported as a :class:`MeshFileError`."""
    try:
        atomic_write(path, text)
    except OSError as exc:
        raise MeshFileError(f"cannot write {path}: {exc.strerror}; check that the folder "
                            f"{path.parent} exists and is writable") from exc


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
    element: str | None = None                         # formulation named by the file
    block_elements: dict = field(default_factory=dict)  # mixed: cell type -> element name
    element_ids: list | None = None    # file ids of the rows of each block (None: unknown)
    contact_pairs: list = field(default_factory=list)  # _ContactPair, in file order
    node_surfaces: set = field(default_factory=set)    # names of node-based surfaces
    boundaries: list = field(default_factory=list)     # (node set name, first, last dof)
    #: facet sets that cut through a body (a pretension section's internal faces), each
    #: face in the orientation of the cell that owns it; not matched to the boundary
    cut_sets: set = field(default_factory=set)


@dataclass(frozen=True)
class _ContactPair:
    """A ``*CONTACT PAIR`` row: surface names, the interaction's friction coefficient
    (None if it defines none) and where it was read."""

    slave: str
    master: str
    mu: float | None
    kind: str
    where: tuple


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


def _cell_type_of(source: str, blocks: list, requested: str | None, *,
                  per_body: bool = False) -> tuple:
    """The cell types of a file: the types of the highest-dimensional elements that may
    be cells, in the order of their first block. Several types (a mixed mesh) must share
    their facet type (:data:`qsma.mesh.mesh.MIXABLE`), unless the file is read as an
    assembly (``per_body``): then each body is one mesh of its own, and the rule holds
    for each body when its mesh is made (a hexahedral body beside a tetrahedral one, or
    a quadratic beside a linear one, is a model qsma computes)."""
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
    top = list(dict.fromkeys(t for t, d in types.items() if d == dim))
    for vtype in top:
        if vtype not in CELL_TYPES:
            raise MeshFileError(f"{source}: {vtype} cells are not supported (yet): qsma "
                                f"reads meshes of {', '.join(sorted(CELL_TYPES))}; convert "
                                f"the mesh to them (e.g. Gmsh: Mesh.ElementOrder = 1, "
                                f"Mesh.RecombineAll = 1 for hexahedra)")
    facet_types = {CELL_TYPES[t].facet_type for t in top}
    if len(top) > 1 and not per_body and (len(facet_types) > 1
                                          or not facet_types <= set(MIXABLE)):
        raise MeshFileError(f"{source}: the file holds {dim}D cells of types "
                            f"{', '.join(top)}, a mix qsma does not support; mixed meshes "
                            f"may be 2D {MIXABLE['line']} or {MIXABLE['line3']} (one facet "
                            f"type). Mesh with a single cell type (e.g. all {top[0]}) or "
                            f"one of these mixes")
    other = sorted(t for t in types if t not in top and not _set_element(t))
    if other:
        raise MeshFileError(f"{source}: {', '.join(other)} elements are not supported beside "
                            f"the {' and '.join(top)} cells; remove them or use linear "
                            f"elements")
    if requested is not None and [requested] != top:
        raise MeshFileError(f"{source}: the cells are {' and '.join(top)}, but "
                            f"cell_type={requested!r} was requested")
    return tuple(top)


def _set_element(name: str) -> bool:
    """Whether elements of type ``name`` can only carry sets here: vertices, lines and
    surface elements (they are cells only of a mesh of their own dimension)."""
    return name in TYPES and TYPES[name].dim <= 2


def _first_appearance(values: np.ndarray) -> np.ndarray:
    _, first = np.unique(values, return_index=True)
    return values[np.sort(first)]


def _plane_points(source: str, points: np.ndarray, vtype: str) -> np.ndarray:
    if CELL_TYPES[vtype].dim == 3:
        return points
    scale = max(1.0, float(np.abs(points[:, :2]).max(initial=0.0)))
    z = np.abs(points[:, 2]).max(initial=0.0)
    if z > 1e-12 * scale:
        raise MeshFileError(f"{source}: the {vtype} cells are 2D but nodes have non-zero z "
                            f"(largest |z| = {z:g}); qsma reads 2D meshes in the plane z = 0")
    return np.ascontiguousarray(points[:, :2])


def _to_mesh(fm: _FileMesh, vtypes: tuple) -> Mesh:
    """Build the Mesh: cells of the types ``vtypes`` (several: a mixed mesh, one cell
    block per type), sets split by element dimension, facets matched to boundary
    facets."""
    src = fm.source
    dim = CELL_TYPES[vtypes[0]].dim
    elements = _Elements(fm.blocks)
    element_cell = np.full(elements.offsets[-1], -1, dtype=np.int64)
    cell_blocks, ids, start = [], [], 0
    for vtype in vtypes:
        volume = [b for b, (t, _, _, cell) in enumerate(fm.blocks) if t == vtype and cell]
        rows = np.concatenate([fm.blocks[b][2] for b in volume])
        where = np.concatenate([np.arange(*elements.offsets[b:b + 2]) for b in volume])
        # one cell per set of nodes: Gmsh 2.2 repeats an element once per physical group
        first, inverse, _ = unique_rows(np.sort(rows, axis=1))
        rank = np.empty(len(first), dtype=np.int64)
        rank[np.argsort(first)] = np.arange(len(first))
        element_cell[where] = start + rank[inverse]
        start += len(first)
        name = fm.block_elements.get(vtype, fm.element)
        cell_blocks.append(CellBlock(vtype, rows[np.sort(first)], name))
        if fm.element_ids is not None:
            ids.append(np.concatenate([fm.element_ids[b] for b in volume])[np.sort(first)])
    vtype = " and ".join(vtypes)                   # for the messages
    points = _plane_points(src, fm.points, vtypes[0])
    try:
        bare = mixed_mesh(points, [CellBlock(b.cell_type, b.cells) for b in cell_blocks])
    except InputError as exc:
        raise MeshFileError(f"{src}: {exc}") from exc
    boundary = facet_index(bare)

    cell_sets: dict = {}
    node_sets = {k: list(v) for k, v in fm.node_sets.items()}
    facet_rows = {k: list(v) for k, v in fm.facet_rows.items()}
    for name, parts in fm.element_sets.items():
        for b, mine in elements.by_block(np.unique(_joined(parts, (0,)))):
            etype, edim, conn, cell = fm.blocks[b]
            if etype in vtypes and cell:
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

    nf = TYPES[bare.facet_type].n_nodes
    facet_sets = {name: _joined(parts, (0, nf)) if name in fm.cut_sets else
                  _match_facets(src, name, _joined(parts, (0, nf)), boundary, fm.labels, bare)
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
        mesh = mixed_mesh(points, cell_blocks, node_sets, facet_sets, cell_sets)
    except InputError as exc:
        raise MeshFileError(f"{src}: {exc}") from exc
    if fm.element_ids is not None:
        cell_ids = np.concatenate(ids)
    else:       # the file's element numbers are not known: count the cells from 1
        cell_ids = np.arange(1, mesh.n_cells + 1)
    validate_mesh(mesh, source=src, node_ids=fm.labels, cell_ids=cell_ids)
    return mesh


def _joined(parts: list, empty_shape: tuple) -> np.ndarray:
    return np.concatenate(parts) if parts else np.zeros(empty_shape, dtype=np.int64)


def _match_facets(src, name, rows, boundary: FacetIndex, labels, mesh: Mesh) -> np.ndarray:
    """The boundary facets (outward orientation) of the facet rows of set ``name``."""
    if len(rows) == 0:
        return np.zeros((0, CELL_TYPES[mesh.cell_type].nodes_per_facet), dtype=np.int64)
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
    return read_regular(path, "a mesh file", MeshFileError)


def read_regular(path, what: str, error=InputError) -> bytes:
    """The bytes of the input file ``path``; ``error`` (naming ``what`` the file should
    be) for a missing or unreadable path and for anything but a regular file. A FIFO,
    a socket or a device is refused, not read: a read from a FIFO that no program
    writes waits forever. The file is opened without blocking and checked on the
    opened descriptor, so it cannot be swapped for a FIFO in between."""
    path = Path(path)
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    except FileNotFoundError:
        raise error(f"{path}: no such file; check the path (relative paths start in "
                    f"{os.getcwd()})") from None
    except IsADirectoryError:
        raise error(f"{path}: is a folder, not {what}") from None
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror})") from exc
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise error(f"{path}: is a folder, not {what}")
        if not stat.S_ISREG(mode):
            raise error(f"{path}: is not a regular file (a FIFO, socket or device, whose "
                        f"read could wait forever); give {what}")
        with os.fdopen(fd, "rb") as f:
            fd = None
            return f.read()
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror})") from exc
    finally:
        if fd is not None:
            os.close(fd)


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


def _boundary_of_sets(mesh: Mesh, boundary: FacetIndex) -> dict:
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
