r"""Rigid-body freedom: bodies held only through the joint, free-free assemblies
(docs/theory.md section 10).

A body whose clamps leave rigid motions free is held, if at all, by the joint. Its
condensed stiffness ``Kc_j`` is then singular along those motions (basis ``B_j`` on
its interface DOFs, :func:`interface_basis`), and so is the interface stiffness
``K = (Kc_1^-1 + Kc_2^-1)^-1`` along their images ``N`` in the relative displacement
``d``; if no clamp holds the assembly, the welded pair's ``S`` is singular along the
assembly's rigid motions ``Z``. qsma uses

.. math:: S_{reg} = S + c Z Z^T, \qquad K_{reg} = K + k N N^T,
          \quad k = \text{SUPPORT_RTOL} \cdot \overline{\operatorname{diag} K} .

The first only fixes the gauge (exact for self-equilibrated loads, which a free-free
structure must have, :func:`assembly_gauge` checks); the second is a soft spring
between the bodies, in parallel with the joint, whose share of the load
(:func:`support_share`) is checked at every solve (:func:`held_by_joint`): above
:data:`SHARE_MAX` the joint no longer holds the body (gross slip).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from ..contact.state import Outcome
from ..errors import InputError
from ..model.spring import held_dofs

#: Stiffness of the spring between the bodies along their relative rigid motions,
#: relative to the mean diagonal of ``K``. On the cantilever lap-2d (top plate held
#: only by the joint, mu = 0.1) the results deviate from the limit k -> 0 by 0.8 k in
#: frequency and 0.08 k in zeta, and a held body's spring share is ~2 k
#: (tests/test_freefree.py::test_cantilever_support_limit); 1e-8 keeps that far below
#: the 1e-6 to which stuck levels are checked while ``K`` stays factorisable.
SUPPORT_RTOL = 1e-8
#: Largest share of the floating bodies' load resultant the spring may carry in a
#: reported state. A body held by the joint gives shares ~2 SUPPORT_RTOL; one that
#: slides or lifts off as a whole is held only by the spring (share 0.52 measured at
#: the gross slip of the cantilever lap-2d with mu = 0.02).
SHARE_MAX = 1e-4


def rigid_body_modes(points: np.ndarray) -> np.ndarray:
    """Infinitesimal rigid-body motions (translations, rotations) as columns over the
    node-major DOFs: 3 in 2D, 6 in 3D."""
    n, dim = points.shape
    x = points - points.mean(axis=0)
    if dim == 2:
        rot = np.stack([-x[:, 1], x[:, 0]], axis=1)[:, :, None]
    else:
        e = np.eye(3)
        rot = np.stack([np.cross(e[k], x) for k in range(3)], axis=2)
    trans = np.broadcast_to(np.eye(dim), (n, dim, dim))
    return np.concatenate([trans, rot], axis=2).reshape(n * dim, -1)


#: Relative size below which a clamp does not hold a rigid-body motion: sqrt(eps).
#: Clamps spread over a length d of a body of size L resist its rotation with a
#: stiffness of relative size (d / L)^2, which is lost in round-off once it falls
#: below eps = 2.2e-16, i.e. d / L < 1.5e-8.
CLAMP_RANK_TOL = float(np.sqrt(np.finfo(float).eps))


_NAMES = {2: ("translation x", "translation y", "rotation z"),
          3: ("translation x", "translation y", "translation z", "rotation x",
              "rotation y", "rotation z")}


def free_motions(points: np.ndarray, fixed: np.ndarray, openings=None) -> np.ndarray:
    """Rigid motions of the node cloud ``points`` that the clamped DOFs ``fixed``
    leave free: ``(n_nodes * dim, r)`` columns, ``r = 0`` for a held body.
    ``openings``: motions of a body cut by pretension sections beside its rigid ones
    (columns, :attr:`qsma.fe.sections.SectionTerms.opening`).

    The rotations are scaled by the size of the cloud (motions of size 1), so the
    rank test (:data:`CLAMP_RANK_TOL`) is independent of the units.
    """
    modes = _scaled_modes(points)
    if openings is not None:
        modes = np.column_stack([modes, openings])
    at = modes[np.asarray(fixed, dtype=int)]
    if len(at) == 0:
        return modes
    _, s, vt = np.linalg.svd(at)
    rank = int(np.sum(s > CLAMP_RANK_TOL * max(s.max(initial=0.0), 1.0)))
    return modes @ vt[rank:].T


def held(assembled) -> np.ndarray:
    """DOFs of an assembled body that hold it against rigid motion: the clamped ones
    and those on a grounded spring of nonzero stiffness (:mod:`qsma.model.spring`)."""
    return np.union1d(assembled.fixed, held_dofs(assembled.body)).astype(np.int64)


def describe(motion: np.ndarray, dim: int) -> str:
    """A rigid motion's coefficients in words ("+1.00 rotation z")."""
    return ", ".join(f"{c:+.2f} {n}" for c, n in zip(motion, _NAMES[dim]) if abs(c) > 1e-6)


def assembly_free_motions(model, assembled) -> int:
    """Number of rigid motions of the whole (welded) assembly left free by the union of
    all clamps: 0 for a structure clamped somewhere, 3 (2D) or 6 (3D) free-free."""
    return assembly_motions(model, assembled).shape[1]


def assembly_motions(model, assembled) -> np.ndarray:
    """The rigid motions of the whole (welded) assembly left free by the union of all
    clamps (:func:`free_motions` over the stacked DOFs of ``model.dof_offsets()``):
    ``(n_dofs, r)``, ``r = 0`` for a structure clamped somewhere."""
    off = model.dof_offsets()
    points = np.vstack([b.mesh.points for b in model.bodies])
    fixed = np.concatenate([off[k] + held(a) for k, a in enumerate(assembled)]) \
        if assembled else np.zeros(0, int)
    return free_motions(points, fixed)


def interface_basis(assembled, C: np.ndarray, to_local) -> np.ndarray | None:
    """Orthonormal basis ``B_j`` of the body's free rigid motions on its interface DOFs
    (local frames: ``u_local = to_local @ u_C``, ``R^T`` of a rotation ``u_C = R
    u_local``), or None for a body its clamps hold.

    Raises :class:`InputError` naming the body if a free motion does not move the
    interface (then nothing can hold it: its ``K_EE`` would be singular)."""
    body = assembled.body
    free = free_motions(body.mesh.points, held(assembled),
                        getattr(assembled, "openings", None))
    if free.shape[1] == 0:
        return None
    B, r = np.linalg.qr(np.asarray(to_local @ free[C]))
    if np.min(np.abs(np.diag(r))) < CLAMP_RANK_TOL * np.abs(np.diag(r)).max():
        raise InputError(f"body {body.name!r} is held neither by its clamps nor by its "
                         f"interface nodes (free motion: "
                         f"{describe(_weakest(free, C, body.mesh.points), body.dim)}); "
                         f"add a clamp or extend the interface set")
    return B


def orthonormal(columns: list) -> np.ndarray | None:
    """An orthonormal basis of the span of the given column blocks (rank by
    :data:`CLAMP_RANK_TOL`), or None if there are none."""
    cols = [c for c in columns if c is not None and c.shape[1]]
    if not cols:
        return None
    U, s, _ = np.linalg.svd(np.hstack(cols), full_matrices=False)
    return U[:, s > CLAMP_RANK_TOL * s.max()]


#: Largest net load resultant of a free-free assembly relative to the largest
#: resultant on one body (round-off of a balanced pair of bolt loads is ~1e-15).
EQUILIBRIUM_RTOL = 1e-8


def assembly_gauge(assembled, bodies, index, loads=None) -> np.ndarray | None:
    """Rigid motions of the whole assembly left free by every clamp, on the interface
    DOFs of ``bodies[index]`` (the unknowns of the welded pair's ``S``), orthonormal;
    None for an assembly held by a clamp. ``loads``: per body, full load patterns
    (columns), which must then be self-equilibrated (else :class:`InputError`)."""
    points = np.vstack([a.body.mesh.points for a in assembled])
    starts = np.cumsum([0] + [a.n_dofs for a in assembled])
    fixed = np.concatenate([s + held(a) for s, a in zip(starts, assembled)])
    free = free_motions(points, fixed)
    if free.shape[1] == 0:
        return None
    if loads is not None:
        parts = [free[s:e].T @ L for s, e, L in zip(starts[:-1], starts[1:], loads)]
        net = np.abs(sum(parts)).max(initial=0.0)
        scale = max(np.abs(p).max(initial=0.0) for p in parts)
        if net > EQUILIBRIUM_RTOL * max(scale, np.finfo(float).tiny) and net > 0:
            raise InputError(
                f"the assembly has no clamp (free-free) but its loads are not "
                f"self-equilibrated (net resultant {net:.3e} against {scale:.3e} on one "
                f"body): it would accelerate as a rigid body. Load it with balanced pairs "
                f"(bolts, equal pressures on both bodies) or clamp it")
    b = bodies[index]
    return orthonormal([np.asarray(b.to_local @ free[starts[index]:starts[index + 1]][b.C])])


def regularised_S(S, Z):
    r"""``S + c Z Z^T``, ``c`` the mean diagonal of ``S``: with ``Z`` the null space of
    ``S`` (rigid motions of a free-free assembly) this fixes their gauge
    (``Z^T u = 0``) and leaves every solve with a self-equilibrated right-hand side
    (``Z^T f = 0``) exact."""
    if Z is None:
        return S
    return S + float(np.mean(np.diag(S))) * (Z @ Z.T)


@dataclass(frozen=True, eq=False)
class Ghost:
    r"""The soft spring between the bodies along the null space of the relative
    stiffness (relative rigid motions of a body held only by the joint).

    ``K_reg = K + k N N^T``; the spring force ``g = k N N^T (d - d_anchor)`` is carried
    in the contact force ``lam`` in place of the joint; :meth:`share` measures it.
    :func:`anchored` moves the anchor (the spring's rest position) to a solved state.

    Attributes
    ----------
    N : (n, r) orthonormal, contact-point-major local frames
    k : spring stiffness, ``SUPPORT_RTOL`` times the mean diagonal of ``K``
    """

    N: np.ndarray
    k: float
    anchor: np.ndarray | None = None

    def share(self, d, lam_w, lam_w_ref) -> float:
        r"""``|k N^T (d - d_anchor)| / max(|N^T lam_w|, |N^T lam_w_ref|)``: the share of
        the floating bodies' load resultant held by the spring instead of the joint."""
        rel = np.ravel(d) - (0.0 if self.anchor is None else self.anchor)
        carried = self.k * np.linalg.norm(self.N.T @ rel)
        load = max(np.linalg.norm(self.N.T @ np.ravel(lam_w)),
                   np.linalg.norm(self.N.T @ np.ravel(lam_w_ref)), np.finfo(float).tiny)
        return float(carried / load)


def ghost(K, images) -> Ghost | None:
    """:class:`Ghost` of the relative stiffness ``K`` for the relative-displacement
    images of the bodies' free rigid motions (None if there are none)."""
    N = orthonormal(images)
    if N is None:
        return None
    return Ghost(N, SUPPORT_RTOL * float(np.mean(np.diag(K))))


def _weakest(free, C, points):
    """The free motion least seen by the interface DOFs, as coefficients of the
    (size-scaled) translations and rotations."""
    _, _, vt = np.linalg.svd(free[C])
    coef = np.linalg.lstsq(_scaled_modes(points), free @ vt[-1], rcond=None)[0]
    return coef / np.abs(coef).max()


def _scaled_modes(points):
    """Rigid motions of ``points`` with rotations scaled to motions of size 1."""
    modes = rigid_body_modes(points)
    dim = points.shape[1]
    size = np.abs(modes[:, dim:]).max() if len(modes) else 0.0
    if size > 0:
        modes[:, dim:] /= size
    return modes


def support_share(reduced, d, a) -> float:
    """Share of the floating bodies' load held by the ghost spring of ``reduced`` at the
    contact state ``d`` and load factors ``a`` (0 without one)."""
    g = getattr(reduced, "ghost", None)
    if g is None:
        return 0.0
    ref = np.zeros(len(reduced.patterns))
    ref[reduced.patterns.index("preload")] = 1.0
    return g.share(d, reduced.W @ np.asarray(a, float), reduced.W @ ref)


def rigid_modes_message(lam, n_found, n_expected, who) -> str:
    """The message for a tied assembly with more rigid modes than its clamps explain."""
    return (f"the tied assembly has {n_found} rigid-body mode(s) but its clamps leave "
            f"only {n_expected} free (eigenvalue {lam:.3e}, mostly in body {who!r}): that "
            f"body is not held by the joint; clamp it or tie it to another body")


def held_by_joint(reduced, res, a, where):
    """``res`` if the joint holds every body at this solve (ghost share at most
    :data:`SHARE_MAX`), else ``res`` marked failed (``Outcome.REJECTED``) with a message
    naming the cause: the joint no longer holds a body (gross slip or lift-off)."""
    share = support_share(reduced, res.d, a)
    if share <= SHARE_MAX:
        return res
    names = [b.name for b in reduced.bodies if b.rigid is not None]
    return replace(res, success=False, outcome=Outcome.REJECTED, message=(
        f"gross slip at {where}: the joint no longer holds body "
        f"{' / '.join(repr(n) for n in names)} (the regularising spring of its rigid "
        f"motions carries {share:.2e} of its load, more than {SHARE_MAX:g}); "
        f"{res.n_stuck} pairs stuck, {res.n_slipping} slipping, {res.n_open} open. "
        f"Levels beyond this one need the body held by a clamp or a stronger joint"))


def elastic_probe(l, model, assembled):
    r"""The probe functional ``l`` (stacked DOFs) measured in the frame of the centre of
    mass of a free-free assembly: ``l - M R (R^T M R)^-1 R^T l`` with ``R`` its free
    rigid motions, so that ``l'^T u`` ignores any rigid motion of the assembly (the
    tip deflection of an elastic mode is unchanged: ``R^T M phi = 0``). ``l`` itself
    where a clamp holds the assembly."""
    R = assembly_motions(model, assembled)
    if R.shape[1] == 0:
        return l
    M = sp.block_diag([a.M for a in assembled], format="csr")
    MR = M @ R
    return l - MR @ np.linalg.solve(R.T @ MR, R.T @ l)


#: Proximal rounds of the preload: the spring is re-anchored at the solved preload and
#: the preload solved again, which multiplies its share by about its share (1e-8):
#: one round takes the bolt-force equilibrium from ~2e-8 to round-off.
ANCHOR_ROUNDS = 2


def anchored(reduced, d):
    """``reduced`` with its ghost spring at rest at the relative displacement ``d``:
    the constant ``k N N^T (anchor_old - d)`` joins the 'preload' column of ``W``
    (whose factor is always 1), so the spring carries only ``k N N^T (d' - d)``."""
    g = reduced.ghost
    d = np.ravel(d).astype(float)
    old = np.zeros_like(d) if g.anchor is None else g.anchor
    W = reduced.W.copy()
    W[:, reduced.patterns.index("preload")] += g.k * (g.N @ (g.N.T @ (old - d)))
    return replace(reduced, W=W, ghost=replace(g, anchor=d))
