"""The tied assembly: the transform that ties the chosen interface pairs, the record of
its modes, the checks of rigid motions, the factorised (Lanczos) eigen solve and the
probe.

Tied pairs share their DOFs (elimination, not penalty): the DOFs of the body-2
node of a tied pair are replaced by those of its body-1 partner. With a mortar
coupling a tied contact point is a multipoint constraint: the slave node's DOFs are
eliminated, ``u_slave = sum_k P_ik u_master_k`` per component.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from .._infra.resources import free_memory
from ..errors import AnalysisError, InputError
from ..fe.formulation import hourglass_hint
from ..model.pairing import Coupling, MultiPairing, body_order
from ..reduction import multibody
from ..reduction.multibody import relative_displacement_operator
from ..reduction.rigid import rigid_body_modes, rigid_modes_message
from ..reduction.schur import spd_solver
from .eigen import EIG_SEED

#: Most modes one eigen solve may ask for. ARPACK keeps 2k+1 Lanczos vectors and
#: orthogonalises against them; measured on sandwich-2d (4500 DOFs, 2-core machine,
#: `linear_modes(..., n_modes=k)`): k = 100 in 1.8 s, 200 in 3.1 s, 800 in 28 s, and
#: k = 100000 more than 300 s. QSMA needs mode + 1 modes.
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
    every component (a component tied at a point tied in some components only is
    :func:`partly_tied`'s)."""
    G = _relative_operator(model, pairing)
    s = np.where(np.isinf(springs) | held[:, None], 0.0, springs).ravel()
    return (G.T @ sp.diags(s) @ G).tocsr()


def partly_tied(T, model, pairing, springs, held):
    """``T`` restricted to the motions that keep the tied components of the points tied
    in some components only (an infinite spring beside finite ones: hard normal
    contact with an elastic stick): their relative displacement in the local frame,
    ``G_k T x = 0``, is eliminated by a pivoted QR
    (:func:`qsma.reduction.multibody.constrained_basis`)."""
    partial = ~held[:, None] & np.isinf(springs) & ~np.all(np.isinf(springs), axis=1)[:, None]
    if not partial.any():
        return T
    A = _relative_operator(model, pairing)[np.flatnonzero(partial.ravel())] @ T
    return (T @ multibody.constrained_basis(A)).tocsr()


def _relative_operator(model, pairing):
    """The relative displacement of every contact point in its local frame over the
    stacked DOFs of the model (rows contact-point-major)."""
    couplings = pairing.couplings if isinstance(pairing, MultiPairing) else \
        (Coupling(pairing, *body_order(model, pairing)),)
    nodes = [np.arange(b.mesh.n_nodes) for b in model.bodies]
    G, _ = relative_displacement_operator(couplings, nodes, model.dim)
    return G


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
            f"{_unclamped(model, assembled)} or tie more interface pairs."
            + hourglass_hint(assembled)) from exc


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
