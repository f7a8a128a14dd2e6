r"""Interface nodes that a clamp holds (docs/theory.md, "Clamped interface nodes").

A clamp on the contact face (a symmetry plane cutting it, a support) prescribes part of
the relative displacement ``d`` of a contact point. The bodies are condensed onto their
unclamped interface DOFs only, and ``d = G u`` is written over those unknowns
(:func:`qsma.reduction.multibody.reduce_bodies`). Per component of a contact point:

- free on both sides: as without clamps (the slave DOF is eliminated by ``d``);
- clamped on one side: the other body's displacement is the relative one (the pivot
  eliminated by ``d`` is that body's DOF, :func:`pivot_dofs`);
- clamped on both sides: ``d = 0`` and the force is the clamps' reaction, so the
  contact law acts only in the other directions. Such a component is kept in the
  contact problem (one block of ``dim`` per contact point) with a stiffness of its own
  and no load, ``lam_k = c d_k`` (:func:`decoupled`), whose one solution under any law
  is ``d_k = lam_k = 0``: a tangential one carries no friction, a normal one is
  refused (the contact pressure there would be a share of the clamps' reaction that
  nothing determines, and the friction limit of the free tangential components with
  it) unless every component of the point is fixed on both sides: such a point can
  neither open nor slip, whatever its pressure, so it is inert and kept with
  ``d = lam = 0`` (the clamped ends of two parts whose whole overlap is the
  interface, as the faces found where bodies touch are).

Node-to-node, both sides means the two nodes of the pair. Mortar, the slave node and
the master surface at its place: the slave node lies on a plane normal to the clamped
direction on which the master's nodes near it are clamped in that direction (a
symmetry plane through both bodies), :func:`symmetry_components`. The master's
displacement in that direction is odd about the plane in the whole structure, so its
mortar average at the slave node vanishes there; in the cut model it would not (the
mirror half is missing), hence the component is fixed rather than left to the master.
"""
from __future__ import annotations

import numpy as np
import scipy.linalg as sla
import scipy.sparse as sp

from ..errors import InputError
from ..model.interface import symmetry_axes

#: Relative size below which a row of the relative-displacement operator over the
#: bodies' unknowns counts as zero (its component clamped on both sides).
FIXED_RTOL = 1e-12
#: Relative size below which a pivot of the rows the slave DOFs leave over counts as
#: zero: those rows are then dependent.
DEPENDENT_RTOL = 1e-10
#: Relative size below which a pivot of homogeneous constraints counts as zero (the
#: constraint repeats others).
CONSTRAINT_RTOL = 1e-10
#: Smallest |cosine| between a clamped axis and a local axis of the contact frame for
#: the two to count as the same direction.
AXIS_COS = 1.0 - 1e-9


def clamped_interface(assembled, nodes) -> bool:
    """Whether a clamp holds some component of one of the interface ``nodes``."""
    dim = assembled.body.dim
    dofs = (dim * np.asarray(nodes)[:, None] + np.arange(dim)).ravel()
    return bool(np.isin(dofs, assembled.fixed).any())


def check_prescribed(assembled, nodes):
    """Refuse a clamp with a displacement other than zero on an interface node: the
    relative displacement would then carry a prescribed part that the contact problem,
    written over the unclamped DOFs, does not see."""
    dim = assembled.body.dim
    dofs = (dim * np.asarray(nodes)[:, None] + np.arange(dim)).ravel()
    for name, u in (getattr(assembled, "prescribed", None) or {}).items():
        moved = dofs[np.asarray(u)[dofs] != 0.0]
        if len(moved):
            raise InputError(
                f"body {assembled.body.name!r}: interface node(s) "
                f"{np.unique(moved // dim)[:10].tolist()} have a prescribed displacement "
                f"other than zero ({name!r}); qsma holds clamped interface nodes at zero "
                f"only (the relative displacement there would carry the prescribed part). "
                f"Fix: prescribe the displacement on nodes off the contact face, or leave "
                f"these nodes out of the interface set")


def symmetry_components(pairing, slave, master) -> np.ndarray:
    """(n_pairs, dim) mask, in global components, of the mortar contact points clamped
    on both sides (module docstring; :func:`qsma.model.interface.symmetry_axes` on the
    rows of the projection). ``slave``, ``master``: the assembled bodies. Node-to-node
    pairings give all False (their zero rows say it already)."""
    if pairing.projection is None:
        return np.zeros((pairing.n_pairs, pairing.frames.shape[1]), dtype=bool)
    return symmetry_axes(slave.body, pairing.contact_nodes, master.body,
                         pairing.master_nodes, pairing.projection)


def local_rows(frames, components) -> np.ndarray:
    """Flat indices (contact-point-major) of the local components that are the global
    ``components`` (mask (n, dim)) up to sign; a clamped axis oblique to the frame has
    none (the caller's operator then shows what it holds)."""
    dim = frames.shape[1]
    rows = []
    for i, c in zip(*np.nonzero(components)):
        k = np.flatnonzero(np.abs(frames[i][:, c]) >= AXIS_COS)
        rows.extend(dim * i + k)
    return np.asarray(rows, dtype=np.int64)


def pivot_dofs(G, slave, dim):
    r"""``(fixed, pivots)``: the contact components that the clamps fix on both sides
    (zero rows of ``G``, the relative-displacement operator over the bodies'
    unknowns), and the unknowns that the other components determine (``G``
    restricted to those rows and these columns is square and regular), the unclamped
    slave DOFs ``slave`` first.

    Without clamps on the interface the pivots are the slave DOFs. Where a slave
    component is clamped, the master's displacement is the relative one: its pivot is
    a master DOF, chosen by a column-pivoted QR of what the slave columns cannot reach
    (the rows projected onto the orthogonal complement of the slave columns). A normal
    component fixed on both sides, and rows that stay dependent, are refused
    (:func:`fixed_normal`, :func:`dependent`)."""
    G = sp.csr_matrix(G)
    norms = np.asarray(abs(G).max(axis=1).todense()).ravel() if G.nnz \
        else np.zeros(G.shape[0])
    scale = max(norms.max(initial=0.0), np.finfo(float).tiny)
    fixed = np.flatnonzero(norms <= FIXED_RTOL * scale)
    points, count = np.unique(fixed // dim, return_counts=True)
    held = points[count == dim]             # every component fixed: inert (docstring)
    normal = fixed[(fixed % dim == dim - 1) & ~np.isin(fixed // dim, held)]
    if len(normal):
        raise fixed_normal(normal // dim)
    rows = np.setdiff1d(np.arange(G.shape[0]), fixed)
    if len(slave) == len(rows):
        return fixed, slave
    A = G[rows].toarray()
    rest = np.setdiff1d(np.arange(A.shape[1]), slave)
    Q = sla.qr(A[:, slave], mode="full")[0][:, len(slave):]
    left = Q.T @ A[:, rest]                           # what the slave DOFs cannot reach
    if left.shape[0] > left.shape[1]:
        raise dependent(_dependent_points(Q, left, rows, dim))
    _, R2, perm = sla.qr(left, mode="economic", pivoting=True)
    r = np.abs(np.diag(R2))[:left.shape[0]]
    if r.size and r.min() <= DEPENDENT_RTOL * scale:
        raise dependent(_dependent_points(Q, left, rows, dim))
    return fixed, np.concatenate([slave, rest[perm[:left.shape[0]]]])


def _dependent_points(Q, left, rows, dim):
    """Contact points of the ``rows`` in the combination ``Q y`` that ``left = Q^T A``
    reaches least (``y`` its last left singular vector)."""
    y = Q @ np.linalg.svd(left, full_matrices=True)[0][:, -1]
    return np.unique(rows[np.abs(y) > 1e-6 * np.abs(y).max()] // dim)


def fixed_normal(points) -> InputError:
    """The error of contact points whose normal the clamps hold on both sides."""
    return InputError(
        f"contact point(s) {points[:10].tolist()} (contact-point order) are clamped along "
        f"the contact normal on both sides: such a pair can neither open nor close, and "
        f"its contact pressure is part of the clamps' reaction, which nothing splits "
        f"from them (any pressure balances), so the friction limit mu p there is "
        f"undefined. Fix: release the normal clamp of one side at these nodes (the "
        f"contact then holds that body against the clamped one), or leave the nodes out "
        f"of the interface set")


def dependent(points) -> InputError:
    """The error of relative displacements that the clamps tie together."""
    return InputError(
        f"the clamps hold a combination of the relative displacements of contact points "
        f"{points[:10].tolist()} (contact-point order) rather than single components: "
        f"a clamped direction neither along the contact normal nor in its tangent plane, "
        f"or a clamped slave surface whose master surface cannot follow every slave "
        f"node (the master's nodes do not determine its displacement at each slave "
        f"node). The contact law acts on each contact point's own components and cannot "
        f"act on such a combination. Fix: make the clamped side the master "
        f"(Interface(slave=...), or the deck's *CONTACT PAIR order), clamp interface "
        f"nodes only along the normal or in the contact plane, or leave them out of the "
        f"interface set")


def decoupled(K, fixed):
    """``K`` with a stiffness of its own at each fixed component (module docstring):
    ``lam_k = c d_k`` with ``W`` zero there, ``c`` the mean of the other diagonal
    entries (the problem's own scale)."""
    if not len(fixed):
        return K
    diag = np.delete(np.diag(K), fixed)
    K = K.copy()
    K[fixed, :] = 0.0
    K[:, fixed] = 0.0
    K[fixed, fixed] = float(np.mean(diag)) if diag.size else 1.0
    return K


def constrained_basis(A) -> sp.csr_matrix:
    r"""Sparse ``Y`` whose columns span the null space of the sparse homogeneous
    constraints ``A y = 0`` (a repeated constraint counts once): a column-pivoted QR
    of the columns ``A`` touches, ``A_J P = Q R``, gives the rank ``r``, the pivots
    ``p`` (the first ``r`` columns of ``J P``) and
    ``y_p = -R_{11}^{-1} R_{12} y_{J \setminus p}``; every other ``y`` stays free."""
    A = sp.csr_matrix(A)
    A.eliminate_zeros()
    n = A.shape[1]
    J = np.unique(A.indices)
    if not len(J):
        return sp.identity(n, format="csr")
    _, R, perm = sla.qr(A[:, J].toarray(), mode="economic", pivoting=True)
    d = np.abs(np.diag(R))
    rank = int(np.sum(d > CONSTRAINT_RTOL * d.max())) if d.size else 0
    piv, other = J[perm[:rank]], J[perm[rank:]]
    free = np.setdiff1d(np.arange(n), piv)
    col = np.searchsorted(free, other)
    X = -sla.solve_triangular(R[:rank, :rank], R[:rank, rank:])     # (rank, |other|)
    rows = np.concatenate([free, np.repeat(piv, len(other))])
    cols = np.concatenate([np.arange(len(free)), np.tile(col, rank)])
    vals = np.concatenate([np.ones(len(free)), X.ravel()])
    return sp.coo_matrix((vals, (rows, cols)), shape=(n, len(free))).tocsr()
