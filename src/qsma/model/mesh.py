"""Meshes with named node, facet and cell sets (dimension generic)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..errors import InputError

#: cell type -> (spatial dimension, nodes per cell, facet cell type); meshio names and
#: node orders (VTK): corner nodes first, then edge midside nodes, face and body centres
CELL_TYPES = {
    "triangle": (2, 3, "line"),
    "quad": (2, 4, "line"),
    "tetra": (3, 4, "triangle"),
    "hexahedron": (3, 8, "quad"),
    "triangle6": (2, 6, "line3"),
    "quad8": (2, 8, "line3"),
    "quad9": (2, 9, "line3"),
    "tetra10": (3, 10, "triangle6"),
    "hexahedron20": (3, 20, "quad8"),
    "hexahedron27": (3, 27, "quad9"),
}
#: facet cell type -> nodes per facet
FACET_TYPES = {"line": 2, "triangle": 3, "quad": 4,
               "line3": 3, "triangle6": 6, "quad8": 8, "quad9": 9}
#: facet cell type -> corner nodes per facet (the first nodes of a facet row)
FACET_CORNERS = {"line": 2, "triangle": 3, "quad": 4,
                 "line3": 2, "triangle6": 3, "quad8": 4, "quad9": 4}


@dataclass(frozen=True, eq=False)
class Mesh:
    """A single-cell-type finite element mesh with named sets.

    Parameters
    ----------
    points : (n_nodes, dim) float array
    cells : (n_cells, nodes_per_cell) int array, meshio node ordering
    cell_type : one of ``CELL_TYPES`` (meshio names)
    node_sets : name -> sorted unique node indices
    facet_sets : name -> (n_facets, nodes_per_facet) node indices of boundary facets
    cell_sets : name -> cell indices
    """

    points: np.ndarray
    cells: np.ndarray
    cell_type: str
    node_sets: dict = field(default_factory=dict)
    facet_sets: dict = field(default_factory=dict)
    cell_sets: dict = field(default_factory=dict)
    element: str | None = None  # element name given by the source file, e.g. Abaqus 'CPS4', 'C3D8I'; None when the file names no formulation (Gmsh)

    def __post_init__(self):
        if self.cell_type not in CELL_TYPES:
            raise InputError(f"unsupported cell type {self.cell_type!r}; "
                             f"expected one of {sorted(CELL_TYPES)}")
        dim, nv, ftype = CELL_TYPES[self.cell_type]
        points = np.ascontiguousarray(self.points, dtype=float)
        cells = np.ascontiguousarray(self.cells, dtype=np.int64)
        if points.ndim != 2 or points.shape[1] != dim:
            raise InputError(f"points of a {self.cell_type} mesh must have shape "
                             f"(n, {dim}), got {points.shape}")
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
            f = np.asarray(v, dtype=np.int64).reshape(-1, FACET_TYPES[ftype])
            _index_array(f.ravel(), len(points), f"facet set {k!r}")
            facet_sets[k] = f
        cell_sets = {k: _index_array(v, len(cells), f"cell set {k!r}", unique=True)
                     for k, v in self.cell_sets.items()}
        for name, value in [("points", points), ("cells", cells), ("node_sets", node_sets),
                            ("facet_sets", facet_sets), ("cell_sets", cell_sets)]:
            object.__setattr__(self, name, value)
        points.flags.writeable = False
        cells.flags.writeable = False

    @property
    def dim(self) -> int:
        return CELL_TYPES[self.cell_type][0]

    @property
    def facet_type(self) -> str:
        return CELL_TYPES[self.cell_type][2]

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
        """A new mesh with sets added (existing names are replaced)."""
        return Mesh(self.points, self.cells, self.cell_type,
                    {**self.node_sets, **(node_sets or {})},
                    {**self.facet_sets, **(facet_sets or {})},
                    {**self.cell_sets, **(cell_sets or {})}, element=self.element)


def _index_array(values, bound, what, unique=False):
    a = np.asarray(values, dtype=np.int64).ravel()
    if a.size and (a.min() < 0 or a.max() >= bound):
        raise InputError(f"{what} refers to indices outside 0..{bound - 1}")
    return np.unique(a) if unique else a


#: local node lists of the facets of each cell type (meshio / VTK node order), corner
#: nodes first (counter-clockwise seen from outside in 3D), then the facet's midside
#: nodes in the facet type's own order (line3: ends then middle; triangle6 / quad8:
#: midside of corner edge (0, 1), (1, 2), ...; quad9: then the face centre)
CELL_FACETS = {
    "triangle": [(0, 1), (1, 2), (2, 0)],
    "quad": [(0, 1), (1, 2), (2, 3), (3, 0)],
    "tetra": [(0, 2, 1), (0, 1, 3), (1, 2, 3), (0, 3, 2)],
    "hexahedron": [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4),
                   (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)],
    "triangle6": [(0, 1, 3), (1, 2, 4), (2, 0, 5)],
    "quad8": [(0, 1, 4), (1, 2, 5), (2, 3, 6), (3, 0, 7)],
    "quad9": [(0, 1, 4), (1, 2, 5), (2, 3, 6), (3, 0, 7)],
    # tetra10 edges: 4 (0,1), 5 (1,2), 6 (0,2), 7 (0,3), 8 (1,3), 9 (2,3)
    "tetra10": [(0, 2, 1, 6, 5, 4), (0, 1, 3, 4, 8, 7), (1, 2, 3, 5, 9, 8),
                (0, 3, 2, 7, 9, 6)],
    # hexahedron20 edges: 8 (0,1), 9 (1,2), 10 (2,3), 11 (3,0), 12 (4,5), 13 (5,6),
    # 14 (6,7), 15 (7,4), 16 (0,4), 17 (1,5), 18 (2,6), 19 (3,7)
    "hexahedron20": [(0, 3, 2, 1, 11, 10, 9, 8), (4, 5, 6, 7, 12, 13, 14, 15),
                     (0, 1, 5, 4, 8, 17, 12, 16), (1, 2, 6, 5, 9, 18, 13, 17),
                     (2, 3, 7, 6, 10, 19, 14, 18), (3, 0, 4, 7, 11, 16, 15, 19)],
    # hexahedron27 face centres: 20 (x-), 21 (x+), 22 (y-), 23 (y+), 24 (z-), 25 (z+)
    "hexahedron27": [(0, 3, 2, 1, 11, 10, 9, 8, 24), (4, 5, 6, 7, 12, 13, 14, 15, 25),
                     (0, 1, 5, 4, 8, 17, 12, 16, 22), (1, 2, 6, 5, 9, 18, 13, 17, 21),
                     (2, 3, 7, 6, 10, 19, 14, 18, 23), (3, 0, 4, 7, 11, 16, 15, 19, 20)],
}


def boundary_facets(mesh: Mesh) -> np.ndarray:
    """All boundary facets (facets that belong to exactly one cell), as node rows in
    the local order of ``CELL_FACETS`` (corner nodes first)."""
    local = CELL_FACETS[mesh.cell_type]
    allf = np.concatenate([mesh.cells[:, list(f)] for f in local])
    key = np.sort(allf, axis=1)
    _, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    return allf[counts[inv.ravel()] == 1]
