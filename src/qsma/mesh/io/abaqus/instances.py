r"""Abaqus parts and instances made flat: each ``*INSTANCE`` of a ``*PART`` becomes the
part's nodes, elements and sets with ids moved past those of the instances before it,
names prefixed ``<instance>.``, coordinates placed, and a cell set named after the
instance holding its elements (a body of :func:`qsma.mesh.io.read_assembly`).

Placement (Abaqus keyword reference, ``*INSTANCE``): the first data line is a
translation :math:`t`, the optional second line a rotation by the angle
:math:`\theta` (degrees) about the axis through the points :math:`a` and :math:`b`,
applied after the translation:

.. math:: x' = a + R_{\hat e}(\theta) (x + t - a), \qquad \hat e = (b - a) / |b - a|

Assembly-level ``*NSET`` / ``*ELSET`` with ``INSTANCE=`` are moved to that instance's
ids; other assembly-level node and element definitions (reference points, connectors)
are not the mesh and are left out, as :func:`qsma.mesh.io.read_mesh` does. The cards
of a part that are not mesh (sections, materials) are dropped with the part.
"""
from __future__ import annotations

import re

import numpy as np

from ...celltypes import TYPES
from .lexer import _abaqus_cell_type, _abaqus_float, _inp_error, _rows

_INT = re.compile(r"[+-]?\d{1,18}")


def needs_flattening(cards) -> bool:
    """Several parts or instances, or a placed instance (what read_mesh refuses)."""
    parts = sum(c.keyword == "PART" for c in cards)
    insts = [c for c in cards if c.keyword == "INSTANCE"]
    return parts > 1 or len(insts) > 1 or any(placement(c) is not None for c in insts)


def flatten_instances(cards, card_type) -> list:
    """The cards of a deck with parts and instances, made flat (module docstring).
    ``card_type`` is the reader's card class (``keyword, params, where, data``)."""
    parts, out, offsets = {}, [], {}
    current, scope, skipping = None, "model", False
    node_off = elem_off = 0
    for card in cards:
        kw = card.keyword
        if kw == "PART":
            current = (str(card.params.get("NAME", "")), [])
            continue
        if kw == "END PART":
            parts[current[0].upper()] = current
            current = None
            continue
        if current is not None:
            current[1].append(card)
            continue
        if kw in ("ASSEMBLY", "END ASSEMBLY"):
            scope = "assembly" if kw == "ASSEMBLY" else "model"
            continue
        if kw == "INSTANCE":
            name = str(card.params.get("NAME", ""))
            part = parts.get(str(card.params.get("PART", "")).upper())
            if part is None:
                raise _inp_error(card.where, f"instance {name!r} of part "
                                 f"{card.params.get('PART')!r}, which no *PART defines",
                                 "define the part before the assembly")
            moved, n_nodes, n_elems = _instance(part[1], name, node_off, elem_off,
                                                placement(card), card_type)
            out += moved
            offsets[name.upper()] = (node_off, elem_off, name)
            node_off += n_nodes
            elem_off += n_elems
            skipping = True
            continue
        if kw == "END INSTANCE":
            skipping = False
            continue
        if skipping:
            continue
        if scope == "assembly":
            moved = _assembly_card(card, offsets, card_type)
            if moved is not None:
                out.append(moved)
            continue
        out.append(card)
    return out


def check_instances_closed(cards):
    """Refuse an ``*INSTANCE`` not closed by ``*END INSTANCE`` before the next
    ``*INSTANCE``, ``*END ASSEMBLY``, ``*PART`` or the end of the file: the cards up to
    there would be taken as the instance's (and dropped with it)."""
    instance = None
    for card in list(cards) + [None]:
        kw = None if card is None else card.keyword
        if instance is not None and kw in (None, "INSTANCE", "END ASSEMBLY", "ASSEMBLY",
                                           "PART", "END PART"):
            before = "the end of the file" if card is None else \
                f"*{card.keyword} (line {card.where[1]})"
            raise _inp_error(instance.where, f"*INSTANCE {instance.params.get('NAME')!r} "
                             f"has no *END INSTANCE before {before}",
                             "close every instance with *END INSTANCE")
        if kw == "INSTANCE":
            instance = card
        elif kw == "END INSTANCE":
            instance = None


#: Values of the data lines of an ``*INSTANCE``: the translation, then the rotation.
_PLACEMENT_LINES = (("translation", "x, y, z", 3),
                    ("rotation", "ax, ay, az, bx, by, bz, angle in degrees", 7))


def placement(card):
    """``(t, a, b, angle)`` of an ``*INSTANCE`` card, or None when it is not moved.
    Refused: a line that is not numbers, one with more values than it holds, a third
    line, and a rotation about an axis from a point to itself (it would be ignored)."""
    rows = []
    for k, (where, tokens, text) in enumerate(_rows(card)):
        if k >= len(_PLACEMENT_LINES):
            raise _inp_error(where, f"a third data line {text!r} in *INSTANCE",
                             "give the translation on the first line and the rotation on "
                             "the second, nothing more")
        what, form, most = _PLACEMENT_LINES[k]
        try:
            values = [_abaqus_float(t) for t in tokens if t.strip()]
        except ValueError:
            values = None
        if values is None or not np.all(np.isfinite(values)):
            raise _inp_error(where, f"cannot read the {what} line {text!r} of *INSTANCE",
                             f"expected numbers: '{form}'")
        if len(values) > most:
            raise _inp_error(where, f"the {what} line {text!r} of *INSTANCE has "
                             f"{len(values)} values, it holds at most {most}",
                             f"give '{form}'")
        rows.append(((values + [0.0] * most)[:most], where))
    t = np.array(rows[0][0]) if rows else np.zeros(3)
    rot = rows[1][0] if len(rows) > 1 else [0.0] * 7
    a, b = np.array(rot[:3]), np.array(rot[3:6])
    if rot[6] != 0.0 and not np.linalg.norm(b - a):
        raise _inp_error(rows[1][1], f"the rotation of *INSTANCE by {rot[6]:g} degrees is "
                         f"about an axis from a point to itself (a = b = {a.tolist()})",
                         "give two distinct points a and b on the rotation axis")
    if not t.any() and rot[6] == 0.0:
        return None
    return t, a, b, rot[6]


def _place(xyz, placement):
    if placement is None:
        return xyz
    t, a, b, angle = placement
    x = xyz + t
    axis = b - a
    if angle == 0.0:
        return x
    e = axis / np.linalg.norm(axis)
    th = np.deg2rad(angle)
    K = np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])
    R = np.eye(3) + np.sin(th) * K + (1 - np.cos(th)) * K @ K        # Rodrigues
    return a + (x - a) @ R.T


def _instance(cards, name, node_off, elem_off, placement, card_type):
    """The part's mesh cards for one instance; ``(cards, node id span, element id span)``."""
    prefix = f"{name}."
    out, elem_ids = [], []
    n_nodes = max((int(tokens[0]) for c in cards if c.keyword == "NODE"
                   for _, tokens, _ in _rows(c) if tokens and _INT.fullmatch(tokens[0])),
                  default=0)
    for c in cards:
        params = dict(c.params)
        for key in ("NSET", "ELSET", "NAME"):
            if isinstance(params.get(key), str):
                params[key] = prefix + params[key]
        if c.keyword == "NODE":
            data = []
            for where, tokens, _ in _rows(c):
                xyz = np.array(([_abaqus_float(t) for t in tokens[1:4]] + [0.0] * 3)[:3])
                x = _place(xyz, placement)
                data.append((*where, ", ".join([str(int(tokens[0]) + node_off)]
                                               + [repr(float(v)) for v in x])))
            out.append(card_type("NODE", params, c.where, data))
        elif c.keyword == "ELEMENT":
            cell = _abaqus_cell_type(str(c.params.get("TYPE", "")))
            nv = TYPES[cell].n_nodes if cell in TYPES else 0
            data, k = [], 0
            for where, tokens, _ in _rows(c):
                moved = []
                for t in tokens:
                    if k % (nv + 1) == 0:
                        elem_ids.append(int(t) + elem_off)
                        moved.append(str(int(t) + elem_off))
                    else:
                        moved.append(str(int(t) + node_off))
                    k += 1
                data.append((*where, ", ".join(moved) + ("," if k % (nv + 1) else "")))
            out.append(card_type("ELEMENT", params, c.where, data))
        elif c.keyword in ("NSET", "ELSET"):
            off = node_off if c.keyword == "NSET" else elem_off
            out.append(card_type(c.keyword, params, c.where,
                                 _moved_ids(c, off, prefix, c.params.get("GENERATE") is True)))
        elif c.keyword == "SURFACE":
            node = str(c.params.get("TYPE", "ELEMENT")).upper() == "NODE"
            data = []
            for where, tokens, _ in _rows(c):
                ref = tokens[0]
                ref = str(int(ref) + (node_off if node else elem_off)) \
                    if _INT.fullmatch(ref) else prefix + ref
                data.append((*where, ", ".join([ref] + tokens[1:])))
            out.append(card_type("SURFACE", params, c.where, data))
    n_elems = max(elem_ids, default=elem_off) - elem_off
    ids = [str(i) for i in elem_ids]
    lines = [(c.where[0], c.where[1], ", ".join(ids[k:k + 16])) for k in range(0, len(ids), 16)]
    if lines:
        out.append(card_type("ELSET", {"ELSET": name}, cards[0].where, lines))
    return out, n_nodes, n_elems


def _moved_ids(card, off, prefix, generate):
    """Set data lines with ids moved by ``off`` and set names prefixed."""
    data = []
    for where, tokens, _ in _rows(card):
        if generate:
            vals = [int(t) for t in tokens if t]
            vals[0] += off
            vals[1] += off
            data.append((*where, ", ".join(map(str, vals))))
            continue
        moved = [str(int(t) + off) if _INT.fullmatch(t) else (prefix + t if t else t)
                 for t in tokens]
        data.append((*where, ", ".join(moved)))
    return data


def _assembly_card(card, offsets, card_type):
    """An assembly-level card in flat form, or None when it is not part of the mesh."""
    if card.keyword in ("NSET", "ELSET"):
        inst = card.params.get("INSTANCE")
        if not isinstance(inst, str) or inst.upper() not in offsets:
            return None                     # e.g. the node set of a reference point
        node_off, elem_off, name = offsets[inst.upper()]
        params = {k: v for k, v in card.params.items() if k != "INSTANCE"}
        off = node_off if card.keyword == "NSET" else elem_off
        return card_type(card.keyword, params, card.where,
                         _moved_ids(card, off, f"{name}.", params.get("GENERATE") is True))
    if card.keyword in ("NODE", "ELEMENT"):
        return None                         # reference points, connectors
    return card
