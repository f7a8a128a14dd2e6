"""Abaqus / CalculiX ``.inp`` files written: nodes, elements, node and element sets,
and one ``*SURFACE`` per facet set (faces listed through internal element sets), in
fields CalculiX reads whole."""
from __future__ import annotations

import numpy as np

from ....errors import InputError
from ...celltypes import CELL_TYPES, abaqus_faces
from ...mesh import Mesh, facet_index
from ..common import _boundary_of_sets, _check_names
from .lexer import _PLAIN_NAME, _abaqus_cell_type, _is_continuum

#: Characters of a coordinate field that CalculiX reads: its *NODE reader takes the first
#: 20 characters of a field (Fortran ``f20.0``), so a longer field is cut short without a
#: message and a field of 22 characters or more stops it ("*ERROR reading *NODE").
CALCULIX_FIELD = 20
#: Entries per data line that CalculiX reads (its line splitter stops at 16): an element
#: row of more nodes continues on the next line after a trailing comma.
CALCULIX_ENTRIES = 16


def _inp_name(name: str) -> str:
    return name if _PLAIN_NAME.fullmatch(name) else f'"{name}"'


def _id_lines(ids: np.ndarray) -> list:
    """Set data lines, 16 ids per line (the Abaqus limit)."""
    ids = (np.asarray(ids) + 1).tolist()
    return [", ".join(map(str, ids[k:k + 16])) for k in range(0, len(ids), 16)]


def _abaqus_write_type(mesh: Mesh) -> str:
    """The element type written: ``mesh.element`` when it is an Abaqus continuum type of
    the mesh's cell type, else the plane-strain / full-integration default."""
    default = CELL_TYPES[mesh.cell_type].abaqus_write
    if default is None:
        raise InputError(f"{mesh.cell_type} cells cannot be written to an .inp file (Abaqus "
                         f"and CalculiX have no such continuum element we have checked); "
                         f"write a .msh file instead")
    if mesh.element is None:
        return default
    name = mesh.element.upper()
    if not (_is_continuum(name) and _abaqus_cell_type(name) == mesh.cell_type):
        raise InputError(f"mesh.element = {mesh.element!r} is not an Abaqus continuum "
                         f"element type of {mesh.cell_type} cells; set element=None (writes "
                         f"{default}) or a matching type such as {default}R")
    return name


def inp_number(x: float) -> str:
    """``x`` in at most :data:`CALCULIX_FIELD` characters: the shortest text that reads
    back as the same double where it fits, else the most significant digits that fit
    (13 or more: a relative change below 5e-14)."""
    text, digits = repr(float(x)), 17
    while len(text) > CALCULIX_FIELD:
        digits -= 1
        text = f"{float(x):.{digits}g}"
    return text


def _element_lines(ids: np.ndarray, cells: np.ndarray) -> list:
    """``id, node, node, ...`` rows, 1-based; a row of more than
    :data:`CALCULIX_ENTRIES` entries goes on over several lines, each but the last
    ending with a comma."""
    rows = np.column_stack([ids, cells + 1]).tolist()
    if len(rows[0]) <= CALCULIX_ENTRIES:
        return [", ".join(map(str, r)) for r in rows]
    return [", ".join(map(str, r[k:k + CALCULIX_ENTRIES]))
            + ("," if k + CALCULIX_ENTRIES < len(r) else "")
            for r in rows for k in range(0, len(r), CALCULIX_ENTRIES)]


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
    boundary = facet_index(mesh)
    on_boundary = _boundary_of_sets(mesh, boundary)
    etype = _abaqus_write_type(mesh)
    # local facet of the cell type's facets -> Abaqus face number
    face_number = [1 + [sorted(f) for f in abaqus_faces(mesh.cell_type)].index(sorted(local))
                   for local in CELL_TYPES[mesh.cell_type].facets]
    out = ["*HEADING", f"qsma mesh: {mesh.n_nodes} nodes, {len(mesh.cells)} {etype} elements",
           "** written by qsma.mesh.io.write_mesh; facet sets are *SURFACE definitions over",
           "** the internal element sets _<set>_S<face> (Abaqus face numbering)", "*NODE"]
    out += [", ".join([str(i)] + [inp_number(v) for v in p])
            for i, p in enumerate(mesh.points.tolist(), 1)]
    out.append(f"*ELEMENT, TYPE={etype}")
    out += _element_lines(np.arange(1, len(mesh.cells) + 1), mesh.cells)
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
