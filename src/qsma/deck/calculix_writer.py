"""The deck and the tied deck of :func:`qsma.deck.calculix.export_calculix`
(:class:`_Writer`), with the interface laws as CalculiX's ``*SURFACE BEHAVIOR`` and the
loaded mode of qsma they need."""
from __future__ import annotations

import re

import numpy as np

from ..errors import InputError
from ..mesh.io.abaqus.writer import inp_number
from ..model.pairing import make_pairing
from ..model.spring import set_shares
from .calculix_bolts import (ELEMENTS_PER_BOLT, bolt_layouts, locked_cards, model_cards,
                             node_rows, preload_cards, tied_cards)
from .calculix_cards import (FIELD_CONTROLS, PENALTY_FACTOR, CalculixRefusal,
                             _surface_behavior, calculix_element, calculix_numbering,
                             surface_rows)


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
        self.bolts = bolt_layouts(model, self.first_node[-1], self.first_element[-1])
        self.next_element = self.first_element[-1] + ELEMENTS_PER_BOLT * len(self.bolts)
        self.sets = {}                 # (body index, set, kind) -> deck name
        self.taken = set()
        self.penalty = penalty
        self.slopes = []

    def deck(self, opts, mode, alphas, steps, cycles) -> str:
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
        body_cards += self.bolt_cards()
        clamps, interaction = self.clamps(), self.interfaces()
        steps_cards = self.preload_step()
        if alphas:
            steps_cards += self.cyclic_steps(mode, alphas, steps, cycles)
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
        body_cards += self.bolt_cards()
        clamps = self.clamps() + tied_cards(self.bolts)
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
        basis = pairing.slave_basis
        dim, used, out = m.dim, set(), ["** ties of the closed contact points"]
        for i in np.flatnonzero(mode["closed"]):
            s = int(pairing.contact_nodes[i])
            if P is None:
                partners = [(int(pairing.master_nodes[i]), 1.0)]
            else:
                row = P.getrow(i)
                partners = [(int(pairing.master_nodes[j]), float(w))
                            for j, w in zip(row.indices, row.data) if w != 0.0]
            own = [(slave, s, 1.0)] if basis is None else _coefficient_terms(
                basis, pairing.contact_nodes, i, slave)
            for c in range(dim):
                terms = own + [(master, n, -w) for n, w in partners]
                free = [t for t in terms if (t[0], dim * t[1] + c) not in held
                        and (t[0], t[1], c) not in used]
                if not free:
                    continue
                first = free[0]
                used.add((first[0], first[1], c))
                terms = [first] + [t for t in terms if t is not first
                                   and (t[0], dim * t[1] + c) not in held]
                entries = [f"{self.first_node[k] + n}, {c + 1}, {inp_number(w)}"
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
            out += [", ".join([str(n0 + i)] + [inp_number(v) for v in p])
                    for i, p in enumerate(b.mesh.points.tolist())]
        return out + node_rows(self.bolts)

    def bolt_cards(self) -> list:
        """The bolts' couplings, members and ties (:mod:`qsma.deck.calculix_bolts`)."""
        if not self.bolts:
            return []
        m = self.model
        for lay in self.bolts:        # the washers as surfaces, for a reader of the deck
            for (k, *_), name in zip(lay.ends, (lay.bolt.set_a, lay.bolt.set_b)):
                self.set_name(k, name, "facet")
        clamped = [set((b.clamped_dofs() // b.dim).tolist()) for b in m.bodies]
        k = m.body_index(m.bolts[0].body_a)
        taken = {self.body_set(j).upper() for j in range(len(m.bodies))}
        return model_cards(self.bolts, self.first_node, clamped, f"M_{self.body_set(k)}",
                           m.bodies[k].material.E, taken)

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
               f"{inp_number(mat.E)}, {inp_number(mat.nu)}", "*DENSITY",
               inp_number(mat.rho), f"*SOLID SECTION, ELSET={self.body_set(k)}, "
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
                    inp_number(float(v))]
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
                    f"{inp_number(mu)}, {inp_number(stick if stick is not None else slope)}",
                    f"*CONTACT PAIR, INTERACTION={name}, TYPE=NODE TO SURFACE"
                    + ("" if itf.adjust is None else f", ADJUST={inp_number(itf.adjust)}"),
                    f"{s_name}, {m_name}"]
        return out

    def _slave(self, itf):
        """The body whose nodes carry the contact points: qsma's mortar slave, body 2
        of a node-to-node interface (both meshes coincide there)."""
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
                        f"{self.set_name(k, p.set, 'facet')}, P, {inp_number(p.p)}"]
            for f in b.forces:
                if f.load != "preload":
                    out.append(f"** force on {f.set!r} of body {b.name!r}: load pattern "
                               f"{f.load!r}, not part of qsma's preload, not applied")
                    continue
                name = self.set_name(k, f.set, "node")
                out += [f"** body {b.name!r}: force {list(f.force)} on every node of "
                        f"{f.set!r}", "*CLOAD"]
                out += [f"{name}, {c + 1}, {inp_number(v)}" for c, v in enumerate(f.force)
                        if v != 0.0]
        out += preload_cards(self.bolts)
        out += ["*NODE PRINT, NSET=NALL", "U", "*CONTACT PRINT", "CSTR", "*END STEP"]
        return out

    def frequency_step(self, opts) -> list:
        return ["** step 2: the modes about the preloaded state: the contact elements of "
                "step 1 hold the closed pairs (penalty and stick slope), the open ones are "
                "free, as qsma ties them; CalculiX adds the preload's stress stiffness, "
                "which qsma's tied modes (and the tied deck) leave out",
                f"** qsma loads its elastic mode {opts.mode} (RunOptions.mode; rigid-body "
                f"modes come first in both codes)",
                "*STEP, PERTURBATION", "*FREQUENCY", f"{self.n_modes(opts)}",
                *locked_cards(self.bolts), "*END STEP"]

    def cyclic_steps(self, mode, alphas, steps, cycles) -> list:
        """Per amplitude ``1 + 2 cycles`` static steps of the modal load (module
        docstring), each of unit step time, increments of at most ``1 / steps``
        (CalculiX may cut them back), the displacements printed at every increment: the
        modal force at total time ``t`` within a step is linear between the step's start
        and end values."""
        out = [f"** steps 2..: the modal load alpha M phi of qsma's loaded mode "
               f"({mode['f0_hz']:.10g} Hz tied, mass-normalised) as nodal forces, per "
               f"amplitude {1 + 2 * cycles} steps (0 -> +A, then {cycles} cycles +A -> -A "
               f"-> +A; the last one is compared with qsma's stabilised loop), at most "
               f"1/{steps} of a branch per increment; q = phi^T M (u - u_pre) of the "
               f"printed displacements. No frequency step: CalculiX 2.20 solves a static "
               f"step after a PERTURBATION step as linear (no contact iterations)"]
        prev, inc = 0.0, inp_number(1.0 / steps)
        for A in alphas:
            for k, target in enumerate((A,) + (-A, A) * cycles):
                what = "ramp" if k == 0 else f"cycle {(k + 1) // 2} of {cycles}"
                out += [f"** modal force {prev:.10g} -> {target:.10g} ({what})",
                        f"*STEP, INC={100 * steps}", "*STATIC",
                        f"{inc}, 1., 1e-8, {inc}", "*CONTROLS, PARAMETERS=FIELD",
                        FIELD_CONTROLS, *(locked_cards(self.bolts) if prev == 0.0 else []),
                        "*CLOAD"]
                for n0, mphi in zip(self.first_node, mode["mphi"]):
                    for i, row in enumerate(mphi):
                        out += [f"{n0 + i}, {c + 1}, {inp_number(target * v)}"
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


def _qsma_mode(model, opts) -> dict:
    """qsma's preload and loaded mode: the contact forces of the preload (``lam``, local
    axes, normal last), the contact points it closed (``closed``, with the
    ``pairing``) and those slipping (``slipping``), the tied ``f0_hz``, ``omega0``, ``phi_tip`` and
    per body ``phi`` and ``mphi`` ((n_nodes, dim) arrays, mass-normalised, the sign of
    a run)."""
    from ..analysis import StageClock, prepare
    from ..contact import OPEN, SLIPPING
    p = prepare(model, opts)
    clock = StageClock()
    reduced, layer, pre = p.preloaded(opts, clock)
    closed = pre.status != OPEN
    others, phi, phi_tip, omega0, _ = p.mode(closed, opts, clock, reduced, layer)
    others.cancel()                     # the modes beyond the loaded one: not needed
    off = model.dof_offsets()
    phis = [phi[off[k]:off[k + 1]].reshape(-1, model.dim) for k in range(len(model.bodies))]
    mphi = [(a.M @ f.ravel()).reshape(-1, model.dim) for a, f in zip(p.assembled, phis)]
    return dict(f0_hz=omega0 / (2 * np.pi), omega0=omega0, phi_tip=phi_tip, phi=phis,
                mphi=mphi, closed=closed, slipping=pre.status == SLIPPING,
                pairing=p.pairing, lam=pre.lam)


def _modal_forces(amplitudes, mode) -> tuple:
    """The modal forces of the cyclic steps: ``amplitudes`` as given, or a
    :class:`qsma.levels.Levels` converted through qsma's tied mode."""
    from ..analysis.levels import Levels
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


def _coefficient_terms(basis, nodes, i, body):
    """The slave side of the tie of contact point ``i`` on mixed quadratic facets: the
    coefficient ``u~_i = sum_j from_nodes[i, j] u_j`` (:class:`qsma.model.dual_basis.
    SlaveBasis`), its own node first (the dependent DOF where no clamp holds it)."""
    row = basis.from_nodes.getrow(i)
    terms = [(body, int(nodes[j]), float(w)) for j, w in zip(row.indices, row.data)]
    return sorted(terms, key=lambda t: t[1] != int(nodes[i]))
