"""The pairing of a model: the contact points of its interface, or of all its
interfaces stacked (:class:`MultiPairing`, one :class:`Coupling` per interface), with
what the run reads per contact point (friction, interface laws, initial gaps)."""
from __future__ import annotations

from dataclasses import dataclass
import warnings

import numpy as np
import scipy.sparse as sp

from ..contact.laws import InterfaceLaw
from ..contact.pairlaws import PairLaws
from ..errors import InputError, InterfaceGapWarning
from .interface import Pairing, pair_interface


def make_pairing(model, interface=None) -> Pairing | MultiPairing:
    """The contact points of ``interface`` (default: ``model.interface``): node pairs or
    the mortar coupling (:func:`qsma.model.interface.pair_interface`). A model of
    several interfaces (and no ``interface`` given): every one of them, as a
    :class:`MultiPairing`."""
    if interface is None and model.interface is None:
        return multi_pairing(model)
    return pair_interface(model, interface)


@dataclass(frozen=True)
class Coupling:
    """One interface of a multi-body model: its pairing (node-to-node or mortar) and
    the indices of its body 1 and body 2 in the list of assembled bodies."""

    pairing: object
    body1: int
    body2: int

    @property
    def slave(self) -> int:
        return self.body1 if self.pairing.slave == 1 else self.body2

    @property
    def master(self) -> int:
        return self.body2 if self.pairing.slave == 1 else self.body1

    @property
    def sigma(self) -> float:
        return -1.0 if self.pairing.slave == 1 else 1.0

    @property
    def projection(self) -> sp.csr_matrix:
        p = self.pairing
        return p.projection if p.projection is not None else sp.identity(p.n_pairs,
                                                                         format="csr")


@dataclass(frozen=True, eq=False)
class MultiPairing:
    """The contact points of every interface of a model, stacked in interface order.

    Offers what the run reads of a :class:`qsma.model.interface.Pairing` (``n_pairs``,
    ``x``, ``frames``, ``area``, ``normals``, ``coupling``) plus the couplings.

    Attributes
    ----------
    couplings : one :class:`Coupling` per interface (``model.interface_list`` order)
    interfaces : the :class:`qsma.model.Interface` of each coupling
    rows : start of each interface's contact points (``rows[I]:rows[I+1]``)
    """

    couplings: tuple
    interfaces: tuple

    @property
    def rows(self) -> np.ndarray:
        return np.concatenate([[0], np.cumsum([c.pairing.n_pairs for c in self.couplings])])

    @property
    def n_pairs(self) -> int:
        return int(self.rows[-1])

    def _stack(self, name):
        return np.concatenate([getattr(c.pairing, name) for c in self.couplings])

    @property
    def x(self):
        return self._stack("x")

    @property
    def frames(self):
        return self._stack("frames")

    @property
    def area(self):
        return self._stack("area")

    @property
    def normals(self):
        return self.frames[:, -1, :]

    @property
    def coupling(self) -> str:
        """The couplings of the interfaces, e.g. ``"node+mortar"``."""
        return "+".join(c.pairing.coupling for c in self.couplings)

    @property
    def projection(self):
        return None                  # per interface: see couplings

    @property
    def gap(self):
        return None                  # reported per interface (couplings)


def multi_pairing(model) -> MultiPairing:
    """Pair every interface of ``model`` (:func:`pair_interface`)."""
    couplings = []
    for itf in model.interface_list:
        couplings.append(Coupling(pair_interface(model, itf), model.body_index(itf.body1),
                                  model.body_index(itf.body2)))
    return MultiPairing(tuple(couplings), tuple(model.interface_list))


def pair_mu(model, pairing) -> np.ndarray | float:
    """Friction coefficient of each contact point: its interface's ``mu``, else the
    model's (a scalar when no interface sets its own)."""
    itfs = model.interface_list
    if all(i.mu is None for i in itfs):
        return model.mu
    if not isinstance(pairing, MultiPairing):
        return itfs[0].mu if itfs[0].mu is not None else model.mu
    return np.concatenate([np.full(c.pairing.n_pairs, model.mu if i.mu is None else i.mu)
                           for c, i in zip(pairing.couplings, pairing.interfaces)])


def pair_laws(model, pairing):
    """The :class:`qsma.contact.pairlaws.PairLaws` of the contact points (each interface's
    ``law``), or None where every interface is rigid (hard contact, rigid stick)."""
    laws, index = [], []
    for itf, p in interface_pairings(model, pairing):
        law = getattr(itf, "law", None) or InterfaceLaw()
        if law not in laws:
            laws.append(law)
        index.append(np.full(p.n_pairs, laws.index(law)))
    if all(law.rigid for law in laws):
        return None
    return PairLaws(tuple(laws), np.concatenate(index), np.asarray(pairing.area, float),
                    model.dim)


def body_order(model, pairing) -> list:
    """Indices in ``model.bodies`` of the bodies of the reduced model, in its order:
    every body for a :class:`MultiPairing`, ``(body1, body2)`` of the interface else."""
    if isinstance(pairing, MultiPairing):
        return list(range(len(model.bodies)))
    return [model.body_index(model.interface.body1), model.body_index(model.interface.body2)]


def contact_sides(model, pairing):
    """``(body index, nodes, contact points)`` of each side carrying contact points:
    both sides of a node-to-node interface, the slave side of a mortar one."""
    cps = pairing.couplings if isinstance(pairing, MultiPairing) else \
        (Coupling(pairing, *body_order(model, pairing)),)
    out, start = [], 0
    for c in cps:
        p = c.pairing
        rows = np.arange(start, start + p.n_pairs)
        if p.projection is None:
            out += [(c.body1, p.nodes1, rows), (c.body2, p.nodes2, rows)]
        else:
            out.append((c.slave, p.contact_nodes, rows))
        start += p.n_pairs
    return out


def interface_pairings(model, pairing):
    """``(interface, pairing)`` of each interface."""
    if isinstance(pairing, MultiPairing):
        return [(i, c.pairing) for i, c in zip(pairing.interfaces, pairing.couplings)]
    return [(model.interface, pairing)]


def _significant_gaps(p, rtol):
    """The mortar gaps of pairing ``p`` with those within ``rtol`` of the interface size
    (coincident surfaces written with ~10 digits) set to zero; None for node-to-node."""
    gap = getattr(p, "gap", None)
    if gap is None or not len(gap):
        return None
    size = float(np.linalg.norm(np.ptp(p.x, axis=0)))
    return np.where(np.abs(gap) > rtol * size, gap, 0.0)


def _meshed_gaps(model, itf, p, rtol):
    """:func:`_significant_gaps` with those the interface's ``adjust`` closes zero:
    within its distance, or at the slave nodes of its node set."""
    g = _significant_gaps(p, rtol)
    adjust = getattr(itf, "adjust", None)
    if g is None or adjust is None:
        return g
    if not isinstance(adjust, str):
        return np.where(np.abs(g) <= adjust, 0.0, g)
    name = itf.body1 if p.slave == 1 else itf.body2
    mesh = model.body(name).mesh
    if adjust not in mesh.node_sets and adjust not in mesh.facet_sets:
        raise InputError(f"interface {itf.label}: adjust = {adjust!r} is no node set of "
                         f"its slave body {name!r} (the side whose nodes carry the contact "
                         f"points); its node sets: {sorted(mesh.node_sets)}. Name a node "
                         f"set of {name!r}, or give the slave (slave = ...)")
    slave_nodes = p.nodes1 if p.slave == 1 else p.nodes2
    return np.where(np.isin(slave_nodes, mesh.nodes(adjust)), 0.0, g)


def pair_gaps(model, pairing, rtol) -> np.ndarray | None:
    r"""Initial normal gap ``g0`` of each contact point (opening ``w = d_n + g0``): the
    mortar weighted gap :math:`g_i = D_i^{-1} \int \psi_i (x_m - x_s) \cdot n_s\,dA` of
    the undeformed surfaces, positive apart, negative where they overlap; zero at
    node-to-node pairs and where ``|g_i|`` is within ``rtol`` of the interface size;
    zero also within ``Interface.adjust`` (a deck's ``ADJUST=``); plus the
    interface's own gap field (``Interface.gap``, the surfaces' shape).
    ``None`` when every gap is zero (the contact problem's default)."""
    parts = []
    for itf, p in interface_pairings(model, pairing):
        g = _meshed_gaps(model, itf, p, rtol)
        if getattr(itf, "gap", None) is not None:
            g = (0.0 if g is None else g) + shape_gaps(itf, p)
        parts.append(g)
    if all(g is None or not np.any(g) for g in parts):
        return None
    return np.concatenate([np.zeros(p.n_pairs) if g is None else g for g, (_, p) in
                           zip(parts, interface_pairings(model, pairing))])


#: A gap field whose largest gap exceeds this fraction of the interface's size is
#: refused as a unit error: surface shapes are micrometres over millimetres (the
#: Brake-Reuss beam's lap: about 10 um over 120 mm, 1e-4), a gap of a tenth of the
#: interface is no longer the shape of one surface.
GAP_SIZE_MAX = 0.1


def shape_gaps(itf, p) -> np.ndarray:
    """The gap field of interface ``itf`` at its contact points (pairing ``p``),
    checked: finite, one per point, and small against the interface."""
    try:
        g = np.asarray(itf.gap(p.x), dtype=float)
    except InputError:
        raise
    except Exception as exc:                       # a user's function failed
        raise InputError(f"interface {itf.label}: its gap function failed on the "
                         f"contact points ({type(exc).__name__}: {exc})") from exc
    if g.shape != (p.n_pairs,):
        raise InputError(f"interface {itf.label}: the gap field must give one value per "
                         f"contact point, shape ({p.n_pairs},), got {g.shape}")
    if not np.all(np.isfinite(g)):
        raise InputError(f"interface {itf.label}: the gap field gives "
                         f"{int(np.count_nonzero(~np.isfinite(g)))} NaN/Inf value(s)")
    size = float(np.linalg.norm(np.ptp(p.x, axis=0)))
    if np.abs(g).max(initial=0.0) > GAP_SIZE_MAX * size:
        raise InputError(f"interface {itf.label}: the gap field reaches "
                         f"{np.abs(g).max():.3e} m on an interface {size:.3e} m across "
                         f"(more than {GAP_SIZE_MAX:g} of it): gaps are in metres; a "
                         f"field in micrometres needs scale = 1e-6")
    return g


def warn_closed_gaps(model, pairing, rtol):
    """Say so when the mortar coupling found surfaces that are apart (or overlap) in the
    mesh: the contact problem starts from these gaps (docs/theory.md section 8)."""
    for itf, p in interface_pairings(model, pairing):
        gap = _meshed_gaps(model, itf, p, rtol)
        if gap is None or not gap.any():
            continue
        worst = float(np.abs(gap).max())
        what = "apart" if gap[np.argmax(np.abs(gap))] > 0 else "overlapping"
        warnings.warn(f"interface {itf.label}: the two surfaces are up to {worst:.3e} "
                      f"{what} in the mesh (largest of {int(np.count_nonzero(gap))} mortar "
                      f"gaps); the contact problem starts from these initial gaps, which the "
                      f"preload closes where it can (the gaps of the geometry, as of a punch "
                      f"on a block, or of faceted curved surfaces, about h^2 / 8R). If the "
                      f"surfaces should touch, mesh them coincident or refine",
                      InterfaceGapWarning, stacklevel=4)
