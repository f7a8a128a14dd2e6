"""The supports and loads of a deck: ``*BOUNDARY`` rows as clamps, the ``*CLOAD``,
``*DSLOAD`` and ``*DLOAD`` of the first static step as the preload."""
from __future__ import annotations

import re

import numpy as np

from .records import _BOUNDARY_TYPES, _number, _row_where, _rows_of, _where


class SupportsAndLoads:
    """The part of the deck reader (:class:`qsma.deck.reader._DeckReader`) that reads
    supports and loads; it uses the reader's notes, sets and bodies."""

    def _clamps(self, bodies, preload):
        out = [[] for _ in bodies]
        cards = [c for c in self.model_cards if c.keyword == "BOUNDARY"]
        if preload is not None:
            cards += [c for c in preload.cards if c.keyword == "BOUNDARY"]
        for card in cards:
            scale = 1.0 if preload is None or card not in preload.cards \
                else self._amplitude(card, preload)
            if scale is None:
                continue
            moved = [(where, text) for where, tokens, text in _rows_of(card)
                     if self._clamp_row(bodies, out, where, tokens, text, scale)
                     == "prescribed"]
            if moved:
                (where, text), n = moved[0], len(moved)
                self.note(_row_where(where), f"*BOUNDARY row {text!r} prescribes a "
                          f"displacement" + (f" (and {n - 1} more rows of this *BOUNDARY)"
                                             if n > 1 else ""),
                          "read as part of the preload: the DOF is moved there in the "
                          "preload step and held there from then on", False)
        return [_overridden(rows) for rows in out]

    def _clamp_row(self, bodies, out, where, tokens, text, scale=1.0):
        """Clamps of one *BOUNDARY row into ``out``; ``"prescribed"`` for a row with a
        non-zero value (its displacement times ``scale``, the amplitude at the end of
        the preload step; named per card by the caller)."""
        w = _row_where(where)
        ref = tokens[0]
        if ref.upper() in self._bolt_refs:
            return None                        # a bolt's pretension node (deck.bolts)
        kind = tokens[1].upper() if len(tokens) > 1 else ""
        value = 0.0
        if kind in _BOUNDARY_TYPES:
            first, last = _BOUNDARY_TYPES[kind]
        else:
            try:
                first = int(tokens[1])
                last = int(tokens[2]) if len(tokens) > 2 and tokens[2] else first
                value = _number(tokens[3], where, "the prescribed value") \
                    if len(tokens) > 3 and tokens[3] else 0.0
            except (ValueError, IndexError):
                self.note(w, f"*BOUNDARY row {text!r} is not read", "give 'node or node "
                          "set, first dof[, last dof[, value]]'", True)
                return
            if first > 3:
                self.note(w, f"*BOUNDARY on DOFs {first}-{last} (not displacements) is not "
                          f"used", "qsma's nodes have displacement DOFs 1-3 only", False)
                return
            last = min(last, 3)
        owners = self._owners(bodies, ref, "_BC")
        for k, found in owners:
            dofs = [d for d in range(first, last + 1) if d <= bodies[k]["mesh"].dim]
            if dofs:
                table = {"set": found, "dofs": dofs}
                if value != 0.0:
                    table["displacement"] = [value * scale] * len(dofs)
                out[k].append((table, f"*BOUNDARY, {w}"))
        if not owners:
            self.note(w, f"*BOUNDARY on {ref!r}, which holds no node of a body",
                      "check the set", True)
        return "prescribed" if value != 0.0 and owners else None

    def _loads(self, bodies, preload):
        out = {"forces": [[] for _ in bodies], "pressures": [[] for _ in bodies]}
        if preload is None:
            return out
        for card in preload.cards:
            handler = {"CLOAD": self._cload, "DLOAD": self._dload,
                       "DSLOAD": self._dsload}.get(card.keyword)
            if handler is None:
                continue
            scale = self._amplitude(card, preload)
            if scale is None:
                continue
            for where, tokens, text in _rows_of(card):
                handler(bodies, out, where, tokens, text, scale)
        return out

    def _amplitude(self, card, step):
        """The factor of a load's ``AMPLITUDE=`` at the end of the preload step (1
        without one; None, with a refusal, where it cannot be evaluated)."""
        name = card.params.get("AMPLITUDE")
        if name is None:
            return 1.0
        where = _where(card)
        amp = next((c for c in self.model_cards if c.keyword == "AMPLITUDE"
                    and str(c.params.get("NAME", "")).upper() == str(name).upper()), None)
        definition = str(amp.params.get("DEFINITION", "TABULAR")).upper() if amp else ""
        time = str(amp.params.get("TIME", "STEP TIME")).upper() if amp else ""
        if amp is None or definition != "TABULAR" or \
                (time == "TOTAL TIME" and step.index > 0):
            self.note(where, f"*{card.keyword}, AMPLITUDE={name}", "qsma evaluates tabular "
                      "amplitudes in step time at the end of the preload step; give the "
                      "end-of-step magnitude without AMPLITUDE=", True)
            return None
        values = [_number(t, w, "an amplitude value") for w, row, _ in _rows_of(amp)
                  for t in row if t]
        period = 1.0
        if step.data and len(step.data[0]) > 1 and step.data[0][1]:
            period = _number(step.data[0][1], amp.where, "the step's time period")
        factor = float(np.interp(period, values[0::2], values[1::2]))
        self.note(where, f"*{card.keyword}, AMPLITUDE={name}: the magnitudes times "
                  f"{factor:g}, the amplitude at the end of the step (time {period:g})",
                  "qsma's preload is the end of the step", False)
        return factor

    def _cload(self, bodies, out, where, tokens, text, scale):
        w = _row_where(where)
        try:
            dof = int(tokens[1])
            value = scale * _number(tokens[2], where, "the force")
        except (ValueError, IndexError):
            self.note(w, f"*CLOAD row {text!r} is not read", "give 'node or node set, dof, "
                      "magnitude'", True)
            return
        ref = tokens[0]
        if ref.upper() in self._bolt_refs:
            return                             # a bolt's pretension (deck.bolts)
        owners = self._owners(bodies, ref, "_N")
        for k, found in owners:
            b = bodies[k]
            dim = b["mesh"].dim
            if not 1 <= dof <= dim:
                self.note(w, f"*CLOAD on DOF {dof}", f"qsma's {dim}D nodes have forces on "
                          f"DOFs 1-{dim} only", True)
                return
            force = [0.0] * dim
            force[dof - 1] = value / b["thickness"]
            note = f"*CLOAD, {w}" + (f", divided by the thickness {b['thickness']:g}"
                                     if b["thickness"] != 1.0 else "")
            out["forces"][k].append(({"set": found, "force": force}, note))
        if not owners:
            self.note(w, f"*CLOAD on {ref!r}, which holds no node of a body", "check the "
                      "set", True)

    def _dsload(self, bodies, out, where, tokens, text, scale):
        w = _row_where(where)
        if len(tokens) < 3 or tokens[1].upper() != "P":
            self.note(w, f"*DSLOAD row {text!r}", "qsma reads pressures (label P) on "
                      "element-face surfaces", True)
            return
        value = scale * _number(tokens[2], where, "the pressure")
        owners = self._owners(bodies, tokens[0], "", kinds=("facet",))
        for k, found in owners:
            out["pressures"][k].append(({"set": found, "p": value}, f"*DSLOAD, {w}"))
        if not owners:
            self.note(w, f"*DSLOAD on {tokens[0]!r}, which is no element-face surface of a "
                      f"body", "define it with *SURFACE, TYPE=ELEMENT", True)

    def _dload(self, bodies, out, where, tokens, text, scale):
        w = _row_where(where)
        label = tokens[1].upper() if len(tokens) > 1 else ""
        m = re.fullmatch(r"P(\d)", label)
        if m is None or len(tokens) < 3:
            self.note(w, f"*DLOAD row {text!r} ({label or 'no label'})", "qsma reads "
                      "pressures on element faces (labels P1..P6); it has no body forces "
                      "(GRAV, CENTRIF) and no shell pressures", True)
            return
        value = scale * _number(tokens[2], where, "the pressure")
        ref = tokens[0]
        owners = self._owners(bodies, ref, "_E", kinds=("cell",))
        for k, found in owners:
            out["pressures"][k].append(({"set": found, "face": int(m.group(1)), "p": value},
                                        f"*DLOAD, {w}"))
        if not owners:
            self.note(w, f"*DLOAD on {ref!r}, which holds no element of a body",
                      "check the element set", True)

    # --- interfaces ---------------------------------------------------------------------


def _overridden(rows):
    """A body's clamp rows in deck order with what a later row sets on the same set and
    DOF taken out of the earlier rows (a step's ``*BOUNDARY`` modifies the model data's,
    as in Abaqus and CalculiX); rows left with no DOF are dropped."""
    out = []
    for k, (table, comment) in enumerate(rows):
        later = {d for t, _ in rows[k + 1:] if t["set"] == table["set"] for d in t["dofs"]}
        keep = [i for i, d in enumerate(table["dofs"]) if d not in later]
        if not keep:
            continue
        if len(keep) < len(table["dofs"]):
            table = dict(table, dofs=[table["dofs"][i] for i in keep])
            if "displacement" in table:
                table["displacement"] = [table["displacement"][i] for i in keep]
        out.append((table, comment))
    return out
