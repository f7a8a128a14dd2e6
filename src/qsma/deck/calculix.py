"""A qsma model written as a runnable CalculiX 2.20 deck of the same QSMA, so that a
result of qsma can be checked by another code (:func:`export_calculix`; the command
``qsma export --calculix OUT.inp``; docs/mesh-io.md, "Export to CalculiX").

The deck holds the same discrete problem as qsma: every body's nodes and elements (the
element qsma computes, by its Abaqus name), one material and solid section per body,
the clamps as ``*BOUNDARY``, grounded springs as ``SPRING1`` and point masses as
``MASS`` elements (each node with its share), one ``*CONTACT PAIR`` per interface with
its ``*SURFACE INTERACTION`` (the interface law and ``*FRICTION``), and the steps

1. the preload: the pressures (``*DSLOAD``) and nodal forces (``*CLOAD``) of the
   ``preload`` pattern, nonlinear static with frictional contact;
2. the tied modes: ``*FREQUENCY, PERTURBATION`` about the preloaded state. CalculiX
   keeps the contact elements of the end of step 1 in the stiffness: a closed pair is
   held by its normal penalty and its stick slope, an open one is free, which is qsma's
   tied structure (closed pairs tied, open ones free) up to the penalty (hard law) or
   exactly its layer's springs (a linear law);
3. with ``amplitudes``: for each modal force ``A`` three static steps of the modal
   load ``alpha M phi`` (qsma's mass-normalised loaded mode, as nodal forces
   ``*CLOAD``): 0 -> +A, +A -> -A, -A -> +A, in ``steps`` fixed increments per branch,
   with the displacements printed at every increment. ``q = phi^T M (u - u_pre)``
   of the printed displacements against ``alpha`` is the loop; its area the
   dissipation per cycle (:func:`qsma.deck.calculix_output.loop_dissipation`).

qsma's hard contact becomes a stiff linear penalty (CalculiX's node-to-surface contact
is a penalty method): slope :data:`PENALTY_FACTOR` ``E / h`` (``E`` the stiffer body's
modulus, ``h`` the shortest edge of the interface's facets), the same as stick slope;
contact forces then differ from qsma's by about ``1 / PENALTY_FACTOR`` of their size
(the slope is written in a comment beside it). A linear, exponential (CalculiX's form)
or tabular law is written as CalculiX's own; an elastic stick as the stick slope.
What CalculiX 2.20 cannot express is refused by name (:class:`CalculixRefusal`, an
:class:`~qsma.errors.InputError`), never changed silently.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
import re

import numpy as np

from .._infra.files import atomic_write
from ..errors import InputError
from ..fe.formulation import resolve_formulations
from ..mesh.celltypes import CELL_TYPES, abaqus_faces
from ..mesh.io.abaqus.writer import _inp_number
from ..mesh.mesh import facet_index
from ..model.spring import set_shares

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


@dataclass(frozen=True, eq=False)
class CalculixDeck:
    """A model as a CalculiX deck (:func:`calculix_deck`).

    Attributes
    ----------
    text : the deck
    first_node, first_element : per body, its first CalculiX node / element number
        (1-based, bodies in the model's order; node ``i`` of body ``k`` is
        ``first_node[k] + i``); one entry more, past the last body
    penalty : per interface (model order), the normal slope written (Pa/m; the
        penalty of hard contact or the linear law's slope, None for other laws) and the
        stick slope written (the penalty where qsma's stick is rigid)
    amplitudes : the modal forces of the cyclic steps (empty: none)
    steps : per amplitude, the number of increments per branch
    mode : qsma's preload and loaded mode when the tied deck or cyclic steps are
        written: ``f0_hz``, ``closed`` (mask of the contact points), ``phi`` and
        ``mphi`` per body ((n_nodes, dim) arrays), else None
    path : the deck written (None: not written)
    tied_text, tied_path : the tied deck (:func:`tied_deck`), where written
    """

    text: str
    first_node: tuple
    first_element: tuple
    penalty: tuple
    amplitudes: tuple = ()
    steps: int = LOOP_STEPS
    mode: dict | None = field(default=None, repr=False)
    path: Path | None = None
    tied_text: str | None = field(default=None, repr=False)
    tied_path: Path | None = None

    def per_body(self, u: np.ndarray) -> list:
        """Split nodal rows of the whole deck (``u[i]`` of node ``i + 1``) per body."""
        return [u[a - 1:b - 1] for a, b in zip(self.first_node[:-1], self.first_node[1:])]


def export_calculix(model, path, *, options=None, amplitudes=None, penalty=None,
                    steps: int = LOOP_STEPS, tied: bool = False) -> CalculixDeck:
    """Write ``model`` as a runnable CalculiX deck to ``path`` (atomically), and with
    ``tied`` its tied deck beside it (``<stem>-tied.inp``).

    Parameters
    ----------
    model : :class:`qsma.model.Model`
    path : the ``.inp`` file written
    options : :class:`qsma.options.RunOptions` (its ``mode`` and ``n_modes``, and the
        contact solver of qsma's preload when cyclic steps need qsma's mode)
    amplitudes : modal forces ``alpha`` of the cyclic steps (a sequence), or a
        :class:`qsma.levels.Levels` (``"tip"`` levels through qsma's tied mode, as a
        run converts them); None: preload and frequency steps only
    penalty : normal (and stick) slope standing for qsma's hard contact and rigid
        stick, Pa/m (None: :data:`PENALTY_FACTOR` ``E / h`` per interface)
    steps : increments per branch of the cyclic steps
    tied : also write the tied deck (:func:`tied_deck`; runs qsma's preload)

    Returns
    -------
    CalculixDeck
    """
    deck = calculix_deck(model, options=options, amplitudes=amplitudes, penalty=penalty,
                         steps=steps, tied=tied)
    path = Path(path)
    tied_path = path.with_name(f"{path.stem}-tied{path.suffix}") if tied else None
    for where, text in ((path, deck.text), (tied_path, deck.tied_text)):
        if where is None:
            continue
        try:
            atomic_write(where, text)
        except OSError as exc:
            raise InputError(f"cannot write {where}: {exc.strerror}; choose another "
                             f"file") from None
    return replace(deck, path=path, tied_path=tied_path)


def calculix_deck(model, *, options=None, amplitudes=None, penalty=None,
                  steps: int = LOOP_STEPS, tied: bool = False) -> CalculixDeck:
    """The deck (and tied deck) of :func:`export_calculix`, not written."""
    from ..options import RunOptions
    opts = options or RunOptions()
    _refuse_what_calculix_cannot_hold(model)
    if not (isinstance(steps, (int, np.integer)) and not isinstance(steps, bool)
            and steps >= 1):
        raise InputError(f"steps must be a positive integer (increments per branch), "
                         f"got {steps!r}")
    if tied:
        _refuse_tied(model)
    writer = _Writer(model, penalty)
    mode, alphas = None, ()
    if amplitudes is not None or tied:
        mode = _qsma_mode(model, opts)
    if amplitudes is not None:
        alphas = _modal_forces(amplitudes, mode)
    text = writer.deck(opts, mode, alphas, int(steps))
    tied_text = _Writer(model, penalty).tied_deck(opts, mode) if tied else None
    return CalculixDeck(text, tuple(writer.first_node), tuple(writer.first_element),
                        tuple(writer.slopes), tuple(alphas), int(steps), mode,
                        tied_text=tied_text)


# --- numbering and faces, shared with the CalculiX benchmarks ------------------------
def calculix_number(x) -> str:
    """A number as CalculiX reads it whole: at most 20 characters (its ``f20.0``
    fields), the shortest text that reads back as the same double where that fits
    (:func:`qsma.mesh.io.abaqus.writer._inp_number`)."""
    return _inp_number(x)


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
    if model.bolts:
        names = ", ".join(repr(b.name) for b in model.bolts)
        raise CalculixRefusal(
            f"bolt(s) {names}: a qsma bolt is force-controlled in the preload and a spring "
            f"locked at the preloaded length afterwards, which a CalculiX deck does not "
            f"express in one element; export the model with each bolt's pretension as "
            f"washer pressures (Pressure on set_a and set_b, p = N0 / washer area) to "
            f"check the joint, or compare the bolt preload alone with "
            f"benchmarks/bench_bolt_calculix.py")
    for itf in model.interface_list:
        if itf.gap is not None:
            raise CalculixRefusal(
                f"interface {itf.label}: an initial gap field (gap=) has no CalculiX "
                f"equivalent per contact point (*CLEARANCE is one number per pair of "
                f"surface-to-surface contact): move the nodes by the gap in the mesh, "
                f"or export the interface without it")
        _surface_behavior(itf.law, 1.0, itf.label)      # refuses what has none


# --- the deck -------------------------------------------------------------------------
def _name(text: str) -> str:
    """A plain Abaqus label (letters, digits, ``_``) of ``text``."""
    name = re.sub(r"[^A-Za-z0-9_]", "_", text)
    return name if name[:1].isalpha() else f"S_{name}"


class _Writer:
    """The cards of the deck, block by block (each with the comment of where it came
    from)."""

    def __init__(self, model, penalty):
        self.model = model
        self.first_node, self.first_element = calculix_numbering(model)
        self.next_element = self.first_element[-1]
        self.sets = {}                 # (body index, set, kind) -> deck name
        self.taken = set()
        self.penalty = penalty
        self.slopes = []

    def deck(self, opts, mode, alphas, steps) -> str:
        m = self.model
        lines = [f"** CalculiX 2.20 deck of the qsma model {m.name!r}, written by "
                 f"qsma.deck.export_calculix",
                 f"** units: {m.units} (the model's numbers as they are, nothing "
                 f"converted)",
                 "** step 1: the preload (nonlinear static, frictional contact); then "
                 + ("the cyclic modal load" if alphas else "step 2: the modes about the "
                    "preloaded state (*FREQUENCY in a PERTURBATION step)"),
                 "*HEADING", f"qsma {m.name}: preload, tied modes"
                 + (", cyclic modal load" if alphas else "")]
        lines += self.nodes() + self.elements()
        body_cards = []
        for k, b in enumerate(m.bodies):
            body_cards += self.material(k, b) + self.springs_and_masses(k, b)
        clamps, interaction = self.clamps(), self.interfaces()
        steps_cards = self.preload_step()
        if alphas:
            steps_cards += self.cyclic_steps(mode, alphas, steps)
        else:
            steps_cards += self.frequency_step(opts)
        # the sets the cards above name, defined before them
        lines += self.set_cards() + body_cards + clamps + interaction + steps_cards
        return "\n".join(lines) + "\n"

    def tied_deck(self, opts, mode) -> str:
        """qsma's tied structure as CalculiX reads it: the same bodies, supports,
        springs and masses, each contact point the preload closed tied by ``*EQUATION``
        (``u_slave = u_master`` per component for a node pair; ``u_slave = sum_j P_ij
        u_master_j`` with the mortar projection ``P``), the open ones free, and a
        linear frequency step. No preload: qsma's tied modes are those of the
        unstressed structure (the deck's perturbation step adds the preload's stress
        stiffness)."""
        m = self.model
        closed = mode["closed"]
        lines = [f"** CalculiX 2.20 tied deck of the qsma model {m.name!r}, written by "
                 f"qsma.deck.export_calculix",
                 f"** the {int(closed.sum())} of {len(closed)} contact points that qsma's "
                 f"preload closed, tied by *EQUATION; the open ones free; qsma's tied "
                 f"f0 = {mode['f0_hz']:.10g} Hz (elastic mode {opts.mode})",
                 "*HEADING", f"qsma {m.name}: tied modes"]
        lines += self.nodes() + self.elements()
        body_cards = []
        for k, b in enumerate(m.bodies):
            body_cards += self.material(k, b) + self.springs_and_masses(k, b)
        clamps = self.clamps()
        lines += self.set_cards() + body_cards + clamps + self.ties(mode)
        lines += ["** the tied modes (linear, about the unstressed state)", "*STEP",
                  "*FREQUENCY", f"{self.n_modes(opts)}", "*END STEP"]
        return "\n".join(lines) + "\n"

    def ties(self, mode) -> list:
        """``*EQUATION`` of every closed contact point (:meth:`tied_deck`): the slave
        DOF depends, or the first master DOF of the equation that no clamp and no other
        equation holds; an equation whose DOFs are all clamped holds already."""
        m, itf, pairing = self.model, self.model.interface, mode["pairing"]
        names = (itf.body1, itf.body2)
        slave = m.body_index(names[pairing.slave - 1])
        master = m.body_index(names[2 - pairing.slave])
        held = {(k, int(d)) for k in (slave, master) for d in m.bodies[k].clamped_dofs()}
        P = pairing.projection.tocsr() if pairing.projection is not None else None
        dim, used, out = m.dim, set(), ["** ties of the closed contact points"]
        for i in np.flatnonzero(mode["closed"]):
            s = int(pairing.contact_nodes[i])
            if P is None:
                partners = [(int(pairing.master_nodes[i]), 1.0)]
            else:
                row = P.getrow(i)
                partners = [(int(pairing.master_nodes[j]), float(w))
                            for j, w in zip(row.indices, row.data) if w != 0.0]
            for c in range(dim):
                terms = [(slave, s, 1.0)] + [(master, n, -w) for n, w in partners]
                free = [t for t in terms if (t[0], dim * t[1] + c) not in held
                        and (t[0], t[1], c) not in used]
                if not free:
                    continue
                first = free[0]
                used.add((first[0], first[1], c))
                terms = [first] + [t for t in terms if t is not first
                                   and (t[0], dim * t[1] + c) not in held]
                entries = [f"{self.first_node[k] + n}, {c + 1}, {_inp_number(w)}"
                           for k, n, w in terms]
                out += ["*EQUATION", str(len(entries))]
                out += [", ".join(entries[j:j + 4]) for j in range(0, len(entries), 4)]
        return out

    def n_modes(self, opts) -> int:
        """Modes asked of CalculiX: qsma's loaded mode and those below it, with room
        for the rigid-body modes of a free-free assembly."""
        return max(10, opts.mode + 7) if opts.n_modes is None else max(opts.n_modes, 10)

    # sets, named once per (body, set)
    def set_name(self, k, name, kind) -> str:
        key = (k, name, kind)
        if key not in self.sets:
            base = _name(f"{self.model.bodies[k].name}_{name}").upper()
            deck_name, n = base, 1
            while deck_name in self.taken:
                n += 1
                deck_name = f"{base}_{n}"
            self.taken.add(deck_name)
            self.sets[key] = deck_name
        return self.sets[key]

    def set_cards(self) -> list:
        out = []
        for (k, name, kind), deck_name in self.sets.items():
            b = self.model.bodies[k]
            if kind == "node":
                nodes = np.unique(b.mesh.nodes(name)) + self.first_node[k]
                out += [f"** node set {name!r} of body {b.name!r}",
                        f"*NSET, NSET={deck_name}", *_id_rows(nodes)]
            else:
                out += [f"** facet set {name!r} of body {b.name!r} (element faces)",
                        f"*SURFACE, NAME={deck_name}, TYPE=ELEMENT"]
                out += [f"{e}, S{f}" for e, f in surface_rows(b, name,
                                                               self.first_element[k])]
        return out

    def nodes(self) -> list:
        out = ["** nodes: body after body, node i of a body is its first number + i",
               "*NODE, NSET=NALL"]
        for b, n0 in zip(self.model.bodies, self.first_node):
            out.append(f"** body {b.name!r}: nodes {n0}..{n0 + b.mesh.n_nodes - 1}")
            out += [", ".join([str(n0 + i)] + [_inp_number(v) for v in p])
                    for i, p in enumerate(b.mesh.points.tolist())]
        return out

    def elements(self) -> list:
        out = []
        for k, (b, e0) in enumerate(zip(self.model.bodies, self.first_element)):
            names = calculix_element(b)
            start = e0
            for block, etype in zip(b.mesh.cell_blocks, names):
                out += [f"** body {b.name!r}: {len(block.cells)} {block.cell_type} cells, "
                        f"qsma's formulation {etype}",
                        f"*ELEMENT, TYPE={etype}, ELSET={self.body_set(k)}"]
                ids = np.arange(start, start + len(block.cells))
                out += _element_rows(ids, block.cells + self.first_node[k])
                start += len(block.cells)
        return out

    def body_set(self, k) -> str:
        """The element set of body ``k``: its name (``qsma.deck.read_deck`` names the
        body after its section's element set)."""
        return _name(self.model.bodies[k].name)

    def material(self, k, b) -> list:
        mat, name = b.material, f"M_{self.body_set(k)}"
        out = [f"** body {b.name!r}: material E = {mat.E:g}, nu = {mat.nu:g}, "
               f"rho = {mat.rho:g}", f"*MATERIAL, NAME={name}", "*ELASTIC",
               f"{_inp_number(mat.E)}, {_inp_number(mat.nu)}", "*DENSITY",
               _inp_number(mat.rho), f"*SOLID SECTION, ELSET={self.body_set(k)}, "
               f"MATERIAL={name}"]
        if b.dim == 2:
            out.insert(-1, "** 2D: unit thickness, as qsma's bodies (forces per unit depth)")
            out.append("1.")
        return out

    def springs_and_masses(self, k, b) -> list:
        """Grounded springs (``SPRING1``, one per node and direction) and point masses
        (``MASS``, one per node), each node with its share of the set
        (:func:`qsma.model.spring.set_shares`), grouped by value."""
        out = []
        n0 = self.first_node[k]
        for s in b.springs:
            nodes, shares = set_shares(b, s.set, "spring")
            out.append(f"** body {b.name!r}: grounded spring on {s.set!r}, total stiffness "
                       f"{list(s.stiffness)} per direction, node shares of the set")
            for c, kc in enumerate(s.stiffness):
                if kc > 0:
                    out += self._grouped("SPRING1", nodes + n0, kc * shares,
                                         lambda e: ["*SPRING, ELSET=" + e, f"{c + 1}"])
        for pm in b.masses:
            nodes, shares = set_shares(b, pm.set, "point mass")
            out.append(f"** body {b.name!r}: point mass {pm.mass:g} on {pm.set!r}, node "
                       f"shares of the set")
            out += self._grouped("MASS", nodes + n0, pm.mass * shares,
                                 lambda e: ["*MASS, ELSET=" + e])
        return out

    def _grouped(self, etype, nodes, values, header) -> list:
        out = []
        for v in np.unique(values):
            at = nodes[values == v]
            elset = f"E{etype}_{self.next_element}"
            ids = np.arange(self.next_element, self.next_element + len(at))
            self.next_element += len(at)
            out += [f"*ELEMENT, TYPE={etype}, ELSET={elset}",
                    *[f"{e}, {n}" for e, n in zip(ids, at)], *header(elset),
                    _inp_number(float(v))]
        return out

    def clamps(self) -> list:
        out = []
        for k, b in enumerate(self.model.bodies):
            for c in b.clamps:
                comps = sorted(range(b.dim) if c.components is None else c.components)
                name = self.set_name(k, c.set, "node")
                out += [f"** body {b.name!r}: clamp on {c.set!r}, components {comps} "
                        f"(qsma counts from 0, CalculiX from 1)", "*BOUNDARY"]
                for first, last in _ranges(comps):
                    out.append(f"{name}, {first + 1}, {last + 1}")
        return out

    def interfaces(self) -> list:
        out = []
        m = self.model
        for j, itf in enumerate(m.interface_list):
            slave = self._slave(itf)
            master = itf.body1 if slave == itf.body2 else itf.body2
            sets = {itf.body1: itf.set1, itf.body2: itf.set2}
            s_name = self.set_name(m.body_index(slave), sets[slave], "facet")
            m_name = self.set_name(m.body_index(master), sets[master], "facet")
            mu = itf.mu if itf.mu is not None else m.mu
            slope = self.penalty if self.penalty is not None else _default_penalty(m, itf)
            behaviour, stick, note, normal = _surface_behavior(itf.law, slope, itf.label)
            self.slopes.append((normal, stick if stick is not None else float(slope)))
            name = f"I{j + 1}"
            out += [f"** interface {itf.label}: node-to-surface, slave {slave!r} (qsma's "
                    f"contact points), master {master!r}; mu = {mu:g}"
                    + ("" if itf.mu is not None else " (the model's mu)"),
                    *[f"** {line}" for line in note],
                    f"*SURFACE INTERACTION, NAME={name}", *behaviour, "*FRICTION",
                    f"{_inp_number(mu)}, {_inp_number(stick if stick is not None else slope)}",
                    f"*CONTACT PAIR, INTERACTION={name}, TYPE=NODE TO SURFACE",
                    f"{s_name}, {m_name}"]
        return out

    def _slave(self, itf):
        """The body whose nodes carry the contact points: qsma's mortar slave, body 2
        of a node-to-node interface (both meshes coincide there)."""
        from ..model.pairing import make_pairing
        if itf.slave is not None:
            return itf.slave
        if itf.coupling == "node":
            return itf.body2
        if len(self.model.interface_list) == 1:
            p = make_pairing(self.model)
            if p.coupling == "mortar":
                return itf.body1 if p.slave == 1 else itf.body2
        return itf.body2

    def preload_step(self) -> list:
        out = ["** step 1: the preload, the loads of qsma's 'preload' pattern",
               "*STEP, INC=1000", "*STATIC", "0.25, 1., 1e-5, 0.25"]
        for k, b in enumerate(self.model.bodies):
            for p in b.pressures:
                if p.load != "preload":
                    out.append(f"** pressure on {p.set!r} of body {b.name!r}: load pattern "
                               f"{p.load!r}, not part of qsma's preload, not applied")
                    continue
                out += [f"** body {b.name!r}: pressure {p.p:g} on {p.set!r}", "*DSLOAD",
                        f"{self.set_name(k, p.set, 'facet')}, P, {_inp_number(p.p)}"]
            for f in b.forces:
                if f.load != "preload":
                    out.append(f"** force on {f.set!r} of body {b.name!r}: load pattern "
                               f"{f.load!r}, not part of qsma's preload, not applied")
                    continue
                name = self.set_name(k, f.set, "node")
                out += [f"** body {b.name!r}: force {list(f.force)} on every node of "
                        f"{f.set!r}", "*CLOAD"]
                out += [f"{name}, {c + 1}, {_inp_number(v)}" for c, v in enumerate(f.force)
                        if v != 0.0]
        out += ["*NODE PRINT, NSET=NALL", "U", "*CONTACT PRINT", "CSTR", "*END STEP"]
        return out

    def frequency_step(self, opts) -> list:
        return ["** step 2: the modes about the preloaded state: the contact elements of "
                "step 1 hold the closed pairs (penalty and stick slope), the open ones are "
                "free, as qsma ties them; CalculiX adds the preload's stress stiffness, "
                "which qsma's tied modes (and the tied deck) leave out",
                f"** qsma loads its elastic mode {opts.mode} (RunOptions.mode; rigid-body "
                f"modes come first in both codes)",
                "*STEP, PERTURBATION", "*FREQUENCY", f"{self.n_modes(opts)}", "*END STEP"]

    def cyclic_steps(self, mode, alphas, steps) -> list:
        """Per amplitude three static steps of the modal load (module docstring), each
        of unit step time, increments of at most ``1 / steps`` (CalculiX may cut them
        back), the displacements printed at every increment: the modal force at total
        time ``t`` within a step is linear between the step's start and end values."""
        out = [f"** steps 2..: the modal load alpha M phi of qsma's loaded mode "
               f"({mode['f0_hz']:.10g} Hz tied, mass-normalised) as nodal forces, three "
               f"steps per amplitude (0 -> +A, +A -> -A, -A -> +A), at most 1/{steps} of "
               f"a branch per increment; q = phi^T M (u - u_pre) of the printed "
               f"displacements. No frequency step: CalculiX 2.20 solves a static step "
               f"after a PERTURBATION step as linear (no contact iterations)"]
        prev, inc = 0.0, _inp_number(1.0 / steps)
        for A in alphas:
            for target in (A, -A, A):
                out += [f"** modal force {prev:.10g} -> {target:.10g}",
                        f"*STEP, INC={100 * steps}", "*STATIC",
                        f"{inc}, 1., 1e-8, {inc}", "*CONTROLS, PARAMETERS=FIELD",
                        FIELD_CONTROLS, "*CLOAD"]
                for n0, mphi in zip(self.first_node, mode["mphi"]):
                    for i, row in enumerate(mphi):
                        out += [f"{n0 + i}, {c + 1}, {_inp_number(target * v)}"
                                for c, v in enumerate(row) if v != 0.0]
                out += ["*NODE PRINT, NSET=NALL", "U", "*END STEP"]
                prev = target
        return out


def _ranges(values) -> list:
    """``[(first, last)]`` of the runs of consecutive integers in sorted ``values``."""
    out = []
    for v in values:
        if out and v == out[-1][1] + 1:
            out[-1] = (out[-1][0], v)
        else:
            out.append((v, v))
    return out


def _id_rows(ids) -> list:
    ids = [str(i) for i in np.asarray(ids).tolist()]
    return [", ".join(ids[k:k + 16]) for k in range(0, len(ids), 16)]


def _element_rows(ids, cells) -> list:
    """``id, node, ...`` rows; more than 16 entries go on over lines ending in a comma
    (CalculiX reads at most 16 per line)."""
    rows = np.column_stack([ids, cells]).tolist()
    return [", ".join(map(str, r[k:k + 16])) + ("," if k + 16 < len(r) else "")
            for r in rows for k in range(0, len(r), 16)]


def _default_penalty(model, itf) -> float:
    """:data:`PENALTY_FACTOR` ``E / h``: the stiffer body's modulus over the shortest
    edge of the interface's facets."""
    E = max(model.body(itf.body1).material.E, model.body(itf.body2).material.E)
    h = min(_shortest_edge(model.body(b).mesh, s) for b, s in ((itf.body1, itf.set1),
                                                               (itf.body2, itf.set2)))
    return PENALTY_FACTOR * E / h


def _shortest_edge(mesh, name) -> float:
    f = mesh.facet_sets[name]
    x = mesh.points[f]
    d = [np.linalg.norm(x[:, i] - x[:, (i + 1) % f.shape[1]], axis=1)
         for i in range(f.shape[1])]
    return float(np.min(d))


def _surface_behavior(law, slope, label):
    """``(cards, stick slope or None, comment lines, normal slope or None)`` of an
    interface law: ``*SURFACE BEHAVIOR``, the stick slope of ``*FRICTION`` (None: qsma's
    rigid stick, written with the penalty ``slope``) and the slope of a linear or hard
    (penalty) normal law."""
    from ..contact.laws import ElasticStick, InterfaceLaw
    law = law if law is not None else InterfaceLaw()
    normal, tangential = law.normal, law.tangential
    note = []
    if normal.name == "hard":
        cards = ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR",
                 f"{_inp_number(slope)}, {_inp_number(TENSION)}, {_inp_number(TENSION_RANGE)}"]
        note.append(f"qsma's hard contact: a linear penalty of slope {slope:.6g} Pa/m "
                    f"(PENALTY_FACTOR E / h): contact forces within ~1e-4 of hard contact")
    elif normal.name == "linear":
        cards = ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=LINEAR",
                 f"{_inp_number(normal.k)}, {_inp_number(TENSION)}, "
                 f"{_inp_number(TENSION_RANGE)}"]
        note.append(f"qsma's linear law, slope {normal.k:g} Pa/m; tension "
                    f"{TENSION:g} Pa at clearances (qsma's layer carries none)")
    elif normal.name == "exponential":
        if normal.form != "calculix":
            raise CalculixRefusal(
                f"interface {label}: the exponential law in Abaqus' form (form="
                f"{normal.form!r}) is another curve than CalculiX's EXPONENTIAL: give "
                f"form='calculix', or a tabular law sampled from it")
        cards = ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=EXPONENTIAL",
                 f"{_inp_number(normal.c0)}, {_inp_number(normal.p0)}"]
        note.append("qsma's exponential law in CalculiX's form (c0, p0)")
    elif normal.name == "tabular":
        rows = [list(r) for r in normal.table]
        (p1, h1), (p2, h2) = rows[-2], rows[-1]
        far = h2 + 1e3 * (h2 - rows[0][1])
        rows.append([p2 + (p2 - p1) / (h2 - h1) * (far - h2), far])
        cards = ["*SURFACE BEHAVIOR, PRESSURE-OVERCLOSURE=TABULAR"]
        cards += [f"{_inp_number(p)}, {_inp_number(h)}" for p, h in rows]
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


def _qsma_mode(model, opts) -> dict:
    """qsma's preload and loaded mode: the contact forces of the preload (``lam``, local
    axes, normal last), the contact points it closed (``closed``, with the
    ``pairing``), the tied ``f0_hz``, ``omega0``, ``phi_tip`` and
    per body ``phi`` and ``mphi`` ((n_nodes, dim) arrays, mass-normalised, the sign of
    a run)."""
    from ..analysis import _Timer, prepare
    from ..contact import OPEN
    p = prepare(model, opts)
    clock = _Timer()
    reduced, layer, pre = p.preloaded(opts, clock)
    closed = pre.status != OPEN
    _, phi, phi_tip, omega0, _ = p.mode(closed, opts, clock, reduced, layer)
    off = model.dof_offsets()
    phis = [phi[off[k]:off[k + 1]].reshape(-1, model.dim) for k in range(len(model.bodies))]
    mphi = [(a.M @ f.ravel()).reshape(-1, model.dim) for a, f in zip(p.assembled, phis)]
    return dict(f0_hz=omega0 / (2 * np.pi), omega0=omega0, phi_tip=phi_tip, phi=phis,
                mphi=mphi, closed=closed, pairing=p.pairing, lam=pre.lam)


def _modal_forces(amplitudes, mode) -> tuple:
    """The modal forces of the cyclic steps: ``amplitudes`` as given, or a
    :class:`qsma.levels.Levels` converted through qsma's tied mode."""
    from ..levels import Levels
    if isinstance(amplitudes, Levels):
        return tuple(float(a) for a in amplitudes.alpha(mode["omega0"], mode["phi_tip"]))
    try:
        alphas = tuple(float(a) for a in np.atleast_1d(np.asarray(amplitudes, float)))
    except (TypeError, ValueError):
        raise InputError(f"amplitudes must be modal forces (numbers) or qsma.Levels, got "
                         f"{amplitudes!r}") from None
    return Levels("alpha", alphas).values            # positive, increasing: validated


def _refuse_tied(model):
    """The tied deck holds qsma's tie of one interface with the rigid law."""
    if model.interface is None:
        raise CalculixRefusal(
            f"a tied deck of {len(model.interface_list)} interfaces is not written (the "
            f"ties of chained interfaces): export without tied and compare the "
            f"perturbation frequency step of the deck")
    law = model.interface.law
    if law is not None and not law.rigid:
        raise CalculixRefusal(
            f"interface {model.interface.label}: its {law.normal.name} law holds the "
            f"closed pairs by springs, not by a tie: export without tied; the deck's "
            f"perturbation frequency step holds them by the same law")
