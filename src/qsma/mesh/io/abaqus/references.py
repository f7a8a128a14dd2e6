"""The sets and ids that the supports and loads of an ``.inp`` file name, made sets of
the mesh so that a deck's ``*BOUNDARY``, ``*CLOAD`` and ``*DLOAD`` rows find them
(:mod:`qsma.deck` reads the rows themselves)."""
from __future__ import annotations

import re

import numpy as np

_ID = re.compile(r"[+-]?\d{1,18}")


def name_in_row(reader, kind: str, tokens):
    """Remember the set a support or load row names (``Set``, and ``Set`` of
    ``Instance.Set`` where instances are not made flat)."""
    if tokens and tokens[0] and not _ID.fullmatch(tokens[0]):
        key = tokens[0].upper()
        reader.named[kind].update({key, key.rsplit(".", 1)[-1]})


def named_internal_sets(reader, fm, nodes, elsets, index):
    """The internal sets a support or load names, exposed; the other internal sets stay
    hidden. Abaqus/CAE writes each picked region as ``*NSET, NSET=_PickedSet5,
    INTERNAL`` (at assembly level, ``INSTANCE=``) and names it in the ``*BOUNDARY`` or
    ``*CLOAD`` rows of its supports and loads."""
    for key in reader.named["NSET"]:
        s = reader.sets["NSET"].get(key)
        if s is not None and s.internal and s.name not in fm.node_sets:
            fm.node_sets[s.name] = [reader._node_indices(s, nodes, elsets, index)]
    for key in reader.named["ELSET"]:
        s = reader.sets["ELSET"].get(key)
        if s is not None and s.internal and len(elsets[key]) \
                and s.name not in fm.element_sets:
            fm.element_sets[s.name] = [elsets[key]]


def load_id_sets(reader, fm, nodes, elements):
    """A node (element) that a *CLOAD (*DLOAD) row names by its id gets a node set
    ``_N<id>`` (a cell set ``_E<id>``) of its own, so that a configuration can name it
    (qsma.deck)."""
    is_cell = np.concatenate([np.full(len(conn), bool(cell))
                              for _, _, conn, cell in fm.blocks])
    for kind, lookup, sets, prefix in (("NSET", nodes, fm.node_sets, "_N"),
                                       ("ELSET", elements, fm.element_sets, "_E")):
        for ident in sorted(reader.load_ids[kind]):
            idx = lookup(np.array([ident]))
            if idx[0] >= 0 and (kind == "NSET" or is_cell[idx[0]]):
                sets.setdefault(f"{prefix}{ident}", []).append(idx)
