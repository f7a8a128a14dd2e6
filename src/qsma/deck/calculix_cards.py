"""What a CalculiX 2.20 deck of a qsma model is made of, shared by the writer
(:mod:`qsma.deck.calculix_writer`) and the CalculiX benchmarks: the settings of the
contact and the steps, CalculiX's element names, its numbers, numbering and faces, and
what it cannot hold as qsma computes it (refused by name, :class:`CalculixRefusal`)."""
from __future__ import annotations

import numpy as np

from ..contact.laws import ElasticStick, InterfaceLaw
from ..errors import InputError
from ..fe.formulation import resolve_formulations
from ..mesh.celltypes import CELL_TYPES, abaqus_faces
from ..mesh.io.abaqus.writer import inp_number
from ..mesh.mesh import facet_index

#: Slope of the penalty that stands for qsma's hard contact, as a multiple of ``E / h``
#: (Pa/m): a node's penalty spring ``K A ~ K h^(d-1)`` against the elastic stiffness of
#: the bodies at a node ``~ E h^(d-2)`` is then 1e4, so the contact forces differ from
#: hard contact by ~1e-4 of their size (bench_bolt_calculix measured the difference
#: falling as 1 / K: 3.1e-4, 3.1e-5, 3.2e-6 at K = 1e16, 1e17, 1e18 Pa/m, where E / h
#: = 4e14 Pa/m), while CalculiX's equations keep ~12 of their 16 digits.
PENALTY_FACTOR = 1e4
#: sigma_inf of CalculiX's linear pressure-overclosure law (Pa, its second value): the
#: tension its node-to-surface springs carry at small clearances. Its default, E / 70000
#: (2.9 MPa for steel), made open nodes near the contact pull and shifted the pressure
#: (RMS radius -6.5 % on the bolted stack, benchmarks/bench_bolt_calculix.py); 1 Pa
#: leaves the law qsma's (no tension).
TENSION = 1.0
#: c0 of CalculiX's linear law (its third value, relative to the square root of the slave
#: node's area): the clearance up to which the tension above acts. At its default 1e-3
#: the open pairs near the contact kept a spring in the frequency step and sandwich-2d's
#: tied f0 came out 224.0 Hz, the frequency with every pair tied (qsma: 212.54 Hz with
#: the 17 closed pairs tied); at 1e-9 they are free, as qsma leaves them.
TENSION_RANGE = 1e-9
#: CalculiX's equilibrium controls (``*CONTROLS, PARAMETERS=FIELD``): force residual
#: and solution-correction ratios far tighter than its defaults (0.005, 0.01), so that
#: its answer is converged as far as qsma's (benchmarks/bench_law_calculix.py).
FIELD_CONTROLS = "1e-6, 1e-5, , , 1e-6, 1e-5"
#: Increments per branch of a cyclic step (0 -> +A, +A -> -A, -A -> +A).
LOOP_STEPS = 20
#: Cycles (+A -> -A -> +A) per amplitude of the cyclic steps, and the fewest allowed:
#: the last is compared with qsma's stabilised loop, the one before it says whether
#: CalculiX's loop has settled (a first cycle may slip where later ones do not).
LOOP_CYCLES = 2

#: Element names of CalculiX 2.20 per (cell type, kinematics); what is missing is refused.
_ELEMENTS = {
    ("triangle", "plane strain"): "CPE3", ("triangle", "plane stress"): "CPS3",
    ("quad", "plane strain"): "CPE4", ("quad", "plane stress"): "CPS4",
    ("triangle6", "plane strain"): "CPE6", ("triangle6", "plane stress"): "CPS6",
    ("quad8", "plane strain"): "CPE8", ("quad8", "plane stress"): "CPS8",
    ("tetra", "3d"): "C3D4", ("tetra10", "3d"): "C3D10",
    ("hexahedron", "3d"): "C3D8", ("hexahedron20", "3d"): "C3D20",
}


class CalculixRefusal(InputError):
    """A model that CalculiX 2.20 cannot hold as qsma computes it (the message names
    the part and what to do)."""


# --- numbering and faces, shared with the CalculiX benchmarks ------------------------
def calculix_number(x) -> str:
    """A number as CalculiX reads it whole: at most 20 characters (its ``f20.0``
    fields), the shortest text that reads back as the same double where that fits
    (:func:`qsma.mesh.io.abaqus.writer.inp_number`)."""
    return inp_number(x)


def calculix_numbering(model) -> tuple:
    """``(first_node, first_element)``: per body its first CalculiX node and element
    number (1-based, bodies in order), one entry more past the last body."""
    nodes, elements = [1], [1]
    for b in model.bodies:
        nodes.append(nodes[-1] + b.mesh.n_nodes)
        elements.append(elements[-1] + b.mesh.n_cells)
    return nodes, elements


def surface_rows(body, facet_set, first_element) -> list:
    """``(element number, face number)`` of every facet of ``facet_set`` of ``body``,
    sorted (Abaqus face numbering, :func:`qsma.mesh.celltypes.abaqus_faces`; elements
    numbered from ``first_element`` in the order of the mesh's cell blocks)."""
    mesh = body.mesh
    index = facet_index(mesh)
    found = index.find(mesh.facet_sets[facet_set])
    starts = np.cumsum([0] + [len(b.cells) for b in mesh.cell_blocks])
    numbers = []
    for b in mesh.cell_blocks:
        faces = [sorted(f) for f in abaqus_faces(b.cell_type)]
        numbers.append([1 + faces.index(sorted(local))
                        for local in CELL_TYPES[b.cell_type].facets])
    rows = []
    for i in np.unique(found):
        cell, local = int(index.cell[i]), int(index.local_face[i])
        block = int(np.searchsorted(starts, cell, side="right") - 1)
        rows.append((first_element + cell, numbers[block][local]))
    return sorted(rows)


# --- what cannot be written -----------------------------------------------------------
def calculix_element(body) -> list:
    """The CalculiX element name of each cell block of ``body`` (the formulation qsma
    computes it with, :func:`qsma.fe.formulation.resolve_formulations`); refused where
    CalculiX 2.20 has no such element."""
    f = resolve_formulations(body.mesh)
    names = []
    for part in getattr(f, "parts", (f,)):
        if part.incompatible and part.kinematics != "3d":
            raise CalculixRefusal(
                f"body {body.name!r}: {part.name} (incompatible modes in 2D) has no "
                f"CalculiX 2.20 element (it reads CPE4I/CPS4I as unknown): give the mesh "
                f"element {part.name[:-1]} (Mesh.element) and compare that run, or model "
                f"the body in 3D with C3D8I")
        name = _ELEMENTS.get((part.cell_type, part.kinematics))
        if name is None:
            raise CalculixRefusal(
                f"body {body.name!r}: {part.name} ({part.cell_type} cells) has no "
                f"CalculiX 2.20 element (none with 9 or 27 nodes): mesh it with "
                f"{'quad8' if part.cell_type == 'quad9' else 'hexahedron20'} cells "
                f"(serendipity) to compare in CalculiX")
        names.append(name + ("I" if part.incompatible else ""))
    return names


def _refuse_what_calculix_cannot_hold(model):
    for body in model.bodies:
        calculix_element(body)
        if body.dim == 2 and (body.springs or body.masses):
            raise CalculixRefusal(
                f"body {body.name!r}: grounded springs and point masses of a 2D body have "
                f"no CalculiX 2.20 equivalent (it expands 2D elements into a layer of 3D "
                f"ones and stops on one-node SPRING1 / MASS elements at their nodes: "
                f"'add_bo_st: coefficient should be 0'): export the model without them, "
                f"or model it in 3D")
    for itf in model.interface_list:
        if itf.tied:
            raise CalculixRefusal(
                f"interface {itf.label} is tied: the export writes frictional contact "
                f"pairs and their tied decks only; compare a model whose interfaces are "
                f"all frictional, or write the tie as a *TIE by hand (its slave surface "
                f"first)")
        if itf.gap is not None:
            raise CalculixRefusal(
                f"interface {itf.label}: an initial gap field (gap=) has no CalculiX "
                f"equivalent per contact point (*CLEARANCE is one number per pair of "
                f"surface-to-surface contact): move the nodes by the gap in the mesh, "
                f"or export the interface without it")
        _surface_behavior(itf.law, 1.0, itf.label)      # refuses what has none


def _surface_behavior(law, slope, label):
    """``(cards, stick slope or None, comment lines, normal slope or None)`` of an
    interface law: ``*SURFACE BEHAVIOR``, the stick slope of ``*FRICTION`` (None: qsma's
    rigid stick, written with the penalty ``slope``) and the slope of a linear or hard
    (penalty) normal law."""
    law = law if law is not None else InterfaceLaw()
    normal, tangential = law.normal, law.tangential
    note = []
    if normal.name == "hard":
        cards = ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR",
                 f"{inp_number(slope)}, {inp_number(TENSION)}, {inp_number(TENSION_RANGE)}"]
        note.append(f"qsma's hard contact: a linear penalty of slope {slope:.6g} Pa/m "
                    f"(PENALTY_FACTOR E / h): contact forces within ~1e-4 of hard contact")
    elif normal.name == "linear":
        cards = ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR",
                 f"{inp_number(normal.k)}, {inp_number(TENSION)}, "
                 f"{inp_number(TENSION_RANGE)}"]
        note.append(f"qsma's linear law, slope {normal.k:g} Pa/m; tension "
                    f"{TENSION:g} Pa at clearances (qsma's layer carries none)")
    elif normal.name == "exponential":
        if normal.form != "calculix":
            raise CalculixRefusal(
                f"interface {label}: the exponential law in Abaqus' form (form="
                f"{normal.form!r}) is another curve than CalculiX's EXPONENTIAL: give "
                f"form='calculix', or a tabular law sampled from it")
        cards = ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=EXPONENTIAL",
                 f"{inp_number(normal.c0)}, {inp_number(normal.p0)}"]
        note.append("qsma's exponential law in CalculiX's form (c0, p0)")
    elif normal.name == "tabular":
        rows = [list(r) for r in normal.table]
        (p1, h1), (p2, h2) = rows[-2], rows[-1]
        far = h2 + 1e3 * (h2 - rows[0][1])
        rows.append([p2 + (p2 - p1) / (h2 - h1) * (far - h2), far])
        cards = ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=TABULAR"]
        cards += [f"{inp_number(p)}, {inp_number(h)}" for p, h in rows]
        note.append("qsma's tabular law; the last row continues its last slope (qsma's "
                    "law beyond the table, where CalculiX would keep the pressure)")
    else:
        raise CalculixRefusal(
            f"interface {label}: the {normal.name} law has no CalculiX pressure-"
            f"overclosure equivalent: give it as a tabular law (TabularPressure sampled "
            f"from its pressure curve) to compare in CalculiX")
    if isinstance(tangential, ElasticStick):
        stick = float(tangential.k)
        note.append(f"qsma's elastic stick, slope {stick:g} Pa/m")
    elif tangential.rigid:
        stick = None
        note.append(f"qsma's rigid stick: stick slope {slope:.6g} Pa/m (the penalty)")
    else:
        raise CalculixRefusal(
            f"interface {label}: the {tangential.name} tangential law has no CalculiX "
            f"equivalent (*FRICTION has one stick slope): use an elastic stick")
    slopes = {"hard": float(slope), "linear": getattr(normal, "k", None)}
    return cards, stick, note, slopes.get(normal.name)
