"""Meshes and their files, below everything that computes on them.

- :mod:`.celltypes`: one record per cell type (nodes, facets, reference cell, higher-order
  nodes, scikit-fem element, Gmsh and Abaqus names);
- :mod:`.mesh`: :class:`Mesh` with named node, facet and cell sets, mixed cell blocks,
  the cached index of boundary facets;
- :mod:`.facets`: outward normals and tributary weights of boundary facets;
- :mod:`.validate`: inverted, degenerate, self-intersecting cells, coincident nodes;
- :mod:`.generate`: structured meshes on tensor grids;
- :mod:`.io`: mesh files, one package per format (Gmsh, Abaqus/CalculiX).
"""
from .celltypes import CELL_TYPES, TYPES, CellType, cell_type
from .facets import facet_node_weights, facet_normals
from .mesh import (MIXABLE, CellBlock, FacetIndex, Mesh, boundary_facets, facet_index,
                   mixed_mesh, unique_rows)
from .validate import validate_mesh

__all__ = ["CELL_TYPES", "TYPES", "CellType", "cell_type", "Mesh", "CellBlock",
           "FacetIndex", "MIXABLE", "boundary_facets", "facet_index", "mixed_mesh",
           "unique_rows", "facet_node_weights", "facet_normals", "validate_mesh",
           "read_mesh", "write_mesh"]


def __getattr__(name):
    """``read_mesh`` and ``write_mesh`` imported when first used: the readers and writers
    (Abaqus, Gmsh, meshio) cost 0.08 s of CPU to import, and a run of a model built in
    memory (``qsma run --example``) never reads a mesh file."""
    if name in ("read_mesh", "write_mesh"):
        from . import io
        return getattr(io, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
