"""Gmsh ``.msh`` files: :mod:`.reader` (4.1 and 4.0 of our own, 2.2 through meshio),
:mod:`.writer` (ASCII 4.1 and 2.2), :mod:`.types` (element types and node orders)."""
from .reader import _gmsh_file_mesh, _read_gmsh
from .types import GMSH_VERSIONS
from .writer import _format_gmsh

__all__ = ["GMSH_VERSIONS"]
