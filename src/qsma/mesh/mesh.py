"""Meshes with named node, facet and cell sets (dimension generic), and the index of
their boundary facets."""
from __future__ import annotations

import weakref
from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError
from .celltypes import CELL_TYPES, cell_type as _cell_type

@dataclass(frozen=True, eq=False)
class CellBlock:
    """Cells of one type (and one element formulation) in a mixed mesh.

    Attributes
    ----------
    cell_type : one of ``CELL_TYPES``
    cells : (n_cells, nodes_per_cell) int array, meshio node ordering
    element : element name given by the source file for these cells, or None
    """

    cell_type: str
    cells: np.ndarray
    element: str | None = None


#: facet type of the cells that may be mixed in one mesh -> message naming the mix
MIXABLE = {"line": "triangle + quad", "line3": "triangle6 + quad8 / quad9"}


@dataclass(frozen=True, eq=False)
class Mesh:
    """A finite element mesh with named sets: one cell type, or several (mixed).

    Parameters
    ----------
    points : (n_nodes, dim) float array
    cells : (n_cells, nodes_per_cell) int array, meshio node ordering
    cell_type : a key of ``CELL_TYPES`` (meshio names, :mod:`qsma.mesh.celltypes`)
    node_sets : name -> sorted unique node indices
    facet_sets : name -> (n_facets, nodes_per_facet) node indices of boundary facets
    cell_sets : name -> cell indices
    element : str or None
        element name given by the source file (e.g. Abaqus 'CPS4', 'C3D8I'); None when the file names no formulation (Gmsh)
    extra_blocks : tuple of :class:`CellBlock`
        Mixed meshes: the cells of other types, after ``cells`` (the first block).
        Cell indices (cell sets, facet owners) count ``cells`` first, then each extra
        block in order. Every block must have the facet type of the first: 2D
        ``triangle`` + ``quad`` (line facets) or ``triangle6`` + ``quad8`` / ``quad9``
        (line3 facets); a conforming mix of quadratic and linear cells, or of 3D cells
        (hexahedra with wedges or tetrahedra need wedge / pyramid cells) is refused.
        Use :attr:`cell_blocks` to visit every cell.
    """

    points: np.ndarray
    cells: np.ndarray
    cell_type: str
    node_sets: dict = field(default_factory=dict)
    facet_sets: dict = field(default_factory=dict)
    cell_sets: dict = field(default_factory=dict)
    element: str | None = None
    extra_blocks: tuple = ()

    def __post_init__(self):
        ct = _cell_type(self.cell_type)
        dim, nv = ct.dim, ct.n_nodes
        points = np.ascontiguousarray(self.points, dtype=float)
        cells = np.ascontiguousarray(self.cells, dtype=np.int64)
        if points.ndim != 2 or points.shape[1] != dim:
            raise InputError(f"points of a {self.cell_type} mesh must have shape "
                             f"(n, {dim}), got {points.shape}")
        if self.element is not None and (not isinstance(self.element, str)
                                         or not self.element.strip()):
            raise InputError(f"element must be a non-empty name such as 'C3D8I' or None, "
                             f"got {self.element!r}")
        if not np.all(np.isfinite(points)):
            raise InputError("mesh points contain NaN or Inf")
        if cells.ndim != 2 or cells.shape[1] != nv:
            raise InputError(f"{self.cell_type} cells must have shape (n, {nv}), "
                             f"got {cells.shape}")
        if cells.size and (cells.min() < 0 or cells.max() >= len(points)):
            raise InputError(f"cells refer to node indices outside 0..{len(points) - 1}")
        node_sets = {k: _index_array(v, len(points), f"node set {k!r}", unique=True)
                     for k, v in self.node_sets.items()}
        facet_sets = {}
        for k, v in self.facet_sets.items():
            f = np.asarray(v, dtype=np.int64).reshape(-1, ct.nodes_per_facet)
            _index_array(f.ravel(), len(points), f"facet set {k!r}")
            facet_sets[k] = f
        extra = tuple(_check_block(b, self.cell_type, len(points)) for b in self.extra_blocks)
        n_cells = len(cells) + sum(len(b.cells) for b in extra)
        cell_sets = {k: _index_array(v, n_cells, f"cell set {k!r}", unique=True)
                     for k, v in self.cell_sets.items()}
        for name, value in [("points", points), ("cells", cells), ("node_sets", node_sets),
                            ("facet_sets", facet_sets), ("cell_sets", cell_sets),
                            ("extra_blocks", extra)]:
            object.__setattr__(self, name, value)
        points.flags.writeable = False
        cells.flags.writeable = False

    @property
    def dim(self) -> int:
        return CELL_TYPES[self.cell_type].dim

    @property
    def is_mixed(self) -> bool:
        """True when the mesh has cells of several blocks (:attr:`extra_blocks`)."""
        return bool(self.extra_blocks)

    @property
    def cell_blocks(self) -> tuple:
        """Every cell block, the first (``cells``, ``cell_type``, ``element``) first."""
        return (CellBlock(self.cell_type, self.cells, self.element),) + self.extra_blocks

    @property
    def n_cells(self) -> int:
        return sum(len(b.cells) for b in self.cell_blocks)

    def block_meshes(self) -> tuple:
        """One single-type :class:`Mesh` per cell block, on the block's own nodes, and
        the mesh node of each of its nodes: ``((mesh, nodes), ...)``. A single-type
        mesh gives itself and ``None`` (all nodes, same numbering). Cached per mesh."""
        if not self.is_mixed:
            return ((self, None),)
        found = _BLOCK_CACHE.get(self)
        if found is None:
            found = tuple(_block_mesh(self.points, b) for b in self.cell_blocks)
            _BLOCK_CACHE[self] = found
        return found

    @property
    def facet_type(self) -> str:
        return CELL_TYPES[self.cell_type].facet_type

    @property
    def n_nodes(self) -> int:
        return len(self.points)

    def nodes(self, name: str) -> np.ndarray:
        """Node indices of a node set, or of the nodes of a facet set."""
        if name in self.node_sets:
            return self.node_sets[name]
        if name in self.facet_sets:
            return np.unique(self.facet_sets[name])
        raise InputError(f"no node or facet set named {name!r}; "
                         f"available: {self.set_names()}")

    def facets(self, name: str) -> np.ndarray:
        """Facets (node index rows) of a facet set."""
        if name not in self.facet_sets:
            raise InputError(f"no facet set named {name!r}; available facet sets: "
                             f"{sorted(self.facet_sets)}")
        return self.facet_sets[name]

    def set_names(self) -> list:
        return sorted(set(self.node_sets) | set(self.facet_sets))

    def boundary_facets_where(self, predicate) -> np.ndarray:
        """Boundary facets whose every node satisfies ``predicate(points) -> bool array``."""
        facets = boundary_facets(self)
        inside = predicate(self.points)
        return facets[np.all(inside[facets], axis=1)]

    def with_sets(self, node_sets=None, facet_sets=None, cell_sets=None) -> "Mesh":
        """A new mesh with sets added (existing names are replaced); same ``element``
        and cell blocks."""
        return Mesh(self.points, self.cells, self.cell_type,
                    {**self.node_sets, **(node_sets or {})},
                    {**self.facet_sets, **(facet_sets or {})},
                    {**self.cell_sets, **(cell_sets or {})}, self.element,
                    self.extra_blocks)


def mixed_mesh(points, blocks, node_sets=None, facet_sets=None, cell_sets=None) -> Mesh:
    """A mesh of several cell blocks: ``blocks`` a list of :class:`CellBlock` (or
    ``(cell_type, cells[, element])`` tuples); empty blocks are dropped. One block
    gives a plain single-type mesh."""
    blocks = [b if isinstance(b, CellBlock) else CellBlock(*b) for b in blocks]
    blocks = [b for b in blocks if len(b.cells)] or blocks[:1]
    if not blocks:
        raise InputError("a mesh needs at least one cell block")
    first = blocks[0]
    return Mesh(points, first.cells, first.cell_type, node_sets or {}, facet_sets or {},
                cell_sets or {}, first.element, tuple(blocks[1:]))


def _check_block(block, first_type, n_points) -> CellBlock:
    """A validated copy of an extra cell block of a mesh whose first block is
    ``first_type``."""
    if not isinstance(block, CellBlock):
        raise InputError(f"extra_blocks must hold CellBlock objects, got {block!r}")
    ct = block.cell_type
    ftype, first_ftype = _cell_type(ct).facet_type, CELL_TYPES[first_type].facet_type
    if ftype != first_ftype or first_ftype not in MIXABLE:
        raise InputError(
            f"{first_type} and {ct} cells cannot be mixed in one body: a mixed mesh must "
            f"share one facet type, i.e. 2D {MIXABLE['line']} (linear) or "
            f"{MIXABLE['line3']} (quadratic); 3D mixes (hexahedra with wedges or "
            f"tetrahedra) and linear with quadratic cells are not supported. Mesh the body "
            f"with one of these combinations or with a single cell type")
    if ct == first_type:
        raise InputError(f"two cell blocks of type {ct}: put them in one block")
    nv = CELL_TYPES[ct].n_nodes
    cells = np.ascontiguousarray(block.cells, dtype=np.int64)
    if cells.ndim != 2 or cells.shape[1] != nv:
        raise InputError(f"{ct} cells must have shape (n, {nv}), got {cells.shape}")
    if cells.size and (cells.min() < 0 or cells.max() >= n_points):
        raise InputError(f"cells refer to node indices outside 0..{n_points - 1}")
    if block.element is not None and (not isinstance(block.element, str)
                                      or not block.element.strip()):
        raise InputError(f"element must be a non-empty name such as 'CPE4I' or None, "
                         f"got {block.element!r}")
    cells.flags.writeable = False
    return CellBlock(ct, cells, block.element)


#: mixed mesh -> its block meshes; entries go with their mesh
_BLOCK_CACHE = weakref.WeakKeyDictionary()


def _block_mesh(points, block: CellBlock):
    """The single-type mesh of one block on its own nodes, and their mesh node numbers."""
    nodes, local = np.unique(block.cells, return_inverse=True)
    return (Mesh(points[nodes], local.reshape(block.cells.shape), block.cell_type,
                 element=block.element), nodes)


def _index_array(values, bound, what, unique=False):
    a = np.asarray(values, dtype=np.int64).ravel()
    if a.size and (a.min() < 0 or a.max() >= bound):
        raise InputError(f"{what} refers to indices outside 0..{bound - 1}")
    return np.unique(a) if unique else a


def boundary_facets(mesh: Mesh) -> np.ndarray:
    """All boundary facets (facets that belong to exactly one cell), outward oriented.

    A copy of ``facet_index(mesh).rows``: the local facets (``CellType.facets``) of every
    cell, local facet by local facet, kept where no other cell has the same nodes.
    """
    return facet_index(mesh).rows.copy()


@dataclass(frozen=True, eq=False)
class FacetIndex:
    """The boundary facets of a mesh, their owner cells, and a lookup by node set.

    Built once per mesh by :func:`facet_index` (cached); use it wherever a facet given
    by its nodes (in any order) must be found among the boundary facets.

    Attributes
    ----------
    rows : (n_boundary, nodes_per_facet) int array, read-only
        Node indices of each boundary facet in the outward orientation of
        ``CellType.facets`` (the rows of :func:`boundary_facets`, same order).
    cell : (n_boundary,) int array, read-only
        The one cell each boundary facet belongs to (counting every cell block).
    local_face : (n_boundary,) int array, read-only
        Position of the facet in the ``facets`` of its cell's type (mixed meshes:
        the type of the cell's block).
    """

    rows: np.ndarray
    cell: np.ndarray
    local_face: np.ndarray

    def find(self, rows) -> np.ndarray:
        """Row index in :attr:`rows` of each facet given by its nodes, -1 where none.

        Parameters
        ----------
        rows : (k, nodes_per_facet) int array-like
            Facets as node indices, in any node order or orientation.

        Returns
        -------
        (k,) int64 array
            ``i`` with ``sorted(rows[j]) == sorted(self.rows[i])``, or -1 when no boundary
            facet has these nodes (an internal facet, or no facet of the mesh at all).
        """
        nf = self.rows.shape[1]
        query = np.sort(np.asarray(rows, dtype=np.int64).reshape(-1, nf), axis=1)
        _, inverse, _ = unique_rows(np.concatenate([np.sort(self.rows, axis=1), query]))
        nb = len(self.rows)
        boundary_of_group = np.full(inverse.max(initial=-1) + 1, -1, dtype=np.int64)
        boundary_of_group[inverse[:nb]] = np.arange(nb)
        return boundary_of_group[inverse[nb:]]


#: mesh -> its FacetIndex; entries go with their mesh
_FACET_INDEX_CACHE = weakref.WeakKeyDictionary()


def facet_index(mesh: Mesh) -> FacetIndex:
    """The :class:`FacetIndex` of ``mesh``, built on first use and cached per mesh.

    A facet is a boundary facet when exactly one cell has a local facet (``CellType.facets``)
    with the same set of nodes. Meshes are immutable (frozen, read-only arrays), so the
    index stays valid for the life of the mesh.
    """
    found = _FACET_INDEX_CACHE.get(mesh)
    if found is None:
        found = _build_facet_index(mesh)
        _FACET_INDEX_CACHE[mesh] = found
    return found


def _build_facet_index(mesh: Mesh) -> FacetIndex:
    every, cell, face, start = [], [], [], 0
    for b in mesh.cell_blocks:          # mixed meshes: one facet type for every block
        n = len(b.cells)
        local = CELL_TYPES[b.cell_type].facets
        every += [b.cells[:, list(f)] for f in local]
        cell += [start + np.arange(n)] * len(local)
        face += [np.full(n, k, dtype=np.int64) for k in range(len(local))]
        start += n
    every, cell, face = np.concatenate(every), np.concatenate(cell), np.concatenate(face)
    _, inverse, counts = unique_rows(np.sort(every, axis=1))
    at = np.flatnonzero(counts[inverse] == 1)
    arrays = every[at], cell[at], face[at]
    for a in arrays:
        a.flags.writeable = False
    return FacetIndex(*arrays)


def unique_rows(rows: np.ndarray):
    """Distinct rows of an integer array: ``(first, inverse, counts)``.

    Like ``np.unique(rows, axis=0, return_index=True, return_inverse=True,
    return_counts=True)`` but by one lexicographic sort (faster): ``first[g]`` is the
    first row of group ``g`` (groups in lexicographic order), ``inverse[i]`` the group
    of row ``i``, ``counts[g]`` its size.
    """
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
