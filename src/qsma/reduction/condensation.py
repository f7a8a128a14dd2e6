r"""Static condensation of each body to its interface DOFs (docs/theory.md section 3).

Per body ``j`` with Dirichlet DOFs removed, interface DOFs C (rotated into the
pair frames) and the rest E::

    Kc_j = K_CC - K_CE K_EE^-1 K_EC          Fc_j = F_C - K_CE K_EE^-1 F_E
    Kc_j u_C = Fc_j + R_j                    u_E = K_EE^-1 (F_E - K_EC u_C)

A body congruent to an earlier one (a mirror or rotation of it) is derived from that
one's condensation (:mod:`.congruence`): one factor for both. Load patterns
(preload, modal load, ...) are columns. The two-body problem built from the
condensed bodies is in :mod:`.two_bodies`, several bodies in :mod:`.multibody`.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import logging
import threading
import time

import numpy as np
import scipy.sparse as sp

from .._infra.dense import symmetrised
from ..errors import InputError
from ..fe.formulation import hourglass_hint
from .congruence import CongruentMatrix, MappedSolver, find_congruence, solved_together
from .rigid import interface_basis
from .schur import ee_rhs, schur_complement, spd_solver

log = logging.getLogger("qsma")


@dataclass(frozen=True, eq=False)
class CondensedBody:
    """One body condensed to its interface DOFs (local pair frames, pair-major).

    Attributes
    ----------
    C, E : positions of interface / other DOFs in the body's DOF numbering
    R : sparse block-diagonal rotation, ``u_C = R @ u_local``, ``u_local = R.T @ u_C``;
        on the slave of mixed quadratic mortar facets, the rotation after the change to
        the contact coefficients (:func:`pair_rotation`), and ``R_inv`` its inverse
    Kc : condensed stiffness in local frames
    solve_EE : factorised ``K_EE^-1`` (callable on vectors or matrices)
    K_EC : sparse coupling block
    """

    name: str
    n_dofs: int
    C: np.ndarray
    E: np.ndarray
    R: np.ndarray
    Kc: np.ndarray
    solve_EE: object
    K_EC: object
    timings: dict = None
    rigid: np.ndarray = None     # orthonormal free rigid motions on C (local), or None
    R_inv: object = None         # inverse of R where R is not a rotation, else None

    @property
    def to_local(self):
        """The map ``u_local = to_local @ u_C`` (``R.T`` for a rotation)."""
        return self.R.T if self.R_inv is None else self.R_inv

    def condensed_load(self, F: np.ndarray) -> np.ndarray:
        """``Fc = R^T (F_C - K_CE K_EE^-1 F_E)`` for full-length load(s) ``F``."""
        return condensed_loads((self,), (F,))[0]

    def recover(self, u_local: np.ndarray, F: np.ndarray) -> np.ndarray:
        """Full DOF vector of the body from interface displacements (local) and the
        full applied load ``F``: ``u_E = K_EE^-1 (F_E - K_EC u_C)``; columns of
        ``u_local`` and ``F`` give columns of the result (one multi-RHS solve)."""
        return recovered((self,), (u_local,), (F,))[0]

    def functional(self, l: np.ndarray, patterns: np.ndarray, prescribed=None):
        """Split ``l @ u`` into ``h @ u_local + e @ a`` (``patterns``: full loads,
        columns; ``prescribed``: the displacements the clamps prescribe per pattern, the
        same columns, or None)."""
        z = self.solve_EE(l[self.E])
        h = self.R.T @ (l[self.C] - self.K_EC.T @ z)
        e = patterns[self.E].T @ z
        if prescribed is not None:
            e = e + prescribed.T @ l
        return h, e


def pair_rotation(frames: np.ndarray, basis=None) -> sp.csr_matrix:
    """Sparse block-diagonal ``R`` with ``u_C = R u_local`` (pair-major): block i is
    ``frames[i].T``, its columns the local axes of pair i. With the ``basis``
    (:class:`qsma.model.dual_basis.SlaveBasis`) of a mortar slave whose contact unknowns
    are coefficients ``u~`` of mixed quadratic functions, ``u_C = (B kron I) R u~_local``
    with ``B = basis.to_nodes``."""
    R = sp.block_diag(np.swapaxes(frames, 1, 2), format="csr")
    if basis is None:
        return R
    return sp.csr_matrix(sp.kron(basis.to_nodes, sp.identity(frames.shape[1])) @ R)


def _pair_rotation_inverse(frames, basis):
    """``R^-1`` of :func:`pair_rotation` with a ``basis``: ``R0^T (B^-1 kron I)``."""
    R0 = sp.block_diag(np.swapaxes(frames, 1, 2), format="csr")
    return sp.csr_matrix(R0.T @ sp.kron(basis.from_nodes, sp.identity(frames.shape[1])))


def condense_body(assembled, nodes, frames, backend="auto", basis=None) -> CondensedBody:
    """Condense one assembled body onto the interface ``nodes`` (pair order, frames;
    ``basis``: the contact coefficients of a mixed quadratic mortar slave, :func:`pair_rotation`).

    ``frames`` None: the interface DOFs are the global components of ``nodes`` that no
    clamp holds (``R`` the identity), as the several-body reduction
    (:mod:`.multibody`) takes them; a clamped component is no unknown of the
    condensed body. With pair frames every component of every node is an unknown
    (local frames mix them), so a clamped one is refused: the reduction routes
    interfaces with clamped nodes to :mod:`.multibody`.

    A body whose clamps leave rigid motions free is held through the interface: its
    ``Kc`` is singular along them; ``rigid`` holds their basis on the interface DOFs
    (:func:`qsma.reduction.rigid.interface_basis`; docs/theory.md section 10)."""
    body = assembled.body
    C, bad = _interface_dofs(assembled, nodes, keep_clamped=frames is not None)
    if len(bad):
        raise InputError(f"body {body.name!r}: interface node(s) {bad[:10].tolist()} are "
                         f"clamped and cannot be condensed in the pair frames; condense "
                         f"them in global components (frames=None)")
    free = assembled.free
    K = assembled.K.tocsr()
    if len(C) >= len(free) or not len(C):    # nothing inside, or nothing on the interface
        return _without_interior(assembled, C, frames, K, backend, basis)
    Kf = K[free][:, free]
    try:
        Kc_glob, solve = schur_complement(Kf, np.searchsorted(free, C), backend=backend)
    except InputError as exc:
        raise InputError(f"body {body.name!r}: {exc}; a body without clamps must be held "
                         f"by its interface nodes (not all on one line in 3D)."
                         + hourglass_hint([assembled])) from exc
    t0 = time.perf_counter()
    E = free[solve.E]
    K_EC = K[E][:, C].tocsc()
    R = sp.identity(len(C), format="csr") if frames is None else pair_rotation(frames, basis)
    Kc = np.asarray(R.T @ Kc_glob)
    del Kc_glob
    Kc = symmetrised(np.ascontiguousarray(R.T @ Kc.T))  # R^T Kc R, Kc_glob symmetric
    R_inv = None if basis is None else _pair_rotation_inverse(frames, basis)
    rigid = interface_basis(assembled, C, R.T if R_inv is None else R_inv)
    timings = dict(solve.timings, rotation=time.perf_counter() - t0, backend=solve.backend)
    return CondensedBody(body.name, body.n_dofs, C, E, R, Kc, solve, K_EC, timings, rigid,
                         R_inv)


def _without_interior(assembled, C, frames, K, backend, basis=None) -> CondensedBody:
    """A body whose every unclamped DOF lies on the interface (one layer of cells, or
    every other node clamped): its condensed stiffness is ``K_CC`` itself, ``E`` is
    empty. A body whose interface is clamped all over: ``C`` is empty, the clamps
    alone hold it there (its interior, if any, is solved in the recovery)."""
    t0 = time.perf_counter()
    R = sp.identity(len(C), format="csr") if frames is None else pair_rotation(frames, basis)
    Kc = symmetrised(np.ascontiguousarray(R.T @ (R.T @ K[C][:, C].toarray()).T))
    E = np.setdiff1d(assembled.free, C)
    solve = RefactorisedEE(assembled, E, backend)
    R_inv = None if basis is None else _pair_rotation_inverse(frames, basis)
    rigid = (interface_basis(assembled, C, R.T if R_inv is None else R_inv) if len(C)
             else None)
    return CondensedBody(assembled.body.name, assembled.body.n_dofs, C, E, R, Kc, solve,
                         K[E][:, C].tocsc(), dict(rotation=time.perf_counter() - t0,
                                                  backend="none (no interior DOFs)"),
                         rigid, R_inv)


def congruent_body(base: CondensedBody, assembled, nodes, frames, congruence
                   ) -> CondensedBody | None:
    r"""Body B condensed through the condensation ``base`` of a body A congruent to it
    (:func:`qsma.reduction.congruence.find_congruence`): no factorisation of its own.

    With ``T`` the DOF map of ``congruence`` and ``T_E``, ``T_C`` its blocks between
    the E and the C DOFs of the two bodies (each in its own order: B's interface
    ``nodes`` in its pair order, its E sorted),

    .. math:: Kc_B = G\, Kc_A\, G^T, \quad G = R_B^T T_C R_A, \qquad
              (K^B_{EE})^{-1} = T_E (K^A_{EE})^{-1} T_E^T ,

    the first from A's ``Kc`` in A's pair frames ``R_A`` to B's pair frames ``R_B``
    (``frames``), kept as ``Kc_A`` and the sparse ``G``
    (:class:`qsma.reduction.congruence.CongruentMatrix`: no second dense matrix), the second a
    :class:`qsma.reduction.congruence.MappedSolver` on A's factor.
    ``K_EC`` and the free rigid motions are B's own. None if the E or C DOFs of the
    two bodies do not correspond (then B is condensed on its own)."""
    t0 = time.perf_counter()
    body = assembled.body
    C, bad = _interface_dofs(assembled, nodes, keep_clamped=frames is not None)
    if len(bad):
        return None                          # condense_body names the clamped nodes
    E = np.setdiff1d(assembled.free, C)
    if len(E) != len(base.E) or len(C) != len(base.C):
        return None
    T = congruence.dof_map()
    T_E, T_C = T[E][:, base.E].tocsr(), T[C][:, base.C].tocsr()
    if not (_orthogonal_block(T_E) and _orthogonal_block(T_C)):
        return None
    R = sp.identity(len(C), format="csr") if frames is None else pair_rotation(frames)
    G = (R.T @ T_C @ base.R).tocsr()                 # A's local frames -> B's
    Kc = CongruentMatrix(np.asarray(base.Kc), G)     # G Kc_A G^T, not held densely
    K_EC = assembled.K.tocsr()[E][:, C].tocsc()
    solve = MappedSolver(base.solve_EE, T_E, base.name)
    rigid = interface_basis(assembled, C, R.T)
    timings = dict(congruent_with=base.name, mapped=time.perf_counter() - t0,
                   backend=base.timings.get("backend") if base.timings else None)
    return CondensedBody(body.name, body.n_dofs, C, E, R, Kc, solve, K_EC, timings, rigid)


def _interface_dofs(assembled, nodes, keep_clamped=True):
    """``(C, clamped)``: the interface DOFs of ``nodes`` (node by node, in their order)
    and those of ``nodes`` that a clamp holds in some direction. ``keep_clamped``
    False: ``C`` without the clamped DOFs, and no node reported."""
    nodes = np.asarray(nodes)
    dim = assembled.body.dim
    C = (dim * nodes[:, None] + np.arange(dim)[None, :]).ravel()
    fixed = np.zeros(assembled.body.n_dofs, dtype=bool)
    fixed[assembled.fixed] = True
    if not keep_clamped:
        return C[~fixed[C]], nodes[:0]
    return C, nodes[np.any(fixed[C].reshape(-1, dim), axis=1)]


def _orthogonal_block(T) -> bool:
    """Whether the sparse square block ``T`` of an orthogonal DOF map is orthogonal
    itself (unit rows and columns: the map sends the block's DOFs among themselves)."""
    sq = T.multiply(T)
    one = lambda v: np.allclose(np.asarray(v).ravel(), 1.0, rtol=0.0, atol=1e-12)
    return one(sq.sum(axis=0)) and one(sq.sum(axis=1))


def condense_bodies(assembled, nodes, frames, backend="auto", bases=None) -> tuple:
    """:func:`condense_body` for every body (``nodes[j]``, ``frames[j]`` its interface
    nodes and pair frames, ``bases[j]`` None or the basis of a mixed quadratic mortar
    slave), except that a body congruent to an earlier one
    (:func:`qsma.reduction.congruence.find_congruence`, checked before any factorisation) is
    derived from that one's condensation (:func:`congruent_body`): one factor for
    both (bodies without a basis only: the derivation maps rotations)."""
    bases = bases or (None,) * len(assembled)
    own = {}                                  # body j -> (base body k, congruence)
    for j in range(len(assembled)):
        for k in range(j):
            if k in own or bases[j] is not None or bases[k] is not None:
                continue
            cong = find_congruence(assembled[k], assembled[j], nodes[k], nodes[j])
            if cong is not None:
                own[j] = (k, cong)
                break
    bodies = []
    for j, a in enumerate(assembled):
        b = None
        if j in own:
            k, cong = own[j]
            b = congruent_body(bodies[k], a, nodes[j], frames[j], cong)
            if b is None:
                log.info("body %r is condensed on its own: its interface or other DOFs "
                         "do not correspond to those of %r", a.body.name, bodies[k].name)
        bodies.append(condense_body(a, nodes[j], frames[j], backend, bases[j])
                      if b is None else b)
    return tuple(bodies)


def condensed_loads(bodies, loads) -> list:
    """``[b.condensed_load(F) for b, F in zip(bodies, loads)]`` with the ``K_EE``
    solves of bodies that share a factor in one multi-RHS solve
    (:func:`qsma.reduction.congruence.solved_together`)."""
    loads = [np.asarray(F, dtype=float) for F in loads]
    z = solved_together([b.solve_EE for b in bodies], [F[b.E] for b, F in zip(bodies, loads)])
    return [b.R.T @ (F[b.C] - b.K_EC.T @ zb) for b, F, zb in zip(bodies, loads, z)]


def recovered(bodies, u_locals, loads) -> list:
    """``[b.recover(u, F) ...]`` with the ``K_EE`` solves of bodies that share a factor
    in one multi-RHS solve."""
    uC = [b.R @ u for b, u in zip(bodies, u_locals)]
    z = solved_together([b.solve_EE for b in bodies],
                        [F[b.E] - b.K_EC @ c for b, F, c in zip(bodies, loads, uC)])
    out = []
    for b, u, c, zb in zip(bodies, u_locals, uC, z):
        full = np.zeros((b.n_dofs,) + np.shape(u)[1:])
        full[b.C] = c
        full[b.E] = zb
        out.append(full)
    return out


def prescribed_patterns(assembled, patterns):
    """Per body, the displacements its clamps prescribe (:attr:`qsma.fe.AssembledBody.
    prescribed`) as columns of the load ``patterns`` (n_dofs, n_patterns), None for a
    body that prescribes none; None if no body does."""
    out = tuple(None if not getattr(a, "prescribed", None) else np.column_stack(
        [a.prescribed.get(p, np.zeros(a.n_dofs)) for p in patterns]) for a in assembled)
    return None if all(P is None for P in out) else out


def with_prescribed(fields, prescribed, a) -> tuple:
    """The recovered ``fields`` (one full vector per body) plus the displacements the
    clamps prescribe at the load factors ``a`` (:func:`prescribed_patterns`): the
    recovery leaves the Dirichlet DOFs at zero."""
    if prescribed is None:
        return tuple(fields)
    return tuple(u if P is None else u + P @ a for u, P in zip(fields, prescribed))


def extended_prescribed(prescribed) -> tuple | None:
    """``prescribed`` with a zero column for a new load pattern."""
    if prescribed is None:
        return None
    return tuple(None if P is None else np.column_stack([P, np.zeros(len(P))])
                 for P in prescribed)


# -- a condensed model sent to another process ----------------------------------------

def refactorised_bodies(bodies, assembled) -> tuple:
    """The condensed bodies with each own ``K_EE`` factor replaced by a
    :class:`RefactorisedEE`; a body that solves through a congruent body's factor
    (:class:`qsma.reduction.congruence.MappedSolver`) keeps doing so, through that body's
    ``RefactorisedEE`` (one object, pickled once: one factorisation per worker)."""
    by_name = {a.body.name: a for a in assembled}
    own = {b.name: RefactorisedEE(by_name[b.name], b.E, _backend_of(b.solve_EE))
           for b in bodies if not isinstance(b.solve_EE, MappedSolver)}
    return tuple(replace(b, solve_EE=replace(b.solve_EE, base=own[b.solve_EE.base_name])
                         if isinstance(b.solve_EE, MappedSolver) else own[b.name])
                 for b in bodies)


def _backend_of(solver) -> str:
    """The factorisation backend of a ``K_EE`` solver (``"auto"`` if it does not say)."""
    return getattr(solver, "backend", "auto")


class RefactorisedEE:
    r"""``x = K_EE^{-1} b`` of one body, factorised on first use.

    ``K_EE = K[E][:, E]`` with ``K`` the assembled stiffness of ``assembled`` and ``E``
    the body's non-interface free DOFs (:attr:`CondensedBody.E`), the
    block whose factor the condensation used. The factorisation is
    :func:`qsma.reduction.schur.spd_solver` with the condensation's ``backend`` where it names
    one it knows (its fill-reducing ordering may differ from the condensation's, so
    solves agree with the original factor to round-off, not bit for bit). Accepts
    ``b`` of shape ``(n_E,)`` or ``(n_E, k)``.
    """

    def __init__(self, assembled, E, backend="auto"):
        self.assembled, self.E, self.backend = assembled, np.asarray(E), backend
        self._solve = None
        self._lock = threading.Lock()

    @property
    def n(self) -> int:
        return len(self.E)

    @property
    def factorised(self) -> bool:
        return self._solve is not None

    def __call__(self, b):
        b = ee_rhs(b, self.n)
        if b.size == 0:
            return b.copy()
        with self._lock:
            if self._solve is None:
                K = self.assembled.K.tocsr()
                self._solve = spd_solver(K[self.E][:, self.E], backend=self.backend)
        return self._solve(b)

    def __reduce__(self):                 # shipped again (e.g. spilled): refactorised
        return (RefactorisedEE, (self.assembled, self.E, self.backend))

    def __repr__(self):
        return (f"RefactorisedEE(n={self.n}, backend={self.backend!r}, "
                f"factorised={self.factorised})")
