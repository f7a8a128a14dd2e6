"""The tied surfaces of a deck, read as tied interfaces (``tied = true``).

Two cards tie surfaces: ``*TIE`` (data line: slave surface, master surface) and a
``*CONTACT PAIR`` whose ``*SURFACE INTERACTION`` has ``*SURFACE BEHAVIOR,
PRESSURE-OVERCLOSURE=TIED``. In both the slave side follows the master surface: no
separation and no slip. CalculiX builds the first from multipoint constraints between
each slave node and the master face it faces (the slave nodes moved onto the master
unless ``ADJUST=NO``), the second from penalty springs: normal ones of the slope on
the ``*SURFACE BEHAVIOR`` data line, in tension as in compression, and tangential
ones of the stick slope of ``*FRICTION`` (its friction coefficient is irrelevant).
qsma ties both rigidly (docs/theory.md, "Tied interfaces"): the penalty springs are
not modelled, so a stiff penalty gives qsma's answer and a soft one a softer
structure. A ``*TIE`` with ``CYCLIC SYMMETRY`` or ``MULTISTAGE`` joins the sectors of a
cyclic model, which qsma does not model.
"""
from __future__ import annotations

from .records import DeckInterface, _number, _row_where, _rows_of, _spelling, _where

#: ``*TIE`` parameters that make it something else than tied surfaces.
_CYCLIC = ("CYCLIC SYMMETRY", "MULTISTAGE")


def is_tied(record) -> bool:
    """Whether a ``*SURFACE INTERACTION`` record ties its surfaces (``TIED``)."""
    return record is not None and record.pressure_overclosure == "TIED"


class DeckTies:
    """The ``*TIE`` cards and the ``TIED`` contact pairs of a deck reader."""

    def _tied_table(self, names, bodies, s, m, slave, master):
        """The ``[[interfaces]]`` table of slave surface ``slave`` of body ``s`` tied to
        master surface ``master`` of body ``m``."""
        return {"body1": names[m], "set1": self._find(bodies[m]["mesh"], master, ("facet",)),
                "body2": names[s], "set2": self._find(bodies[s]["mesh"], slave, ("facet",)),
                "coupling": "auto", "slave": names[s], "tied": True}

    def _tied_pair(self, names, bodies, sm, surfaces, record, w):
        """``(table, comment)`` of a TIED ``*CONTACT PAIR`` row (``sm``: the slave and
        master bodies, ``surfaces``: the slave and master surfaces), recorded."""
        (s, m), (slave, master) = sm, surfaces
        self._deck_interfaces.append(DeckInterface(slave, master, names[s], names[m],
                                                   record, w))
        return (self._tied_table(names, bodies, s, m, slave, master),
                f"*CONTACT PAIR, {w}: master {master}, slave {slave}; "
                f"PRESSURE-OVERCLOSURE=TIED of interaction {record.name!r}: tied")

    def _note_tied_interaction(self, card, name):
        self.note(_where(card), f"*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=TIED of "
                  f"interaction {name!r}: its contact pairs are tied interfaces (no "
                  f"separation, no slip), tied rigidly: CalculiX's penalty springs are not "
                  f"modelled", "a stiff penalty gives the same structure", False)

    def _note_tied_only(self):
        self.note(self.path.name, "every interface is tied (*TIE, or TIED contact): no "
                  "interface can open or slip, the structure is linear and every level "
                  "elastic (f = f0, zeta = 0)", "for a QSMA of a joint give its contact "
                  "surfaces as a *CONTACT PAIR with *FRICTION", False)

    def _ties(self, bodies, seen):
        """``[(table, comment)]`` of every ``*TIE`` of the deck (``seen``: the surface
        pairs already read, updated)."""
        out = []
        names = [b["table"]["name"] for b in bodies]
        cyclic = {str(c.params.get("TIE", "")).upper() for c in self.cards
                  if c.keyword == "CYCLIC SYMMETRY MODEL"}
        for card in self.cards:
            if card.keyword != "TIE":
                continue
            name = card.params.get("NAME")
            label = f"*TIE, NAME={name}" if isinstance(name, str) else "*TIE"
            kind = next((k for k in _CYCLIC if k in card.params), None)
            if kind or (isinstance(name, str) and name.upper() in cyclic):
                self.note(_where(card), f"{label}, {kind or 'of a *CYCLIC SYMMETRY MODEL'}",
                          "qsma models the whole structure, no cyclic symmetry: mesh every "
                          "sector", True)
                continue
            tol = self._position_tolerance(card, label)
            if str(card.params.get("ADJUST", "YES")).upper() != "NO":
                self.note(_where(card), f"{label}: the slave nodes are not moved onto the "
                          f"master surface (CalculiX adjusts them unless ADJUST=NO)",
                          "qsma ties the surfaces where they are meshed; they may lie at most "
                          "the position tolerance apart", False)
            rows = list(_rows_of(card))
            for where, tokens, _ in rows[:1]:
                entry = self._tie_row(bodies, names, seen, _row_where(where), tokens, label)
                if entry is None:
                    continue
                if tol is not None:
                    entry[0]["position_tol"] = tol
                out.append(entry)
            if len(rows) > 1:
                self.note(_where(card), f"{label} has more than one data line",
                          "a *TIE ties one slave surface to one master surface: give one "
                          "*TIE per pair of surfaces", True)
        return out

    def _position_tolerance(self, card, label):
        """The ``POSITION TOLERANCE`` of a ``*TIE`` (None: absent, or below 1e-10, which
        CalculiX reads as its default)."""
        value = card.params.get("POSITION TOLERANCE")
        if value is None or value is True:
            return None
        tol = _number(str(value), card.where, f"the position tolerance of {label}")
        return tol if tol >= 1e-10 else None

    def _tie_row(self, bodies, names, seen, w, tokens, label):
        """``(table, comment)`` of a ``*TIE`` data line, or None (a note says why)."""
        if len(tokens) < 2 or not tokens[1]:
            self.note(w, f"{label} without its master surface", "give the slave and the "
                      "master surface on the data line", True)
            return None
        slave, master = (_spelling(self.asm, t) for t in tokens[:2])
        owners = [[k for k, b in enumerate(bodies)
                   if self._find(b["mesh"], surf, kinds=("facet",)) is not None]
                  for surf in (slave, master)]
        if len(owners[0]) != 1 or len(owners[1]) != 1:
            which = slave if len(owners[0]) != 1 else master
            self.note(w, f"{label}: surface {which!r} is not made of element faces of one "
                      f"body", "a tied surface is made of element faces of one body: give "
                      "it as a *SURFACE, TYPE=ELEMENT of faces", True)
            return None
        s, m = owners[0][0], owners[1][0]
        if s == m:
            self.note(w, f"{label}: {slave!r} and {master!r} lie on one body",
                      "qsma's interfaces join two bodies: mesh the part as one", True)
            return None
        key = frozenset(((s, slave), (m, master)))
        if key in seen:
            return None
        seen.add(key)
        return (self._tied_table(names, bodies, s, m, slave, master),
                f"{label}, {w}: slave {slave} tied to master {master}")
