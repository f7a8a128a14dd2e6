r"""qsma's bolts as CalculiX 2.20 runs them (:func:`qsma.deck.export_calculix`).

A qsma bolt (:class:`qsma.model.Bolt`) joins the washer centroids of two bodies by
distributing couplings, carries its pretension ``N0`` in the preload and is a spring
``k`` locked at the preloaded length afterwards. CalculiX has every piece, but not in
one element: its pretension section of a beam (``*PRE-TENSION SECTION, ELEMENT=``)
deletes the beam and keeps a constraint ``n . (u_2 - u_1) + u_P = 0`` with the
pretension node ``P``: force controlled while ``P`` is free and loaded (``*CLOAD``),
rigid once ``P`` is held (``*BOUNDARY, FIXED``). The deck therefore writes per bolt
four nodes and a chain

.. code-block:: text

    washer a --DCOUP3D-- A --B31 with pretension section-- M --SPRINGA k-- B --DCOUP3D-- washer b

``A`` and ``B`` are the reference nodes of ``*DISTRIBUTING COUPLING`` with qsma's
washer weights (the consistent nodal forces of a uniform traction,
:func:`qsma.fe.bolts.washer_weights`: ``u_A = sum w_i u_i``, as qsma's reference
point), ``M`` lies halfway on the axis and follows ``B`` across the axis
(``*EQUATION``: ``M - B`` parallel to the axis, so that the spring acts along the
axis only and ``M`` is held in every direction). In the preload the spring carries
``N0`` whatever its stiffness (the chain is force controlled); held afterwards, the
bolt force is ``N0 + k (ell - ell_pre)``, qsma's locked bolt. CalculiX's
``*COUPLING`` with ``*DISTRIBUTING`` is not used: in CalculiX it spreads loads of the
reference node only and ties no motion to it.

A meshed bolt cut by a pretension section (:class:`qsma.model.SectionBolt`) is
CalculiX's own ``*PRE-TENSION SECTION, SURFACE=``: the section's faces as an element
surface of the cells that own them, the section's normal as its data line, one
pretension node loaded, then held, like the beam's (:class:`SectionLayout`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..fe.bolts import bolt_vectors, washer_weights
from ..fe.sections import section_terms
from ..mesh.celltypes import abaqus_faces
from ..mesh.io.abaqus.writer import inp_number
from .calculix_cards import CalculixRefusal

#: Deck nodes per bolt: the two coupling reference nodes, the middle node, the
#: pretension node.
NODES_PER_BOLT = 4
#: Deck elements per bolt: two DCOUP3D, the B31 of the pretension section, the SPRINGA.
ELEMENTS_PER_BOLT = 4


@dataclass(frozen=True)
class BoltLayout:
    """A bolt as the deck writes it.

    Attributes
    ----------
    bolt : the :class:`qsma.model.Bolt`
    ends : per end (a, b): ``(body index, washer nodes, weights, centroid)`` (nodes of
        the body's mesh, weights summing to 1)
    axis : unit vector from the centroid of washer a to that of washer b
    length : distance of the two centroids
    nodes : deck numbers ``(A, B, M, P)``
    elements : deck numbers ``(coupling a, coupling b, beam, spring)``
    """

    bolt: object
    ends: tuple
    axis: np.ndarray
    length: float
    nodes: tuple
    elements: tuple

    @property
    def label(self) -> str:
        return "".join(c if c.isalnum() else "_" for c in self.bolt.name)


def bolt_layouts(model, first_node: int, first_element: int) -> list:
    """The :class:`BoltLayout` of every bolt of ``model``, nodes numbered from
    ``first_node`` and elements from ``first_element`` (after the bodies')."""
    if model.bolts and model.dim != 3:
        names = ", ".join(repr(b.name) for b in model.bolts)
        raise CalculixRefusal(
            f"bolt(s) {names} of a 2D model: CalculiX 2.20 expands 2D elements into a "
            f"layer of 3D ones and has no distributing coupling or pretension section "
            f"between plane bodies: model the joint in 3D to compare its bolts in "
            f"CalculiX, or export the 2D model with each bolt's pretension as washer "
            f"pressures (p = N0 / washer width on set_a and set_b)")
    out = []
    for j, bolt in enumerate(b for b in model.bolts if not hasattr(b, "section")):
        bolt_vectors(model, bolt)                  # the geometry checks of a run
        ends = []
        for body_name, set_name in ((bolt.body_a, bolt.set_a), (bolt.body_b, bolt.set_b)):
            k = model.body_index(body_name)
            nodes, w, _, centroid = washer_weights(model.bodies[k], set_name)
            ends.append((k, nodes, w, centroid))
        axis = ends[1][3] - ends[0][3]
        length = float(np.linalg.norm(axis))
        n0, e0 = first_node + NODES_PER_BOLT * j, first_element + ELEMENTS_PER_BOLT * j
        out.append(BoltLayout(bolt, tuple(ends), axis / length, length,
                              tuple(range(n0, n0 + NODES_PER_BOLT)),
                              tuple(range(e0, e0 + ELEMENTS_PER_BOLT))))
    return out


@dataclass(frozen=True)
class SectionLayout:
    """A meshed bolt as the deck writes it: its pretension node ``nodes[3]`` (the
    other entries unused, as :class:`BoltLayout`'s for :func:`preload_cards`), placed
    at the section's centroid, and the section's faces ``(element, face number)``."""

    bolt: object
    body: int
    nodes: tuple
    centroid: np.ndarray
    normal: np.ndarray
    faces: list


def section_layouts(model, first_node: int, first_element) -> list:
    """The :class:`SectionLayout` of every meshed bolt of ``model``: pretension nodes
    numbered from ``first_node``; ``first_element``: per body its first element."""
    out = []
    for j, bolt in enumerate(b for b in model.bolts if hasattr(b, "section")):
        k = model.body_index(bolt.body)
        body = model.bodies[k]
        t = section_terms(body, bolt)
        out.append(SectionLayout(bolt, k, (None, None, None, first_node + j),
                                 body.mesh.points[t.nodes].mean(axis=0), t.normal,
                                 section_faces(body, bolt, first_element[k])))
    return out


def section_faces(body, bolt, first_element) -> list:
    """``(element number, face number)`` of each face of the section, of the cell that
    owns it (Abaqus face numbering, :func:`qsma.mesh.celltypes.abaqus_faces`)."""
    t = section_terms(body, bolt)
    faces = [sorted(f) for f in abaqus_faces(body.mesh.cell_type)]
    out = []
    for row, cell in zip(body.mesh.facet_sets[bolt.section], t.face_owners):
        conn = body.mesh.cells[cell]
        local = sorted(int(np.flatnonzero(conn == node)[0]) for node in row)
        out.append((first_element + int(cell), 1 + faces.index(local)))
    return sorted(out)


def section_cards(layouts, surface_names) -> list:
    """The surfaces and pretension sections of the meshed bolts (model data);
    ``surface_names``: the deck name of each one's surface."""
    out = []
    for lay, name in zip(layouts, surface_names):
        out += [f"** meshed bolt {lay.bolt.name!r}: pretension {lay.bolt.pretension:g} "
                f"across the section {lay.bolt.section!r} of body {lay.bolt.body!r} "
                f"(faces of the cells on one side; its normal out of them)",
                f"*SURFACE, NAME={name}, TYPE=ELEMENT",
                *[f"{e}, S{f}" for e, f in lay.faces],
                f"*PRE-TENSION SECTION, SURFACE={name}, NODE={lay.nodes[3]}",
                ", ".join(_num(c) for c in lay.normal)]
    return out


def _num(x) -> str:
    """A real CalculiX reads as a real (its ``*SPRING`` tells reals from integers by
    the decimal point or exponent)."""
    text = inp_number(float(x))
    return text if any(c in text for c in ".eE") else text + "."


def node_rows(layouts) -> list:
    """``*NODE`` rows of the bolts' nodes (under the deck's ``*NODE`` card)."""
    out = []
    for lay in layouts:
        a, b = lay.ends[0][3], lay.ends[1][3]
        A, B, M, P = lay.nodes
        out.append(f"** bolt {lay.bolt.name!r}: coupling reference nodes {A} (washer "
                   f"a) and {B} (washer b), middle node {M}, pretension node {P}")
        for node, x in ((A, a), (B, b), (M, (a + b) / 2), (P, a)):
            out.append(", ".join([str(node)] + [inp_number(float(v)) for v in x]))
    return out


def _coupling_rows(lay, end, first_node, clamped) -> list:
    """``node, weight`` rows of one washer, the largest weight of a node no clamp holds
    first (CalculiX makes the first node the dependent of the coupling's equations)."""
    k, nodes, w, _ = lay.ends[end]
    order = sorted(range(len(nodes)), key=lambda i: (int(nodes[i]) in clamped[k], -w[i]))
    return [f"{first_node[k] + int(nodes[i])}, {_num(w[i])}" for i in order]


def model_cards(layouts, first_node, clamped, material, E, taken=()) -> list:
    """The couplings, members, pretension sections and ties of the bolts (model data).

    ``first_node``: per body its first deck node; ``clamped``: per body the set of its
    nodes some clamp holds; ``material``, ``E``: a material of the deck and its modulus
    (CalculiX asks a section of the beam it deletes: a square shank whose ``E A / L``
    over the bolt's length is ``k``, the bolt's stiffness for a reader that takes the
    beam alone as the member); ``taken``: element set names
    in use (upper case). The beam's element set is the bolt's name, which the deck
    reader gives the bolt back (CalculiX 2.20 reads ``ELEMENT=`` as a number only)."""
    out = []
    for lay in layouts:
        A, B, M, P = lay.nodes
        ea, eb, beam, spring = lay.elements
        n, name, bolt = lay.axis, lay.label, lay.bolt
        pre = name if name.upper() not in taken and name[:1].isalpha() else f"BOLT_{name}"
        out.append(f"** bolt {bolt.name!r}: pretension {bolt.pretension:g}, locked "
                   f"stiffness k = {bolt.stiffness:g}; washer a = {bolt.set_a!r} of "
                   f"{bolt.body_a!r}, washer b = {bolt.set_b!r} of {bolt.body_b!r}")
        for end, (elem, ref) in enumerate(((ea, A), (eb, B))):
            elset = f"BOLT_{name}_{'AB'[end]}"
            out += [f"*ELEMENT, TYPE=DCOUP3D, ELSET={elset}", f"{elem}, {ref}",
                    f"*DISTRIBUTING COUPLING, ELSET={elset}",
                    *_coupling_rows(lay, end, first_node, clamped)]
        side = np.sqrt(bolt.stiffness * lay.length / E)
        cross = np.eye(3)[int(np.argmin(np.abs(n)))]
        out += ["** the member: its pretension section of a B31 beam (CalculiX deletes the "
                "beam and keeps a constraint, force controlled while the pretension node "
                "is free, rigid once it is held) in series with the spring k",
                f"*ELEMENT, TYPE=B31, ELSET={pre}", f"{beam}, {A}, {M}",
                f"*BEAM SECTION, ELSET={pre}, MATERIAL={material}, SECTION=RECT",
                f"{_num(side)}, {_num(side)}", ", ".join(_num(c) for c in cross),
                f"*PRE-TENSION SECTION, ELEMENT={beam}, NODE={P}",
                ", ".join(_num(c) for c in n),
                f"*ELEMENT, TYPE=SPRINGA, ELSET=BOLT_{name}_K", f"{spring}, {M}, {B}",
                f"*SPRING, ELSET=BOLT_{name}_K", "", _num(bolt.stiffness)]
        out += _transverse_ties(M, B, n)
    return out


def _transverse_ties(M, B, n) -> list:
    """``*EQUATION``: ``d = u_M - u_B`` parallel to ``n`` (``n_i d_j - n_j d_i = 0`` for
    the two components ``j`` other than ``n``'s largest ``i``), ``M``'s DOF ``j``
    dependent."""
    i = int(np.argmax(np.abs(n)))
    out = []
    for j in range(3):
        if j == i:
            continue
        terms = [(M, j, n[i]), (B, j, -n[i])]
        if n[j] != 0.0:
            terms += [(M, i, -n[j]), (B, i, n[j])]
        out += ["*EQUATION", str(len(terms)),
                ", ".join(f"{node}, {c + 1}, {_num(v)}" for node, c, v in terms)]
    return out


def preload_cards(layouts) -> list:
    """``*CLOAD`` of every bolt's pretension on its pretension node."""
    if not layouts:
        return []
    return ["** the bolts' pretensions (force controlled: the pretension nodes are free)",
            "*CLOAD"] + [f"{lay.nodes[3]}, 1, {_num(lay.bolt.pretension)}"
                         for lay in layouts]


def locked_cards(layouts) -> list:
    """The pretension nodes held where the preload left them: the bolts locked."""
    if not layouts:
        return []
    return ["** the bolts locked at their preloaded length: springs k from here on",
            "*BOUNDARY, FIXED"] + [f"{lay.nodes[3]}, 1, 1" for lay in layouts]


def tied_cards(layouts) -> list:
    """The pretension nodes held at zero (the tied deck has no preload: the locked
    bolts as springs k about the unstressed state)."""
    if not layouts:
        return []
    return ["** the bolts locked: the pretension nodes held", "*BOUNDARY"] + \
        [f"{lay.nodes[3]}, 1, 1, 0." for lay in layouts]


def spring_forces(layouts, u) -> np.ndarray:
    """The force in each bolt's spring from CalculiX's printed displacements ``u``
    (``u[i]`` of deck node ``i + 1``): ``k n . (u_B - u_M)``."""
    return np.array([lay.bolt.stiffness * float(lay.axis @ (u[lay.nodes[1] - 1]
                                                             - u[lay.nodes[2] - 1]))
                     for lay in layouts])
