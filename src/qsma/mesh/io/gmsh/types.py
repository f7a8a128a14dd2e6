"""Gmsh's element types and node order against qsma's, and the file versions written."""
from __future__ import annotations

import numpy as np

from ...celltypes import TYPES

#: Gmsh element types of no qsma cell type (wedges, pyramids): known here so that files
#: holding them are parsed and the message refusing them names them
_GMSH_OTHER = {6: ("wedge", 6, 3), 7: ("pyramid", 5, 3), 13: ("wedge18", 18, 3),
               14: ("pyramid14", 14, 3), 18: ("wedge15", 15, 3), 19: ("pyramid13", 13, 3)}
#: Gmsh element type number -> (meshio name, nodes per element, topological dimension)
_GMSH_TYPES = {**{t.gmsh: (t.name, t.n_nodes, t.dim) for t in TYPES.values()},
               **_GMSH_OTHER}
_GMSH_DIM = {name: dim for name, _, dim in _GMSH_TYPES.values()}


def _gmsh_to_meshio(cell_type: str):
    """Column order taking Gmsh rows of ``cell_type`` to meshio order (None: the same),
    derived by matching the corner groups of each node in both orders."""
    t = TYPES.get(cell_type)
    if t is None or t.gmsh_higher_nodes is None:
        return None
    nc = t.corners
    gmsh = [frozenset(g) for g in t.gmsh_higher_nodes]
    return np.array(list(range(nc)) + [nc + gmsh.index(frozenset(g)) for g in t.higher_nodes])

#: Gmsh file versions write_mesh can produce
GMSH_VERSIONS = ("4.1", "2.2")
