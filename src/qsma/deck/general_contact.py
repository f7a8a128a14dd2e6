"""Abaqus' general contact in a deck: ``*CONTACT`` with ``*CONTACT INCLUSIONS, ALL
EXTERIOR`` and a global ``*CONTACT PROPERTY ASSIGNMENT`` (``, , name``) becomes one
interface per pair of bodies that touch, its faces found by qsma
(:mod:`qsma.model.touching`: ``touching = true`` in the TOML), its friction and law
those of the assigned ``*SURFACE INTERACTION``. What narrows or changes general contact
(inclusions of named surfaces, exclusions, property assignments to surface pairs,
initialisation) is refused with the ``*CONTACT PAIR`` to write instead."""
from __future__ import annotations

from itertools import combinations

from ..mesh.touching import touching_facets
from .records import (DeckInterface, _GENERAL_CONTACT, _row_where, _rows_of, _where,
                      law_table)

#: The cards of general contact that qsma reads.
GENERAL_CONTACT_CARDS = ("CONTACT", "CONTACT INCLUSIONS", "CONTACT PROPERTY ASSIGNMENT")


class GeneralContact:
    """The part of the deck reader (:class:`qsma.deck.reader._DeckReader`) that reads
    general contact; it leaves in ``_general_cards`` the cards it used."""

    def _general_interfaces(self, bodies) -> list:
        """``[(table, comment)]``: an interface per pair of bodies that touch, or none
        (no general contact, or one qsma refuses: noted)."""
        self._general_cards = set()
        cards = [c for c in self.cards if c.keyword in GENERAL_CONTACT_CARDS]
        if not cards:
            return []
        if not self._general_contact_is_read(cards):
            return []
        record, where = self._assigned_property(cards)
        if record is False:
            return []
        self._general_cards |= {id(c) for c in cards}
        names = [b["table"]["name"] for b in bodies]
        out = []
        for i, j in combinations(range(len(bodies)), 2):
            fi, fj = touching_facets(bodies[i]["mesh"], bodies[j]["mesh"])
            if not len(fi) or not len(fj):
                continue
            table = {"body1": names[i], "body2": names[j], "touching": True,
                     "mu": record.mu if record is not None and record.mu is not None
                     else 0.0, "coupling": "auto"}
            law = law_table(record, where)
            if law is not None:
                table["law"] = law
            comment = (f"*CONTACT INCLUSIONS, ALL EXTERIOR, {where}: the faces where "
                       f"{names[i]!r} and {names[j]!r} touch ({len(fi)} and {len(fj)} "
                       f"facets, found by qsma)")
            if record is None or record.mu is None:
                comment += "; no *FRICTION: frictionless (set mu)"
                self.note(where, f"general contact of {names[i]!r} and {names[j]!r} has "
                          f"no *FRICTION", "frictionless (mu = 0); give mu (--mu or the "
                          "TOML) for a joint that dissipates", False)
            else:
                comment += f"; mu from *FRICTION of interaction {record.name!r}"
            out.append((table, comment))
            self._deck_interfaces.append(DeckInterface(
                f"touching:{names[i]}", f"touching:{names[j]}", names[j], names[i], record,
                where))
        if not out:
            self.note(where, "general contact: no two bodies touch (no boundary facet of "
                      "one lies on a boundary facet of another, facing it)", "check the "
                      "parts' placement, or define the contact by *CONTACT PAIR", True)
        return out

    def _general_contact_is_read(self, cards) -> bool:
        """Whether the deck's general contact is the form qsma reads (ALL EXTERIOR);
        each card of another form refused with the way."""
        inclusions = [c for c in cards if c.keyword == "CONTACT INCLUSIONS"]
        readable = True
        for card in inclusions:
            rows = [t for _, t, _ in _rows_of(card) if any(x.strip() for x in t)]
            if "ALL EXTERIOR" not in card.params or rows:
                self.note(_where(card), "*CONTACT INCLUSIONS of named surfaces",
                          _GENERAL_CONTACT, True)
                readable = False
        if not inclusions:
            self.note(_where(cards[0]), "*CONTACT without *CONTACT INCLUSIONS, ALL EXTERIOR",
                      _GENERAL_CONTACT, True)
            readable = False
        return readable

    def _assigned_property(self, cards):
        """``(SurfaceInteraction or None, where)`` of the global ``*CONTACT PROPERTY
        ASSIGNMENT``; ``(False, where)`` with a note where it cannot be read."""
        assignments = [(w, t) for c in cards if c.keyword == "CONTACT PROPERTY ASSIGNMENT"
                       for w, t, _ in _rows_of(c) if any(x.strip() for x in t)]
        where = _where(cards[0])
        if not assignments:
            return None, where
        ok, name = True, None
        for w, t in assignments:
            t = [x.strip() for x in t] + ["", "", ""]
            if t[0] or t[1]:
                self.note(_row_where(w), f"*CONTACT PROPERTY ASSIGNMENT to surfaces "
                          f"{t[0]!r}, {t[1]!r}", "qsma reads one property for all of "
                          "general contact (a row ', , name'); " + _GENERAL_CONTACT, True)
                ok = False
            else:
                name, where = t[2], _row_where(w)
        if not ok:
            return False, where
        record = self._interaction(name)
        if record is None:
            self.note(where, f"*CONTACT PROPERTY ASSIGNMENT names interaction {name!r}, "
                      f"which the deck does not define", "define it by *SURFACE "
                      "INTERACTION, NAME=... with its *FRICTION", True)
            return False, where
        return record, where
