"""Abaqus / CalculiX ``.inp`` files: our own reader (nodes, elements, ``*NSET``,
``*ELSET``, ``*SURFACE``, ``*INCLUDE``, one part and one instance) and writer.

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

from ...errors import InputError, MeshFileError
from ...mesh.celltypes import CELL_TYPES, TYPES, abaqus_element_types, abaqus_faces
from ..mesh import Mesh, facet_index
from .common import (_MAX_ID, _boundary_of_sets,
                     _cell_type_of, _check_names, _ContactPair, _Elements, _FileMesh,
                     _IdLookup, _line_of, _read_bytes, _to_mesh)

#: derived from the cell type records (:mod:`qsma.mesh.celltypes`), for code that reads
#: these tables: Abaqus faces of the linear types; Abaqus/CalculiX element names read
#: (without the letters R, I, H, T of their variants) -> meshio type
ABAQUS_FACES = {name: [tuple(f) for f in t.abaqus_faces] for name, t in TYPES.items()
                if t.abaqus_faces}
ABAQUS_ELEMENT_TYPES = abaqus_element_types()
#: element types refused with a reason of their own
_ABAQUS_REFUSED = {
    "C3D27": "its optional face and centre nodes (21-27) have no node order qsma has "
             "checked; use C3D20",
}
#: Characters of a coordinate field that CalculiX reads: its *NODE reader takes the first
#: 20 characters of a field (Fortran ``f20.0``), so a longer field is cut short without a
#: message and a field of 22 characters or more stops it ("*ERROR reading *NODE").
CALCULIX_FIELD = 20
#: Entries per data line that CalculiX reads (its line splitter stops at 16): an element
#: row of more nodes continues on the next line after a trailing comma.
CALCULIX_ENTRIES = 16


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


#: most ids one GENERATE row may produce
_MAX_GENERATED = 10**8
_BINARY_BYTES = re.compile(rb"[\x00-\x08\x0b\x0e-\x1f\x7f]")
_PLAIN_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_\-]*")

# ----- Abaqus / CalculiX --------------------------------------------------------------

@dataclass
class _Card:
    """A keyword line (upper-case keyword, parameters) and its data lines."""

    keyword: str
    params: dict
    where: tuple            # (file, line)
    data: list              # [(file, line, text)]


def _at(where) -> str:
    return f"{where[0]}, line {where[1]}"


def _inp_error(where, problem: str, fix: str) -> MeshFileError:
    return MeshFileError(f"{_at(where)}: {problem}; {fix}")


def _split_fields(text: str) -> list:
    """Split on commas outside double quotes."""
    if '"' not in text:
        return text.split(",")
    fields, current, quoted = [], [], False
    for ch in text:
        if ch == '"':
            quoted = not quoted
        if ch == "," and not quoted:
            fields.append("".join(current))
            current = []
        else:
            current.append(ch)
    fields.append("".join(current))
    return fields


def _unquote(text: str) -> str:
    text = text.strip()
    return text[1:-1] if len(text) >= 2 and text[0] == text[-1] == '"' else text


def _parse_keyword(line: str, where) -> tuple:
    fields = _split_fields(line[1:])
    keyword = " ".join(fields[0].split()).upper()
    if not keyword:
        raise _inp_error(where, f"empty keyword line {line!r}", "write the keyword after '*'")
    params = {}
    for item in fields[1:]:
        if item.strip():
            key, eq, value = item.partition("=")
            params[" ".join(key.split()).upper()] = _unquote(value) if eq else True
    return keyword, params


def _read_inp_text(path: Path, where=None) -> str:
    if where is not None and not path.is_file():
        raise _inp_error(where, f"included file {str(path)!r} not found",
                         "check the INPUT= path (relative to the including file)")
    data = _read_bytes(path)
    bad = _BINARY_BYTES.search(data)
    if bad:
        raise MeshFileError(f"{path}, line {_line_of(data, bad.start())}: binary data "
                            f"(byte 0x{data[bad.start()]:02x}); an .inp file is plain text: "
                            f"check that this is an Abaqus/CalculiX input file")
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError:
        return data.decode("latin-1")


def _inp_lines(path: Path, stack=(), where=None):
    """(file, line number, text) of the lines that are not blank or comments, with
    ``*INCLUDE`` expanded."""
    text = _read_inp_text(path, where)
    _check_terminated(path, text)
    here = path.resolve()
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.strip()
        if not line or line.startswith("**"):
            continue
        if line.startswith("*") and line[1:].split(",")[0].strip().upper() == "INCLUDE":
            _, params = _parse_keyword(line, (str(path), number))
            target = params.get("INPUT")
            if not isinstance(target, str) or not target:
                raise _inp_error((str(path), number), "*INCLUDE without INPUT=file",
                                 "name the included file with INPUT=")
            included = path.parent / target
            if included.resolve() in stack + (here,):
                raise _inp_error((str(path), number), f"{target!r} includes itself",
                                 "remove the circular *INCLUDE")
            yield from _inp_lines(included, stack + (here,), (str(path), number))
            continue
        yield str(path), number, line


def _check_terminated(path: Path, text: str):
    """Refuse a file whose last line is a data line without a line end: a copy or
    download cut off there (a set row ``1, 126, 251, 37`` would silently lose nodes).
    A keyword or comment line without one is accepted (nothing of it can be lost)."""
    if not text or text.endswith(("\n", "\r")):
        return
    lines = text.splitlines()
    last = lines[-1].strip()
    if last and not last.startswith("*"):
        raise MeshFileError(f"{path}, line {len(lines)}: the file ends inside the data "
                            f"line {last[:40]!r} (no line end after it): it looks cut off "
                            f"(an interrupted copy or download); copy or export it again "
                            f"(if the file is complete, end its last line with a line "
                            f"break)")


def _inp_cards(path: Path) -> list:
    items = list(_inp_lines(path))
    cards, i = [], 0
    while i < len(items):
        file, number, line = items[i]
        i += 1
        if not line.startswith("*"):
            raise _inp_error((file, number), f"data line {line[:40]!r} before any keyword",
                             "an .inp file starts with keyword lines such as *HEADING or "
                             "*NODE: check that this is an Abaqus/CalculiX input file")
        # a keyword line ending with a comma continues on the next line
        while (line.endswith(",") and i < len(items) and not items[i][2].startswith("*")
               and items[i][2][:1].isalpha() and "=" in items[i][2]):
            line += items[i][2]
            i += 1
        keyword, params = _parse_keyword(line, (file, number))
        start = i
        while i < len(items) and not items[i][2].startswith("*"):
            i += 1
        cards.append(_Card(keyword, params, (file, number), items[start:i]))
    return cards


def _rows(card: _Card):
    """((file, line), tokens) of the data lines; a trailing comma adds no token."""
    for file, number, text in card.data:
        if '"' in text:
            tokens = [_unquote(t) for t in _split_fields(text)]
        else:
            tokens = [t.strip() for t in text.split(",")]
        if tokens and tokens[-1] == "" and len(tokens) > 1:
            tokens.pop()
        yield (file, number), tokens, text


def _integer(token: str) -> int:
    """An id or count of an .inp file (ValueError if it is none or out of range)."""
    value = int(token)
    if abs(value) >= _MAX_ID:
        raise ValueError(f"{token} is out of range")
    return value


def _abaqus_float(token: str) -> float:
    token = token.strip()
    return float(token.replace("D", "E").replace("d", "e")) if token else 0.0


def _abaqus_cell_type(name: str):
    """meshio type of an Abaqus element type, or None."""
    base = name.upper()
    while base not in ABAQUS_ELEMENT_TYPES and len(base) > 2 and base[-1] in "RIHT":
        base = base[:-1]
    return ABAQUS_ELEMENT_TYPES.get(base)


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
    def file_mesh(self, cell_type):
        """What the file holds (nodes in id order), and its cell type."""
        node_ids, xyz = self._nodes()
        nodes = _IdLookup(node_ids)
        blocks = [(b.cell_type, TYPES[b.cell_type].dim, self._connectivity(b, nodes),
                   _is_continuum(b.abaqus_type)) for b in self.blocks]
        vtypes = _cell_type_of(self.source, blocks, cell_type)
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
        for name, rows in self.surfaces.values():
            self._surface(fm, name, rows, vtypes, elements, elsets, index)
        fm.node_surfaces = {s.name for s in self.node_surfaces.values()}
        fm.contact_pairs = [_ContactPair(self._surface_name(slave), self._surface_name(master),
                                         self.friction.get((inter or "").upper()), kind, where)
                            for slave, master, inter, kind, where in self.pairs]
        fm.boundaries = self._boundary_sets(fm, nodes, elsets, index)
        self._load_id_sets(fm, nodes, elements)
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

    def _load_id_sets(self, fm, nodes: _IdLookup, elements: _IdLookup):
        """A node (element) that a *CLOAD (*DLOAD) row names by its id gets a node set
        ``_N<id>`` (a cell set ``_E<id>``) of its own, so that a configuration can name
        it (qsma.model.io.deck)."""
        is_cell = np.concatenate([np.full(len(conn), bool(cell))
                                  for _, _, conn, cell in fm.blocks])
        for kind, lookup, sets, prefix in (("NSET", nodes, fm.node_sets, "_N"),
                                           ("ELSET", elements, fm.element_sets, "_E")):
            for ident in sorted(self.load_ids[kind]):
                idx = lookup(np.array([ident]))
                if idx[0] >= 0 and (kind == "NSET" or is_cell[idx[0]]):
                    sets.setdefault(f"{prefix}{ident}", []).append(idx)

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

    @staticmethod
    def _element_indices(s: _InpSet, elements: _IdLookup) -> np.ndarray:
        parts = [np.zeros(0, np.int64)]
        for ids, where in s.chunks:
            idx = elements(ids)
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
                faces = abaqus_faces(vtype)
                m = re.fullmatch(r"S(\d)", face.upper())
                if m is None or not 1 <= int(m.group(1)) <= len(faces):
                    raise _inp_error(where, f"face {face!r} does not exist on {vtype} "
                                     f"elements", f"use S1..S{len(faces)} (Abaqus face "
                                     f"numbering)")
                local = list(faces[int(m.group(1)) - 1])
                fm.facet_rows.setdefault(name, []).append(fm.blocks[b][2][rows_b][:, local])


def _is_continuum(abaqus_type: str) -> bool:
    return abaqus_type.upper().startswith(("C3D", "CPE", "CPS", "CAX"))


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
            from .instances import placement
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
    return handler


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
}


def _read_abaqus(path: Path, cell_type: str | None) -> Mesh:
    return _to_mesh(*_abaqus_file_mesh(path, cell_type))


def _abaqus_file_mesh(path: Path, cell_type: str | None, assembly: bool = False):
    """``(what the file holds, its cell type)``, before it becomes a Mesh; ``assembly``:
    several parts and placed instances are made flat (:mod:`.instances`)."""
    from .instances import check_instances_closed, flatten_instances, needs_flattening
    reader = _InpReader(path)
    cards = _inp_cards(path)
    check_instances_closed(cards)
    if assembly and needs_flattening(cards):
        cards = flatten_instances(cards, _Card)
    for card in cards:
        handler = _INP_KEYWORDS.get(card.keyword)
        if handler is not None:
            handler(reader, card)
    return reader.file_mesh(cell_type)


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


def _inp_number(x: float) -> str:
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
           "** written by qsma.model.io.write_mesh; facet sets are *SURFACE definitions over",
           "** the internal element sets _<set>_S<face> (Abaqus face numbering)", "*NODE"]
    out += [", ".join([str(i)] + [_inp_number(v) for v in p])
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
