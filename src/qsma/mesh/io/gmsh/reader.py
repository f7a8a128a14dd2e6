"""Gmsh ``.msh`` files: our own reader of versions 4.1 (ASCII, binary) and 4.0 (ASCII),
version 2.2 through meshio with checks of our own (the writers: :mod:`.writer`).

Why our own reader for version 4 (``docs/mesh-io.md``): meshio 5.3.5 keeps only the
first physical tag of an entity unless it is named, merges equal names of different
dimensions, fails on 4.1 files where some entities have no physical group, and reads
Gmsh's version "4" files as 4.1. Do not replace it by ``meshio.read``.
"""
from __future__ import annotations

import contextlib
import io
import re
import warnings
from pathlib import Path

import numpy as np

from ....errors import MeshFileError
from ...celltypes import CELL_TYPES
from ...mesh import Mesh
from ..common import (_MAX_ID, _cell_type_of, _FileMesh, _IdLookup, _line_of, _read_bytes,
                      _to_mesh)
from .types import _GMSH_DIM, _GMSH_TYPES, _gmsh_to_meshio

def _read_gmsh(path: Path, cell_type: str | None) -> Mesh:
    return _to_mesh(*_gmsh_file_mesh(path, cell_type))


def _gmsh_file_mesh(path: Path, cell_type: str | None, per_body: bool = False):
    """``(what the file holds, its cell type)``, before it becomes a Mesh; ``per_body``:
    the cell types are checked per body (an assembly), not for the whole file."""
    raw = _read_bytes(path)
    src = str(path)
    version, is_ascii, size_t = _gmsh_header(raw, src)
    if version in ("4", "4.0") and not is_ascii:
        raise MeshFileError(f"{src}: binary Gmsh 4.0 files are not supported; save the mesh "
                            f"as version 4.1 (Gmsh: Mesh.MshFileVersion = 4.1)")
    if version in ("4", "4.0", "4.1"):    # Gmsh writes format 4.0 as version "4"
        fm, dims = _Gmsh4(raw, src, is_ascii, size_t, version == "4.1").file_mesh()
    elif version in ("2", "2.0", "2.1", "2.2"):
        fm, dims = _gmsh_with_meshio(path, raw, src, version, is_ascii)
    else:
        raise MeshFileError(f"{src}: Gmsh format version {version} is not supported; save "
                            f"the mesh as version 4.1 or 2.2 (Gmsh: Mesh.MshFileVersion)")
    vtypes = _cell_type_of(src, fm.blocks, cell_type, per_body=per_body)
    dim = CELL_TYPES[vtypes[0]].dim
    kinds = {dim: "cell", dim - 1: "facet"}
    for name, gdim in dims.items():
        if name not in fm.element_sets:
            fm.empty_sets[name] = kinds.get(gdim, "node")
    return fm, vtypes


def _gmsh_header(raw: bytes, src: str):
    m = re.match(rb"\s*(?:\$Comments.*?\$EndComments\s*)*\$MeshFormat[ \t]*\r?\n"
                 rb"[ \t]*(\S+)[ \t]+(\S+)[ \t]+(\S+)[ \t]*\r?\n", raw, re.S)
    if m is None:
        raise MeshFileError(f"{src}: not a Gmsh mesh file (no $MeshFormat header at the "
                            f"start); check that the file is a .msh file saved by Gmsh")
    try:
        version, file_type, size_t = m.group(1).decode(), int(m.group(2)), int(m.group(3))
    except ValueError:
        raise MeshFileError(f"{src}, line 2: malformed $MeshFormat line "
                            f"{m.group(0).splitlines()[-1]!r}; expected "
                            f"'version file-type data-size'") from None
    if file_type not in (0, 1) or size_t not in (4, 8):
        raise MeshFileError(f"{src}, line 2: unexpected file type {file_type} or data size "
                            f"{size_t} in $MeshFormat; expected 0 or 1, and 4 or 8")
    if file_type == 1 and raw[m.end():m.end() + 4] != np.array(1, np.int32).tobytes():
        raise MeshFileError(f"{src}: binary Gmsh file of another byte order or damaged "
                            f"header; save it as ASCII (Gmsh: Mesh.Binary = 0)")
    return version, file_type == 0, size_t


def _gmsh_physical_names(text: bytes, src: str, first_line: int) -> dict:
    """``(dim, tag) -> name`` from the body of a $PhysicalNames section."""
    lines = text.decode("utf-8", errors="replace").splitlines()
    names, count = {}, None
    for number, line in enumerate(lines, start=first_line):
        if line.strip():
            if not line.strip().isdigit():
                raise MeshFileError(f"{src}, line {number}: expected the number of physical "
                                    f"names, found {line.strip()[:40]!r}; the file is damaged")
            count, lines = int(line), lines[number - first_line + 1:]
            first_line = number
            break
    for number, line in enumerate(lines, start=first_line + 1):
        if not line.strip():
            continue
        m = re.fullmatch(r'\s*(\d+)\s+(-?\d+)\s+"(.*)"\s*', line)
        if m is None:
            raise MeshFileError(f"{src}, line {number}: malformed physical name {line!r}; "
                                f"expected 'dimension tag \"name\"'")
        if (int(m.group(1)), int(m.group(2))) in names:
            raise MeshFileError(f"{src}, line {number}: physical group {m.group(1)} "
                                f"{m.group(2)} is named twice; give each group one name")
        names[(int(m.group(1)), int(m.group(2)))] = m.group(3)
    if count is not None and count != len(names):
        raise MeshFileError(f"{src}, line {first_line}: $PhysicalNames declares {count} names "
                            f"but holds {len(names)}; the file is damaged: save it again "
                            f"from Gmsh")
    return names


def _gmsh_sections(raw: bytes, src: str, is_ascii: bool, parsers: dict):
    """Walk the ``$Name ... $EndName`` sections, calling ``parsers[name](body, start)``.

    For ASCII files ``body`` is the section text; for binary ones the parser gets the
    whole file and returns the offset where its data ends.
    """
    pos = raw.find(b"$EndMeshFormat") + len(b"$EndMeshFormat")
    while True:
        while pos < len(raw) and raw[pos:pos + 1].isspace():
            pos += 1
        if pos >= len(raw):
            return
        eol = raw.find(b"\n", pos)
        eol = len(raw) if eol < 0 else eol
        header = raw[pos:eol].strip()
        if not header.startswith(b"$"):
            raise MeshFileError(f"{src}, line {_line_of(raw, pos)}: expected a section "
                                f"header such as $Nodes, found {header[:40]!r}; the file is "
                                f"damaged or not a Gmsh file")
        name = header[1:].decode("ascii", errors="replace")
        start = eol + 1
        parse = parsers.get(name)
        if parse is not None and not (is_ascii or name == "PhysicalNames"):
            start = parse(raw, start)
        end = raw.find(b"$End" + name.encode(), start)
        if end < 0:
            raise MeshFileError(f"{src}, line {_line_of(raw, pos)}: section ${name} is not "
                                f"closed by $End{name}: the file is truncated or damaged; "
                                f"save it again from Gmsh")
        if parse is not None and not (is_ascii or name == "PhysicalNames") \
                and raw[start:end].strip():
            raise MeshFileError(f"{src}, byte {start}: section ${name} holds "
                                f"{end - start} bytes after the data its counts declare; the "
                                f"file is damaged (data added or a count changed): save it "
                                f"again from Gmsh")
        if parse is not None and (is_ascii or name == "PhysicalNames"):
            parse(raw[start:end], start)
        pos = end + len(name) + 4


class _Stream:
    """Values of a Gmsh section, read in order: ASCII tokens or binary words."""

    def __init__(self, gmsh, data: bytes, start: int, section: str):
        self.src, self.raw, self.ascii = gmsh.src, gmsh.raw, gmsh.is_ascii
        self.size_t = np.dtype(f"u{gmsh.size_t}")
        self.section, self.start = section, start
        if self.ascii:
            lines = data.decode("ascii", errors="replace").splitlines()
            self.tokens = " ".join(lines).split()
            counts = [len(line.split()) for line in lines]
            self.token_line = np.repeat(np.arange(len(lines)), counts)
            self.line0 = _line_of(self.raw, start)
        self.pos = 0 if self.ascii else start

    def where(self) -> str:
        """File and line (ASCII) or byte offset (binary) of the next value."""
        if not self.ascii:
            return f"{self.src}, byte {self.pos}"
        k = min(self.pos, len(self.tokens) - 1)
        return f"{self.src}, line {self.line0 + (int(self.token_line[k]) if k >= 0 else 0)}"

    def _take(self, n: int, dtype) -> np.ndarray:
        n = int(n)
        if n < 0:
            raise MeshFileError(f"{self.where()}: negative count in ${self.section}; the "
                                f"file is damaged")
        if n == 0:
            return np.zeros(0, dtype=float if dtype == "d" else np.int64)
        if self.ascii:
            if n > len(self.tokens) - self.pos:
                raise self.truncated()
            chunk = self.tokens[self.pos:self.pos + n]
            try:
                values = np.array(chunk, dtype=float if dtype == "d" else np.int64)
            except (ValueError, OverflowError):
                raise MeshFileError(f"{self.where()}: unexpected value in ${self.section} "
                                    f"(expected {'numbers' if dtype == 'd' else 'integers'}); "
                                    f"the file is damaged") from None
            self.pos += n
            return values
        dt = {"i": np.dtype("i4"), "d": np.dtype("f8"), "z": self.size_t}[dtype]
        if n * dt.itemsize > len(self.raw) - self.pos:
            raise self.truncated()
        values = np.frombuffer(self.raw, dtype=dt, count=n, offset=self.pos)
        self.pos += n * dt.itemsize
        return values.astype(float if dtype == "d" else np.int64)

    def ints(self, n):
        return self._take(n, "i")

    def sizes(self, n):
        return self._take(n, "z")

    def doubles(self, n):
        return self._take(n, "d")

    def finish(self) -> int:
        """Check that every value of the section was read; the position after them."""
        if self.ascii and self.pos != len(self.tokens):
            extra = len(self.tokens) - self.pos
            raise MeshFileError(f"{self.where()}: section ${self.section} holds {extra} "
                                f"value(s) more than its counts declare; the file is damaged "
                                f"(a line duplicated or added, or a count changed): save it "
                                f"again from Gmsh")
        return self.pos

    def truncated(self) -> MeshFileError:
        return MeshFileError(f"{self.where()}: section ${self.section} ends before all its "
                             f"data was read: the file is truncated or damaged; save it again "
                             f"from Gmsh")


class _Gmsh4:
    """Reader of Gmsh 4.1 (ASCII and binary) and 4.0 (ASCII) files that keeps every
    physical group.

    meshio 5.3.5 keeps only the first physical tag of an entity unless it is named,
    merges names of different dimensions, fails on 4.1 files where some entities have no
    physical group, and reads Gmsh's version "4" (format 4.0) as 4.1; hence this reader.
    """

    def __init__(self, raw: bytes, src: str, is_ascii: bool, size_t: int, v41: bool):
        self.raw, self.src, self.is_ascii, self.size_t = raw, src, is_ascii, size_t
        self.v41 = v41
        self.names, self.entity_groups = {}, {}
        self.node_tags, self.node_xyz, self.blocks = [], [], []
        self.saw_nodes = self.saw_elements = False

    def file_mesh(self):
        _gmsh_sections(self.raw, self.src, self.is_ascii, {
            "PhysicalNames": lambda body, start: self.names.update(
                _gmsh_physical_names(body, self.src, _line_of(self.raw, start))),
            "Entities": self._entities, "Nodes": self._nodes, "Elements": self._elements})
        if not self.saw_nodes or not self.saw_elements:
            raise MeshFileError(f"{self.src}: no ${'Nodes' if not self.saw_nodes else 'Elements'}"
                                f" section: the file is truncated or holds no mesh; mesh the "
                                f"geometry in Gmsh before saving")
        tags = np.concatenate(self.node_tags) if self.node_tags else np.zeros(0, np.int64)
        points = np.concatenate(self.node_xyz) if self.node_xyz else np.zeros((0, 3))
        lookup = _IdLookup(tags)
        if lookup.duplicate is not None:
            raise MeshFileError(f"{self.src}: node tag {tags[lookup.duplicate]} is defined "
                                f"twice in $Nodes; the file is damaged")
        tags, points = tags[lookup.order], points[lookup.order]     # nodes in tag order
        lookup = _IdLookup(tags)
        every_element = np.concatenate([b[5] for b in self.blocks] + [np.zeros(0, np.int64)])
        twice = _IdLookup(every_element).duplicate
        if twice is not None:
            raise MeshFileError(f"{self.src}: element tag {every_element[twice]} is defined "
                                f"twice in $Elements; the file is damaged: give every "
                                f"element a distinct tag")
        blocks, element_sets, element_ids = [], {}, []
        first = 0
        for dim, entity, etype, conn_tags, where, ids in self.blocks:
            conn = lookup(conn_tags)
            if (conn < 0).any():
                bad = conn_tags[conn < 0][0]
                raise MeshFileError(f"{where}: an element refers to node tag {bad}, which is "
                                    f"not in $Nodes; the file is damaged")
            order = _gmsh_to_meshio(etype)
            conn = conn if order is None else conn[:, order]
            blocks.append((etype, _GMSH_DIM[etype], conn, True))
            element_ids.append(ids)
            for group in self.entity_groups.get((dim, entity), ()):
                name = self.names.get((dim, group), str(group))
                element_sets.setdefault(name, []).append(first + np.arange(len(conn)))
            first += len(conn)
        fm = _FileMesh(self.src, points, tags, blocks, element_sets=element_sets,
                       element_ids=element_ids)
        return fm, {name: dim for (dim, _), name in self.names.items()}

    def _stream(self, data, start, section):
        return _Stream(self, data, start, section)

    def _entities(self, data, start):
        s = self._stream(data, start, "Entities")
        counts = s.sizes(4)
        for dim in range(4):
            for _ in range(int(counts[dim])):
                tag = int(s.ints(1)[0])
                s.doubles(3 if dim == 0 and self.v41 else 6)
                groups = s.ints(int(s.sizes(1)[0]))
                if dim > 0:
                    s.ints(int(s.sizes(1)[0]))   # bounding entities
                self.entity_groups[(dim, tag)] = tuple(int(g) for g in groups)
        return s.finish()

    def _nodes(self, data, start):
        s = self._stream(data, start, "Nodes")
        header_at = s.where()
        header = s.sizes(4 if self.v41 else 2)
        n_blocks = int(header[0])
        for _ in range(n_blocks):
            where = s.where()
            first, second, parametric = (int(v) for v in s.ints(3))
            dim = first if self.v41 else second         # 4.0: entity tag, then dimension
            if not 0 <= dim <= 3 or parametric not in (0, 1):
                raise MeshFileError(f"{where}: node block of dimension {dim} with parametric "
                                    f"flag {parametric}; the file is damaged")
            n = int(s.sizes(1)[0])
            width = 3 + (dim if parametric else 0)
            if self.v41:                                # tags, then coordinates
                self.node_tags.append(s.sizes(n))
                self.node_xyz.append(s.doubles(n * width).reshape(n, width)[:, :3])
            else:                                       # tag x y z per node (ASCII)
                table = s.doubles(n * (1 + width)).reshape(n, 1 + width)
                if not np.all(np.abs(table[:, 0]) < _MAX_ID) or np.any(table[:, 0] % 1):
                    raise MeshFileError(f"{where}: node tags that are not integers; the "
                                        f"file is damaged")
                self.node_tags.append(table[:, 0].astype(np.int64))
                self.node_xyz.append(table[:, 1:4])
        tags = np.concatenate(self.node_tags) if self.node_tags else np.zeros(0, np.int64)
        self._check_totals(header_at, "node", header, tags)
        self.saw_nodes = True
        return s.finish()

    def _check_totals(self, where, what, header, tags):
        """The header's count (and in 4.1 the smallest and largest tag) against the
        blocks."""
        if int(header[1]) != len(tags):
            raise MeshFileError(f"{where}: the header declares {int(header[1])} {what}s but "
                                f"its blocks hold {len(tags)}; the file is damaged: save it "
                                f"again from Gmsh")
        if self.v41 and len(tags) and (tags.min() < header[2] or tags.max() > header[3]):
            raise MeshFileError(f"{where}: {what} tags run from {tags.min()} to {tags.max()}, "
                                f"outside the declared range {int(header[2])}.."
                                f"{int(header[3])}; the file is damaged: save it again "
                                f"from Gmsh")

    def _elements(self, data, start):
        s = self._stream(data, start, "Elements")
        header_at = s.where()
        header = s.sizes(4 if self.v41 else 2)
        n_blocks = int(header[0])
        for _ in range(n_blocks):
            where = s.where()
            first, second, number = (int(v) for v in s.ints(3))
            dim, entity = (first, second) if self.v41 else (second, first)
            if number not in _GMSH_TYPES:
                raise MeshFileError(f"{where}: unknown Gmsh element type number {number}; "
                                    f"qsma reads the types {sorted(_GMSH_TYPES)}")
            etype, nv, _ = _GMSH_TYPES[number]
            n = int(s.sizes(1)[0])
            rows = (s.sizes if self.v41 else s.ints)(n * (1 + nv)).reshape(n, 1 + nv)
            self.blocks.append((dim, entity, etype, rows[:, 1:], where, rows[:, 0]))
        self._check_totals(header_at, "element", header,
                           np.concatenate([b[5] for b in self.blocks] + [np.zeros(0, int)]))
        self.saw_elements = True
        return s.finish()


def _gmsh22_binary_end(raw: bytes, start: int, src: str, section: str) -> int:
    """Offset just past the data of a binary Gmsh 2.2 $Nodes or $Elements section: a
    count line, then per node ``int tag, 3 doubles``, or element groups ``int type,
    number, number of tags`` each followed by ``number x (1 + tags + nodes)`` ints."""
    eol = raw.find(b"\n", start)
    line = raw[start:eol if eol >= 0 else len(raw)].strip()
    if not line.isdigit():
        raise MeshFileError(f"{src}, byte {start}: ${section} does not start with its "
                            f"count; the file is damaged: save it again from Gmsh")
    count, pos = int(line), eol + 1
    if section == "Nodes":
        pos += count * (4 + 3 * 8)
        if pos <= len(raw):
            tags = np.frombuffer(raw, np.dtype([("tag", np.int32), ("xyz", np.float64, 3)]),
                                 count, eol + 1)["tag"]
            twice = _IdLookup(tags.astype(np.int64)).duplicate
            if twice is not None:
                raise MeshFileError(f"{src}, byte {eol + 1 + 28 * twice}: node tag "
                                    f"{tags[twice]} is defined twice; the file is damaged: "
                                    f"give every node a distinct tag")
    seen = 0
    while section == "Elements" and seen < count:
        if pos + 12 > len(raw):
            break
        etype, follow, n_tags = (int(v) for v in np.frombuffer(raw, np.int32, 3, pos))
        if etype not in _GMSH_TYPES or follow <= 0 or n_tags < 0 or seen + follow > count:
            raise MeshFileError(f"{src}, byte {pos}: element group header ({etype}, "
                                f"{follow}, {n_tags}) does not fit the {count} elements of "
                                f"$Elements; the file is damaged: save it again from Gmsh")
        pos += 12 + follow * (1 + n_tags + _GMSH_TYPES[etype][1]) * 4
        seen += follow
    if pos > len(raw) or (section == "Elements" and seen < count):
        raise MeshFileError(f"{src}, byte {start}: section ${section} ends before its "
                            f"{count} entries: the file is truncated or damaged; save it "
                            f"again from Gmsh")
    return pos


def _gmsh22_element_width(tokens: list) -> int:
    """Values on a Gmsh 2.2 element line: tag, type, number of tags, tags, nodes."""
    try:
        etype, n_tags = int(tokens[1]), int(tokens[2])
    except (ValueError, IndexError):
        return -1
    return 3 + n_tags + _GMSH_TYPES[etype][1] if etype in _GMSH_TYPES else len(tokens)


def _gmsh22_rows(body: bytes, first_line: int, src: str, section: str, width) -> int:
    """Check a Gmsh 2.2 ASCII $Nodes or $Elements body: a count, then that many lines of
    ``width(tokens)`` values each; return the count."""
    lines = [(k, line.split()) for k, line in enumerate(
        body.decode("ascii", errors="replace").splitlines(), start=first_line)]
    lines = [(k, t) for k, t in lines if t]
    if not lines or len(lines[0][1]) != 1 or not lines[0][1][0].isdigit():
        at = lines[0][0] if lines else first_line
        raise MeshFileError(f"{src}, line {at}: ${section} does not start with its count; "
                            f"the file is damaged: save it again from Gmsh")
    count = int(lines[0][1][0])
    if len(lines) - 1 != count:
        raise MeshFileError(f"{src}, line {lines[0][0]}: ${section} declares {count} lines "
                            f"but holds {len(lines) - 1}; the file is damaged (a line "
                            f"duplicated, added or deleted): save it again from Gmsh")
    seen = {}
    for k, tokens in lines[1:]:
        if len(tokens) != width(tokens):
            raise MeshFileError(f"{src}, line {k}: {len(tokens)} values on a ${section} "
                                f"line, expected {width(tokens)}; the file is damaged: save "
                                f"it again from Gmsh")
        if section == "Nodes" and seen.setdefault(tokens[0], k) != k:
            raise MeshFileError(f"{src}, line {k}: node tag {tokens[0]} is defined twice "
                                f"(first on line {seen[tokens[0]]}); the file is damaged: "
                                f"give every node a distinct tag")
    return count


def _gmsh_with_meshio(path: Path, raw: bytes, src: str, version: str, is_ascii: bool):
    """Gmsh 2.x files through meshio, with names and checks of our own."""
    import meshio

    names = {}

    def read_names(body, start):
        names.update(_gmsh_physical_names(body, src, _line_of(raw, start)))

    declared = {}

    def count_rows(section, row_width):
        def parse(body, start):
            declared[section] = _gmsh22_rows(body, _line_of(raw, start), src, section,
                                             row_width)
        return parse

    parsers = {"PhysicalNames": read_names}
    # meshio reads by the declared counts and ignores what is left over: count ourselves
    if is_ascii:
        parsers.update(Nodes=count_rows("Nodes", lambda t: 4),
                       Elements=count_rows("Elements", _gmsh22_element_width))
    else:
        parsers.update(Nodes=lambda raw_, start: _gmsh22_binary_end(raw_, start, src, "Nodes"),
                       Elements=lambda raw_, start: _gmsh22_binary_end(raw_, start, src,
                                                                       "Elements"))
    _gmsh_sections(raw, src, is_ascii, parsers)
    notes = io.StringIO()
    try:
        # meshio prints its warnings to stderr (rich); keep them to report them here
        with contextlib.redirect_stderr(notes), warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            m = meshio.gmsh.read(path)
    except Exception as exc:  # meshio raises ReadError, ValueError, KeyError, IndexError...
        raise MeshFileError(f"{src}: cannot be read as a Gmsh {version} file "
                            f"({type(exc).__name__}: {exc}); check that the file is complete "
                            f"and saved by Gmsh") from exc
    problems = [str(w.message) for w in caught
                if not issubclass(w.category, (DeprecationWarning, FutureWarning))
                or "could not be read" in str(w.message)]
    problems += [p.strip() for p in notes.getvalue().split("\n")     # partition tags: fine
                 if p.strip() and "tag data that couldn't be processed" not in p]
    if problems:
        raise MeshFileError(f"{src}: the Gmsh reader reported: {'; '.join(problems)}; the "
                            f"file is damaged or uses features qsma does not read")
    n = len(m.points)
    physical = m.cell_data.get("gmsh:physical")
    blocks, element_sets = [], {}
    first = 0
    for k, block in enumerate(m.cells):
        conn = np.asarray(block.data, dtype=np.int64).reshape(len(block.data), -1)
        if conn.size and (conn.min() < 0 or conn.max() >= n):
            raise MeshFileError(f"{src}: {block.type} elements refer to nodes missing from "
                                f"$Nodes; the file is damaged")
        blocks.append((block.type, block.dim, conn, True))
        tags = None if physical is None else np.asarray(physical[k])
        if tags is not None and len(tags) != len(conn):
            raise MeshFileError(f"{src}: some elements have no physical tag; save the mesh "
                                f"with physical and elementary tags for every element")
        for tag in np.unique(tags) if tags is not None else ():
            if tag > 0:
                name = names.get((block.dim, int(tag)), str(int(tag)))
                element_sets.setdefault(name, []).append(first + np.flatnonzero(tags == tag))
        first += len(conn)
    labels = np.arange(1, n + 1)
    fm = _FileMesh(src, np.asarray(m.points, dtype=float), labels, blocks,
                   element_sets=element_sets)
    return fm, {name: dim for (dim, _), name in names.items()}
