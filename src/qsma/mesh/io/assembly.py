"""Several bodies in one mesh file: each body is a cell set (Gmsh physical group of the
mesh dimension, Abaqus ``*ELSET`` of continuum elements).

:func:`read_assembly` reads the file once; :meth:`Assembly.body_mesh` makes the
:class:`~qsma.mesh.mesh.Mesh` of one cell set: its cells, the nodes they use
(numbered in file order), and every set of the file restricted to that body:

- node sets keep the body's nodes (a set with none of them is left out);
- facet sets keep the facets whose nodes all belong to the body; each must be a
  boundary facet *of the body* (a contact surface between two bodies of one file is
  interior to the whole mesh but on the boundary of each body), and a facet of the
  body's interior is refused as for a single-body file;
- cell sets keep the body's cells.

Two bodies that share nodes in the file (a conforming interface meshed in one go)
get their own copies of those nodes, so the interface is node-to-node; bodies meshed
apart get a mortar interface (``Interface(coupling="auto")``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ...errors import InputError, MeshFileError
from ..celltypes import CELL_TYPES
from ..mesh import MIXABLE, Mesh, boundary_facets
from .abaqus.reader import _abaqus_file_mesh
from .common import _FileMesh, _to_mesh
from .gmsh.reader import _gmsh_file_mesh


@dataclass(frozen=True, eq=False)
class Assembly:
    """What one mesh file holds, from which bodies are taken by cell set.

    Attributes
    ----------
    source : the file
    file_mesh : the reader's raw content (blocks, sets)
    cell_types : the cell types of the file's cells (several: a mixed mesh)
    cell_sets : names of the cell sets that can be bodies
    """

    source: str
    file_mesh: _FileMesh
    cell_types: tuple

    @property
    def cell_sets(self) -> list:
        return sorted(name for name in self.file_mesh.element_sets
                      if self._volume_members(name).size)

    def _volume_members(self, name) -> np.ndarray:
        """Global element indices of the cells (continuum elements of the cell type) of
        element set ``name``."""
        fm = self.file_mesh
        members = np.unique(np.concatenate(fm.element_sets[name])) \
            if fm.element_sets.get(name) else np.zeros(0, np.int64)
        is_cell = np.concatenate([np.full(len(conn), t in self.cell_types and cell)
                                  for t, _, conn, cell in fm.blocks])
        return members[is_cell[members]]

    def body_mesh(self, cells: str) -> Mesh:
        """The mesh of the body made of cell set ``cells`` (module docstring)."""
        fm = self.file_mesh
        if cells not in fm.element_sets or not self._volume_members(cells).size:
            raise InputError(f"{self.source}: no cell set named {cells!r} (a Gmsh physical "
                             f"group of the mesh dimension or an Abaqus *ELSET of "
                             f"{' or '.join(self.cell_types)} elements); cell sets of the file: "
                             f"{self.cell_sets}")
        return self._mesh_of(self._volume_members(cells), f"cell set {cells!r}")

    def _mesh_of(self, members, what) -> Mesh:
        fm = self.file_mesh
        keep_cells = np.zeros(sum(len(c) for _, _, c, _ in fm.blocks), dtype=bool)
        keep_cells[members] = True
        body = _restrict(fm, keep_cells, self.cell_types)
        held = tuple(t for t in self.cell_types      # the types this body holds
                     if any(bt == t and cell and len(conn)
                            for bt, _, conn, cell in body.blocks))
        if len(held) > 1 and not _mixable(held):
            raise MeshFileError(self._unmixable(members, held, what))
        try:
            mesh = _to_mesh(body, held)
        except MeshFileError as exc:
            raise MeshFileError(f"{exc} (body: {what})") from exc
        return _with_node_surfaces(mesh, fm.node_surfaces)

    def _unmixable(self, members, held, what) -> str:
        """The refusal of a body whose cells are of types one mesh cannot mix: each type
        with its element name and the element sets of the file that hold such cells."""
        fm = self.file_mesh
        sizes = [len(conn) for _, _, conn, _ in fm.blocks]
        block_type = np.repeat([t for t, *_ in fm.blocks], sizes)
        parts = []
        for t in held:
            mine = members[block_type[members] == t]
            sets = [name for name, p in fm.element_sets.items()
                    if np.isin(np.concatenate(p), mine).any()]
            element = fm.block_elements.get(t) or t
            parts.append(f"{len(mine)} {element} ({t}) cell(s)"
                         + (f" in element set(s) {', '.join(sets[:4])}" if sets else ""))
        return (f"{self.source}: the body made of {what} holds " + " and ".join(parts)
                + f", a mix of cell types one body cannot hold (a body's cells must share "
                f"one facet type: 2D {MIXABLE['line']} or {MIXABLE['line3']}). Fix: mesh "
                f"the body with one cell type (e.g. all {held[0]}), or make each cell type "
                f"a body of its own, meshed apart and joined by an interface (a *CONTACT "
                f"PAIR in a deck, [[interfaces]] in TOML); bodies of different cell types "
                f"in one file are read")

    def components(self) -> list:
        """Global element indices of the cells of each connected part of the mesh (cells
        joined through shared nodes), ordered by their first cell: the bodies of a file
        that names none (a CalculiX deck)."""
        from scipy.sparse import coo_matrix
        from scipy.sparse.csgraph import connected_components
        fm = self.file_mesh
        offsets = np.concatenate([[0], np.cumsum([len(c) for _, _, c, _ in fm.blocks])])
        cells = [(offsets[b] + np.arange(len(conn)), conn) for b, (t, _, conn, cell)
                 in enumerate(fm.blocks) if t in self.cell_types and cell]
        index = np.concatenate([i for i, _ in cells])
        n_cells, n_nodes = len(index), len(fm.points)
        # cell -> node edges, block by block (blocks of several types differ in width)
        rows = np.concatenate([np.repeat(np.arange(len(c)), c.shape[1]) + start
                               for (_, c), start in zip(cells, np.cumsum(
                                   [0] + [len(c) for _, c in cells[:-1]]))])
        cols = np.concatenate([c.ravel() for _, c in cells])
        graph = coo_matrix((np.ones(len(rows)), (rows, n_cells + cols)),
                           shape=(n_cells + n_nodes,) * 2)
        _, label = connected_components(graph, directed=False)
        cell_label = label[:n_cells]
        order = [lab for lab in _first_appearance_labels(cell_label)]
        return [index[cell_label == lab] for lab in order]

    def component_meshes(self) -> list:
        """The mesh of each of :meth:`components` (named ``body1``, ``body2``, ...)."""
        return [self._mesh_of(c, f"connected part {k + 1}")
                for k, c in enumerate(self.components())]

    @property
    def contact_pairs(self) -> list:
        """The ``*CONTACT PAIR`` rows of the file (slave, master, mu, kind, where)."""
        return list(self.file_mesh.contact_pairs)


def read_assembly(path, *, cell_type: str | None = None) -> Assembly:
    """Read a Gmsh ``.msh`` or Abaqus ``.inp`` file holding several bodies.

    Parameters
    ----------
    path : str or os.PathLike
    cell_type : str, optional
        The expected cell type (as :func:`qsma.mesh.io.read_mesh`).

    Returns
    -------
    Assembly
        ``assembly.body_mesh("plate_top")`` is the mesh of one body.
    """
    path = Path(path)
    if cell_type is not None and cell_type not in CELL_TYPES:
        raise InputError(f"cell_type must be one of {sorted(CELL_TYPES)} or None, "
                         f"got {cell_type!r}")
    readers = {".msh": lambda p, c: _gmsh_file_mesh(p, c, per_body=True),
               ".inp": lambda p, c: _abaqus_file_mesh(p, c, assembly=True)}
    read = readers.get(path.suffix.lower())
    if read is None:
        raise MeshFileError(f"{path}: unknown mesh file extension {path.suffix!r}; use .msh "
                            f"(Gmsh) or .inp (Abaqus/CalculiX)")
    fm, vtypes = read(path, cell_type)
    return Assembly(str(path), fm, tuple(vtypes))


def _restrict(fm: _FileMesh, keep_cells: np.ndarray, vtypes: tuple) -> _FileMesh:
    """``fm`` with only the cells in mask ``keep_cells`` (global element indices), the
    nodes they use, and the lower-dimensional elements and sets on those nodes."""
    used = np.zeros(len(fm.points), dtype=bool)
    offsets = np.concatenate([[0], np.cumsum([len(c) for _, _, c, _ in fm.blocks])])
    for b, (t, _, conn, cell) in enumerate(fm.blocks):
        mine = keep_cells[offsets[b]:offsets[b + 1]]
        used[conn[mine].ravel()] = True
    new_node = np.full(len(fm.points), -1, dtype=np.int64)
    new_node[used] = np.arange(int(used.sum()))
    keep_el = np.zeros(offsets[-1], dtype=bool)
    blocks, ids = [], []
    for b, (t, d, conn, cell) in enumerate(fm.blocks):
        if t in vtypes and cell:
            mine = keep_cells[offsets[b]:offsets[b + 1]]
        else:          # facet, line and point elements on the body's nodes only
            mine = np.all(used[conn], axis=1) if len(conn) else np.zeros(0, bool)
        keep_el[offsets[b]:offsets[b + 1]] = mine
        blocks.append((t, d, new_node[conn[mine]], cell))
        if fm.element_ids is not None:
            ids.append(np.asarray(fm.element_ids[b])[mine])
    new_el = np.full(offsets[-1], -1, dtype=np.int64)
    new_el[keep_el] = np.arange(int(keep_el.sum()))

    def elements(parts):
        idx = new_el[np.concatenate(parts)] if parts else np.zeros(0, np.int64)
        return [idx[idx >= 0]]

    def nodes(parts):
        idx = new_node[np.concatenate(parts)] if parts else np.zeros(0, np.int64)
        return [idx[idx >= 0]]

    def facets(parts):      # part by part: facets of several types differ in width
        kept = [new_node[rows[np.all(used[rows], axis=1)]] for rows in parts if len(rows)]
        return [rows for rows in kept if len(rows)] or [np.zeros((0, 1), np.int64)]

    element_sets = {k: v for k, v in ((k, elements(p)) for k, p in
                                      fm.element_sets.items()) if v[0].size}
    node_sets = {k: v for k, v in ((k, nodes(p)) for k, p in fm.node_sets.items())
                 if v[0].size}
    facet_rows = {k: v for k, v in ((k, facets(p)) for k, p in fm.facet_rows.items())
                  if sum(len(rows) for rows in v)}
    free_faces = {k: v for k, v in ((k, elements(p)) for k, p in fm.free_faces.items())
                  if v[0].size}
    return replace(fm, points=fm.points[used], labels=np.asarray(fm.labels)[used],
                   blocks=blocks, element_sets=element_sets, node_sets=node_sets,
                   facet_rows=facet_rows, free_faces=free_faces,
                   empty_sets=dict(fm.empty_sets),
                   element_ids=ids if fm.element_ids is not None else None)


def _mixable(types) -> bool:
    """Whether cells of ``types`` can be one body (one mesh of several blocks)."""
    facet_types = {CELL_TYPES[t].facet_type for t in types}
    return len(facet_types) == 1 and facet_types <= set(MIXABLE)


def _first_appearance_labels(labels):
    _, first = np.unique(labels, return_index=True)
    return labels[np.sort(first)]


def _with_node_surfaces(mesh: Mesh, names) -> Mesh:
    """A node-based surface (``*SURFACE, TYPE=NODE``) also becomes the facet set of the
    boundary facets whose nodes all belong to it, so it can be one side of an interface."""
    extra = {}
    for name in names:
        if name in mesh.node_sets and name not in mesh.facet_sets:
            inside = np.zeros(mesh.n_nodes, dtype=bool)
            inside[mesh.node_sets[name]] = True
            facets = boundary_facets(mesh)
            facets = facets[np.all(inside[facets], axis=1)]
            if len(facets):
                extra[name] = facets
    return mesh.with_sets(facet_sets=extra) if extra else mesh
