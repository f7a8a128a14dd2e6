"""Mesh files with named sets: Gmsh ``.msh`` and Abaqus/CalculiX ``.inp``.

:func:`read_mesh` and :func:`write_mesh` choose the format from the file
extension through the registry :data:`MESH_FORMATS`. Both formats map onto a
:class:`~qsma.mesh.mesh.Mesh` the same way:

==============  =======================================  ==========================================
Mesh            Gmsh (physical groups)                    Abaqus / CalculiX
==============  =======================================  ==========================================
``cell_sets``   groups of the mesh dimension              ``*ELSET`` of volume elements
``facet_sets``  groups of dimension - 1 (facet elements)  ``*SURFACE, TYPE=ELEMENT`` (faces S1..S6),
                                                          ``*ELSET`` of surface/line elements
``node_sets``   groups of dimension 0 (point elements)    ``*NSET``
==============  =======================================  ==========================================

Facets read from a file are matched to the boundary facets of the volume mesh
and returned in the orientation of :func:`~qsma.mesh.mesh.boundary_facets`
(outward), whatever their node order in the file. Every mesh read is checked by
:func:`~qsma.mesh.validate.validate_mesh` (cells, duplicate and unused nodes), after
the reader has checked that each section holds exactly what its counts declare.
``docs/mesh-io.md`` lists the conventions, the face numbering and the known limits.

One package per format: :mod:`.gmsh`, :mod:`.abaqus`; :mod:`.common` turns what a
reader found into a :class:`~qsma.mesh.mesh.Mesh`; :mod:`.assembly` takes several bodies
from one file.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from ...errors import InputError, MeshFileError
from ..celltypes import CELL_TYPES
from ..mesh import Mesh
from .abaqus import ABAQUS_ELEMENT_TYPES, _format_abaqus, _read_abaqus
from .assembly import Assembly, read_assembly
from .common import _write_atomically
from .gmsh import GMSH_VERSIONS, _format_gmsh, _read_gmsh

__all__ = ["read_mesh", "read_assembly", "Assembly", "write_mesh", "MESH_FORMATS",
           "ABAQUS_ELEMENT_TYPES", "GMSH_VERSIONS"]


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
        ``element`` is the element type the file names (Abaqus, upper case), else
        None.

    Raises
    ------
    MeshFileError
        The file is missing, unreadable, truncated or malformed (a section holding
        more or less than its counts declare, an id defined twice), holds mixed or
        unsupported cell types, a set that cannot be resolved, or a damaged mesh
        (an inverted, self-intersecting or degenerate element, two unjoined nodes at
        one point, a node no element uses). The message names the file, the line or
        the element or node id where known, and what to fix.
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
    if mesh.is_mixed:
        raise InputError(f"cannot write {path}: writing mixed meshes ("
                         f"{' + '.join(b.cell_type for b in mesh.cell_blocks)}) is not "
                         f"implemented (reading them is); write each cell type to its own "
                         f"file or use meshio")
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


MESH_FORMATS = {
    ".msh": MeshFormat("Gmsh", _read_gmsh, _format_gmsh),
    ".inp": MeshFormat("Abaqus/CalculiX", _read_abaqus, _format_abaqus),
}
