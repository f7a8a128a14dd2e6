"""Abaqus' connector bolts, read as ``[[bolts]]`` tables.

In Abaqus a bolt is often an ``AXIAL`` connector (``CONN3D2``) between the reference
nodes of two distributing couplings on the washer faces: ``*CONNECTOR SECTION`` names
the connection type and its ``BEHAVIOR``, whose ``*CONNECTOR ELASTICITY, COMPONENT=1``
is the bolt's axial stiffness, and a ``*CONNECTOR LOAD`` on component 1 in the first
``*STATIC`` step tightens it. That is qsma's bolt (:class:`qsma.model.Bolt`): the
pretension, then the bolt held at its tightened length by its stiffness.

An ``AXIAL`` connector's component 1 is the change of distance between its nodes and
its force acts along the line joining them; the load tightening a bolt is its
tension, whichever sign the deck gives it (a bolt pushing its washers apart is no
bolt), so the pretension is the magnitude of the load, and the note says so. A
connector whose length is then held (``*CONNECTOR MOTION``) or whose elasticity is
rigid has no stiffness qsma can take: refused with the fix.
"""
from __future__ import annotations

from .records import _number, _row_where, _rows_of, _where

#: The fix named by every refusal of a connector bolt.
_PATTERN = ("an Abaqus connector bolt is a CONN3D2 element between the reference nodes of "
            "two distributing couplings on washer faces of two bodies, *CONNECTOR SECTION "
            "with AXIAL and a BEHAVIOR whose *CONNECTOR ELASTICITY, COMPONENT=1 gives the "
            "bolt's stiffness, and *CONNECTOR LOAD on component 1 in the first *STATIC step "
            "(docs/mesh-io.md)")


class ConnectorBolts:
    """The part of :class:`qsma.deck.bolts.DeckBolts` that reads connector bolts."""

    def _connector_bolts(self, bodies, preload, start) -> list:
        """``[(table, comment)]`` of the deck's connector bolts; notes for what is no
        bolt (numbered from ``start`` where the deck names none)."""
        out = []
        for card in self.cards:
            if card.keyword != "CONNECTOR SECTION":
                continue
            self._bolt_cards.add(id(card))
            elset = str(card.params.get("ELSET", "")).upper()
            rows = [t for _, t, _ in _rows_of(card)]
            kind = rows[0][0].strip().upper() if rows and rows[0] else ""
            if kind != "AXIAL":
                self.note(_where(card), f"*CONNECTOR SECTION, ELSET={elset} of type "
                          f"{kind or 'none'}", "qsma reads connectors only as bolts, of "
                          "type AXIAL: " + _PATTERN, True)
                continue
            k = self._connector_stiffness(card)
            for elem in self._elsets.get(elset, []):
                found = self._connector_bolt(card, elem, elset, k, bodies, preload,
                                             start + len(out))
                if found is not None:
                    out.append(found)
        return out

    def _connector_stiffness(self, section):
        """The stiffness of a section's ``BEHAVIOR`` (its ``*CONNECTOR ELASTICITY`` of
        component 1), or None with a note."""
        where = _where(section)
        name = str(section.params.get("BEHAVIOR", "")).upper()
        if not name:
            self.note(where, "*CONNECTOR SECTION without BEHAVIOR", "an AXIAL connector "
                      "without elasticity holds nothing along the bolt: " + _PATTERN, True)
            return None
        k = None
        for j, card in enumerate(self.cards):
            if card.keyword != "CONNECTOR BEHAVIOR" or \
                    str(card.params.get("NAME", "")).upper() != name:
                continue
            self._bolt_cards.add(id(card))
            for option in self.cards[j + 1:]:
                if not option.keyword.startswith("CONNECTOR ") or \
                        option.keyword in ("CONNECTOR BEHAVIOR", "CONNECTOR SECTION"):
                    break
                self._bolt_cards.add(id(option))
                if option.keyword != "CONNECTOR ELASTICITY":
                    self.note(_where(option), f"*{option.keyword} of connector behavior "
                              f"{name!r}", "a bolt's connector is linear elastic along its "
                              "axis: " + _PATTERN, True)
                    return None
                if str(option.params.get("COMPONENT", "1")).strip() != "1":
                    continue
                if any(p in option.params for p in ("RIGID", "NONLINEAR")):
                    self.note(_where(option), f"*CONNECTOR ELASTICITY of behavior {name!r} "
                              f"is not linear", "give the bolt's axial stiffness as a "
                              "linear *CONNECTOR ELASTICITY, COMPONENT=1 (E A / L of the "
                              "shank in series with the clamped parts' thread)", True)
                    return None
                rows = [(w, t) for w, t, _ in _rows_of(option) if t and t[0].strip()]
                if rows:
                    k = _number(rows[0][1][0], rows[0][0], "the connector stiffness")
        if k is None or k <= 0:
            self.note(where, f"connector behavior {name!r}: no positive *CONNECTOR "
                      f"ELASTICITY, COMPONENT=1", "give the bolt's axial stiffness: "
                      + _PATTERN, True)
            return None
        return k

    def _connector_bolt(self, section, elem, elset, k, bodies, preload, j):
        """The ``[[bolts]]`` table of connector element ``elem``, or None with a note."""
        where = _where(section)
        nodes = self._connectors.get(elem)
        refs = [n for n in (nodes or ()) if n in self._couplings]
        if nodes is None or len(refs) != 2:
            self.note(where, f"connector element {elem} of *CONNECTOR SECTION, ELSET="
                      f"{elset} joins {len(refs)} coupling reference node(s)", _PATTERN,
                      True)
            return None
        self._bolt_cards |= {id(c) for r in refs for c in self._couplings[r].cards}
        ends = [self._washer(self._couplings[r], bodies) for r in refs]
        if any(e is None for e in ends) or k is None:
            return None
        (ka, set_a), (kb, set_b) = ends
        if ka == kb:
            self.note(where, f"connector element {elem}: both couplings lie on one body",
                      "a bolt joins two bodies: put its washers on both", True)
            return None
        load = self._connector_load(elem, elset, preload, where)
        if load is None:
            return None
        names = [b["table"]["name"] for b in bodies]
        name = elset if len(self._elsets.get(elset, [])) == 1 else f"{elset}_{elem}"
        table = {"name": name or f"bolt{j + 1}", "body_a": names[ka], "set_a": set_a,
                 "body_b": names[kb], "set_b": set_b, "pretension": abs(load),
                 "stiffness": k}
        return table, (f"*CONNECTOR SECTION, {where}: connector {elem}; pretension the "
                       f"magnitude of its *CONNECTOR LOAD ({load:g}: a bolt is in tension "
                       f"whichever sign the deck gives), stiffness its *CONNECTOR "
                       f"ELASTICITY; washers the couplings of reference nodes {refs[0]} "
                       f"and {refs[1]}")

    def _connector_load(self, elem, elset, preload, where):
        """The ``*CONNECTOR LOAD`` on component 1 of ``elem`` in the preload step, or
        None with a note (also for a ``*CONNECTOR MOTION`` there)."""
        names = {str(elem), elset}
        held = (f"*CONNECTOR MOTION on connector {elem} in the preload step",
                "qsma's bolts are force controlled: give the pretension as *CONNECTOR "
                "LOAD on component 1")
        summed = self._component_one_load(preload, names, "CONNECTOR LOAD",
                                          "CONNECTOR MOTION", held, "the connector load",
                                          claim=True)
        if summed is None:
            return None
        total, found = summed
        for step in self.steps:
            if step is preload:
                continue
            for card in step.cards:
                if card.keyword == "CONNECTOR MOTION" and any(
                        t and t[0].strip().upper() in names for _, t, _ in _rows_of(card)):
                    self.note(_where(card), f"*CONNECTOR MOTION on connector {elem} after "
                              f"the preload", "Abaqus would hold the bolt at its tightened "
                              "length (rigid); qsma's bolt keeps the stiffness of its "
                              "*CONNECTOR ELASTICITY, as the bolt's shank does", False)
        if not found or total == 0.0:
            self.note(where, f"connector {elem}: no *CONNECTOR LOAD on its component 1 in "
                      f"the first *STATIC step", "give the bolt's tension as *CONNECTOR "
                      "LOAD, element, 1, N0 in the first *STATIC step", True)
            return None
        return total

    def _component_one_load(self, preload, names, load, held, note, what, claim=False):
        """``(sum, found)`` of the ``load`` rows on component 1 of the references
        ``names`` in the preload step (scaled by their amplitudes; with ``claim`` the
        cards used are counted as the bolt's); None with the refusal ``note`` (what,
        fix) where a ``held`` card prescribes that component instead."""
        total, found = 0.0, False
        upper = {n.upper() for n in names}
        for card in (preload.cards if preload is not None else []):
            if card.keyword not in (load, held):
                continue
            for w, t, _ in _rows_of(card):
                if not t or t[0].strip().upper() not in upper:
                    continue
                if claim:
                    self._bolt_cards.add(id(card))
                if card.keyword == held:
                    self.note(_row_where(w), note[0], note[1], True)
                    return None
                scale = self._amplitude(card, preload)
                if len(t) > 2 and t[1].strip() == "1" and scale is not None:
                    total += scale * _number(t[2], w, what)
                    found = True
        return total, found
