"""Shift-invert through the condensation's factors (one factorisation per body): the
inverse of the tied stiffness applied by the condensed bodies (:class:`SubstructuredInverse`)
and the modes it gives."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from ..fe.bolts import bolt_vectors, locked_bolts
from ..model.pairing import MultiPairing, body_order
from ..reduction.rigid import assembly_motions, rigid_body_modes
from ..reduction.two_bodies import tied_solver
from .eigen import ShiftInvert
from .tied import RIGID_TOL, Modes, _check_rigid

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
        k = np.array([b.stiffness for b in locked_bolts(model)])
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
    lam, vec = substructured_iteration(inverse, M, n_modes, model, assembled).finish()
    return substructured_modes(lam, vec, inverse, M, T, tied, model, assembled)


def substructured_iteration(inverse, M, n_modes, model, assembled) -> ShiftInvert:
    """The shift-invert iteration of the elastic modes through ``inverse``, not yet run
    (:class:`qsma.modal.eigen.ShiftInvert`)."""
    n = M.shape[0]
    n_free = 0 if inverse.Z is None else inverse.Z.shape[1]
    k = min(n_modes, n - 2 - n_free)
    start = None if n_free else _rigid_fields(model, assembled)[inverse.rows]
    return ShiftInvert(inverse, M, k, inverse.Z, inverse.gram, start)


def substructured_modes(lam, vec, inverse, M, T, tied, model, assembled) -> Modes:
    """:class:`Modes` of the eigenpairs ``(lam, vec)`` of the iteration (the rigid
    motions of a free-free assembly first), checked not to be rigid-body motions."""
    n_free = 0 if inverse.Z is None else inverse.Z.shape[1]
    _check_rigid(lam, model, assembled, T, vec)
    vec = vec / np.sqrt(np.einsum("ik,ik->k", vec, M @ vec))
    omega = np.sqrt(np.maximum(lam, 0.0))
    if n_free:
        L = np.linalg.cholesky(inverse.gram)
        rigid = np.linalg.solve(L, inverse.Z.T).T        # Z L^-T: M-orthonormal
        vec = np.column_stack([rigid, vec])
        omega = np.concatenate([np.zeros(n_free), omega])
    return Modes(omega, T @ vec, tied.copy(), n_free)
