r"""The two-body relative-displacement contact problem from the condensed bodies
(docs/theory.md section 4).

With ``lam`` the contact force on body 2 and ``d = u_C^2 - u_C^1``::

    lam = K d + lam_w,  K = Kc_1 S^-1 Kc_2,  lam_w = Kc_2 S^-1 Fc_1 - Kc_1 S^-1 Fc_2,
    S = Kc_1 + Kc_2 .

Load patterns (preload, modal load, ...) are columns; the load factors ``a``
weight them, so ``Fc_j = Fc_j[:, patterns] @ a``. A mortar interface joins a slave
and a master body through a projection (:func:`combine`); bodies held only by the
joint get the gauge and the spring of :mod:`.rigid`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from .._infra.dense import cho_solved, mirror_triangle, symmetrised
from ..errors import InputError
from .condensation import (condense_bodies, condensed_loads, extended_prescribed,
                           pair_rotation, prescribed_patterns, recovered, with_prescribed)
from ..model.pairing import Coupling
from .multibody import reduce_bodies
from .clamps import clamped_interface
from .rigid import assembly_gauge, ghost, regularised_S


@dataclass(frozen=True, eq=False)
class ReducedModel:
    r"""The two-body problem ``lam = K d + W a`` with everything the load loop needs.

    Node-to-node (``P is None``): ``d = u_2 - u_1`` on the pairs, ``S = Kc_1 + Kc_2``.
    Projection (mortar, :func:`combine`): slave ``s``, master ``m``,
    ``d = sigma (u_s - P u_m)`` (sigma = +1 if the slave is body 2, -1 if body 1) and
    ``S = Kc_m + P^T Kc_s P``.

    Attributes
    ----------
    K : (n, n) relative-displacement stiffness (local frames, contact-point-major)
    W : (n, n_patterns) welded contact force per unit load factor (``lam_w = W a``)
    patterns : names of the load patterns (columns of W, entries of a)
    bodies : the two :class:`CondensedBody` (body order)
    loads : per body, (n_dofs, n_patterns) full load patterns
    S_cho : Cholesky factor of ``S``, the condensed stiffness of the welded pair
    Fc : per body, condensed load patterns
    functionals : name -> (c_d, c_a) with value ``c_d @ d + c_a @ a``
    P : None, or the sparse (n, n_master dofs) projection, slave local frames from
        master global components (:func:`projection_matrix`)
    slave : 0 or 1, index of the slave body in ``bodies`` (0 for node-to-node)
    ghost : None, or the :class:`qsma.reduction.rigid.Ghost` spring added to ``K`` along the
        relative rigid motions of bodies held only by the joint (``S`` then carries
        the gauge of a free-free assembly, docs/theory.md section 10)
    """

    K: np.ndarray
    W: np.ndarray
    patterns: tuple
    bodies: tuple
    loads: tuple
    S_cho: object
    Fc: tuple
    dim: int
    functionals: dict
    definitions: dict
    P: sp.csr_matrix | None = None
    slave: int = 0
    ghost: object = None          # qsma.reduction.rigid.Ghost: K holds its spring, or None
    gauge: np.ndarray | None = None   # rigid motions of a free-free assembly in S
    #: per body, the displacements its clamps prescribe per pattern (or None): the
    #: recovered fields and the functionals include them
    prescribed: tuple | None = None

    def __post_init__(self):
        # Read-only, so the contact problem can hold this K instead of a copy of it
        # (qsma.contact.ContactProblem takes an exactly symmetric read-only K as is).
        a = self.K
        while isinstance(a, np.ndarray):        # the array and the arrays it views
            a.flags.writeable = False
            a = a.base

    @property
    def n_pairs(self):
        return self.K.shape[0] // self.dim

    @property
    def sigma(self):
        """+1 if the slave is body 2 (``d = u_2 - P u_1``), -1 if body 1."""
        return 1.0 if self.slave == 1 else -1.0

    def welded_contact_force(self, a) -> np.ndarray:
        """``lam_w(a)`` as (n_pairs, dim)."""
        return (self.W @ np.asarray(a, dtype=float)).reshape(-1, self.dim)

    def interface_displacements(self, d, a):
        """Interface displacements (local frames) of body 1 and body 2.

        Node-to-node: ``u1 = S^-1 (Fc_1 + Fc_2 - Kc_2 d)``, ``u2 = u1 + d``.
        Projection: ``u_m = S^-1 (P^T Fc_s + Fc_m - sigma P^T Kc_s d)``,
        ``u_s = P u_m + sigma d`` (the equilibrium of the pair with ``d`` imposed).
        """
        return _released_interface(self, np.asarray(d, dtype=float).ravel(), self.Fc,
                                   np.asarray(a, dtype=float))

    def recover(self, d, a):
        """Full displacement vectors of both bodies from ``d`` and the load factors."""
        u1, u2 = self.interface_displacements(d, a)
        a = np.asarray(a, dtype=float)
        return with_prescribed(recovered(self.bodies, (u1, u2), [F @ a for F in self.loads]),
                               self.prescribed, a)

    def evaluate(self, name, d, a) -> float:
        c_d, c_a = self.functionals[name]
        return float(c_d @ np.asarray(d).ravel() + c_a @ np.asarray(a, dtype=float))

    def add_pattern(self, name, F1, F2) -> "ReducedModel":
        """A new reduced model with one more load pattern (full loads per body)."""
        if name in self.patterns:
            raise InputError(f"load pattern {name!r} exists already")
        loads = tuple(np.column_stack([L, F]) for L, F in zip(self.loads, (F1, F2)))
        Fc = tuple(np.column_stack([fc, new]) for fc, new in
                   zip(self.Fc, condensed_loads(self.bodies, (F1, F2))))
        w_new = _welded(self.bodies, self.S_cho, tuple(f[:, -1:] for f in Fc), self.P,
                        self.slave, self.gauge is not None)
        # the existing columns are kept as they are (the preload was solved with them;
        # the ghost spring's anchor lives in the 'preload' column, rigid.anchored)
        new = replace(self, W=np.column_stack([self.W, w_new]),
                      patterns=self.patterns + (name,), loads=loads, Fc=Fc, functionals={},
                      prescribed=extended_prescribed(self.prescribed))
        return new.with_functionals(self.definitions)

    def with_functionals(self, definitions: dict) -> "ReducedModel":
        """Attach linear functionals ``name -> (l_1, l_2)`` (full DOF vectors per body),
        evaluated later by :meth:`evaluate` without touching the full model."""
        funcs = dict(self.functionals)
        for name, (l1, l2) in definitions.items():
            funcs[name] = _functional(self, l1, l2)
        return replace(self, functionals=funcs, definitions={**self.definitions, **definitions})


def _welded(bodies, S_cho, Fc, P=None, slave=0, gauged=False):
    """``W``: node-to-node ``Kc_2 S^-1 Fc_1 - Kc_1 S^-1 Fc_2``; projection
    ``sigma (Kc_s P S^-1 (P^T Fc_s + Fc_m) - Fc_s)``. With the gauge of a free-free
    assembly in ``S`` (``gauged``) only ``S^-1`` of the self-equilibrated sum is exact:
    node-to-node then ``Kc_2 S^-1 (Fc_1 + Fc_2) - Fc_2``."""
    if P is None and gauged:
        return bodies[1].Kc @ cho_solved(S_cho, Fc[0] + Fc[1]) - Fc[1]
    if P is None:
        Kc1, Kc2 = bodies[0].Kc, bodies[1].Kc
        return Kc2 @ cho_solved(S_cho, Fc[0]) - Kc1 @ cho_solved(S_cho, Fc[1])
    s, m = slave, 1 - slave
    sigma = 1.0 if slave == 1 else -1.0
    y = cho_solved(S_cho, P.T @ Fc[s] + Fc[m])
    return sigma * (bodies[s].Kc @ (P @ y) - Fc[s])


def _functional(rm, l1, l2):
    """``l1 @ u_body1 + l2 @ u_body2`` as ``c_d @ d + c_a @ a``.

    Node-to-node: ``y = S^-1 (h_1 + h_2)``, ``c_d = h_2 - Kc_2 y``. Projection: with
    ``u_s = P u_m + sigma d``, ``y = S^-1 (P^T h_s + h_m)`` and
    ``c_d = sigma (h_s - Kc_s P y)``; in both ``c_a = (sum of condensed loads seen by
    S)^T y + e_1 + e_2``.
    """
    given = rm.prescribed or (None, None)
    (h1, e1), (h2, e2) = (b.functional(l, L, Pr) for b, l, L, Pr
                          in zip(rm.bodies, (l1, l2), rm.loads, given))
    if rm.P is None:
        y = cho_solved(rm.S_cho, h1 + h2)
        c_d = h2 - rm.bodies[1].Kc @ y
        c_a = (rm.Fc[0] + rm.Fc[1]).T @ y + e1 + e2
        return c_d, c_a
    s, m, P = rm.slave, 1 - rm.slave, rm.P
    h = (h1, h2)
    y = cho_solved(rm.S_cho, P.T @ h[s] + h[m])
    c_d = rm.sigma * (h[s] - rm.bodies[s].Kc @ (P @ y))
    c_a = (P.T @ rm.Fc[s] + rm.Fc[m]).T @ y + e1 + e2
    return c_d, c_a


def _factor_S(S, Z=None):
    try:
        return sla.cho_factor(regularised_S(S, Z), overwrite_a=True)  # S: a temporary
    except np.linalg.LinAlgError as exc:
        raise InputError("the condensed stiffness of the welded pair (Kc_1 + Kc_2, or "
                         "Kc_m + P^T Kc_s P) is not positive definite: the two bodies "
                         "together are not held against rigid-body motion; add clamps"
                         ) from exc


def minus_gram(A, S_cho, B) -> np.ndarray:
    r"""``A - B S^{-1} B^T`` for a symmetric ``A`` and ``S = U^T U`` (``S_cho`` from
    :func:`scipy.linalg.cho_factor`), as ``A - Y^T Y`` with ``Y = U^{-T} B^T``.

    One triangular solve and one symmetric rank-k product (BLAS ``trsm`` and
    ``syrk``, ``n^3 / 3`` flops each for square ``B``) replace the general solve and
    product of ``B S^{-1} B^T`` (``2 n^3`` and more). The node-to-node combination
    ``K = Kc_1 S^{-1} Kc_2`` with ``S = Kc_1 + Kc_2`` is ``Kc_1 - Kc_1 S^{-1} Kc_1``
    (``Kc_2 = S - Kc_1``), so it is ``minus_gram(Kc_1, S_cho, Kc_1)``, or the same with
    ``Kc_2``; the softer body is taken, whose round-off ``eps |Kc_j|`` is the smaller
    one in the difference. The result is exactly symmetric."""
    c, lower = S_cho
    Y = sla.solve_triangular(c, np.asarray(B, dtype=float).T, lower=lower,
                             trans=0 if lower else 1, check_finite=False)
    G = sla.blas.dsyrk(1.0, Y, trans=1, lower=0)    # upper triangle of Y^T Y
    del Y
    if G.flags.f_contiguous:                         # BLAS order: its C view, lower
        G = mirror_triangle(G.T, "lower")
    else:
        G = mirror_triangle(G, "upper")
    np.subtract(A, G, out=G)                         # in place: no further n x n copy
    return symmetrised(G)


def projection_matrix(pairing) -> sp.csr_matrix:
    """Sparse ``P`` over DOFs: ``(P u_m)`` in the slave's local frames from master global
    components, ``P = R_s^T (N kron I_dim)`` with ``N`` the pairing's projection and
    ``R_s`` the rotation into the contact points' frames (a slave DOF couples to the
    master DOFs of the few facets it faces)."""
    dim = pairing.frames.shape[1]
    N = sp.kron(pairing.projection, sp.identity(dim), format="csr")
    return sp.csr_matrix(pair_rotation(pairing.frames).T @ N)


def combine(slave, master, P, Z=None):
    r"""Relative-displacement stiffness of a slave body coupled to a master body by the
    projection ``P``, and the factor of the welded pair's stiffness.

    With ``u_s = P u_m + sigma d`` and the contact force ``sigma lam`` on the slave,
    ``-sigma P^T lam`` on the master, eliminating ``u_m`` from the equilibrium of both::

        S = Kc_m + P^T Kc_s P
        K = Kc_s - Kc_s P S^-1 P^T Kc_s      (= (Kc_s^-1 + P Kc_m^-1 P^T)^-1, Woodbury)

    Only ``S`` (SPD when the welded pair is held) is factorised; for ``P = I`` this is
    ``Kc_s S^-1 Kc_m`` of the node-to-node formula (which the node coupling uses as is).
    ``P`` is sparse (:func:`projection_matrix`) and ``Kc_s`` symmetric (symmetrised by
    :func:`condense_body`): ``Kc_s P = (P^T Kc_s)^T`` and ``P^T (Kc_s P)`` are
    sparse-times-dense products, ``nnz(P)`` multiply-adds per column of the dense
    factor instead of a dense product's ``n_m``.
    """
    Ks = np.asarray(slave.Kc)
    KP = (P.T @ Ks).T                               # Kc_s P (a transposed view)
    S_cho = _factor_S(np.asarray(master.Kc) + P.T @ KP, Z)
    if Z is None:                                   # Kc_s - (Kc_s P) S^-1 (Kc_s P)^T
        return minus_gram(Ks, S_cho, KP), S_cho
    K = Ks - KP @ cho_solved(S_cho, KP.T)        # gauged S: the product form
    return 0.5 * (K + K.T), S_cho


def reduce_two_bodies(assembled1, assembled2, pairing, patterns=("preload",),
                      backend="auto") -> ReducedModel:
    """Condense both bodies and combine them into the relative-displacement problem.

    Node-to-node pairings use the pair frames on both sides; a mortar pairing condenses
    the slave on its contact points (local frames; on mixed quadratic facets the
    coefficients of the mixed functions, ``pairing.slave_basis``) and the master on its
    own interface nodes (global components), joined by the projection (:func:`combine`).
    ``backend`` chooses the Schur-complement method (:data:`qsma.reduction.schur.SCHUR_BACKENDS`).

    An interface node that a clamp holds in some direction makes the relative
    displacement partly prescribed; such a pair is reduced in global components with
    the clamped DOFs left out (:func:`qsma.reduction.multibody.reduce_bodies`, which
    returns a :class:`~qsma.reduction.multibody.MultiReducedModel` of the same use).
    """
    asm = (assembled1, assembled2)
    if any(clamped_interface(a, n) for a, n in zip(asm, (pairing.nodes1, pairing.nodes2))):
        return reduce_bodies(asm, [Coupling(pairing, 0, 1)], patterns=patterns,
                             backend=backend)
    loads = tuple(np.column_stack([a.loads.get(p, np.zeros(a.n_dofs)) for p in patterns])
                  for a in asm)
    dim = assembled1.body.dim
    if pairing.projection is None:
        b1, b2 = condense_bodies(asm, (pairing.nodes1, pairing.nodes2),
                                 (pairing.frames, pairing.frames), backend)
        Fc = tuple(condensed_loads((b1, b2), loads))
        Z = _gauge(asm, (b1, b2), 0, loads)
        K, S_cho = _node_to_node(np.asarray(b1.Kc), np.asarray(b2.Kc), Z)
        W = _welded((b1, b2), S_cho, Fc, gauged=Z is not None)
        K, g = _ghost(K, [None if b1.rigid is None else -b1.rigid, b2.rigid])
        return ReducedModel(K, W, tuple(patterns), (b1, b2), loads, S_cho, Fc, dim, {}, {},
                            ghost=g, gauge=Z, prescribed=prescribed_patterns(asm, patterns))
    s = pairing.slave - 1
    m = 1 - s
    nodes = (pairing.nodes1, pairing.nodes2)
    eye = np.broadcast_to(np.eye(dim), (len(nodes[m]), dim, dim))
    framed = (pairing.frames, eye) if s == 0 else (eye, pairing.frames)
    bases = [None, None]
    bases[s] = pairing.slave_basis            # mixed quadratic slave facets: u_s = B u~
    bodies = condense_bodies(asm, nodes, framed, backend, bases)
    bs, bm = bodies[s], bodies[m]
    P = projection_matrix(pairing)
    sigma = 1.0 if s == 1 else -1.0
    Fc = tuple(condensed_loads(bodies, loads))
    Z = _gauge(asm, bodies, m, loads)
    K, S_cho = combine(bs, bm, P, Z)
    W = _welded(bodies, S_cho, Fc, P, s)
    K, g = _ghost(K, [None if bs.rigid is None else sigma * bs.rigid,
                      None if bm.rigid is None else -sigma * (P @ bm.rigid)])
    return ReducedModel(K, W, tuple(patterns), bodies, loads, S_cho, Fc, dim, {}, {}, P, s,
                        ghost=g, gauge=Z, prescribed=prescribed_patterns(asm, patterns))


def _node_to_node(Kc1, Kc2, Z):
    """``(K, S_cho)`` of the node-to-node pair from the dense ``Kc_1``, ``Kc_2``:
    ``S = Kc_1 + Kc_2`` factorised and ``K = Kc_1 S^-1 Kc_2`` (:func:`minus_gram` of
    the softer body; a gauged ``S`` of a free-free assembly: the product form)."""
    S_cho = _factor_S(Kc1 + Kc2, Z)
    if Z is None:
        soft = min((Kc1, Kc2), key=lambda Kc: np.trace(Kc))
        return minus_gram(soft, S_cho, soft), S_cho      # = Kc_1 S^-1 Kc_2
    K = Kc1 @ cho_solved(S_cho, Kc2)
    return 0.5 * (K + K.T), S_cho


def _gauge(asm, bodies, index, loads):
    """Rigid motions of a free-free assembly on the unknowns of ``S`` (or None), its
    loads checked to be self-equilibrated (:func:`qsma.reduction.rigid.assembly_gauge`)."""
    return assembly_gauge(asm, bodies, index, loads)


def _ghost(K, images):
    """``(K + k N N^T, Ghost)`` along the relative rigid motions, or ``(K, None)``."""
    g = ghost(K, images)
    if g is None:
        return K, None
    return K + g.k * (g.N @ g.N.T), g


@dataclass(frozen=True, eq=False)
class TiedSolver:
    r"""Static solve of the assembly with the pairs of a mask tied and the others free
    (no contact force), through the condensed bodies of a two-body reduced model: the
    bodies' ``K_EE`` factors of the condensation and dense interface algebra, no
    factorisation of the whole assembly (docs/theory.md, tied modes).

    For full loads ``F_j`` per body, with ``Fc_j`` their condensed loads and ``w`` the
    welded contact force (:func:`_welded`, all pairs tied), the relative displacement
    ``d`` is zero on the tied pairs and makes the contact force vanish on the free ones
    (DOFs ``G``):

    .. math:: K_{GG}\, d_G = -w_G, \qquad d_{\bar G} = 0,

    with ``K`` the relative-displacement stiffness of the bodies alone (without the
    regularising spring of a body held by the joint, without locked bolts). The
    interface displacements follow from ``d`` as in
    :meth:`ReducedModel.interface_displacements`, the full fields from the recovery
    ``u_E = K_EE^-1 (F_E - K_EC u_C)``. Exact: the same equations as the assembled
    tied stiffness, solved by blocks. A free-free assembly (gauged ``S``) needs
    self-equilibrated loads; the rigid part of the answer is then arbitrary.

    Attributes
    ----------
    reduced : the two-body :class:`ReducedModel`
    G : free (open) DOFs of the relative displacement, contact-point-major
    KGG_cho : Cholesky factor of ``K_GG`` (None when every pair is tied)
    """

    reduced: ReducedModel
    G: np.ndarray
    KGG_cho: object

    def __call__(self, F1, F2):
        """Full displacement vectors ``(u_1, u_2)`` of the bodies under ``F_1, F_2``;
        loads of shape (n_dofs, k) give k columns (each body's ``K_EE`` factor applied
        to all of them at once)."""
        rm = self.reduced
        Fc = tuple(f.reshape(len(b.C), -1)
                   for b, f in zip(rm.bodies, condensed_loads(rm.bodies, (F1, F2))))
        d = np.zeros((rm.K.shape[0], Fc[0].shape[1]))
        if len(self.G):
            w = _welded(rm.bodies, rm.S_cho, Fc, rm.P, rm.slave, rm.gauge is not None)
            d[self.G] = -cho_solved(self.KGG_cho, w[self.G])
        u = _released_interface(rm, d, Fc)
        if np.ndim(F1) == 1:
            u = tuple(v[:, 0] for v in u)
        return tuple(recovered(rm.bodies, u, (F1, F2)))


def tied_solver(reduced, tied, springs=None) -> TiedSolver | None:
    """The :class:`TiedSolver` of ``reduced`` (a :class:`ReducedModel`, or a model with
    locked bolts whose ``base`` is one) with the contact points in mask ``tied`` tied;
    None where ``K_GG`` is not positive definite (the tied pairs do not hold the bodies
    together: a mechanism, left to the caller's full solve to diagnose).

    ``springs``, optional: (n_pairs, dim) stiffness of a compliant layer at the tied
    points (``inf``: tied component; see :func:`qsma.modal.linear_modes`): the
    components with a finite spring are free DOFs of ``d`` whose stiffness gains it,
    ``(K_GG + S_G) d_G = -w_G``."""
    rm = getattr(reduced, "base", reduced)
    if not isinstance(rm, ReducedModel):
        return None
    tied = np.asarray(tied, dtype=bool)
    if springs is None:
        fixed, spring = np.repeat(tied, rm.dim), np.zeros(len(tied) * rm.dim)
    else:
        springs = np.asarray(springs, dtype=float)
        fixed = (tied[:, None] & np.isinf(springs)).ravel()
        spring = np.where(tied[:, None] & np.isfinite(springs), springs, 0.0).ravel()
    G = np.flatnonzero(~fixed)
    if not len(G):
        return TiedSolver(rm, G, None)
    K_GG = rm.K[np.ix_(G, G)]
    K_GG[np.diag_indices_from(K_GG)] += spring[G]
    if rm.ghost is not None:                     # the bodies' own stiffness
        N_G = rm.ghost.N[G]
        K_GG -= rm.ghost.k * (N_G @ N_G.T)
    try:
        cho = sla.cho_factor(K_GG, overwrite_a=True)
    except np.linalg.LinAlgError:
        return None
    return TiedSolver(rm, G, cho)


def _released_interface(rm, d, Fc, a=None):
    """Interface displacements of both bodies for the relative displacement ``d`` and
    condensed loads ``Fc`` (vectors, or matrices of as many columns), times the load
    factors ``a`` if given: the formulas of :meth:`ReducedModel.interface_displacements`."""
    applied = (lambda F: F) if a is None else (lambda F: F @ a)
    if rm.P is None:
        u1 = cho_solved(rm.S_cho, applied(Fc[0] + Fc[1]) - rm.bodies[1].Kc @ d)
        return u1, u1 + d
    s, m, P = rm.slave, 1 - rm.slave, rm.P
    um = cho_solved(rm.S_cho, P.T @ (applied(Fc[s]) - rm.sigma * (rm.bodies[s].Kc @ d))
                       + applied(Fc[m]))
    us = P @ um + rm.sigma * d
    return (us, um) if s == 0 else (um, us)
