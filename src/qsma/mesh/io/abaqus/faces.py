"""The Abaqus face numbering on a mesh: the facets that are face ``S<k>`` of the cells
of a cell set, what an Abaqus ``*DLOAD`` row loads."""
from __future__ import annotations

import numpy as np

from ....errors import InputError
from ...celltypes import abaqus_faces
from ...mesh import Mesh, facet_index


def element_face_facets(mesh: Mesh, cell_set: str, face: int) -> np.ndarray:
    """The facets (outward node rows) that are face ``S<face>`` (Abaqus numbering,
    :func:`~qsma.mesh.celltypes.abaqus_faces`) of the cells of ``cell_set``: what an
    Abaqus ``*DLOAD`` row ``cell_set, P<face>, p`` loads. Every such face must be on the
    boundary."""
    if mesh.is_mixed:
        raise InputError(f"faces of cell set {cell_set!r}: a mesh of several cell types; "
                         f"name the loaded faces as a *SURFACE instead")
    faces = abaqus_faces(mesh.cell_type)
    if cell_set not in mesh.cell_sets:
        raise InputError(f"no cell set named {cell_set!r} (an *ELSET of the cells); cell "
                         f"sets: {sorted(mesh.cell_sets)}")
    if not (isinstance(face, int) and 1 <= face <= len(faces)):
        raise InputError(f"face {face!r} of cell set {cell_set!r}: {mesh.cell_type} cells "
                         f"have faces 1..{len(faces)} (Abaqus S1..S{len(faces)})")
    rows = mesh.cells[mesh.cell_sets[cell_set]][:, list(faces[face - 1])]
    index = facet_index(mesh)
    found = index.find(rows)
    if (found < 0).any():
        raise InputError(f"face S{face} of {int((found < 0).sum())} cell(s) of {cell_set!r} "
                         f"is not on the boundary of the body (a pressure acts on its "
                         f"surface): check the face number")
    return index.rows[np.unique(found)]
