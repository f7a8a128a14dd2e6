"""The reader of a deck: its cards, read once, become the configuration a TOML file
would hold (:func:`read_deck`)."""
from __future__ import annotations

from pathlib import Path
import re
from types import SimpleNamespace

import numpy as np

from ..errors import InputError
from ..mesh.io.abaqus.lexer import _inp_cards
from ..mesh.io.assembly import read_assembly
from ..units import SI, UNIT_SYSTEMS, plausible, unit_system
from .bolts import DeckBolts
from .loads import SupportsAndLoads
from .parts import PartBodies
from .probe import ProbeAndLevels
from .general_contact import GENERAL_CONTACT_CARDS, GeneralContact
from .interactions import DeckInteractions
from .ties import DeckTies, is_tied
from .records import (Deck, DeckInterface, DeckNote,
                      _HARMLESS, _INTERACTION_KEYWORDS, _MATERIAL_KEYWORDS, _PROCEDURES,
                      _REFUSED, _SILENT, _USED, _Material, _Step, _loads_in, _number,
                      _row_where, _rows_of, _spelling, _where, law_table)


def read_deck(path, *, mode: int = 0, tip_node: int | None = None,
              tip_direction=None, levels=None, density: float | None = None,
              units: str | None = None) -> Deck:
    """Read an Abaqus / CalculiX deck as a QSMA run (module docstring).

    Parameters
    ----------
    path : the ``.inp`` deck
    mode : the mode loaded (0 = lowest elastic mode of the tied structure)
    tip_node : the deck's id of the probe node; None: the node of largest displacement
        in mode ``mode``
    tip_direction : the probe's direction (one number per coordinate); None: the axis of
        the probe node's largest displacement in that mode
    levels : :class:`qsma.levels.Levels` or None (:data:`DEFAULT_LEVELS`)
    density : the density of the materials that give no ``*DENSITY`` (in the deck's
        units); None: such a material is refused (a frequency needs mass)
    units : the deck's unit system (a name of :data:`qsma.units.UNIT_SYSTEMS`); None:
        the one system in which every material's E and rho are those of a solid (a
        deck states no units), else SI

    Returns
    -------
    Deck
    """
    path = Path(path)
    cards = _inp_cards(path)
    if units is not None:
        unit_system(units)                       # an unknown name is refused here
    reader = _DeckReader(path, cards, read_assembly(path), density)
    return reader.deck(mode, tip_node, tip_direction, levels, units)


class _DeckReader(SupportsAndLoads, ProbeAndLevels, DeckBolts, GeneralContact,
                  DeckInteractions, DeckTies, PartBodies):
    """What :func:`read_deck` builds, step by step."""

    def __init__(self, path, cards, assembly, density=None):
        self.path, self.cards, self.asm, self.density = path, cards, assembly, density
        self.notes, self.comments = [], {}
        self.materials, self.sections = {}, []      # (elset, material, thickness, where)
        self.interactions = {}
        self.steps, self.model_cards = [], []
        self._split()

    def note(self, where, what, fix, refuses):
        note = DeckNote(where, what, fix, refuses)
        if note not in self.notes:           # e.g. one material of two bodies
            self.notes.append(note)

    # --- walking the cards ------------------------------------------------------------
    def _split(self):
        """Model data and steps; materials, sections and interactions by their owner."""
        material = interaction = None
        step = None
        for card in self.cards:
            kw = card.keyword
            if kw == "STEP":
                step = _Step(len(self.steps), _where(card),
                             nlgeom=str(card.params.get("NLGEOM", "")).upper() not in ("", "NO"))
                self.steps.append(step)
                material = interaction = None
                continue
            if kw == "END STEP":
                step = None
                continue
            if kw == "MATERIAL":
                name = str(card.params.get("NAME", ""))
                material = self.materials.setdefault(name.upper(), _Material(name, _where(card)))
                interaction = None
                continue
            if kw == "SURFACE INTERACTION":
                name = str(card.params.get("NAME", ""))
                interaction = self.interactions.setdefault(
                    name.upper(), {"name": name, "where": _where(card)})
                material = None
                continue
            if material is not None and kw in _MATERIAL_KEYWORDS:
                self._material_card(material, card)
                continue
            if interaction is not None and kw in _INTERACTION_KEYWORDS:
                self._interaction_card(interaction, card)
                continue
            material = interaction = None
            if kw == "SOLID SECTION":
                self._section(card)
                continue
            if step is None:
                self.model_cards.append(card)
            elif step.procedure is None and kw in _PROCEDURES:
                step.procedure = kw
                step.data = [t for _, t, _ in _rows_of(card)][:1]
            else:
                step.cards.append(card)

    def _material_card(self, material, card):
        rows = [(w, t) for w, t, _ in _rows_of(card)]
        if card.keyword == "ELASTIC":
            kind = str(card.params.get("TYPE", "ISO")).upper()
            if kind not in ("ISO", "ISOTROPIC"):
                self.note(_where(card), f"*ELASTIC, TYPE={kind} of material "
                          f"{material.name!r}", "qsma's materials are isotropic: give "
                          "TYPE=ISO with E and nu", True)
                return
            if not rows or len(rows[0][1]) < 2:
                raise InputError(f"{_where(card)}: *ELASTIC without 'E, nu' data line; give "
                                 f"Young's modulus and Poisson's ratio")
            w, t = rows[0]
            material.elastic = (_number(t[0], w, "Young's modulus"),
                                _number(t[1], w, "Poisson's ratio"), _row_where(w))
            if len(rows) > 1:
                self.note(_row_where(rows[1][0]), f"*ELASTIC of material {material.name!r} "
                          f"has {len(rows)} temperature rows", "qsma takes the first "
                          "(line above); give one row for the temperature of the test", False)
        elif card.keyword == "DENSITY":
            if not rows or not rows[0][1] or not rows[0][1][0]:
                raise InputError(f"{_where(card)}: *DENSITY without a value; give the "
                                 f"density")
            w, t = rows[0]
            material.rho = _number(t[0], w, "the density")
        elif card.keyword in _REFUSED:
            self.note(_where(card), f"*{card.keyword} of material {material.name!r}",
                      _REFUSED[card.keyword] + "; remove it to accept a linear elastic "
                      "body", True)
        else:
            self.note(_where(card), f"*{card.keyword} of material {material.name!r} is not "
                      f"used", _HARMLESS[card.keyword], False)

    def _section(self, card):
        elset = card.params.get("ELSET")
        material = card.params.get("MATERIAL")
        if not isinstance(elset, str) or not isinstance(material, str):
            raise InputError(f"{_where(card)}: *SOLID SECTION without ELSET= and MATERIAL=; "
                             f"name both")
        if "ORIENTATION" in card.params:
            self.note(_where(card), f"ORIENTATION={card.params['ORIENTATION']} of the "
                      f"section of {elset!r}", "the materials read are isotropic: the "
                      "orientation changes nothing", False)
        rows = [t for _, t, _ in _rows_of(card)]
        thickness = 1.0
        if rows and rows[0] and rows[0][0]:
            thickness = _number(rows[0][0], card.where, "the section thickness")
        self.sections.append((elset, material, thickness, _where(card)))

    # --- the run ----------------------------------------------------------------------
    def deck(self, mode, tip_node, tip_direction, levels, units=None) -> Deck:
        bodies = self._body_list = self._bodies()
        self._formulations(bodies)
        preload = self._preload_step()
        bolts = self._bolts(bodies, preload)
        self._frequency = self._frequency_step()
        self._model_data()
        clamps = self._clamps(bodies, preload)
        loads = self._loads(bodies, preload)
        interfaces = self._interfaces(bodies)
        config = {"name": self.path.stem, "units": self._units(bodies, units),
                  "bodies": []}
        per_body = {"clamps": clamps, **loads}         # key -> per body [(entry, comment)]
        for k, b in enumerate(bodies):
            table = dict(b["table"])
            for key, rows in per_body.items():
                if rows[k]:
                    table[key] = [entry for entry, _ in rows[k]]
                    for j, (_, comment) in enumerate(rows[k]):
                        self.comments[("bodies", k, key, j)] = comment
            config["bodies"].append(table)
        if len(interfaces) == 1 and len(bodies) == 2:
            config["interface"] = interfaces[0][0]
            self.comments[("interface",)] = interfaces[0][1]
        else:
            config["interfaces"] = [t for t, _ in interfaces]
            for j, (_, c) in enumerate(interfaces):
                self.comments[("interfaces", j)] = c
        if bolts:
            config["bolts"] = [t for t, _ in bolts]
            for j, (_, c) in enumerate(bolts):
                self.comments[("bolts", j)] = c
        config["analysis"] = {"mode": mode}
        if self._frequency is None:
            self.note(self.path.name, "no *FREQUENCY step", f"qsma loads mode {mode} of "
                      f"the structure tied after the preload (--mode K for another)", False)
        if not any(n.refuses for n in self.notes):
            config["tip"], config["levels"] = self._tip_and_levels(
                config, mode, tip_node, tip_direction, levels)
        else:       # a model that cannot be run: the probe from the caller or a placeholder
            config["tip"], config["levels"] = self._given_tip(
                config, tip_node, tip_direction, levels)
            if tip_node is None:
                self.comments[("tip",)] = ("a placeholder (the deck cannot be run as it is, "
                                           "so no mode was computed): choose the probe")
        return Deck(self.path, config, dict(self.comments), tuple(self.notes),
                    tuple(self._deck_interfaces), self._frequency)

    def _preload_step(self):
        """The first *STATIC step (its loads are the preload); notes for the others."""
        preload = next((s for s in self.steps if s.procedure == "STATIC"), None)
        if preload is None:
            kinds = sorted({s.procedure or "no procedure" for s in self.steps})
            self.note(self.path.name, f"no *STATIC step (steps: {', '.join(kinds) or 'none'})",
                      "qsma's preload is the loads of the first *STATIC step: put the bolt "
                      "load and the supports in a *STATIC step", True)
            return None
        if preload.nlgeom:
            self.note(preload.where, "NLGEOM of the preload step", "qsma's preload is "
                      "small-displacement (with frictional contact), as with NLGEOM=NO: "
                      "the two agree where the preload's rotations are small, as under a "
                      "bolt", False)
        for s in self.steps:
            if s is preload or (s.procedure == "FREQUENCY" and not _loads_in(s)):
                continue
            if s.index < preload.index and not _loads_in(s) and not s.cards:
                continue
            self.note(s.where, f"step {s.index + 1} (*{s.procedure or 'no procedure'}) is "
                      f"not used", "qsma's preload is the first *STATIC step (step "
                      f"{preload.index + 1}), its mode the structure tied after it", False)
        return preload

    def _frequency_step(self):
        step = next((s for s in self.steps if s.procedure == "FREQUENCY"), None)
        if step is None:
            return None
        card = next(c for c in self.cards if c.keyword == "STEP" and _where(c) == step.where)
        if "PERTURBATION" not in card.params and step.index > 0:
            self.note(step.where, "the *FREQUENCY step is no PERTURBATION step", "CalculiX "
                      "computes its modes without the preload's contact (the bodies apart); "
                      "qsma's mode is that of the structure tied after the preload, which "
                      "CalculiX computes with *STEP, PERTURBATION (as Abaqus always does)",
                      False)
        try:
            return int(float(step.data[0][0])) if step.data and step.data[0] else None
        except ValueError:
            return None

    def _model_data(self):
        """Notes for the model-data keywords and those of the preload step that qsma does
        not read."""
        preload = next((s for s in self.steps if s.procedure == "STATIC"), None)
        cards = list(self.model_cards) + (list(preload.cards) if preload else [])
        for card in cards:
            kw = card.keyword
            if kw in _SILENT or kw in _USED or id(card) in self._bolt_cards \
                    or kw in GENERAL_CONTACT_CARDS:       # read (or refused) with the pairs
                continue
            if kw == "INITIAL CONDITIONS" and \
                    str(card.params.get("TYPE", "")).upper() == "TEMPERATURE":
                self.note(_where(card), "*INITIAL CONDITIONS, TYPE=TEMPERATURE is not used",
                          "qsma applies no temperature (a *TEMPERATURE in the preload step "
                          "is refused)", False)
            elif kw in _REFUSED:
                self.note(_where(card), f"*{kw}", _REFUSED[kw], True)
            elif kw in _HARMLESS:
                self.note(_where(card), f"*{kw} is not used", _HARMLESS[kw], False)
            else:
                self.note(_where(card), f"*{kw} is not a keyword qsma reads",
                          "remove it if it does not change the structure, its supports or "
                          "the preload, or model it otherwise", True)

    # --- bodies -------------------------------------------------------------------------
    def _bodies(self) -> list:
        """One entry per body: its configuration table (without loads), its mesh and its
        section thickness."""
        instances = [c for c in self.cards if c.keyword == "INSTANCE"]
        if len(instances) > 1:
            return self._instance_bodies(instances)
        parts = self.asm.components()
        meshes = self.asm.component_meshes()
        bodies = []
        for k, (cells, mesh) in enumerate(zip(parts, meshes)):
            table = {"name": f"part{k + 1}", "mesh": self.path.name}
            section = self._section_of(cells)
            exact = self._exact_elset(cells)
            if len(parts) > 1 and exact is not None:
                table["name"] = exact
                table["cells"] = exact
                self.comments[("bodies", k, "cells")] = ("the element set of its *SOLID "
                                                         "SECTION")
            elif len(parts) > 1:
                table["part"] = k + 1
                self.comments[("bodies", k, "part")] = (
                    f"connected part {k + 1} of the mesh (cells joined through shared "
                    f"nodes), {len(cells)} elements")
            self._material_keys(table, k, section)
            self._element_key(table, k, mesh)
            bodies.append({"table": table, "mesh": mesh,
                           "thickness": section[2] if section else 1.0})
        if len(bodies) == 1:
            self.note(self.path.name, "the mesh is one connected part",
                      "a contact interface joins two bodies: mesh the parts apart (no "
                      "shared nodes) or as *INSTANCEs of parts", True)
        return bodies

    def _elset(self, name):
        """The spelling of element set ``name`` in the file (names ignore case)."""
        sets = self.asm.file_mesh.element_sets
        return name if name in sets else next(
            (n for n in sets if n.upper() == name.upper()), None)

    def _exact_elset(self, cells):
        """The section element set holding exactly ``cells``, or None."""
        for s in self.sections:
            name = self._elset(s[0])
            if name is not None and np.array_equal(np.sort(self.asm._volume_members(name)),
                                                   np.sort(cells)):
                return name
        return None

    def _section_of(self, cells):
        """The section ``(elset, material, thickness, where)`` of a body's cells; a note
        if they have several materials or none."""
        found = []
        for s in self.sections:
            name = self._elset(s[0])
            if name is not None and np.isin(cells, self.asm._volume_members(name)).any():
                found.append(s)
        ids = np.concatenate(self.asm.file_mesh.element_ids)
        first = int(ids[cells[0]])
        if not found:
            self.note(self.path.name, f"no *SOLID SECTION covers the body of element {first}",
                      "give every body a *SOLID SECTION", True)
            return None
        materials = sorted({s[1].upper() for s in found})
        if len(materials) > 1:
            self.note(found[1][3], f"the body of element {first} has the materials "
                      f"{materials}", "a qsma body has one material: split it into bodies "
                      "or give it one material", True)
        return found[0]

    def _material_keys(self, table, k, section):
        if section is None:
            table.update(E=1.0, nu=0.0, rho=1.0)
            return
        material = self.materials.get(section[1].upper())
        where = section[3]
        if material is None:
            self.note(where, f"material {section[1]!r} of the section is not defined",
                      "define it with *MATERIAL", True)
            table.update(E=1.0, nu=0.0, rho=1.0)
            return
        if material.elastic is None:
            self.note(material.where, f"material {material.name!r} has no *ELASTIC",
                      "give E and nu with *ELASTIC", True)
            E, nu, ewhere = 1.0, 0.0, material.where
        else:
            E, nu, ewhere = material.elastic
        rho = material.rho
        if rho is None and self.density is None:
            self.note(material.where, f"material {material.name!r} has no *DENSITY",
                      "a frequency needs mass: add *DENSITY (e.g. 7.85e-9 t/mm^3 or 7850 "
                      "kg/m^3 for steel), or give --density", True)
            rho = 1.0
        elif rho is None:
            rho = self.density
            self.note(material.where, f"material {material.name!r} has no *DENSITY",
                      f"the density {rho:g} given (--density) is used", False)
        table.update(E=E, nu=nu, rho=rho)
        self.comments[("bodies", k, "E")] = f"*ELASTIC of material {material.name!r}, {ewhere}"
        self.comments[("bodies", k, "rho")] = (
            f"*DENSITY of material {material.name!r}" if material.rho is not None
            else "--density (the material gives no *DENSITY)")
        if section[2] != 1.0:
            self.comments[("bodies", k, "name")] = (
                f"section thickness {section[2]:g} ({section[3]}): qsma's 2D bodies have "
                f"unit depth, forces are per unit depth")

    def _units(self, bodies, given):
        """The unit system: ``given``, else the one in which every body's E and rho are
        those of a solid (:func:`qsma.units.plausible`), else SI (where qsma's check
        of the model then warns)."""
        if given is not None:
            self.comments[("units",)] = "--units"
            return unit_system(given).name
        materials = [SimpleNamespace(E=b["table"]["E"], rho=b["table"]["rho"])
                     for b in bodies]
        fits = [name for name in UNIT_SYSTEMS
                if all(plausible(m, name) for m in materials)]
        if len(fits) == 1 and fits[0] != SI.name:
            u = UNIT_SYSTEMS[fits[0]]
            self.comments[("units",)] = (
                f"a deck states no units: E and rho of every material are those of a "
                f"solid in {u.name} (E in {u.stress}, rho in {u.density}) and in no "
                f"other system (--units for another)")
            self.note(self.path.name, f"units: {u.name}, from the materials (E in "
                      f"{u.stress}, rho in {u.density})", "labels, files and messages use "
                      "them; give --units if the deck is in another system", False)
            return u.name
        self.comments[("units",)] = ("a deck states no units: SI unless its materials "
                                     "look like another system (--units for another)")
        return SI.name

    # --- supports and loads -------------------------------------------------------------
    def _find(self, mesh, name, kinds=("node", "facet")):
        """The spelling of set ``name`` in ``mesh`` (Abaqus names ignore case), or None."""
        pools = {"node": mesh.node_sets, "facet": mesh.facet_sets, "cell": mesh.cell_sets}
        for kind in kinds:
            sets = pools[kind]
            if name in sets and len(sets[name]):
                return name
            match = [n for n in sets if n.upper() == name.upper() and len(sets[n])]
            if match:
                return match[0]
        return None

    def _owners(self, bodies, ref, prefix, kinds=("node", "facet")):
        """``(body index, set name)`` of each body holding the set a row names: by name,
        or by id (``ref`` an integer: the set ``<prefix><id>`` the mesh reader made)."""
        name = f"{prefix}{int(ref)}" if re.fullmatch(r"[+-]?\d+", ref) else ref
        return [(k, found) for k, b in enumerate(bodies)
                for found in [self._find(b["mesh"], name, kinds)] if found is not None]

    def _interfaces(self, bodies):
        out, seen = [], set()
        self._deck_interfaces = []
        names = [b["table"]["name"] for b in bodies]
        for card in self.cards:
            if card.keyword != "CONTACT PAIR":
                continue
            inter = card.params.get("INTERACTION")
            record = self._interaction(inter if isinstance(inter, str) else None)
            adjust = self._adjust(card)
            for where, tokens, text in _rows_of(card):
                w = _row_where(where)
                if len(tokens) < 2:
                    continue       # the mesh reader refuses such a row
                slave, master = (_spelling(self.asm, t) for t in tokens[:2])
                owners = []
                for surf in (slave, master):
                    found = [k for k, b in enumerate(bodies)
                             if self._find(b["mesh"], surf, kinds=("facet",)) is not None]
                    owners.append(found)
                if len(owners[0]) != 1 or len(owners[1]) != 1:
                    which = slave if len(owners[0]) != 1 else master
                    n = len(owners[0] if which == slave else owners[1])
                    self.note(w, f"contact surface {which!r} lies on {n} bodies"
                              if n else f"contact surface {which!r} holds no element face "
                              f"(a node surface whose nodes span no face, e.g. one node)",
                              "a contact surface is made of element faces of one body: "
                              "give it as a *SURFACE, TYPE=ELEMENT of faces", True)
                    continue
                s, m = owners[0][0], owners[1][0]
                if s == m:
                    self.note(w, f"contact pair {slave!r} / {master!r} on one body (self "
                              f"contact)", "qsma's interfaces join two bodies", True)
                    continue
                key = frozenset(((s, slave), (m, master)))
                if key in seen:
                    continue
                seen.add(key)
                if is_tied(record):
                    out.append(self._tied_pair(names, bodies, (s, m), (slave, master),
                                               record, w))
                    continue
                mu = record.mu if record is not None and record.mu is not None else 0.0
                table = {"body1": names[m], "set1": self._find(bodies[m]["mesh"], master,
                                                                 ("facet",)),
                         "body2": names[s], "set2": self._find(bodies[s]["mesh"], slave,
                                                                ("facet",)),
                         "mu": mu, "coupling": "auto", "slave": names[s]}
                law = law_table(record, w)
                if law is not None:
                    table["law"] = law
                if adjust is not None:
                    table["adjust"] = self._adjust_set(adjust, bodies[s]["mesh"], card)
                    if table["adjust"] is None:
                        del table["adjust"]
                comment = f"*CONTACT PAIR, {w}: master {master}, slave {slave}"
                if record is None or record.mu is None:
                    comment += "; no *FRICTION: frictionless as in CalculiX (set mu)"
                    self.note(w, f"contact pair {slave!r} / {master!r} has no *FRICTION",
                              "frictionless (mu = 0), as in CalculiX; give mu (--mu or the "
                              "TOML) for a joint that dissipates", False)
                else:
                    comment += f"; mu from *FRICTION of interaction {record.name!r}"
                out.append((table, comment))
                self._deck_interfaces.append(DeckInterface(
                    slave, master, names[s], names[m], record, w))
        out += self._general_interfaces(bodies)
        out += self._ties(bodies, seen)
        if not out:
            self.note(self.path.name, "no *CONTACT PAIR joins two bodies",
                      "qsma's joint is a contact interface: define a *CONTACT PAIR", True)
        elif all(t.get("tied") for t, _ in out):
            self._note_tied_only()
        return out

    def _adjust(self, card):
        """A contact pair's ``ADJUST=`` (the interface's ``adjust``): a distance, the
        name of a node set (:meth:`_adjust_set`), or None."""
        value = card.params.get("ADJUST")
        if value is None or value is True:
            return None
        try:
            adjust = float(value)
        except (TypeError, ValueError):
            return str(value)
        if not np.isfinite(adjust) or adjust < 0:
            self.note(_where(card), f"ADJUST={value} of the contact pair",
                      "give ADJUST= a distance >= 0", True)
            return None
        return adjust

    def _adjust_set(self, adjust, mesh, card):
        """The adjust of a pair: a distance as it is, a node set spelled as in the slave
        body's ``mesh``; None with a note where the slave has no such set."""
        if not isinstance(adjust, str):
            return adjust
        found = self._find(mesh, adjust, ("node", "facet"))
        if found is None:
            self.note(_where(card), f"ADJUST={adjust} of the contact pair: no node set of "
                      f"the slave surface's body", "qsma takes these gaps as meshed; give "
                      "ADJUST= a distance, or a node set of the slave's nodes", False)
        return found
