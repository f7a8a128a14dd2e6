"""Gmsh ``.msh`` files written, ASCII 4.1 or 2.2: one physical group per set."""
from __future__ import annotations

import re

import numpy as np

from ....errors import InputError
from ...celltypes import TYPES
from ...mesh import Mesh, facet_index
from ..common import _boundary_of_sets, _check_names, _number
from .types import _gmsh_to_meshio

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
    boundary = facet_index(mesh)
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
    order = _gmsh_to_meshio(mesh.cell_type)
    cells = mesh.cells if order is None else mesh.cells[:, np.argsort(order)]
    blocks = [(d, k, TYPES[mesh.cell_type].gmsh, cells[a:b], g)
              for k, (g, a, b) in enumerate(runs, start=1)]
    by_groups = {}
    for i, g in facet_groups.items():
        by_groups.setdefault(tuple(g), []).append(i)
    blocks += [(d - 1, k, TYPES[mesh.facet_type].gmsh, boundary.rows[members], g)
               for k, (g, members) in enumerate(by_groups.items(), start=1)]
    blocks += [(0, k, TYPES["vertex"].gmsh, np.array([[node]]), tuple(g))
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
    """File text of ``mesh``. A Gmsh file names no element formulation: what is read
    back is plane strain / 3D continuum with full integration, so a mesh whose
    ``element`` says otherwise (CPS4, C3D8I, ...) is refused rather than silently
    turned into another element."""
    if mesh.element is not None and not re.fullmatch(r"(CPE|C3D)\d+", mesh.element):
        raise InputError(f"mesh.element = {mesh.element!r} cannot be kept in a Gmsh file "
                         f"(Gmsh names no formulation: reading it back gives plane strain / "
                         f"full integration); write an .inp file instead")
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
