"""Abaqus / CalculiX ``.inp`` files: our own reader (nodes, elements, ``*NSET``,
``*ELSET``, ``*SURFACE``, ``*INCLUDE``, one part and one instance, the contact pairs,
supports and loads a deck names).

Why our own reader (``docs/mesh-io.md``): meshio 5.3.5 drops ``*SURFACE`` definitions
(the facet sets a contact interface is made of), does not know the plane-strain CPE
types, and mishandles ``NSET=`` on ``*NODE`` and several ``*NODE`` blocks (meshio
issues #1527, #1528). Do not replace it by ``meshio.read``.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ....errors import MeshFileError
from ...celltypes import CELL_TYPES, TYPES, outward_abaqus_faces
from ...mesh import Mesh
from ..common import (_MAX_ID, _cell_type_of, _ContactPair, _Elements, _FileMesh, _IdLookup,
                      _to_mesh)
from .references import load_id_sets, name_in_row, named_internal_sets
from .instances import check_instances_closed, flatten_instances, needs_flattening, placement
from .lexer import (ABAQUS_ELEMENT_TYPES, CONNECTOR_TYPES, _Card, _abaqus_cell_type,
                    _abaqus_float, _connector_ids, _inp_cards, _inp_error, _integer,
                    _is_continuum, _rows)

#: element types refused with a reason of their own
_ABAQUS_REFUSED = {
    "C3D27": "its optional face and centre nodes (21-27) have no node order qsma has "
             "checked; use C3D20",
}
#: most ids one GENERATE row may produce
_MAX_GENERATED = 10**8


@dataclass
class _InpSet:
    name: str
    internal: bool
    chunks: list = field(default_factory=list)   # (ids array, where) or ("elset", key)


@dataclass
class _InpBlock:
    cell_type: str
    abaqus_type: str
    ids: np.ndarray             # element ids
    conn: np.ndarray            # (k, nodes) node ids
    where: list                 # (file, line) of each row


class _InpReader:
    """State of an .inp file being read; the handlers in ``_INP_KEYWORDS`` fill it."""

    def __init__(self, path: Path):
        self.source = str(path)
        self.node_ids, self.node_xyz, self.node_where = [], [], []
        self.fewest_coordinates = None      # (count, where, text) of the shortest node row
        self.blocks = []
        self.sets = {"NSET": {}, "ELSET": {}}
        self.surfaces = {}          # key -> (name, [(reference, face or None, where)])
        self.node_surfaces = {}     # key -> _InpSet
        self.scope = "model"        # model | part | assembly | instance
        self.parts = self.instances = 0
        self.pairs = []             # (slave, master, interaction, type, where)
        self.friction = {}          # interaction name (upper) -> mu
        self.interaction = None     # the *SURFACE INTERACTION being defined
        self.boundaries = []        # (node set or node id, first dof, last dof, where)
        self.load_ids = {"NSET": set(), "ELSET": set()}   # ids a *CLOAD / *DLOAD names
        self.named = {"NSET": set(), "ELSET": set()}      # sets they name (upper case)
        self.connectors = []        # ids of the skipped connector elements (arrays)
        self.cuts = set()           # surfaces of *PRE-TENSION SECTION (upper case)

    def skips(self, card: _Card) -> bool:
        """Definitions at assembly level (reference points, connectors) are not the mesh."""
        return self.scope == "assembly" and "INSTANCE" not in card.params

    def named_set(self, kind: str, name: str, internal: bool) -> _InpSet:
        s = self.sets[kind].setdefault(name.upper(), _InpSet(name, internal))
        s.internal = s.internal and internal
        return s

    def find_set(self, kind: str, name: str, where) -> _InpSet:
        sets = self.sets[kind]
        key = name.upper()
        if key not in sets and "." in key:        # instance.set
            key = key.rsplit(".", 1)[1]
        if key not in sets:
            raise _inp_error(where, f"unknown {'node' if kind == 'NSET' else 'element'} set "
                             f"{name!r}", f"define it with *{kind} before it is used")
        return sets[key]

    # --- after the last card -----------------------------------------------------------
    def file_mesh(self, cell_type, per_body: bool = False):
        """What the file holds (nodes in id order), and its cell type; ``per_body``: the
        cell types are checked per body (an assembly), not for the whole file."""
        node_ids, xyz = self._nodes()
        nodes = _IdLookup(node_ids)
        blocks = [(b.cell_type, TYPES[b.cell_type].dim, self._connectivity(b, nodes),
                   _is_continuum(b.abaqus_type)) for b in self.blocks]
        vtypes = _cell_type_of(self.source, blocks, cell_type, per_body=per_body)
        self._check_node_rows(CELL_TYPES[vtypes[0]].dim)
        elements = self._element_lookup()
        index = _Elements(blocks)
        elsets = {k: self._element_indices(s, elements) for k, s in self.sets["ELSET"].items()}
        names = {t: self._element(t) for t in vtypes}
        fm = _FileMesh(self.source, xyz, node_ids, blocks, element=names[vtypes[0]],
                       block_elements=names, element_ids=[b.ids for b in self.blocks])
        for s in self.sets["NSET"].values():
            if not s.internal:
                fm.node_sets[s.name] = [self._node_indices(s, nodes, elsets, index)]
        for s in self.node_surfaces.values():
            fm.node_sets.setdefault(s.name, []).append(
                self._node_indices(s, nodes, elsets, index))
        for key, s in self.sets["ELSET"].items():
            if not s.internal and len(elsets[key]):
                fm.element_sets[s.name] = [elsets[key]]
            elif not s.internal:
                fm.empty_sets[s.name] = "cell"
        for name, rows in self.surfaces.values():     # a cut's internal faces kept too
            self._surface(fm, name, rows, vtypes, elements, elsets, index)
        fm.cut_sets = {name for name, _ in self.surfaces.values() if name.upper() in self.cuts}
        fm.node_surfaces = {s.name for s in self.node_surfaces.values()}
        fm.contact_pairs = [_ContactPair(self._surface_name(slave), self._surface_name(master),
                                         self.friction.get((inter or "").upper()), kind, where)
                            for slave, master, inter, kind, where in self.pairs]
        fm.boundaries = self._boundary_sets(fm, nodes, elsets, index)
        load_id_sets(self, fm, nodes, elements)
        named_internal_sets(self, fm, nodes, elsets, index)
        return fm, vtypes

    def _check_node_rows(self, dim: int):
        """Every node row gives at least ``dim`` coordinates (the cells' dimension). Abaqus
        reads an omitted coordinate as 0, but a row short of the cells' dimension is a
        row cut off (a truncated file) far more often than a node meant to lie on an
        axis, and would move that node silently."""
        if self.fewest_coordinates is None or self.fewest_coordinates[0] >= dim:
            return
        count, where, text = self.fewest_coordinates
        raise _inp_error(where, f"node row {text!r} gives {count} coordinate(s), but the "
                         f"cells are {dim}D", f"give 'node id, x, y{', z' if dim == 3 else ''}'"
                         f" on every node line (0 written out where it is 0); a row cut "
                         f"short means a damaged or truncated file")

    def _surface_name(self, name: str) -> str:
        """The defined spelling of a surface name (Abaqus names ignore case)."""
        key = name.upper()
        if key in self.surfaces:
            return self.surfaces[key][0]
        if key in self.node_surfaces:
            return self.node_surfaces[key].name
        return name

    def _boundary_sets(self, fm, nodes: _IdLookup, elsets, index) -> list:
        """``*BOUNDARY`` rows with zero value as (node set name, first, last dof); a row
        naming one node gets a node set ``_BC<id>`` of its own."""
        out = []
        for ref, first, last, where in self.boundaries:
            if re.fullmatch(r"[+-]?\d{1,18}", ref):
                idx = nodes(np.array([int(ref)]))
                if idx[0] < 0:
                    continue
                name = f"_BC{ref}"
                fm.node_sets.setdefault(name, []).append(idx)
            else:
                key = ref.upper().rsplit(".", 1)[-1]
                if key not in self.sets["NSET"] and key not in self.node_surfaces:
                    continue
                name = (self.sets["NSET"].get(key) or self.node_surfaces[key]).name
                if name not in fm.node_sets:     # an internal set: expose it
                    s = self.sets["NSET"].get(key)
                    fm.node_sets[name] = [self._node_indices(s, nodes, elsets, index)]
            out.append((name, first, last))
        return out

    def _element(self, vtype: str) -> str:
        """The one Abaqus element type (upper case) of the cells."""
        names = {}
        for b in self.blocks:
            if b.cell_type == vtype and _is_continuum(b.abaqus_type) and len(b.ids):
                names.setdefault(b.abaqus_type.upper(), b.where[0])
        if len(names) > 1:
            (first, _), (second, where) = list(names.items())[:2]
            raise _inp_error(where, f"the {vtype} cells are of several element types "
                             f"({', '.join(names)}): {second} here, {first} before",
                             "use one element type for all cells (a mesh carries one "
                             "formulation)")
        return next(iter(names))

    def _nodes(self):
        if not sum(len(ids) for ids in self.node_ids):
            raise MeshFileError(f"{self.source}: no nodes (no *NODE data lines); an empty "
                                f"mesh cannot be read: check that this is the model's input "
                                f"file")
        ids = np.concatenate(self.node_ids)
        lookup = _IdLookup(ids)
        if lookup.duplicate is not None:
            raise _inp_error(self.node_where[lookup.duplicate],
                             f"node {ids[lookup.duplicate]} is defined twice",
                             "give every node a distinct id")
        return ids[lookup.order], np.concatenate(self.node_xyz)[lookup.order]

    @staticmethod
    def _connectivity(block: _InpBlock, nodes: _IdLookup) -> np.ndarray:
        conn = nodes(block.conn)
        if (conn < 0).any():
            row, col = np.argwhere(conn < 0)[0]
            raise _inp_error(block.where[row], f"element {block.ids[row]} refers to node "
                             f"{block.conn[row, col]}, which no *NODE defines",
                             "define the node or correct the element row")
        return conn

    def _element_lookup(self) -> _IdLookup:
        ids = np.concatenate([b.ids for b in self.blocks] + [np.zeros(0, np.int64)])
        lookup = _IdLookup(ids)
        if lookup.duplicate is not None:
            where = [w for b in self.blocks for w in b.where][lookup.duplicate]
            raise _inp_error(where, f"element {ids[lookup.duplicate]} is defined twice",
                             "give every element a distinct id")
        return lookup

    def _element_indices(self, s: _InpSet, elements: _IdLookup) -> np.ndarray:
        """Element indices of set ``s``, without the ids of the skipped connectors."""
        skipped = np.concatenate(self.connectors + [np.zeros(0, np.int64)])
        parts = [np.zeros(0, np.int64)]
        for ids, where in s.chunks:
            idx = elements(ids)
            if (idx < 0).any() and len(skipped):
                keep = (idx >= 0) | ~np.isin(ids, skipped)
                ids, idx = ids[keep], idx[keep]
            if (idx < 0).any():
                raise _inp_error(where, f"element set {s.name!r} refers to element "
                                 f"{ids[idx < 0][0]}, which no *ELEMENT defines",
                                 "correct the id or define the element")
            parts.append(idx)
        return np.unique(np.concatenate(parts))

    @staticmethod
    def _node_indices(s: _InpSet, nodes: _IdLookup, elsets: dict, index: _Elements):
        parts = [np.zeros(0, np.int64)]
        for chunk in s.chunks:
            if isinstance(chunk[0], str):           # *NSET, ELSET=...: nodes of elements
                parts += [index.blocks[b][2][rows].ravel()
                          for b, rows in index.by_block(elsets[chunk[1]])]
                continue
            ids, where = chunk
            idx = nodes(ids)
            if (idx < 0).any():
                raise _inp_error(where, f"node set {s.name!r} refers to node "
                                 f"{ids[idx < 0][0]}, which no *NODE defines",
                                 "correct the id or define the node")
            parts.append(idx)
        return np.unique(np.concatenate(parts))

    def _surface(self, fm, name, rows, vtypes, elements, elsets, index: _Elements):
        """Facets of an element-based surface: ``(element or set, face)`` rows (the
        face numbering of each element's own type in a mixed mesh)."""
        if not rows:
            fm.empty_sets.setdefault(name, "facet")
        for reference, face, where in rows:
            if re.fullmatch(r"[+-]?\d{1,18}", reference):
                members = elements(np.array([int(reference)]))
                if members[0] < 0:
                    raise _inp_error(where, f"surface {name!r} refers to element {reference}, "
                                     f"which no *ELEMENT defines", "correct the element id")
            else:
                members = elsets[self.find_set("ELSET", reference, where).name.upper()]
            by_block = list(index.by_block(members))
            wrong = [b for b, _ in by_block
                     if fm.blocks[b][0] not in vtypes or not fm.blocks[b][3]]
            if wrong:
                raise _inp_error(where, f"surface {name!r} uses faces of "
                                 f"{fm.blocks[wrong[0]][0]} elements", f"a surface is made "
                                 f"of faces of the {' and '.join(vtypes)} cells; refer to "
                                 f"those")
            if face is None:                            # every boundary face
                fm.free_faces.setdefault(name, []).append(members)
                continue
            for b, rows_b in by_block:
                vtype = fm.blocks[b][0]
                faces = outward_abaqus_faces(vtype)     # a cut's faces: as their cells own them
                m = re.fullmatch(r"S(\d)", face.upper())
                if m is None or not 1 <= int(m.group(1)) <= len(faces):
                    raise _inp_error(where, f"face {face!r} does not exist on {vtype} "
                                     f"elements", f"use S1..S{len(faces)} (Abaqus face "
                                     f"numbering)")
                local = list(faces[int(m.group(1)) - 1])
                fm.facet_rows.setdefault(name, []).append(fm.blocks[b][2][rows_b][:, local])


def _inp_node(r: _InpReader, card: _Card):
    if r.skips(card):
        return
    system = str(card.params.get("SYSTEM", "R")).upper()
    if system != "R":
        raise _inp_error(card.where, f"nodes given in SYSTEM={system}",
                         "give node coordinates in the rectangular system (SYSTEM=R)")
    if "INPUT" in card.params:
        raise _inp_error(card.where, "INPUT= on *NODE is not supported",
                         "put the data lines in the file or use *INCLUDE, INPUT=")
    rows = list(_rows(card))
    long = next((row for row in rows if len(row[1]) > 4), None)
    if long is not None:
        raise _inp_error(long[0], f"node row {long[2]!r} has {len(long[1])} fields",
                         "give 'node id, x, y[, z]' (at most 3 coordinates) on each line")
    try:      # fast path: plain numbers in every row
        ids = np.array([tokens[0] for _, tokens, _ in rows], dtype=np.int64)
        xyz = np.array([(tokens + ["0", "0", "0"])[1:4] for _, tokens, _ in rows],
                       dtype=float).reshape(len(rows), 3)
        if np.abs(ids).max(initial=0) >= _MAX_ID:
            raise ValueError("id out of range")
    except (ValueError, OverflowError):
        ids, xyz = _node_rows(rows)
    bad = np.flatnonzero(~np.isfinite(xyz).all(axis=1))
    if bad.size:
        raise _inp_error(rows[bad[0]][0], f"node {ids[bad[0]]} has a non-finite coordinate",
                         "give finite coordinates")
    if rows:
        short = min(rows, key=lambda row: len(row[1]))
        if r.fewest_coordinates is None or len(short[1]) - 1 < r.fewest_coordinates[0]:
            r.fewest_coordinates = (len(short[1]) - 1, short[0], short[2])
    r.node_ids.append(ids)
    r.node_xyz.append(xyz)
    r.node_where += [where for where, _, _ in rows]
    name = card.params.get("NSET")
    if isinstance(name, str) and name:
        r.named_set("NSET", name, False).chunks.append((ids, card.where))


def _node_rows(rows) -> tuple:
    """Node ids and coordinates row by row (Fortran exponents, empty fields), with the
    line of the first row that cannot be read."""
    ids, xyz = [], []
    for where, tokens, text in rows:
        try:
            ids.append(_integer(tokens[0]))
            xyz.append([_abaqus_float(t) for t in (tokens + ["", "", ""])[1:4]])
        except ValueError:
            raise _inp_error(where, f"cannot read the node row {text!r}",
                             "expected 'node id, x, y[, z]' with an integer id") from None
    return np.array(ids, dtype=np.int64), np.array(xyz, dtype=float).reshape(-1, 3)


def _inp_element(r: _InpReader, card: _Card):
    if r.skips(card):
        return
    etype = card.params.get("TYPE")
    if not isinstance(etype, str) or not etype:
        raise _inp_error(card.where, "*ELEMENT without TYPE=", "give the element type")
    if etype.upper() in CONNECTOR_TYPES:           # no part of a mesh (lexer.py)
        r.connectors.append(_connector_ids(card))
        return
    cell_type = _abaqus_cell_type(etype)
    base = etype.upper().rstrip("RIHT")
    if base in _ABAQUS_REFUSED:
        raise _inp_error(card.where, f"{etype} elements are not supported",
                         _ABAQUS_REFUSED[base])
    if cell_type is not None and etype.upper().startswith("C3D") and cell_type not in CELL_TYPES:
        raise _inp_error(card.where, f"{etype} ({cell_type}) elements are not supported "
                         f"yet", f"qsma reads cells of {', '.join(sorted(CELL_TYPES))}: "
                         f"convert the mesh to linear elements (e.g. C3D8, CPE4)")
    if cell_type is None:
        raise _inp_error(card.where, f"unknown or unsupported element type {etype!r}",
                         f"qsma reads the linear types {', '.join(ABAQUS_ELEMENT_TYPES)} "
                         f"(with R/I/H/T variants); convert the mesh to one of them")
    nv = TYPES[cell_type].n_nodes
    rows, starts, texts = [], [], []
    pending, start = [], None
    for where, tokens, text in _rows(card):
        if not pending:
            start = where
        pending += tokens
        if len(pending) < 1 + nv and text.rstrip().endswith(","):
            continue                                   # the row continues on the next line
        if len(pending) != 1 + nv:
            raise _inp_error(start, f"element row with {len(pending) - 1} node ids, but "
                             f"{etype} elements have {nv}", f"give 'element id' and {nv} "
                             f"node ids (continue a long row by ending the line with a comma)")
        rows.append(pending)
        starts.append(start)
        texts.append(text)
        pending = []
    if pending:
        raise _inp_error(start, "the last element row is incomplete",
                         f"give {nv} node ids for each {etype} element")
    try:
        table = np.array(rows, dtype=np.int64).reshape(len(rows), 1 + nv)
        if np.abs(table).max(initial=0) >= _MAX_ID:
            raise ValueError("id out of range")
    except (ValueError, OverflowError):
        for row, where, text in zip(rows, starts, texts):
            try:
                [_integer(t) for t in row]
            except ValueError:
                raise _inp_error(where, f"cannot read the element row {text!r}",
                                 "expected integer element and node ids") from None
        raise _inp_error(card.where, "cannot read the element rows",
                         "expected integer element and node ids") from None
    r.blocks.append(_InpBlock(cell_type, etype, table[:, 0], table[:, 1:], starts))
    name = card.params.get("ELSET")
    if isinstance(name, str) and name:
        r.named_set("ELSET", name, False).chunks.append((table[:, 0], card.where))


def _inp_set(kind: str):
    def handler(r: _InpReader, card: _Card):
        if r.skips(card):
            return
        name = card.params.get(kind)
        if not isinstance(name, str) or not name:
            raise _inp_error(card.where, f"*{kind} without {kind}=name", "name the set")
        s = r.named_set(kind, name, card.params.get("INTERNAL") is True)
        from_elset = card.params.get("ELSET") if kind == "NSET" else None
        if isinstance(from_elset, str):
            s.chunks.append(("elset", r.find_set("ELSET", from_elset, card.where).name.upper()))
        generate = card.params.get("GENERATE") is True
        for where, tokens, text in _rows(card):
            s.chunks.append((_set_row(r, kind, s, tokens, text, where, generate), where))
    return handler


def _set_row(r, kind, s, tokens, text, where, generate) -> np.ndarray:
    if generate:
        try:
            values = [_integer(t) for t in tokens]
        except ValueError:
            values = []
        if (len(values) not in (2, 3) or values[1] < values[0]
                or (len(values) == 3 and values[2] < 1)
                or (values[1] - values[0]) // (values[2] if len(values) == 3 else 1)
                >= _MAX_GENERATED):
            raise _inp_error(where, f"cannot read the GENERATE row {text!r}",
                             "expected 'first, last[, increment]' with first <= last, a "
                             f"positive increment and fewer than {_MAX_GENERATED} ids")
        return np.arange(values[0], values[1] + 1, values[2] if len(values) == 3 else 1)
    ids = []
    for token in tokens:
        if not token:
            continue
        if re.fullmatch(r"[+-]?\d+", token):
            try:
                ids.append(_integer(token))
            except ValueError:
                raise _inp_error(where, f"id {token} is out of range",
                                 f"use ids below {_MAX_ID}") from None
        else:   # the name of another set of the same kind
            s.chunks.extend(r.find_set(kind, token, where).chunks)
    return np.array(ids, dtype=np.int64)


def _inp_surface(r: _InpReader, card: _Card):
    name = card.params.get("NAME")
    if not isinstance(name, str) or not name:
        raise _inp_error(card.where, "*SURFACE without NAME=", "name the surface")
    stype = str(card.params.get("TYPE", "ELEMENT")).upper()
    if stype == "NODE":
        s = r.node_surfaces.setdefault(name.upper(), _InpSet(name, False))
        for where, tokens, text in _rows(card):
            s.chunks.append((_set_row(r, "NSET", s, tokens[:1], text, where, False), where))
        return
    if stype != "ELEMENT":
        return    # analytical and cutting surfaces are not sets of the mesh
    _, rows = r.surfaces.setdefault(name.upper(), (name, []))
    for where, tokens, text in _rows(card):
        if not tokens[0] or len(tokens) > 2:
            raise _inp_error(where, f"cannot read the surface row {text!r}",
                             "expected 'element set or element id, face (S1, S2, ...)'")
        rows.append((tokens[0], tokens[1] if len(tokens) > 1 and tokens[1] else None, where))


def _inp_scope(scope: str):
    def handler(r: _InpReader, card: _Card):
        if scope == "part":
            r.parts += 1
            if r.parts > 1:
                raise _inp_error(card.where, "a second *PART",
                                 "qsma reads one part per body: write each part to its own "
                                 "file, or read the file as an assembly (one body per "
                                 "instance: cells = \"<instance name>\" in the body's table)")
        if scope == "instance":
            r.instances += 1
            if r.instances > 1:
                raise _inp_error(card.where, "a second *INSTANCE",
                                 "qsma reads one instance per body: read the file as an "
                                 "assembly (cells = \"<instance name>\" in the body's "
                                 "table) or write each instance to its own file")
            if placement(card) is not None:
                raise _inp_error(card.data[0][:2], "the instance is translated or rotated",
                                 "read the file as an assembly (cells = \"<instance "
                                 "name>\" in the body's table), which places instances, "
                                 "or export the mesh in its final position")
        r.scope = scope
    return handler


def _inp_contact_pair(r: _InpReader, card: _Card):
    """``*CONTACT PAIR, INTERACTION=name[, TYPE=...]`` rows ``slave, master``."""
    inter = card.params.get("INTERACTION")
    kind = str(card.params.get("TYPE", "NODE TO SURFACE")).upper()
    for where, tokens, text in _rows(card):
        if len(tokens) < 2 or not tokens[0] or not tokens[1]:
            raise _inp_error(where, f"cannot read the contact pair row {text!r}",
                             "expected 'slave surface, master surface'")
        r.pairs.append((tokens[0], tokens[1], inter if isinstance(inter, str) else None,
                        kind, where))


def _inp_interaction(r: _InpReader, card: _Card):
    name = card.params.get("NAME")
    r.interaction = name.upper() if isinstance(name, str) else None


def _inp_friction(r: _InpReader, card: _Card):
    """``*FRICTION`` under a ``*SURFACE INTERACTION``: the first number is mu."""
    for where, tokens, text in _rows(card):
        if r.interaction is not None and tokens and tokens[0]:
            try:
                r.friction[r.interaction] = _abaqus_float(tokens[0])
            except ValueError:
                raise _inp_error(where, f"cannot read the friction coefficient {text!r}",
                                 "expected 'mu[, stick slope]'") from None
        return


def _inp_boundary(r: _InpReader, card: _Card):
    """Homogeneous ``*BOUNDARY`` rows ``node or set, first dof[, last dof[, 0]]`` (dofs
    1-3: displacements); other rows (prescribed values, types) are left out."""
    for where, tokens, text in _rows(card):
        name_in_row(r, "NSET", tokens)
        try:
            first = int(tokens[1]) if len(tokens) > 1 and tokens[1] else None
            last = int(tokens[2]) if len(tokens) > 2 and tokens[2] else first
            value = _abaqus_float(tokens[3]) if len(tokens) > 3 else 0.0
        except ValueError:
            continue                    # e.g. ENCASTRE, XSYMM: not read
        if first is None or value != 0.0:
            continue
        first, last = max(first, 1), min(last, 3)
        if first <= last:
            r.boundaries.append((tokens[0], first, last, where))


def _inp_load_ids(kind: str):
    """``*CLOAD`` (node) and ``*DLOAD`` (element) rows that name an id: remembered, the
    rest of the load is read by :mod:`.deck`."""
    def handler(r: _InpReader, card: _Card):
        for _, tokens, _ in _rows(card):
            if tokens and re.fullmatch(r"[+-]?\d{1,18}", tokens[0]):
                r.load_ids[kind].add(int(tokens[0]))
            else:
                name_in_row(r, kind, tokens)
    return handler


def _inp_pretension(r: _InpReader, card: _Card):
    """A pretension section's surface cuts a meshed bolt: a facet set of internal faces."""
    if isinstance(card.params.get("SURFACE"), str):
        r.cuts.add(card.params["SURFACE"].upper())        # read by qsma.deck.bolts


#: keyword -> handler; other keywords (materials, steps, loads, ...) are skipped
_INP_KEYWORDS = {
    "NODE": _inp_node, "ELEMENT": _inp_element, "NSET": _inp_set("NSET"),
    "ELSET": _inp_set("ELSET"), "SURFACE": _inp_surface,
    "PART": _inp_scope("part"), "END PART": _inp_scope("model"),
    "ASSEMBLY": _inp_scope("assembly"), "END ASSEMBLY": _inp_scope("model"),
    "INSTANCE": _inp_scope("instance"), "END INSTANCE": _inp_scope("assembly"),
    "CONTACT PAIR": _inp_contact_pair, "SURFACE INTERACTION": _inp_interaction,
    "FRICTION": _inp_friction, "BOUNDARY": _inp_boundary,
    "CLOAD": _inp_load_ids("NSET"), "DLOAD": _inp_load_ids("ELSET"),
    "PRE-TENSION SECTION": _inp_pretension,
}


def _read_abaqus(path: Path, cell_type: str | None) -> Mesh:
    return _to_mesh(*_abaqus_file_mesh(path, cell_type))


def _abaqus_file_mesh(path: Path, cell_type: str | None, assembly: bool = False):
    """``(what the file holds, its cell type)``, before it becomes a Mesh; ``assembly``:
    several parts and placed instances are made flat (:mod:`.instances`)."""
    reader = _InpReader(path)
    cards = _inp_cards(path)
    check_instances_closed(cards)
    if assembly and needs_flattening(cards):
        cards = flatten_instances(cards, _Card)
    for card in cards:
        handler = _INP_KEYWORDS.get(card.keyword)
        if handler is not None:
            handler(reader, card)
    return reader.file_mesh(cell_type, per_body=assembly)
