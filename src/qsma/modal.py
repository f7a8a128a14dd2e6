"""Linear modes of the assembly with a chosen set of interface pairs tied.

Tied pairs share their DOFs (elimination, not penalty): the DOFs of the body-2
node of a tied pair are replaced by those of its body-1 partner. With a mortar
coupling a tied contact point is a multipoint constraint: the slave node's DOFs are
eliminated, ``u_slave = sum_k P_ik u_master_k`` per component.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from ._resources import free_memory
from .errors import AnalysisError, InputError
from .fe.bolts import bolt_stiffness, bolt_vectors
from .model.pairing import Coupling, MultiPairing, body_order
from .reduction import multibody
from .reduction.multibody import relative_displacement_operator
from .reduction.rigid import (assembly_free_motions, assembly_motions, rigid_body_modes,
                              rigid_modes_message)
from .reduction.schur import spd_solver
from .reduction.two_bodies import tied_solver

#: Most modes one eigen solve may ask for. ARPACK keeps 2k+1 Lanczos vectors and
#: orthogonalises against them; measured on sandwich-2d (4500 DOFs, 2-core machine,
#: `linear_modes(..., n_modes=k)`): k = 100 in 1.8 s, 200 in 3.1 s, 800 in 28 s, and
#: n_modes = 100000 ran > 300 s before this limit. QSMA needs mode + 1 modes.
MAX_MODES = 200
#: Fraction of the free memory the 2k+1 Lanczos vectors of n doubles may take; the
#: other half is left to the factorised stiffness and the rest of the run.
LANCZOS_MEMORY_SHARE = 0.5
#: A mode is a rigid-body mode when, body by body, it is a rigid motion to this
#: relative accuracy (norm of the non-rigid part over the norm of the mode). Measured
#: non-rigid parts (:func:`nonrigid_part`) of the first three modes of sandwich-2d
#: (refine 1 and 2, top E = 1e3 Pa, nu = 0.4999999999, pairs tied or not, top body
#: unclamped with pairs tied): 0.03 to 0.96; a rigid motion found by shift-invert carries a
#: non-rigid part of order eps * cond(K), below 1e-6 for cond(K) < 1e10. The test is
#: kinematic, so it does not depend on E, nu or the units.
RIGID_TOL = 1e-4


@dataclass(frozen=True, eq=False)
class Modes:
    """Natural frequencies and mass-normalised shapes (stacked DOFs of all bodies).

    ``shapes[:, k]`` is mode k over the DOF vector of all bodies (``model.dof_offsets``);
    ``tied`` is the mask of tied pairs used; the first ``n_rigid`` modes are the rigid
    motions of an assembly that no clamp holds (frequency ~0), the elastic modes follow.
    """

    omega: np.ndarray
    shapes: np.ndarray
    tied: np.ndarray
    n_rigid: int = 0

    @property
    def f_hz(self):
        return self.omega / (2 * np.pi)


def stacked(matrices):
    """Block-diagonal sparse matrix of the bodies' matrices (stacked DOFs)."""
    return sp.block_diag(matrices, format="csr")


def tie_transform(model, assembled, pairing, tied) -> sp.csr_matrix:
    """``T`` with ``x_all = T x_reduced``: Dirichlet DOFs dropped, tied body-2 DOFs mapped
    onto their body-1 partners (node-to-node) or tied slave DOFs onto the projection of
    the master DOFs (mortar, :func:`_mpc_transform`); several interfaces:
    :func:`qsma.reduction.multibody.tie_transform`."""
    if isinstance(pairing, MultiPairing):
        return multibody.tie_transform(model, assembled, pairing, tied)
    if pairing.projection is not None:
        return _mpc_transform(model, assembled, pairing, tied)
    off = model.dof_offsets()
    dim = model.dim
    n = off[-1]
    target = np.arange(n)
    fixed = np.zeros(n, dtype=bool)
    for k, a in enumerate(assembled):
        fixed[off[k] + a.fixed] = True
    i1 = model.body_index(model.interface.body1)
    i2 = model.body_index(model.interface.body2)
    tied = np.asarray(tied, dtype=bool)
    for c in range(dim):
        s = off[i2] + dim * pairing.nodes2[tied] + c
        m = off[i1] + dim * pairing.nodes1[tied] + c
        target[s] = m
        fixed[s] |= fixed[m]
        fixed[m] |= fixed[s]
    keep = np.flatnonzero(~fixed & (target == np.arange(n)))
    col = np.full(n, -1)
    col[keep] = np.arange(len(keep))
    cols = col[target]
    rows = np.flatnonzero(cols >= 0)
    return sp.csr_matrix((np.ones(len(rows)), (rows, cols[rows])), shape=(n, len(keep)))


def _mpc_transform(model, assembled, pairing, tied):
    """``T`` for a mortar pairing: the rows of the tied slave DOFs (component c of slave
    node i) are ``sum_k P_ik e_(master k, c)``; the slave DOFs leave the unknowns, and so
    do the Dirichlet DOFs (a clamped master DOF contributes zero). The one-interface
    case of :func:`qsma.reduction.multibody.tie_transform`."""
    coupling = Coupling(pairing, *body_order(model, pairing))
    return multibody.tie_transform(model, assembled,
                                   MultiPairing((coupling,), (model.interface,)), tied)


def linear_modes(model, assembled, pairing, tied=None, n_modes=6, reduced=None,
                 springs=None) -> Modes:
    """First ``n_modes`` modes with the pairs in mask ``tied`` tied (default: all).

    Solves ``(T^T K T - w^2 T^T M T) phi_r = 0`` by shift-invert Lanczos about 0;
    shapes are mass-normalised (``phi^T M phi = 1``). An assembly that no clamp holds
    (free-free, :func:`qsma.reduction.rigid.assembly_free_motions` motions free) has its rigid
    modes first (``Modes.n_rigid``) and ``n_modes`` elastic modes follow them.

    ``reduced``: the condensed two-body model of the run (:mod:`qsma.reduction.two_bodies`, bolts
    locked or not). Where given and it covers the case (:func:`substructured_inverse`),
    ``(T^T K T)^-1`` is applied through its per-body ``K_EE`` factors and the dense
    interface matrices, and a free-free assembly's rigid motions are projected out of
    the operator (:class:`SubstructuredInverse`); otherwise, and without it, the tied
    stiffness is factorised (:func:`_factor`), a free-free one shifted to ``-s``
    (:data:`FREE_SHIFT_RTOL`). Both give the same modes to round-off.

    ``springs``, optional: (n_pairs, dim) stiffness of a compliant interface layer at
    each tied contact point, per component of its local frame
    (:func:`qsma.contact.layer.interface_springs`): ``inf`` ties the component, a finite
    value joins the two sides by a spring, 0 leaves it free. Contact points tied in every
    component are tied as without springs.
    """
    if tied is None:
        tied = np.ones(pairing.n_pairs, dtype=bool)
    tied = np.asarray(tied, dtype=bool)
    if tied.shape != (pairing.n_pairs,):
        raise InputError(f"tied mask must have {pairing.n_pairs} entries, got {tied.shape}")
    springs = _checked_springs(springs, pairing.n_pairs, model.dim)
    held = tied if springs is None else tied & np.all(np.isinf(springs), axis=1)
    T = tie_transform(model, assembled, pairing, held)
    n_free = assembly_free_motions(model, assembled)
    check_n_modes(n_modes, T.shape[1])
    M = (T.T @ stacked([a.M for a in assembled]) @ T).tocsc()
    inverse = None if reduced is None else substructured_inverse(
        model, assembled, pairing, tied, reduced, T, M, springs)
    if inverse is not None:
        return _substructured_modes(inverse, M, T, tied, n_modes, model, assembled)
    K = stacked([a.K for a in assembled])
    if getattr(model, "bolts", ()):
        K = K + bolt_stiffness(model)                  # the bolts locked after preload
    if springs is not None:
        K = K + _spring_stiffness(model, pairing, springs, held)
    K = (T.T @ K @ T).tocsc()
    k = min(n_modes + n_free, T.shape[1] - 2)
    shift = free_shift(K, M) if n_free else 0.0
    solve = _factor((K + shift * M).tocsc() if n_free else K, model, assembled, T)
    lam, vec = _lanczos(K, k, M, -shift, solve, solve)
    if n_free:
        _check_free_rigid(lam, model, assembled, T, vec, n_free)
    else:
        _check_rigid(lam, model, assembled, T, vec)
    vec /= np.sqrt(np.einsum("ik,ik->k", vec, M @ vec))
    omega = np.sqrt(np.maximum(lam, 0.0))
    omega[:n_free] = 0.0
    return Modes(omega, T @ vec, tied.copy(), n_free)


def _checked_springs(springs, n_pairs, dim):
    if springs is None:
        return None
    springs = np.asarray(springs, dtype=float)
    if springs.shape != (n_pairs, dim) or np.any(np.isnan(springs)) or np.any(springs < 0):
        raise InputError(f"interface springs must be {n_pairs} x {dim} stiffnesses >= 0 "
                         f"(inf: tied), got shape {springs.shape}")
    return springs


def _spring_stiffness(model, pairing, springs, held):
    """``G^T S G`` over the stacked DOFs: ``G`` the relative displacement of the contact
    points in their local frames, ``S`` the finite springs of the points not tied in
    every component. A point tied in some components only is refused here (the
    substructured solve, :func:`substructured_inverse`, takes it)."""
    partial = ~held & np.any(np.isinf(springs), axis=1)
    if partial.any():
        raise InputError(f"{int(partial.sum())} contact point(s) have an interface law "
                         f"that is rigid in some directions and compliant in others "
                         f"(e.g. hard normal contact with an elastic stick); the tied "
                         f"modes of such a law need a model of two bodies and one "
                         f"interface. Fix: give the law a compliance in every direction "
                         f"(a normal stiffness and a tangential one)")
    couplings = pairing.couplings if isinstance(pairing, MultiPairing) else \
        (Coupling(pairing, *body_order(model, pairing)),)
    nodes = [np.arange(b.mesh.n_nodes) for b in model.bodies]
    G, _ = relative_displacement_operator(couplings, nodes, model.dim)
    s = np.where(np.isinf(springs) | held[:, None], 0.0, springs).ravel()
    return (G.T @ sp.diags(s) @ G).tocsr()


def _lanczos(A, k, M, sigma, matvec, matmat):
    """The ``k`` eigenpairs of ``(A, M)`` nearest ``sigma`` by shift-invert Lanczos
    (ARPACK) with ``(A - sigma M)^-1`` applied by ``matvec`` / ``matmat``, in
    increasing order. ARPACK starts from a seeded random vector (:data:`EIG_SEED`):
    without ``v0`` it draws a new one at every call, and two runs of the same model in
    one process differed in the last digits of every result."""
    op = spla.LinearOperator(M.shape, matvec=matvec, matmat=matmat, dtype=float)
    v0 = np.random.default_rng(EIG_SEED).standard_normal(M.shape[0])
    try:
        lam, vec = spla.eigsh(A, k=k, M=M, sigma=sigma, which="LM", OPinv=op, v0=v0)
    except spla.ArpackNoConvergence as exc:
        raise AnalysisError(f"eigen solver did not converge ({len(exc.eigenvalues)} of {k} "
                            f"modes found)", partial=exc) from exc
    order = np.argsort(lam)
    return lam[order], vec[:, order]


#: Shift of the free-free eigenproblem, ``K + s M`` factorised with
#: ``s = FREE_SHIFT_RTOL * max(diag K / diag M)`` (the largest element frequency
#: squared): positive definite, with condition number ~ 1 / FREE_SHIFT_RTOL. Any
#: s > 0 keeps the order (rigid modes at distance s from -s, elastic ones beyond);
#: on lap-2d-free (refine 1) s = 3.5e-3 w_1^2.
FREE_SHIFT_RTOL = 1e-9


def free_shift(K, M) -> float:
    """The shift ``s`` of :data:`FREE_SHIFT_RTOL`."""
    dk, dm = K.diagonal(), M.diagonal()
    return FREE_SHIFT_RTOL * float(np.max(dk[dm > 0] / dm[dm > 0]))


def _check_free_rigid(lam, model, assembled, T, vec, n_free):
    """The first ``n_free`` modes of a free-free assembly must be rigid motions and the
    next one elastic; otherwise a body is not held by the joint (a mechanism)."""
    parts = [nonrigid_part(model, assembled, T @ vec[:, j]) for j in range(len(lam))]
    rigid = int(np.sum(np.array(parts) < RIGID_TOL))
    if rigid > n_free or not all(p < RIGID_TOL for p in parts[:n_free]):
        j = n_free if rigid > n_free else int(np.argmax(parts[:n_free]))
        full = T @ vec[:, j]
        off = model.dof_offsets()
        share = [np.linalg.norm(full[off[k]:off[k + 1]]) for k in range(len(assembled))]
        worst = assembled[int(np.argmax(share))].body.name
        raise InputError(rigid_modes_message(lam[j], rigid, n_free, worst))


def check_n_modes(n_modes, n_free=None):
    """Refuse a number of modes that is not a positive integer, exceeds
    :data:`MAX_MODES`, the ``n_free - 2`` that ARPACK can compute for ``n_free`` free
    DOFs, or whose Lanczos basis would not fit in memory."""
    if (not isinstance(n_modes, (int, np.integer)) or isinstance(n_modes, bool)
            or n_modes < 1):
        raise InputError(f"number of modes must be a positive integer, got {n_modes!r}")
    if n_modes > MAX_MODES:
        raise InputError(f"{n_modes} modes asked; at most {MAX_MODES} are computed (QSMA "
                         f"uses one mode; ask for mode + 1)")
    if n_free is None:
        return
    if n_modes > n_free - 2:
        raise InputError(f"{n_modes} modes asked, but the model has {n_free} free DOFs, "
                         f"of which at most {max(n_free - 2, 0)} modes can be computed")
    need = (2 * n_modes + 1) * n_free * 8
    free = free_memory()
    if free is not None and need > LANCZOS_MEMORY_SHARE * free:
        raise InputError(f"{n_modes} modes of {n_free} DOFs need {need / 2**30:.1f} GiB "
                         f"of Lanczos vectors, more than half the free memory "
                         f"({free / 2**30:.1f} GiB); ask for fewer modes")


def _factor(K, model, assembled, T):
    """Factorised tied stiffness (:func:`qsma.reduction.schur.spd_solver`: PARDISO if installed,
    else SuperLU on the METIS nested-dissection ordering, or on SuperLU's MMD where
    pymetis is missing)."""
    try:
        return spd_solver(K)
    except InputError as exc:
        raise InputError(
            f"the stiffness of the tied assembly is singular ({exc}): some body is not "
            f"held against rigid-body motion. Add Dirichlet conditions (clamps) to "
            f"{_unclamped(model, assembled)} or tie more interface pairs.") from exc


def _unclamped(model, assembled):
    names = [a.body.name for a in assembled if len(a.fixed) == 0]
    return f"body {names}" if names else "the bodies"


def _check_rigid(lam, model, assembled, T, vec):
    """Raise :class:`InputError` if the lowest mode is a rigid-body motion of the
    bodies (see :data:`RIGID_TOL`); ``lam`` is quoted in the message."""
    part = nonrigid_part(model, assembled, T @ vec[:, 0])
    if part < RIGID_TOL:
        full = T @ vec[:, 0]
        off = model.dof_offsets()
        share = [np.linalg.norm(full[off[k]:off[k + 1]]) for k in range(len(assembled))]
        worst = assembled[int(np.argmax(share))].body.name
        raise InputError(f"the tied assembly has a rigid-body mode (eigenvalue {lam[0]:.3e}, "
                         f"non-rigid part {part:.1e}, mostly in body {worst!r}): clamp that "
                         f"body or tie it to another.")


def nonrigid_part(model, assembled, u) -> float:
    """``|u - P u| / |u|`` with ``P u`` the best rigid motion of each body (least
    squares over the body's translations and rotations)."""
    off = model.dof_offsets()
    rest = 0.0
    for k, a in enumerate(assembled):
        uk = u[off[k]:off[k + 1]]
        R = rigid_body_modes(a.body.mesh.points)
        coef = np.linalg.lstsq(R, uk, rcond=None)[0]
        rest += float(np.sum((uk - R @ coef) ** 2))
    return np.sqrt(rest) / max(float(np.linalg.norm(u)), np.finfo(float).tiny)


def mode_tip(modes: Modes, model, k) -> float:
    """Tip probe value of mode ``k``."""
    return float(probe_vector(model) @ modes.shapes[:, k])


def probe_vector(model) -> np.ndarray:
    """Vector ``l`` over the stacked DOFs with ``l @ x`` the tip probe (mean displacement of
    the probe nodes along its direction)."""
    if model.tip is None:
        raise InputError("the model defines no tip probe")
    off = model.dof_offsets()
    dim = model.dim
    l = np.zeros(off[-1])
    direction = np.asarray(model.tip.direction, dtype=float)
    direction = direction / np.linalg.norm(direction)
    n = 0
    for bname, sname in model.tip.sets:
        k = model.body_index(bname)
        nodes = model.body(bname).mesh.nodes(sname)
        for c in range(dim):
            l[off[k] + dim * nodes + c] += direction[c]
        n += len(nodes)
    if n == 0:
        raise InputError(f"the tip probe sets {list(model.tip.sets)} hold no node: name "
                         f"sets with at least one node")
    return l / n


# ----------------------------------------------------------------------------------
# Shift-invert through the condensation's factors (one factorisation per body)

@dataclass(frozen=True, eq=False)
class SubstructuredInverse:
    r"""``x = (T^T K T)^{-1} b`` on the unknowns of :func:`tie_transform` without
    factorising the tied stiffness: the load ``f`` with ``f[rows] = b`` (elsewhere 0)
    satisfies ``T^T f = b`` (row ``rows[j]`` of ``T`` is ``e_j``), the static solve
    with the pairs tied is done by :class:`qsma.reduction.two_bodies.TiedSolver` (per-body
    ``K_EE`` factors, dense interface algebra) and ``x = u[rows]`` (``u = T x``).

    Locked bolts add ``B k B^T`` (``B = T^T c``, one column per bolt) to the tied
    stiffness; they enter by the Woodbury identity with ``Y = K_0^{-1} B``:

    .. math:: (K_0 + B k B^T)^{-1} b = x_0 - Y (k^{-1} + B^T Y)^{-1} B^T x_0,
              \qquad x_0 = K_0^{-1} b .

    A free-free assembly (rigid motions ``Z``, ``T^T K T Z = 0``) is solved on the
    M-orthogonal complement of ``Z``: ``Pi K^+ Pi^T`` with
    ``Pi = I - Z (Z^T M Z)^{-1} Z^T M``, so the load is self-equilibrated before the
    solve and the rigid part removed after it; the rigid modes are ``Z`` itself
    (eigenvalue 0) and the Lanczos iteration sees only the elastic ones.

    Attributes
    ----------
    solver : :class:`qsma.reduction.two_bodies.TiedSolver` of the closed pairs
    rows : per unknown, the row of ``T`` (stacked DOF) that is that unknown
    offsets, order : ``model.dof_offsets()`` and the model indices of the interface's
        body 1 and body 2
    Z, MZ, gram : free-free: rigid motions on the unknowns, ``M Z`` and ``Z^T M Z``
    B, Y, capacitance : bolts: ``T^T c`` per bolt, ``K_0^{-1} B`` and
        ``k^{-1} + B^T Y``
    """

    solver: object
    rows: np.ndarray
    offsets: np.ndarray
    order: tuple
    Z: np.ndarray | None = None
    MZ: np.ndarray | None = None
    gram: np.ndarray | None = None      # Z^T M Z
    B: np.ndarray | None = None
    Y: np.ndarray | None = None
    capacitance: np.ndarray | None = None

    def __call__(self, b):
        """``(T^T K T)^{-1} b`` for ``b`` of shape (n,) or (n, k) (all columns at once)."""
        b = np.asarray(b, dtype=float)
        if b.ndim == 2 and b.shape[1] == 0:
            return b.copy()
        x = self.unbolted(b)
        if self.B is not None:
            x = x - self.Y @ np.linalg.solve(self.capacitance, self.B.T @ x)
        return x

    def unbolted(self, b):
        """``K_0^{-1} b`` (``Pi K_0^+ Pi^T b`` for a free-free assembly)."""
        if self.Z is not None:
            b = b - self.MZ @ np.linalg.solve(self.gram, self.Z.T @ b)
        f = np.zeros((self.offsets[-1],) + b.shape[1:])
        f[self.rows] = b
        off, (i1, i2) = self.offsets, self.order
        u1, u2 = self.solver(f[off[i1]:off[i1 + 1]], f[off[i2]:off[i2 + 1]])
        u = np.zeros(f.shape)
        u[off[i1]:off[i1 + 1]] = u1
        u[off[i2]:off[i2 + 1]] = u2
        x = u[self.rows]
        if self.Z is not None:
            x = x - self.Z @ np.linalg.solve(self.gram, self.MZ.T @ x)
        return x


def substructured_inverse(model, assembled, pairing, tied, reduced, T, M, springs=None):
    """The :class:`SubstructuredInverse` of the tied assembly, or None where it does not
    apply: several interfaces (:mod:`qsma.reduction.multibody`), a ``T`` without an identity row
    per unknown, free-free rigid motions that ``T`` does not reproduce, or tied pairs
    that do not hold the bodies together (the full factorisation then reports it)."""
    if isinstance(pairing, MultiPairing):
        return None
    rows = identity_rows(T)
    solver = None if rows is None else tied_solver(reduced, tied, springs)
    if solver is None:
        return None
    inv = SubstructuredInverse(solver, rows, np.asarray(model.dof_offsets()),
                               tuple(body_order(model, pairing)))
    Z_full = assembly_motions(model, assembled)
    if Z_full.shape[1]:
        Z = Z_full[rows]
        if np.abs(T @ Z - Z_full).max() > RIGID_TOL * np.abs(Z_full).max():
            return None
        MZ = M @ Z
        inv = replace(inv, Z=Z, MZ=MZ, gram=Z.T @ MZ)
    if getattr(model, "bolts", ()):
        B = np.column_stack([T.T @ np.concatenate(bolt_vectors(model, b))
                             for b in model.bolts])
        Y = inv.unbolted(B)
        k = np.array([b.stiffness for b in model.bolts])
        inv = replace(inv, B=B, Y=Y, capacitance=np.diag(1 / k) + B.T @ Y)
    return inv


def identity_rows(T) -> np.ndarray | None:
    """Per column ``j`` of ``T``, a row equal to ``e_j`` (a DOF that is the unknown
    itself), or None if some column has none."""
    T = sp.csr_matrix(T)
    one = (np.diff(T.indptr) == 1)
    first = T.indptr[:-1]
    single = np.flatnonzero(one)
    single = single[T.data[first[single]] == 1.0]
    rows = np.full(T.shape[1], -1)
    cols = T.indices[first[single]]
    rows[cols[::-1]] = single[::-1]                 # the first such row per column
    return None if np.any(rows < 0) else rows


def _rigid_fields(model, assembled):
    """Translations then rotations of every body (each about its own centroid) over
    the stacked DOFs, one column per kind of motion: a smooth start block."""
    return np.vstack([rigid_body_modes(a.body.mesh.points) for a in assembled])


def _substructured_modes(inverse, M, T, tied, n_modes, model, assembled):
    """:func:`linear_modes` with :class:`SubstructuredInverse` (sigma = 0; the rigid
    modes of a free-free assembly are its motions ``Z``, M-orthonormalised)."""
    n = M.shape[0]
    n_free = 0 if inverse.Z is None else inverse.Z.shape[1]
    k = min(n_modes, n - 2 - n_free)
    start = None if n_free else _rigid_fields(model, assembled)[inverse.rows]
    lam, vec = block_shift_invert(inverse, M, k, inverse.Z, inverse.gram, start)
    _check_rigid(lam, model, assembled, T, vec)
    vec /= np.sqrt(np.einsum("ik,ik->k", vec, M @ vec))
    omega = np.sqrt(np.maximum(lam, 0.0))
    if n_free:
        L = np.linalg.cholesky(inverse.gram)
        rigid = np.linalg.solve(L, inverse.Z.T).T        # Z L^-T: M-orthonormal
        vec = np.column_stack([rigid, vec])
        omega = np.concatenate([np.zeros(n_free), omega])
    return Modes(omega, T @ vec, tied.copy(), n_free)


# ----------------------------------------------------------------------------------
# Block Krylov shift-invert (the inverse applied to blocks: one multi-RHS solve)

#: Converged when every wanted Ritz pair ``(mu, x)`` of ``S = K^-1 M`` (``x^T M x = 1``)
#: has ``||S x - mu x||_M <= EIG_RESIDUAL_RTOL * mu``. The eigenvalue error is then
#: below ``EIG_RESIDUAL_RTOL^2 / gap`` and the angle of the shape below
#: ``EIG_RESIDUAL_RTOL / gap`` (relative gap to the other eigenvalues of ``S``).
EIG_RESIDUAL_RTOL = 1e-11
#: Also converged when every relative residual is below this and the worst one fell by
#: less than half over the last block: the round-off floor of the solves (``eps``
#: times the condition number of ``K``) is reached. lap-2d with a bolt and the top
#: plate free stops at 1.7e-11.
EIG_RESIDUAL_FLOOR = 1e-8
#: Extra columns of the block beyond the wanted modes (they speed up the convergence
#: of the last wanted ones); blocks of 4-16 columns cost 1.6-5 single solves of a
#: SuperLU factor (docs/performance.md).
EIG_GUARD = 2
#: Most columns of a block (the inverse applied to that many vectors at once).
EIG_BLOCK = 6
#: Largest basis, in blocks, before a thick restart keeps the best Ritz vectors.
EIG_MAX_BLOCKS = 8
#: Restarts before the iteration gives up (AnalysisError).
EIG_MAX_RESTARTS = 30
#: Seed of the random start block (reproducible runs).
EIG_SEED = 20240611


def block_shift_invert(solve, M, k, Z=None, gram=None, start=None):
    r"""The ``k`` smallest eigenpairs of ``K x = lambda M x`` from ``solve(B) = K^{-1} B``
    applied to blocks of columns (block Lanczos with full reorthogonalisation and thick
    restarts).

    ``S = K^{-1} M`` is self-adjoint in the ``M`` inner product; its largest eigenvalues
    ``mu = 1 / lambda`` are wanted. The basis ``Q`` (``Q^T M Q = I``) grows by blocks
    of at most :data:`EIG_BLOCK` columns, ``S Q_j`` orthogonalised against ``Q``; the
    Rayleigh-Ritz step solves the small symmetric eigenproblem of
    ``H = Q^T M S Q = (M Q)^T W`` (``W = S Q`` kept: no further solve) and the residual
    of a Ritz pair ``(mu, x = Q y)`` is ``r = W y - mu x``. Converged when
    ``||r||_M <= EIG_RESIDUAL_RTOL mu`` for the ``k`` wanted pairs (the criterion of
    ARPACK with a tolerance instead of machine epsilon), or when they stagnate below
    :data:`EIG_RESIDUAL_FLOOR` (round-off of the solves). A basis of
    :data:`EIG_MAX_BLOCKS` blocks is restarted from the best ``k +`` :data:`EIG_GUARD`
    Ritz vectors, the next block being the Krylov continuation (:meth:`_Basis.restarted`).

    ``Z``, ``gram``: rigid motions of a free-free assembly (``solve`` already returns the
    part M-orthogonal to them) and ``Z^T M Z``; the start block is made M-orthogonal to
    them as well. ``start``: smooth columns for the first block (at most ``b``); each
    gets a seeded random part of its own norm (:data:`EIG_SEED`) and the block is
    completed by random columns. Rigid-body fields as start make the first block
    close to the static deflections under uniform accelerations, close to the low
    modes (load-dependent Ritz vectors). The random part is not optional: a start
    made of the rigid fields alone has no component in the modes of some symmetry
    classes of a symmetric structure, which a Krylov space built from it never
    reaches, and the iteration would converge to the wrong "lowest" modes
    (tests/test_modal.py, the symmetric clamped box).

    Returns ``(lam, vec)``, ``lam`` increasing, ``vec`` M-orthonormal. Raises
    :class:`AnalysisError` if the iteration does not converge.
    """
    n = M.shape[0]
    b = min(EIG_BLOCK, k + EIG_GUARD, n - k)
    want = min(k + EIG_GUARD, n - 1)           # basis size before convergence is judged
    rng = np.random.default_rng(EIG_SEED)
    V = rng.standard_normal((n, b))
    if start is not None:                   # smooth start plus an equal random part:
        S = np.asarray(start, dtype=float)[:, :b]   # every column reaches every mode
        scale = np.linalg.norm(V[:, :S.shape[1]], axis=0) / np.maximum(
            np.linalg.norm(S, axis=0), np.finfo(float).tiny)
        V[:, :S.shape[1]] += S * scale
    MZ = None if Z is None else M @ Z

    def off_motions(V):                       # the part of V M-orthogonal to Z
        return V if Z is None else V - Z @ np.linalg.solve(gram, MZ.T @ V)

    V = off_motions(V)
    basis, worst = _Basis.empty(n, want + EIG_MAX_BLOCKS * b), np.inf
    for _ in range(EIG_MAX_RESTARTS):
        for _ in range(EIG_MAX_BLOCKS):
            V, MV = _m_orthonormal(V, basis, M)
            if V.shape[1] == 0 and basis.size >= want:    # invariant subspace (the
                mu, Y, _ = basis.ritz(want)               # whole space when n is small):
                return 1.0 / mu[:k], basis.Q @ Y[:, :k]   # the Ritz pairs are exact
            if V.shape[1] == 0:              # start in the span of Z: random directions
                V = off_motions(rng.standard_normal((n, b)))
                continue
            W = solve(MV)
            basis = basis.extended(V, MV, W, M @ W)
            if basis.size < want:
                V = W
                continue
            mu, Y, res = basis.ritz(want)
            worst, previous = float(np.max(res[:k] / mu[:k])), worst
            if (worst <= EIG_RESIDUAL_RTOL
                    or worst <= EIG_RESIDUAL_FLOOR and worst > 0.5 * previous):
                return 1.0 / mu[:k], basis.Q @ Y[:, :k]
            V = W
        mu, Y, res = basis.ritz(want)
        basis, V = basis.restarted(Y[:, :min(want, basis.size)], V)
    raise AnalysisError(f"tied modes: the block shift-invert iteration did not converge "
                        f"in {EIG_MAX_RESTARTS} restarts (relative residuals up to "
                        f"{worst:.2e} > {EIG_RESIDUAL_RTOL})")


@dataclass(frozen=True)
class _Basis:
    """M-orthonormal basis ``Q`` of :func:`block_shift_invert` with ``M Q``, ``W = S Q``
    and ``M W`` (each sparse product done once per column).

    The four are the first ``size`` columns of preallocated column-major arrays
    (``arrays``, shared by the bases that :meth:`extended` and :meth:`restarted`
    return: the previous basis is not used again). A new block is written in place
    instead of copying the whole basis (``np.hstack`` held the old and the new basis
    at once: ~0.5 GB more at 222k unknowns)."""

    arrays: tuple
    size: int

    @classmethod
    def empty(cls, n, capacity):
        return cls(tuple(np.zeros((n, capacity), order="F") for _ in range(4)), 0)

    @property
    def Q(self):
        return self.arrays[0][:, :self.size]

    @property
    def MQ(self):
        return self.arrays[1][:, :self.size]

    @property
    def W(self):
        return self.arrays[2][:, :self.size]

    @property
    def MW(self):
        return self.arrays[3][:, :self.size]

    def extended(self, V, MV, W, MW):
        k, m = self.size, V.shape[1]
        arrays = self.arrays
        if k + m > arrays[0].shape[1]:             # not expected: grow
            grown = tuple(np.zeros((a.shape[0], k + m), order="F") for a in arrays)
            for g, a in zip(grown, arrays):
                g[:, :k] = a[:, :k]
            arrays = grown
        for a, new in zip(arrays, (V, MV, W, MW)):
            a[:, k:k + m] = new
        return _Basis(arrays, k + m)

    def ritz(self, wanted):
        """Ritz values ``mu`` (decreasing), coefficients ``Y`` and the residual norms
        ``||W y - mu Q y||_M`` of the first ``wanted`` pairs."""
        H = self.MQ.T @ self.W
        mu, Y = np.linalg.eigh(0.5 * (H + H.T))
        mu, Y = mu[::-1], Y[:, ::-1]
        return mu, Y, self.residuals(Y[:, :wanted], mu[:wanted])

    def residuals(self, Y, mu):
        """``||W y - mu Q y||_M`` per column of ``Y``."""
        R, MR = self.W @ Y - (self.Q @ Y) * mu, self.MW @ Y - (self.MQ @ Y) * mu
        return np.sqrt(np.abs(np.einsum("ik,ik->k", R, MR)))

    def restarted(self, Y, W_last):
        """The basis of the Ritz vectors ``Q Y`` and the next block: the last block's
        ``S Q_j`` without its part in ``Q``, which spans the residuals of all the Ritz
        pairs (thick restart: the Krylov recurrence goes on from there)."""
        nxt = W_last - self.Q @ (self.MQ.T @ W_last)
        j = Y.shape[1]
        for a in self.arrays:                      # a[:, :j] = a[:, :size] Y, one at
            a[:, :j] = a[:, :self.size] @ Y        # a time (one n x j temporary)
        return _Basis(self.arrays, j), nxt


def _m_orthonormal(V, basis, M):
    """``(V', M V')``: the columns of ``V`` minus their M-projection on the basis,
    M-orthonormalised by the eigenvectors of their Gram matrix; two passes (round-off).
    Directions whose norm fell below ``1e-12`` of the largest column of ``V``
    (numerically in the span of the basis or of the other columns) are dropped."""
    MV = M @ V
    scale = float(np.max(np.einsum("ik,ik->k", V, MV), initial=0.0))
    for _ in range(2):
        V = V - basis.Q @ (basis.MQ.T @ V)
        MV = M @ V
        G = V.T @ MV
        w, U = np.linalg.eigh(0.5 * (G + G.T))
        keep = w > 1e-24 * scale
        U = U[:, keep] / np.sqrt(w[keep])
        V, MV = V @ U, MV @ U
        scale = 1.0
    return V, MV
