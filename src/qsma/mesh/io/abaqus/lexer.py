"""The words of an Abaqus / CalculiX ``.inp`` file: keyword cards with their data lines
(``*INCLUDE`` expanded, continued keyword lines joined), fields, numbers, and the
meshio type of an Abaqus element name. Shared by the mesh reader, the instances of an
assembly and the deck reader."""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ....errors import MeshFileError
from ...celltypes import abaqus_element_types
from ..common import _MAX_ID, _line_of, _read_bytes

#: Abaqus/CalculiX element name (without the letters R, I, H, T of its variants) ->
#: meshio type, from the cell type records
ABAQUS_ELEMENT_TYPES = abaqus_element_types()
_BINARY_BYTES = re.compile(rb"[\x00-\x08\x0b\x0e-\x1f\x7f]")
_PLAIN_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_\-]*")


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


def _is_continuum(abaqus_type: str) -> bool:
    return abaqus_type.upper().startswith(("C3D", "CPE", "CPS", "CAX"))


#: element types that are no part of a mesh (one- and two-node connectors, couplings,
#: point masses): the mesh reader skips them (leaving their ids out of element sets),
#: the deck reader (:mod:`qsma.deck`) reads a bolt's and names the others
CONNECTOR_TYPES = frozenset({"DCOUP3D", "SPRINGA", "SPRING1", "SPRING2", "DASHPOTA",
                             "MASS", "CONN3D2", "CONN2D2"})


def _connector_ids(card: _Card) -> np.ndarray:
    """The element ids of an ``*ELEMENT`` card of connectors (rows of other than an
    integer id left out)."""
    return np.array([int(t[0]) for _, t, _ in _rows(card)
                     if t and t[0].strip().lstrip("-").isdigit()], dtype=np.int64)
