"""The bolts of a deck, read as ``[[bolts]]`` tables.

A bolt of qsma (:class:`qsma.model.Bolt`) is, in a deck, two distributing couplings
on washer faces of two bodies (``*DISTRIBUTING COUPLING`` with its ``DCOUP3D``
element, or ``*COUPLING`` with ``*DISTRIBUTING``), an axial member between their
reference nodes (a ``B31`` beam or ``T3D2`` truss, possibly in series with
``SPRINGA`` springs and linked by ``*EQUATION`` ties between the bolt's own nodes)
with a ``*PRE-TENSION SECTION, ELEMENT=``, and the pretension as ``*CLOAD`` on DOF 1
of the section's node in the first ``*STATIC`` step: the pattern
:func:`qsma.deck.export_calculix` writes. Abaqus' connector bolts (an ``AXIAL``
``CONN3D2`` between the couplings' reference nodes) are read by
:mod:`qsma.deck.connector_bolts`.

The locked stiffness is the members' ``E A / L`` in series: a spring its constant,
a truss or beam ``E A / L`` from its section and material. A pretensioned beam in
series with a spring counts as rigid: CalculiX deletes the beam of a pretension
section and keeps a constraint (rigid once the pretension node is held), so the
spring is the bolt's stiffness (the export writes it so). A pretensioned member
alone gives its own ``E A / L`` (Abaqus keeps the member; CalculiX would hold such a
bolt rigid once locked, which a note says).
"""
from __future__ import annotations

from dataclasses import dataclass, field
import math

import numpy as np

from ..fe.bolts import washer_weights
from ..mesh.celltypes import CELL_TYPES, abaqus_faces
from .connector_bolts import ConnectorBolts
from .records import _number, _row_where, _rows_of, _where

#: keywords whose cards a bolt may use
_INDEXED = {"NSET", "ELSET", "ELEMENT", "DISTRIBUTING COUPLING", "COUPLING", "SPRING",
            "EQUATION"}
#: Largest difference, relative to the largest weight, between a deck's coupling weights
#: and a uniform traction's that passes without a note (the export writes 8 digits).
WEIGHTS_RTOL = 1e-5


@dataclass(frozen=True)
class _Washer:
    """What :func:`qsma.fe.bolts.washer_weights` needs of a body: its mesh and name."""
    mesh: object
    name: str

    @property
    def dim(self) -> int:
        return self.mesh.dim


#: member element types and what they are
_MEMBERS = {"B31": "beam", "B31R": "beam", "T3D2": "truss", "T3D2H": "truss",
            "SPRINGA": "spring"}


@dataclass
class _Coupling:
    ref: int
    where: str
    cards: list
    surface: str | None = None          # *COUPLING, SURFACE=
    nodes: list = field(default_factory=list)   # *DISTRIBUTING COUPLING node ids
    weights: list = field(default_factory=list)  # and their weights (same order)


@dataclass
class _Member:
    elem: int
    kind: str
    nodes: tuple
    where: str
    elset: str | None = None


class DeckBolts(ConnectorBolts):
    """The part of the deck reader (:class:`qsma.deck.reader._DeckReader`) that reads
    bolts; it uses the reader's cards, notes, materials and bodies, and leaves in
    ``_bolt_cards`` the cards and in ``_bolt_refs`` the load references (pretension
    nodes) that the bolts use."""

    def _bolts(self, bodies, preload) -> list:
        """``[(table, comment)]`` of the bolts; notes for the pieces of none."""
        self._bolt_cards, self._bolt_refs = set(), set()
        if not any(c.keyword in ("PRE-TENSION SECTION", "CONNECTOR SECTION")
                   for c in self.cards):
            return []                  # no bolt: the deck's sets need not be indexed
        self._index_cards()
        out = []
        for card in self.cards:
            if card.keyword != "PRE-TENSION SECTION":
                continue
            self._bolt_cards.add(id(card))         # named by the notes of this reader
            if "SURFACE" in card.params:
                self._meshed_bolt(card, bodies)
                continue
            found = self._bolt(card, bodies, preload, len(out))
            if found is not None:
                out.append(found)
        return out + self._connector_bolts(bodies, preload, len(out))

    # --- the cards ----------------------------------------------------------------------
    def _index_cards(self):
        self._nsets, self._elsets, self._members, self._springs = {}, {}, {}, {}
        self._couplings, self._equations, self._connectors = {}, [], {}
        fm = self.asm.file_mesh
        self._xyz = {int(i): p for i, p in zip(fm.labels, fm.points)}
        couplings = []                  # read once every element set is known
        for k, card in enumerate(self.cards):
            kw, p = card.keyword, card.params
            etype = str(p.get("TYPE", "")).upper()
            if kw not in _INDEXED or (kw == "ELEMENT" and etype not in _MEMBERS
                                      and etype not in ("DCOUP3D", "CONN3D2")):
                continue                   # e.g. nodes and the bodies' cells
            rows = [(w, t) for w, t, _ in _rows_of(card)]
            if kw in ("NSET", "ELSET"):
                name = str(p.get(kw, "")).upper()
                (self._nsets if kw == "NSET" else self._elsets).setdefault(name, []).extend(
                    _ids(rows, "GENERATE" in p, self._nsets if kw == "NSET" else self._elsets))
            elif kw == "ELEMENT":
                self._elements(card, etype, rows)
            elif kw == "DISTRIBUTING COUPLING":
                couplings.append((card, rows))
            elif kw == "COUPLING":
                follow = self.cards[k + 1] if k + 1 < len(self.cards) else None
                if follow is not None and follow.keyword == "DISTRIBUTING":
                    ref = self._one_node(p.get("REF NODE"))
                    if ref is not None and isinstance(p.get("SURFACE"), str):
                        self._couplings[ref] = _Coupling(ref, _where(card), [card, follow],
                                                         surface=p["SURFACE"])
            elif kw == "SPRING" and "NONLINEAR" not in p:
                constants = [(w, t) for w, t in rows if t and _int(t[0]) is None]
                if constants:          # SPRING1/2 have a line of DOFs (integers) first
                    self._springs[str(p.get("ELSET", "")).upper()] = (constants[0], card)
            elif kw == "EQUATION":
                self._equations += [(eq, card) for eq in _equations(rows)]
        for card, rows in couplings:
            self._distributing(card, rows)

    def _elements(self, card, etype, rows):
        """Members and coupling elements of an ``*ELEMENT`` card (rows of other than
        integers are the mesh reader's to refuse)."""
        ids = []
        for w, t in rows:
            numbers = [_int(x) for x in t if x.strip()]
            if not numbers or None in numbers:
                continue
            ids.append(numbers[0])
            if etype in _MEMBERS and len(numbers) >= 3:
                self._members[numbers[0]] = _Member(
                    numbers[0], _MEMBERS[etype], tuple(numbers[1:3]), _row_where(w),
                    card.params.get("ELSET") if len(rows) == 1 else None)
            elif etype == "CONN3D2" and len(numbers) >= 3:
                self._connectors[numbers[0]] = tuple(numbers[1:3])
            elif etype == "DCOUP3D" and len(numbers) >= 2:
                self._members[numbers[0]] = _Member(numbers[0], "dcoup", (numbers[1],),
                                                    _row_where(w))
        if "ELSET" in card.params:
            self._elsets.setdefault(str(card.params["ELSET"]).upper(), []).extend(ids)

    def _distributing(self, card, rows):
        elems = self._elsets.get(str(card.params.get("ELSET", "")).upper(), [])
        refs = [self._members[e].nodes[0] for e in elems
                if e in self._members and self._members[e].kind == "dcoup"]
        if len(refs) != 1:
            return
        nodes, weights = [], []
        for w, t in rows:
            ref = t[0].strip() if t else ""
            got = [_int(ref)] if _int(ref) is not None else self._nsets.get(ref.upper(), [])
            weight = t[1].strip() if len(t) > 1 else ""
            nodes += got
            weights += [_number(weight, w, "a coupling weight") if weight else 1.0] * len(got)
        self._couplings[refs[0]] = _Coupling(refs[0], _where(card), [card], nodes=nodes,
                                             weights=weights)

    def _one_node(self, ref):
        if ref is None or ref is True:
            return None
        ref = str(ref).strip()
        if ref.lstrip("-").isdigit():
            return int(ref)
        nodes = self._nsets.get(ref.upper(), [])
        return nodes[0] if len(nodes) == 1 else None

    # --- one bolt -----------------------------------------------------------------------
    def _bolt(self, card, bodies, preload, j):
        """The ``[[bolts]]`` table of the pretension section ``card`` (ELEMENT= form),
        or None with a note saying what is missing."""
        where = _where(card)
        fix = ("a bolt is two *DISTRIBUTING COUPLINGs (or *COUPLING with *DISTRIBUTING) "
               "on washer faces of two bodies, an axial member (B31, T3D2, SPRINGA) "
               "between their reference nodes carrying the *PRE-TENSION SECTION, and "
               "*CLOAD on DOF 1 of its node in the first *STATIC step (docs/mesh-io.md)")
        element = str(card.params.get("ELEMENT", "")).strip()
        elems = [int(element)] if element.lstrip("-").isdigit() else \
            self._elsets.get(element.upper(), [])
        member = self._members.get(elems[0]) if len(elems) == 1 else None
        node = self._one_node(card.params.get("NODE"))
        if member is None or member.kind not in ("beam", "truss") or node is None:
            self.note(where, "*PRE-TENSION SECTION: its ELEMENT= is no single B31 or T3D2 "
                      "element, or its NODE= no single node", fix, True)
            return None
        chain = self._chain(member)
        head = self._xyz.get(member.nodes[0], np.zeros(3))
        refs = sorted((n for n in chain["nodes"] if n in self._couplings),
                      key=lambda n: float(np.linalg.norm(self._xyz.get(n, head) - head)))
        if len(refs) != 2 or chain["branched"]:
            self.note(where, f"*PRE-TENSION SECTION: the member's chain reaches "
                      f"{len(refs)} coupling reference node(s)"
                      + (" and branches" if chain["branched"] else ""), fix, True)
            return None
        # a bolt's cards and its pretension node: named by this card's notes from here on
        self._bolt_cards |= {id(c) for r in refs for c in self._couplings[r].cards}
        self._bolt_cards |= {id(card)} | chain["cards"]
        self._bolt_refs |= {n.upper() for n in self._node_names(node)}
        ends = [self._washer(self._couplings[r], bodies) for r in refs]
        if any(e is None for e in ends):
            return None
        (ka, set_a), (kb, set_b) = ends
        if ka == kb:
            self.note(where, "*PRE-TENSION SECTION: both couplings of the bolt lie on one "
                      "body", "a bolt joins two bodies: put its washers on both", True)
            return None
        N0 = self._pretension(node, preload, where)
        k = self._stiffness(chain["members"], member, where)
        if N0 is None or k is None:
            return None
        name = element if not element.lstrip("-").isdigit() else \
            str(member.elset or f"bolt{j + 1}")
        names = [b["table"]["name"] for b in bodies]
        table = {"name": name, "body_a": names[ka], "set_a": set_a, "body_b": names[kb],
                 "set_b": set_b, "pretension": N0, "stiffness": k}
        return table, (f"*PRE-TENSION SECTION, {where}: pretension the *CLOAD on node "
                       f"{node}, stiffness the members in series; washers the couplings "
                       f"of reference nodes {refs[0]} and {refs[1]}")

    def _chain(self, member) -> dict:
        """The members joined to ``member`` through shared nodes and ``*EQUATION`` ties
        between nodes of no body: nodes, members, cards, whether it branches."""
        body_nodes = self._body_node_ids()
        free = lambda n: n not in body_nodes
        ties = [(eq, c) for eq, c in self._equations
                if all(free(n) for n, _, _ in eq)]
        nodes, members, cards = set(member.nodes), [member], set()
        grown = True
        while grown:
            grown = False
            for m in self._members.values():
                if m.kind in _MEMBERS.values() and m not in members and \
                        nodes & set(m.nodes):
                    members.append(m)
                    nodes |= set(m.nodes)
                    grown = True
            for eq, c in ties:
                linked = {n for n, _, _ in eq}
                if nodes & linked and not linked <= nodes:
                    nodes |= linked
                    grown = True
        for eq, c in ties:
            if {n for n, _, _ in eq} <= nodes:
                cards.add(id(c))
        degree = {}
        for m in members:
            for n in m.nodes:
                degree[n] = degree.get(n, 0) + 1
        for elset, (_, c) in self._springs.items():
            if any(m.elem in self._elsets.get(elset, []) for m in members):
                cards.add(id(c))
        for c in self.cards:
            if c.keyword == "BEAM SECTION" and any(
                    m.elem in self._elsets.get(str(c.params.get("ELSET", "")).upper(), [])
                    for m in members):
                cards.add(id(c))
        return dict(nodes=nodes, members=members, cards=cards,
                    branched=any(d > 2 for d in degree.values()))

    def _body_node_ids(self) -> set:
        if not hasattr(self, "_body_ids"):
            fm = self.asm.file_mesh
            used = np.unique(np.concatenate(
                [conn.ravel() for t, _, conn, cell in fm.blocks
                 if cell and t in self.asm.cell_types] or [np.zeros(0, np.int64)]))
            self._body_ids = set(np.asarray(fm.labels)[used].astype(int).tolist())
        return self._body_ids

    def _washer(self, coupling, bodies):
        """``(body index, facet set)`` of a coupling's washer, or None with a note."""
        if coupling.surface is not None:
            owners = [(k, f) for k, b in enumerate(bodies)
                      for f in [self._find(b["mesh"], coupling.surface, ("facet",))]
                      if f is not None]
            if len(owners) == 1:
                method = str(coupling.cards[-1].params.get("WEIGHTING METHOD", "UNIFORM"))
                if method.upper() != "UNIFORM":
                    self.note(coupling.where, f"*DISTRIBUTING, WEIGHTING METHOD={method}",
                              "qsma spreads the bolt force as a uniform traction over the "
                              "washer (WEIGHTING METHOD=UNIFORM) and does not use other "
                              "weightings; the difference changes the preload near the "
                              "washer only", False)
                return owners[0]
            self.note(coupling.where, f"*COUPLING on surface {coupling.surface!r}, which "
                      f"is the element faces of {len(owners)} bodies", "a washer is a "
                      "*SURFACE, TYPE=ELEMENT of faces of one body", True)
            return None
        xyz = {tuple(self._xyz[n]) for n in coupling.nodes if n in self._xyz}
        for k, b in enumerate(bodies):
            mesh = b["mesh"]
            pts = {tuple(p) for p in np.pad(mesh.points, ((0, 0), (0, 3 - mesh.dim)))}
            if not xyz or not xyz <= pts:
                continue
            for name, facets in mesh.facet_sets.items():
                rows = np.pad(mesh.points[np.unique(facets)], ((0, 0), (0, 3 - mesh.dim)))
                if len(facets) and {tuple(p) for p in rows} == xyz:
                    self._weights_note(coupling, mesh, name)
                    return k, name
        self.note(coupling.where, "*DISTRIBUTING COUPLING: its nodes are the nodes of no "
                  "element-face surface of one body", "give the washer as a *SURFACE, "
                  "TYPE=ELEMENT of exactly the coupling's nodes (qsma spreads the bolt "
                  "force over it as a uniform traction)", True)
        return None

    def _weights_note(self, coupling, mesh, name):
        """A note where the deck's coupling weights are not those of a uniform traction
        over the washer, the distribution qsma gives the bolt force."""
        if not coupling.weights or min(coupling.weights) < 0 or sum(coupling.weights) <= 0:
            return
        deck = {}
        for n, w in zip(coupling.nodes, coupling.weights):
            key = tuple(np.pad(self._xyz[n], (0, 3 - len(self._xyz[n]))))
            deck[key] = deck.get(key, 0.0) + w
        total = sum(deck.values())
        nodes, w_uniform, _, _ = washer_weights(_Washer(mesh, name), name)
        pts = np.pad(mesh.points[nodes], ((0, 0), (0, 3 - mesh.dim)))
        w_deck = np.array([deck.get(tuple(p), 0.0) for p in pts]) / total
        gap = float(np.max(np.abs(w_deck - w_uniform)) / np.max(np.abs(w_uniform)))
        if gap > WEIGHTS_RTOL:
            self.note(coupling.where, f"*DISTRIBUTING COUPLING: the deck's weights differ "
                      f"from those of a uniform traction over the washer by up to "
                      f"{100 * gap:.3g} % of the largest", "qsma spreads the bolt force as "
                      "a uniform traction (the consistent nodal forces, docs/theory.md "
                      "section 11) and does not use the deck's weights; the difference "
                      "changes the preload near the washer only. To see it, run the deck "
                      "in CalculiX with weights proportional to the washer's nodal areas",
                      False)

    def _node_names(self, node) -> set:
        """How load rows name ``node``: its id and the node sets of it alone."""
        return {str(node)} | {n for n, ids in self._nsets.items() if ids == [node]}

    def _pretension(self, node, preload, where):
        """The pretension: the ``*CLOAD`` on DOF 1 of ``node`` in the preload step."""
        held = (f"*BOUNDARY on the pretension node {node} in the preload step",
                "qsma's bolts are force controlled: give the pretension as *CLOAD on DOF "
                "1 of the node")
        summed = self._component_one_load(preload, self._node_names(node), "CLOAD",
                                          "BOUNDARY", held, "the pretension")
        if summed is None:
            return None
        total, found = summed
        if not found or total <= 0:
            self.note(where, f"*PRE-TENSION SECTION with node {node}: "
                      + ("no *CLOAD on its DOF 1 in the first *STATIC step" if not found
                         else f"the pretension {total:g} is not a tension"),
                      "give the bolt tension (> 0) as *CLOAD, node, 1, N0 in the first "
                      "*STATIC step", True)
            return None
        return total

    def _stiffness(self, members, pretensioned, where):
        """The locked stiffness of the members in series (module docstring)."""
        others = [m for m in members if m is not pretensioned]
        parts = others if others else [pretensioned]
        ks = [self._member_stiffness(m) for m in parts]
        if any(k is None or k <= 0 for k in ks):
            bad = parts[[k is None or k <= 0 for k in ks].index(True)]
            self.note(bad.where, f"the stiffness of bolt member {bad.elem} ({bad.kind})",
                      "give a SPRINGA its linear *SPRING constant, a B31 a *BEAM SECTION "
                      "(RECT, CIRC or PIPE) and a T3D2 a *SOLID SECTION area, each with "
                      "a material of *ELASTIC", True)
            return None
        if not others:
            self.note(where, f"the bolt's locked stiffness is its member's E A / L = "
                      f"{ks[0]:.6g}", "CalculiX deletes a beam that carries a pretension "
                      "section and holds the bolt rigid once its node is fixed; put a "
                      "SPRINGA of that stiffness in series to run the same bolt in "
                      "CalculiX (qsma export --calculix writes it so)", False)
        return ks[0] if len(ks) == 1 else 1.0 / sum(1.0 / k for k in ks)

    def _member_stiffness(self, m):
        length = float(np.linalg.norm(self._xyz[m.nodes[1]] - self._xyz[m.nodes[0]])) \
            if all(n in self._xyz for n in m.nodes) else 0.0
        if m.kind == "spring":
            for elset, (row, _) in self._springs.items():
                if m.elem in self._elsets.get(elset, []):
                    return _number(row[1][0], row[0], "the spring constant")
            return None
        area, material = self._section_area(m)
        E = self.materials.get(str(material).upper())
        if area is None or E is None or E.elastic is None or length == 0.0:
            return None
        return E.elastic[0] * area / length

    def _section_area(self, m):
        """``(area, material name)`` of a truss or beam member, or ``(None, None)``."""
        for c in self.cards:
            elset = str(c.params.get("ELSET", "")).upper()
            if m.elem not in self._elsets.get(elset, []):
                continue
            rows = [t for _, t, _ in _rows_of(c)]
            if c.keyword == "SOLID SECTION" and m.kind == "truss" and rows:
                return float(rows[0][0]), c.params.get("MATERIAL")
            if c.keyword == "BEAM SECTION" and rows:
                d = [float(x) for x in rows[0] if x.strip()]
                shape = str(c.params.get("SECTION", "")).upper()
                area = {"RECT": lambda: d[0] * d[1], "CIRC": lambda: math.pi * d[0] ** 2,
                        "PIPE": lambda: math.pi * (d[0] ** 2 - (d[0] - d[1]) ** 2)}.get(shape)
                return (area() if area else None), c.params.get("MATERIAL")
        return None, None

    # --- a meshed bolt ------------------------------------------------------------------
    def _meshed_bolt(self, card, bodies):
        """A pretension section cutting a meshed bolt: refused with the pattern to write
        instead and, where the surface can be measured, ``E A / L`` of the cut."""
        surface = str(card.params["SURFACE"])
        node = self._one_node(card.params.get("NODE"))
        if node is not None:               # its load is named by this note
            self._bolt_refs |= {n.upper() for n in self._node_names(node)}
        measured = self._cut(surface)
        hint = ""
        if measured is not None:
            area, length, E = measured
            hint = (f"; for this bolt: cut area A = {area:.6g}, length along the section "
                    f"normal L = {length:.6g}, E = {E:.6g}: stiffness = E A / L = "
                    f"{E * area / length:.6g}")
        self.note(_where(card), f"*PRE-TENSION SECTION, SURFACE={surface} cuts a meshed "
                  f"bolt", "qsma's bolts are axial members between two washer faces: "
                  "remove the meshed bolt and write two *DISTRIBUTING COUPLINGs on the "
                  "washer faces, a B31 between their reference nodes with *PRE-TENSION "
                  "SECTION, ELEMENT= and a SPRINGA of the bolt's stiffness in series, the "
                  "pretension as *CLOAD on DOF 1 of the section's node (or a [[bolts]] "
                  "table: qsma init)" + hint, True)

    def _cut(self, surface):
        """``(area, length, E)`` of a pretension surface: the area of its faces, the
        extent of the body holding them along their mean normal, that body's modulus;
        None where the faces cannot be found."""
        fm = self.asm.file_mesh
        card = next((c for c in self.cards if c.keyword == "SURFACE" and
                     str(c.params.get("NAME", "")).upper() == surface.upper()), None)
        if card is None or fm.element_ids is None:
            return None
        where = {}
        for b, ids in enumerate(fm.element_ids):
            for r, e in enumerate(np.asarray(ids).tolist()):
                where[int(e)] = (b, r)
        normal, area, elems = np.zeros(3), 0.0, []
        for _, t, _ in _rows_of(card):
            if len(t) < 2 or not t[0].strip().isdigit() or int(t[0]) not in where:
                continue
            b, r = where[int(t[0])]
            ctype, _, conn, _ = fm.blocks[b]
            number = _int(t[1].strip().upper().lstrip("S"))
            faces = abaqus_faces(ctype) if ctype in CELL_TYPES else ()
            if number is None or not 1 <= number <= len(faces):
                continue                   # not a face of a cell: not measured
            face = faces[number - 1]
            x = fm.points[conn[r][list(face)]]
            corners = x[:4] if len(face) >= 8 else x[:3] if len(face) == 6 else x
            n = 0.5 * np.cross(corners[2] - corners[0], corners[-1] - corners[1]) \
                if len(corners) == 4 else 0.5 * np.cross(corners[1] - corners[0],
                                                         corners[2] - corners[0])
            normal, area = normal + n, area + float(np.linalg.norm(n))
            elems.append((b, r))
        if not elems or not np.linalg.norm(normal):
            return None
        normal /= np.linalg.norm(normal)
        offsets = np.concatenate([[0], np.cumsum([len(c) for _, _, c, _ in fm.blocks])])
        first = offsets[elems[0][0]] + elems[0][1]
        body = next((k for k, cells in enumerate(self.asm.components()) if first in cells),
                    None)
        if body is None or body >= len(self._body_list):
            return None
        nodes = np.unique(np.concatenate([fm.blocks[b][2][i - offsets[b]]
                                          for b in range(len(fm.blocks))
                                          for i in self.asm.components()[body]
                                          if offsets[b] <= i < offsets[b + 1]]))
        s = fm.points[nodes] @ normal
        return area, float(s.max() - s.min()), float(self._body_list[body]["table"]["E"])


def _int(token):
    """An integer token as an int, else None."""
    token = token.strip()
    return int(token) if token.lstrip("-").isdigit() else None


def _ids(rows, generate, sets) -> list:
    """Ids of ``*NSET``/``*ELSET`` rows (numbers, GENERATE ranges, names of sets);
    what is none of them is the mesh reader's to refuse."""
    out = []
    for _, t in rows:
        vals = [x.strip() for x in t if x.strip()]
        if generate:
            first, last, step = ([_int(v) for v in vals] + [1, 1, 1])[:3]
            if None not in (first, last, step) and step > 0 and len(vals) >= 2:
                out += list(range(first, last + 1, step))
            continue
        for v in vals:
            out += [_int(v)] if _int(v) is not None else sets.get(v.upper(), [])
    return out


def _equations(rows) -> list:
    """``[[(node, dof, coefficient), ...]]`` of an ``*EQUATION`` card's data lines."""
    out, pending, count = [], [], None
    for w, t in rows:
        vals = [x for x in t if x.strip()]
        if count is None:
            count = _int(vals[0]) if vals else None
            if count is None:
                return out             # not an equation qsma can read: named as such
            continue
        for k in range(0, len(vals) - 2, 3):
            node, dof = _int(vals[k]), _int(vals[k + 1])
            pending.append((-1 if node is None else node, dof or 0,
                            _number(vals[k + 2], w, "a coefficient")))
        if len(pending) >= count:
            out.append(pending)
            pending, count = [], None
    return out
