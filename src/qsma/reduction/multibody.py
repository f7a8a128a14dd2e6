r"""Several bodies and interfaces: one contact problem over all interfaces.

Each body ``j`` is condensed onto the union ``C_j`` of its interface nodes over every
interface it belongs to (global components). Interface ``I`` couples a slave body
``s`` to a master body ``m`` (node-to-node: the projection is the identity), and its
contact points' relative displacements, in their local frames ``F_i``, are rows of
one sparse operator ``G`` over the stacked interface DOFs ``u = (u_1, ..., u_B)``::

    d_i = sigma_I F_i (u_s,i - sum_k N_ik u_m,k)     d = G u,   forces on the bodies G^T lam

(sigma_I = -1 when the slave is the interface's body 1, +1 when body 2, so that d is
"body 2 minus body 1" along the normal from body 1 into body 2 as in section 4 of
docs/theory.md). With ``Kc`` the block-diagonal condensed stiffness, equilibrium is
``Kc u = Fc + G^T lam``.

The slave DOFs (every contact point's node, each in exactly one interface) are
eliminated as in section 8 of docs/theory.md: split ``u`` into slave DOFs ``u_s`` and
the rest ``u_r``, ``G = [G_s G_r]`` with ``G_s`` square (one contact point per slave
node), ``Q = G_s^-1``. Then ``u = T_r u_r + T_d d`` with ``T_r = [-Q G_r; I]``,
``T_d = [Q; 0]``, and since ``G T_r = 0`` the contact forces drop out of
``T_r^T (Kc u - Fc) = 0``::

    S     = T_r^T Kc T_r                              (the welded assembly, condensed)
    u_r   = S^-1 T_r^T (Fc - Kc T_d d)
    lam   = Q^T (Kc u - Fc)_s = K d + lam_w
    K     = Q^T [Kc T_d - Kc T_r S^-1 T_r^T Kc T_d]_s
    lam_w = Q^T [Kc T_r S^-1 T_r^T Fc - Fc]_s

Interface nodes held by clamps (:mod:`.clamps`): each body's unknowns are its
unclamped interface DOFs, the columns of clamped DOFs leave ``G``, and the DOFs
eliminated by ``d`` (the pivots) are the slave DOFs where they are free, else DOFs of
the master; a component clamped on both sides (a zero row of ``G``) is fixed,
``d = 0``.

Only ``S`` is factorised (Cholesky): a body need not be held on its own as long as
the welded assembly is (the contact problem then still needs ``K`` positive definite).
For two bodies these are the formulas of :func:`qsma.reduction.two_bodies.combine`. (Not
the interface flexibility form ``K = (G Kc^-1 G^T)^-1``: it inverts every ``Kc_j`` and on
sandwich-2d reproduces the two-body model's recovered fields for a random ``d`` only to
3e-7 relative; this form to 1e-11, ``tests/test_multibody.py``.)
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .._infra.dense import cho_solved
from ..errors import InputError
from .condensation import (condense_bodies, condensed_loads, extended_prescribed,
                           prescribed_patterns, with_prescribed)
from .clamps import (check_prescribed, constrained_basis, decoupled, local_rows,
                     pivot_dofs, symmetry_components)
from .rigid import ghost


@dataclass(frozen=True, eq=False)
class MultiReducedModel:
    r"""``lam = K d + W a`` over the contact points of every interface (interface
    order, then contact-point order; local frames).

    Attributes
    ----------
    K, W, patterns : as :class:`qsma.reduction.two_bodies.ReducedModel`
    bodies : condensed bodies (global components on their interface nodes)
    G : sparse (n_contact dofs, sum of interface dofs) relative-displacement operator
    offsets : start of each body's interface DOFs in ``u``
    rows : start of each interface's contact points (``rows[I]:rows[I+1]``)
    T_r, T_d, S_cho, Kc : the elimination of the slave DOFs (module docstring)
    """

    K: np.ndarray
    W: np.ndarray
    patterns: tuple
    bodies: tuple
    loads: tuple
    Fc: np.ndarray
    G: sp.csr_matrix
    offsets: np.ndarray
    rows: np.ndarray
    T_r: np.ndarray
    T_d: np.ndarray
    S_cho: object
    Kc: np.ndarray
    dim: int
    functionals: dict
    definitions: dict
    prescribed: tuple | None = None     # as ReducedModel.prescribed
    #: the :class:`qsma.reduction.rigid.Ghost` spring of bodies held only by the joint
    ghost: object = None
    #: contact components clamped on every side (``d = 0``, the clamps carry the force;
    #: ``K`` holds a spring of its own there, :func:`_decoupled`)
    fixed: np.ndarray = None
    #: the columns of the elimination ``T_d`` of the tied interfaces' points (their
    #: ``d = 0``; :meth:`tied_forces`), or None
    T_t: np.ndarray | None = None

    @property
    def n_pairs(self):
        return self.K.shape[0] // self.dim

    def welded_contact_force(self, a) -> np.ndarray:
        return (self.W @ np.asarray(a, dtype=float)).reshape(-1, self.dim)

    def interface_displacements(self, d, a):
        """``u = T_r S^-1 T_r^T (Fc a - Kc T_d d) + T_d d``, split per body."""
        u = self._stacked(d, a)
        return tuple(u[self.offsets[j]:self.offsets[j + 1]] for j in range(len(self.bodies)))

    def _stacked(self, d, a):
        d = np.asarray(d, dtype=float).ravel()
        a = np.asarray(a, dtype=float)
        ur = cho_solved(self.S_cho, self.T_r.T @ (self.Fc @ a - self.Kc @ (self.T_d @ d)))
        return self.T_r @ ur + self.T_d @ d

    def tied_forces(self, d, a) -> np.ndarray:
        """The forces of the tied interfaces' points (local frames, ``(n_tied, dim)``):
        ``lam_T = T_t^T (Kc u - Fc a)``, ``u`` the interface displacements of ``d`` (their
        relative displacement zero), i.e. ``K_TF d + W_T a`` of the problem over every
        point (docs/theory.md, "Tied interfaces"). Empty without tied interfaces."""
        if self.T_t is None:
            return np.zeros((0, self.dim))
        u = self._stacked(d, a)
        lam = self.T_t.T @ (self.Kc @ u - self.Fc @ np.asarray(a, dtype=float))
        return lam.reshape(-1, self.dim)

    def recover(self, d, a):
        """Full displacement vectors of every body from ``d`` and the load factors."""
        a = np.asarray(a, dtype=float)
        loads = (L @ a for L in self.loads)
        return with_prescribed((b.recover(u, F) for b, u, F in
                                zip(self.bodies, self.interface_displacements(d, a), loads)),
                               self.prescribed, a)

    def evaluate(self, name, d, a) -> float:
        c_d, c_a = self.functionals[name]
        return float(c_d @ np.asarray(d).ravel() + c_a @ np.asarray(a, dtype=float))

    def add_pattern(self, name, *loads) -> "MultiReducedModel":
        """One more load pattern, ``loads`` the full load vector of each body (body
        order). Its column of ``W`` is ``T_d^T (Kc T_r S^-1 T_r^T fc - fc)``."""
        if name in self.patterns:
            raise InputError(f"load pattern {name!r} exists already")
        if len(loads) != len(self.bodies):
            raise InputError(f"load pattern {name!r}: {len(loads)} load vectors for "
                             f"{len(self.bodies)} bodies")
        fc = np.concatenate([b.condensed_load(F) for b, F in zip(self.bodies, loads)])
        y = cho_solved(self.S_cho, self.T_r.T @ fc)
        w = self.T_d.T @ (self.Kc @ (self.T_r @ y) - fc)
        new = replace(self, W=np.column_stack([self.W, w]), patterns=self.patterns + (name,),
                      loads=tuple(np.column_stack([L, F]) for L, F in zip(self.loads, loads)),
                      Fc=np.column_stack([self.Fc, fc]), functionals={}, definitions={},
                      prescribed=extended_prescribed(self.prescribed))
        return new.with_functionals(self.definitions)

    def with_functionals(self, definitions: dict) -> "MultiReducedModel":
        """Attach ``name -> (l_1, ..., l_B)`` (full DOF vectors per body): with ``h`` the
        condensed functional, ``y = S^-1 T_r^T h``, ``c_d = T_d^T (h - Kc T_r y)`` and
        ``c_a = Fc^T T_r y + sum_j e_j``."""
        funcs = dict(self.functionals)
        for name, ls in definitions.items():
            given = self.prescribed or (None,) * len(self.bodies)
            parts = [b.functional(l, L, Pr) for b, l, L, Pr
                     in zip(self.bodies, ls, self.loads, given)]
            h = np.concatenate([p[0] for p in parts])
            y = cho_solved(self.S_cho, self.T_r.T @ h)
            funcs[name] = (self.T_d.T @ (h - self.Kc @ (self.T_r @ y)),
                           self.Fc.T @ (self.T_r @ y) + sum(p[1] for p in parts))
        return replace(self, functionals=funcs, definitions={**self.definitions,
                                                             **definitions})


def interface_nodes(n_bodies, couplings, names=None):
    """Sorted interface nodes of each body over all couplings; a body in no interface
    is refused (it would float free of the others)."""
    nodes = [[] for _ in range(n_bodies)]
    for c in couplings:
        nodes[c.body1].append(c.pairing.nodes1)
        nodes[c.body2].append(c.pairing.nodes2)
    lonely = [j for j in range(n_bodies) if not nodes[j]]
    if lonely:
        who = [names[j] if names else j for j in lonely]
        raise InputError(f"body {who[0]!r} belongs to no interface: it is not connected to "
                         f"the other bodies. Fix: add an interface joining it to another "
                         f"body, or remove it from the model.")
    return [np.unique(np.concatenate(n)) for n in nodes]


def relative_displacement_operator(couplings, nodes, dim):
    """``G`` with ``d = G u`` (module docstring) and the offsets of each body in ``u``."""
    offsets = np.concatenate([[0], np.cumsum([dim * len(n) for n in nodes])])
    rows, cols, vals = [], [], []
    start = 0
    for c in couplings:
        p = c.pairing
        F = p.frames                                         # (n, dim, dim), rows = axes
        n = p.n_pairs
        r = start + dim * np.arange(n)[:, None, None] + np.arange(dim)[None, :, None]
        for body, local, weight in _terms(c, nodes):
            cc = (offsets[body] + dim * local[1][:, None, None]
                  + np.arange(dim)[None, None, :])
            rows.append(np.broadcast_to(r[local[0]], (len(local[0]), dim, dim)).ravel())
            cols.append(np.broadcast_to(cc, (len(local[0]), dim, dim)).ravel())
            vals.append((weight[:, None, None] * F[local[0]]).ravel())
        start += dim * n
    G = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                      shape=(start, offsets[-1])).tocsr()
    return G, offsets


def _terms(c, nodes):
    """(body, (contact point, node position in the body's set), weight) of ``d``; on
    mixed quadratic slave facets the slave term is the contact coefficient
    ``u~ = from_nodes @ u_s`` (:class:`qsma.model.dual_basis.SlaveBasis`)."""
    p = c.pairing
    n = p.n_pairs
    s_pos = np.searchsorted(nodes[c.slave], p.contact_nodes)
    N = c.projection.tocoo()
    m_pos = np.searchsorted(nodes[c.master], p.master_nodes)[N.col]
    if p.slave_basis is None:
        slave = (c.slave, (np.arange(n), s_pos), np.full(n, c.sigma))
    else:
        Bi = p.slave_basis.from_nodes.tocoo()
        slave = (c.slave, (Bi.row, s_pos[Bi.col]), c.sigma * Bi.data)
    return [slave, (c.master, (N.row, m_pos), -c.sigma * N.data)]


def reduce_bodies(assembled, couplings, patterns=("preload",), backend="auto",
                  names=None, tied=()) -> MultiReducedModel:
    """Condense every body onto its interface nodes and combine all interfaces into one
    relative-displacement problem by eliminating the pivot DOFs (module docstring;
    clamped interface DOFs: :func:`pivot_dofs`).

    ``tied``: the couplings of tied interfaces. Their points' relative displacements
    are rows of ``G`` like the others', held at zero: ``d = (d_F, 0)``, so the problem
    of the other points is ``K_FF``, ``W_F`` and ``T_d``'s columns of the tied rows
    leave the recovery (kept as ``T_t`` for :meth:`MultiReducedModel.tied_forces`)."""
    couplings = list(couplings) + list(tied)
    n_free = sum(c.pairing.n_pairs for c in couplings[:len(couplings) - len(tied)])
    dim = assembled[0].body.dim
    names = names or [a.body.name for a in assembled]
    nodes = interface_nodes(len(assembled), couplings, names)
    for a, n in zip(assembled, nodes):
        check_prescribed(a, n)
    bodies = condense_bodies(assembled, nodes, [None] * len(nodes), backend)
    loads = tuple(np.column_stack([a.loads.get(p, np.zeros(a.n_dofs)) for p in patterns])
                  for a in assembled)
    Fc = np.vstack(condensed_loads(bodies, loads))
    Kc = sla.block_diag(*[np.asarray(b.Kc) for b in bodies])
    G_all, full = relative_displacement_operator(couplings, nodes, dim)
    unknown = _unknown_columns(bodies, nodes, full, dim)
    G = _symmetry_rows_zeroed(G_all[:, unknown].tocsr(), couplings, assembled)
    offsets = np.concatenate([[0], np.cumsum([len(b.C) for b in bodies])])
    fixed, pivots = pivot_dofs(G, _slave_dofs(couplings, nodes, full, dim, unknown), dim)
    n_u, n_c = offsets[-1], G.shape[0]
    rows = np.setdiff1d(np.arange(n_c), fixed)
    rest = np.setdiff1d(np.arange(n_u), pivots)
    Gs, Gr = G[rows][:, pivots].toarray(), G[rows][:, rest].toarray()
    singular = InputError("the contact points do not determine their slave nodes (a node "
                          "is the slave of two interfaces?)")
    try:
        lu = sla.lu_factor(Gs, check_finite=True)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise singular from exc
    diag = np.abs(np.diag(lu[0]))         # lu_factor only warns on a singular matrix
    if diag.size and diag.min() <= 1e3 * np.finfo(float).eps * diag.max():
        raise singular
    T_r = np.zeros((n_u, len(rest)))
    T_r[pivots] = -sla.lu_solve(lu, Gr)
    T_r[rest, np.arange(len(rest))] = 1.0
    T_d = np.zeros((n_u, n_c))
    T_d[np.ix_(pivots, rows)] = sla.lu_solve(lu, np.eye(len(rows)))
    KT_r = Kc @ T_r
    S = T_r.T @ KT_r
    try:
        S_cho = sla.cho_factor(0.5 * (S + S.T))
    except np.linalg.LinAlgError as exc:
        raise InputError("the welded assembly is not held against rigid-body motion; add "
                         "clamps") from exc
    nf = dim * n_free                 # the tied points' columns leave (their d_T = 0)
    T_t = T_d[:, nf:] if tied else None
    T_d, G, fixed = T_d[:, :nf], G[:nf], fixed[fixed < nf]
    KT_d = Kc @ T_d
    # lam = Q^T (Kc u - Fc)_s = T_d^T (Kc u - Fc): T_d is zero outside the pivot rows
    K = T_d.T @ (KT_d - KT_r @ cho_solved(S_cho, KT_r.T @ T_d))
    K = 0.5 * (K + K.T)
    W = T_d.T @ (KT_r @ cho_solved(S_cho, T_r.T @ Fc) - Fc)
    K = decoupled(K, fixed)
    held = held_by_ties(bodies, tied)
    K, g = _ghost(K, [None if b.rigid is None or held[j]
                      else G[:, offsets[j]:offsets[j + 1]] @ b.rigid
                      for j, b in enumerate(bodies)])
    starts = np.concatenate([[0], np.cumsum([c.pairing.n_pairs
                                             for c in couplings[:len(couplings) - len(tied)]])])
    return MultiReducedModel(K, W, tuple(patterns), bodies, loads, Fc, G, offsets, starts,
                             T_r, T_d, S_cho, Kc, dim, {}, {},
                             prescribed_patterns(assembled, patterns), ghost=g,
                             fixed=fixed, T_t=T_t)


def held_by_ties(bodies, tied) -> np.ndarray:
    """Per condensed body, whether it is held against rigid motion on its own (no
    ``rigid`` motions) or through tied interfaces by a body that is: a tie over a
    surface moves the tied bodies as one."""
    held = np.array([b.rigid is None for b in bodies])
    links = [(c.body1, c.body2) for c in tied]
    grew = True
    while grew:
        grew = False
        for i, j in links:
            if held[i] != held[j]:
                held[i] = held[j] = True
                grew = True
    return held


def _symmetry_rows_zeroed(G, couplings, assembled):
    """``G`` with the rows of the mortar components clamped on both sides
    (:func:`qsma.reduction.clamps.symmetry_components`) set to zero."""
    rows, start = [], 0
    for c in couplings:
        p = c.pairing
        sym = symmetry_components(p, assembled[c.slave], assembled[c.master])
        rows.append(start + local_rows(p.frames, sym))
        start += p.frames.shape[1] * p.n_pairs
    rows = np.concatenate(rows)
    if not len(rows):
        return G
    keep = np.ones(G.shape[0])
    keep[rows] = 0.0
    return sp.csr_matrix(sp.diags(keep) @ G)


def _unknown_columns(bodies, nodes, full, dim):
    """Positions, among the columns of the operator over every component of every
    interface node (``full``: each body's start there), of the bodies' unknowns: the
    components no clamp holds (:attr:`CondensedBody.C`, node by node)."""
    cols = []
    for j, b in enumerate(bodies):
        every = (dim * np.asarray(nodes[j])[:, None] + np.arange(dim)).ravel()
        cols.append(full[j] + np.flatnonzero(np.isin(every, b.C)))
    return np.concatenate(cols)


def _ghost(K, images):
    """``(K + k N N^T, Ghost)`` along the relative rigid motions, or ``(K, None)``."""
    g = ghost(K, images)
    if g is None:
        return K, None
    return K + g.k * (g.N @ g.N.T), g


def _slave_dofs(couplings, nodes, full, dim, unknown=None):
    """Positions of the DOFs of every contact point's node (each once): among the
    columns over every component (``full``: each body's start there), or with
    ``unknown`` (those of the columns that are unknowns) among the unknowns, the
    clamped ones left out."""
    dofs = []
    for c in couplings:
        pos = np.searchsorted(nodes[c.slave], c.pairing.contact_nodes)
        dofs.append((full[c.slave] + dim * pos[:, None] + np.arange(dim)).ravel())
    dofs = np.concatenate(dofs)
    if len(np.unique(dofs)) != len(dofs):
        raise InputError("a node is the slave of two interfaces; choose the slave sides "
                         "(Interface(slave=...)) so that each node carries at most one "
                         "interface's contact unknowns")
    if unknown is None:
        return dofs
    where = np.minimum(np.searchsorted(unknown, dofs), len(unknown) - 1)
    return where[unknown[where] == dofs]


def reduce_model(model, assembled, pairing, backend="auto",
                 patterns=("preload",)) -> MultiReducedModel:
    """:func:`reduce_bodies` of a model and its
    :class:`~qsma.model.pairing.MultiPairing` (``patterns``:
    the load patterns to condense, e.g. the bolts' unit tensions besides 'preload')."""
    return reduce_bodies(assembled, list(pairing.couplings), patterns=patterns,
                         backend=backend, names=[b.name for b in model.bodies],
                         tied=list(getattr(pairing, "tied", ())))


def tie_transform(model, assembled, pairing, tied) -> sp.csr_matrix:
    r"""``T`` with ``x_all = T x_reduced`` for the contact points in mask ``tied`` of
    every interface tied: Dirichlet DOFs dropped, and per tied contact point, component
    by component, the slave node's DOFs replaced by the interpolation of the master's,
    ``u_s = sum_k N_ik u_m,k`` (``N = I`` node-to-node; on mixed quadratic slave facets
    the coefficients of the mixed functions, :func:`_tie_rows`). A master DOF that is itself a
    slave of another interface (a washer between two plates) is replaced in turn, so
    ``T`` is the product of the substitutions; a chain that closes on itself is refused.

    A clamped slave DOF of a node-to-node pair clamps its partner. A clamped slave DOF
    of a mortar interface holds the master's interpolation there at zero,
    ``sum_k N_ik u_m,k = 0``: these constraints are eliminated after the substitution
    (:func:`qsma.reduction.clamps.constrained_basis`), except where the master is clamped
    there too (:func:`qsma.reduction.clamps.symmetry_components`: the slave DOF is then
    only clamped).
    """
    off = model.dof_offsets()
    dim = model.dim
    n = off[-1]
    fixed = np.zeros(n, dtype=bool)
    for k, a in enumerate(assembled):
        fixed[off[k] + a.fixed] = True
    couplings = getattr(pairing, "every_coupling", pairing.couplings)
    tied = np.concatenate([np.asarray(tied, dtype=bool),        # tied interfaces: always
                           np.ones(getattr(pairing, "n_tied", 0), dtype=bool)])
    rows, cols, vals, slaves = [], [], [], []
    held = ([], [], [])                       # mortar: rows sum_k N_ik u_m,k = 0
    for c, sl in zip(couplings, _row_slices(couplings)):
        p, t = c.pairing, tied[sl]
        sym = symmetry_components(p, assembled[c.slave], assembled[c.master])[t]
        N_t, corner_t = (m.tocsr() for m in _tie_rows(c, t))
        snodes, mnodes = p.contact_nodes[t], p.master_nodes
        for comp in range(dim):
            free_rows = ~sym[:, comp]                    # a symmetry: clamped only
            N, corner = N_t[free_rows].tocoo(), corner_t[free_rows].tocoo()
            sd = off[c.slave] + dim * snodes[free_rows] + comp
            md = off[c.master] + dim * mnodes[N.col] + comp
            cd = off[c.slave] + dim * p.contact_nodes[corner.col] + comp
            if fixed[sd].any():
                on, on_c = fixed[sd][N.row], fixed[sd][corner.row]
                if p.projection is None:
                    fixed[md[on]] = True
                else:
                    held[0].extend([sd[N.row][on], sd[corner.row][on_c]])
                    held[1].extend([md[on], cd[on_c]])
                    held[2].extend([N.data[on], corner.data[on_c]])
            slaves.append(sd)
            rows += [sd[N.row], sd[corner.row]]
            cols += [md, cd]
            vals += [N.data, corner.data]
    slaves = np.concatenate(slaves)
    if len(np.unique(slaves)) != len(slaves):
        raise InputError("a node is the slave of two interfaces; choose the slave sides "
                         "(Interface(slave=...)) so that each node carries at most one "
                         "interface's contact unknowns")
    is_slave = np.zeros(n, dtype=bool)
    is_slave[slaves] = True
    free = np.flatnonzero(~is_slave)
    B = sp.coo_matrix((np.concatenate([np.ones(len(free))] + vals),
                       (np.concatenate([free] + rows), np.concatenate([free] + cols))),
                      shape=(n, n)).tocsr()
    B = _substitute(B, is_slave, len(couplings) + 1)
    keep = np.flatnonzero(~fixed & ~is_slave)
    T = B[:, keep].tocsr()
    if not held[0]:
        return T
    r = np.unique(np.concatenate(held[0]), return_inverse=True)[1]
    A = sp.coo_matrix((np.concatenate(held[2]), (r, np.concatenate(held[1]))),
                      shape=(r.max() + 1, n)).tocsr() @ T
    return (T @ constrained_basis(A)).tocsr()


def _tie_rows(c, t):
    """``(N, corner)``: the rows ``u_s,i = sum_k N_ik u_m,k + sum_j corner_ij u_s,j`` of
    the contact points in mask ``t``. ``N`` is the projection and ``corner`` empty,
    except on mixed quadratic slave facets (:class:`qsma.model.dual_basis.SlaveBasis`,
    ``u_s = B u~``): there the coefficient is tied, ``u~_i = (P u_m)_i``, and since a
    midside row of ``B`` reaches only corners, whose coefficients are their nodal
    values, ``u_s,i = B_ii (P u_m)_i + sum_{j != i} B_ij u_s,j`` (the corners' own rows
    substituted in turn where they are tied). An open contact point keeps its node's
    DOFs as unknowns."""
    N = c.projection[t]
    basis = c.pairing.slave_basis
    if basis is None:
        return N.tocoo(), sp.coo_matrix((int(t.sum()), c.pairing.n_pairs))
    B = basis.to_nodes[t].tocsr()
    diagonal = B[:, np.flatnonzero(t)].diagonal()
    corner = B.tolil()
    corner[np.arange(len(diagonal)), np.flatnonzero(t)] = 0.0
    corner = corner.tocsr()
    corner.eliminate_zeros()
    return (sp.diags(diagonal) @ N).tocoo(), corner.tocoo()


def _row_slices(couplings):
    r = np.concatenate([[0], np.cumsum([c.pairing.n_pairs for c in couplings])])
    return [slice(r[k], r[k + 1]) for k in range(len(r) - 1)]


def _substitute(B, is_slave, depth):
    """``B`` composed with itself until no column is a slave DOF (at most ``depth``
    times: each interface can pass a DOF on once)."""
    for _ in range(depth + 1):
        if not B[:, np.flatnonzero(is_slave)].count_nonzero():
            return B
        B = (B @ B).tocsr()
        B.eliminate_zeros()
    raise InputError("the slave sides of the interfaces form a closed chain (a node is "
                     "tied, through other interfaces, to itself); choose the slave sides "
                     "(Interface(slave=...)) so that they do not")
