"""The bodies of a deck with parts and instances (as Abaqus/CAE writes it), and the
element types of every body: the part of the deck reader
(:class:`qsma.deck.reader._DeckReader`) that reads them."""
from __future__ import annotations

from ..errors import InputError
from ..fe.formulation import nearest_element, resolve_formulations
from .records import _where


class PartBodies:
    """One body per ``*INSTANCE``, of the material of its part's ``*SOLID SECTION``;
    a refusal for an element type qsma does not compute. Uses the reader's cards,
    sections, notes and materials."""

    def _instance_bodies(self, instances) -> list:
        """The bodies of a deck with parts: one per instance, of the material of its
        part's sections."""
        bodies = []
        for k, inst in enumerate(instances):
            name = str(inst.params.get("NAME", f"instance{k + 1}"))
            table = {"name": name, "mesh": self.path.name, "cells": name}
            self.comments[("bodies", k, "cells")] = f"*INSTANCE, {_where(inst)}"
            section = self._instance_section(inst, name)
            self._material_keys(table, k, section)
            mesh = self.asm.body_mesh(name)
            self._element_key(table, k, mesh)
            bodies.append({"table": table, "mesh": mesh,
                           "thickness": section[2] if section else 1.0})
        return bodies

    def _instance_section(self, inst, name):
        """The section of an instance: that of its part (Abaqus/CAE writes the
        sections inside the parts), else the one material of the deck; None, with a
        refusal, where the part's sections name several materials or none is found."""
        part = str(inst.params.get("PART", ""))
        found = self._part_sections().get(part.upper(), [])
        if not found:
            found = [s for s in self.sections if (s[0], s[3]) not in self._in_parts]
        materials = sorted({s[1].upper() for s in found})
        if len(materials) == 1:
            return found[0]
        if materials:
            self.note(found[1][3], f"part {part!r} (instance {name!r}) has sections of "
                      f"the materials {materials}", "a qsma body has one material: make "
                      "each material's region a part of its own (its own instance), or "
                      "give the part one material", True)
        else:
            self.note(_where(inst), f"no *SOLID SECTION in part {part!r} of instance "
                      f"{name!r}", "give the part a *SOLID SECTION with its material",
                      True)
        return None

    def _part_sections(self) -> dict:
        """``{part name (upper case): [section, ...]}`` of the sections inside each
        ``*PART``; ``self._in_parts`` the ``(elset, where)`` of all of them."""
        out, part, at = {}, None, {}
        for card in self.cards:
            if card.keyword == "PART":
                part = str(card.params.get("NAME", "")).upper()
            elif card.keyword == "END PART":
                part = None
            elif card.keyword == "SOLID SECTION" and part is not None:
                at[_where(card)] = part
        for s in self.sections:
            if s[3] in at:
                out.setdefault(at[s[3]], []).append(s)
        self._in_parts = {(s[0], s[3]) for s in self.sections if s[3] in at}
        return out

    def _formulations(self, bodies):
        """A refusal, at its ``*ELEMENT`` line, for each element type of a body that
        qsma does not compute (C3D8R, the default hexahedron of Abaqus/CAE, ...)."""
        parts = {str(c.params.get("NAME", "")).upper(): str(c.params.get("PART", "")).upper()
                 for c in self.cards if c.keyword == "INSTANCE"}
        for b in bodies:
            if "element" in b["table"]:
                continue              # computed as its nearest element (named)
            try:
                resolve_formulations(b["mesh"])
            except InputError as error:
                element = str(b["mesh"].element or "").upper()
                part = parts.get(b["table"]["name"].upper())
                where, inside = self.path.name, None
                for c in self.cards:
                    inside = str(c.params.get("NAME", "")).upper() \
                        if c.keyword == "PART" else None if c.keyword == "END PART" \
                        else inside
                    if c.keyword == "ELEMENT" and \
                            str(c.params.get("TYPE", "")).upper() == element:
                        where = _where(c)
                        if part is None or inside == part:
                            break
                self.note(where, f"*ELEMENT, TYPE={element} of body "
                          f"{b['table']['name']!r}", f"{error} (in Abaqus/CAE: Mesh > "
                          f"Element Type)", True)

    def _element_key(self, table, k, mesh):
        """``element`` of a body whose elements qsma computes as their nearest one
        (``C3D8R`` as ``C3D8I``, ...), with a note each; nothing where all are its own."""
        found = {}
        for block in [mesh] + list(mesh.extra_blocks):
            near = nearest_element(block.element, block.cell_type)
            if near is not None:
                found[str(block.element).upper()] = near
        if not found:
            return
        table["element"] = next(iter(found.values()))[0] if not mesh.extra_blocks \
            else "nearest"
        for old, (new, why) in found.items():
            card = next((c for c in self.cards if c.keyword == "ELEMENT" and
                         str(c.params.get("TYPE", "")).upper() == old), None)
            self.note(_where(card) if card is not None else self.path.name,
                      f"{old} elements are computed as {new}",
                      why, False)
        self.comments[("bodies", k, "element")] = "; ".join(
            f"the deck's {old} computed as {new}" for old, (new, _) in found.items())
