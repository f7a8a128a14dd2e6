"""The ``*SURFACE INTERACTION`` records of a deck: ``*FRICTION`` and ``*SURFACE
BEHAVIOR`` as read, what an interface's ``mu``, law or tie come from."""
from __future__ import annotations

from ..model.friction import MU_NO_SLIP
from .records import (LAW_NOTES, SurfaceInteraction, _HARMLESS, _number, _row_where,
                      _rows_of, _where)


class DeckInteractions:
    """The interaction cards of a deck reader (``self.interactions``: name -> record)."""

    def _interaction_card(self, interaction, card):
        rows = [(w, t) for w, t, _ in _rows_of(card)]
        name = interaction["name"]
        if card.keyword == "FRICTION" and "ROUGH" in card.params:
            self._rough(interaction, card)
        elif card.keyword == "FRICTION":
            if rows and rows[0][1] and rows[0][1][0]:
                w, t = rows[0]
                interaction["mu"] = _number(t[0], w, "the friction coefficient")
                if interaction["mu"] > MU_NO_SLIP:
                    self.note(_row_where(w), f"*FRICTION mu = {interaction['mu']:g} of "
                              f"interaction {name!r} (no slip)", f"taken as mu = "
                              f"{MU_NO_SLIP:g}: a pair then slips only as it opens, as with "
                              f"the deck's value; larger values only cost the contact solve "
                              f"its accuracy", False)
                    interaction["mu"] = MU_NO_SLIP
                if len(t) > 1 and t[1]:
                    interaction["stick_slope"] = _number(t[1], w, "the stick slope")
        elif card.keyword == "SURFACE BEHAVIOR":
            law = str(card.params.get("PRESSURE-OVERCLOSURE", "HARD")).upper()
            numbers = tuple(_number(x, w, "a surface behavior value")
                            for w, t in rows for x in t if x)
            interaction["pressure_overclosure"] = law
            interaction["behavior"] = numbers
            if "NO SEPARATION" in card.params:
                self.note(_where(card), f"*SURFACE BEHAVIOR, NO SEPARATION of interaction "
                          f"{name!r}", "qsma's pairs open and close as the joint rocks, "
                          "which changes the answer wherever a pair would open: remove NO "
                          "SEPARATION (in Abaqus/CAE: Normal Behavior, allow separation "
                          "after contact)", True)
            if law in LAW_NOTES:
                self.note(_where(card), f"*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE={law} "
                          f"of interaction {name!r}: {LAW_NOTES[law]}", "the interface "
                          "law of qsma that is its layer (docs/theory.md section 12)", False)
            elif law == "TIED":
                self._note_tied_interaction(card, name)
            elif law not in ("HARD", "LINEAR", "EXPONENTIAL", "TABULAR"):
                self.note(_where(card), f"*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE={law} "
                          f"of interaction {name!r}", "qsma reads HARD, LINEAR, EXPONENTIAL, "
                          "TABULAR and TIED", True)
        else:
            self.note(_where(card), f"*{card.keyword} of interaction {name!r} is not used",
                      _HARMLESS[card.keyword], False)

    def _rough(self, interaction, card):
        """``*FRICTION, ROUGH``: no slip, qsma's largest mu (named)."""
        interaction["mu"] = MU_NO_SLIP
        self.note(_where(card), f"*FRICTION, ROUGH of interaction {interaction['name']!r} "
                  f"(no slip)", f"taken as mu = {MU_NO_SLIP:g}: a pair then slips only as "
                  f"it opens", False)

    def _interaction(self, name):
        if name is None:
            return None
        d = self.interactions.get(name.upper())
        if d is None:
            return None
        return SurfaceInteraction(d["name"], d.get("mu"), d.get("stick_slope"),
                                  d.get("pressure_overclosure"), d.get("behavior", ()),
                                  d["where"])
