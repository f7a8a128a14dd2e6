"""Linear modes of the assembly with a chosen set of interface pairs tied.

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

from .errors import AnalysisError, InputError


@dataclass(frozen=True, eq=False)
class Modes:
    """Natural frequencies and mass-normalised shapes (stacked DOFs of all bodies).

    ``shapes[:, k]`` is mode k over the DOF vector of all bodies (``model.dof_offsets``);
    ``tied`` is the mask of tied pairs used.
    """

    omega: np.ndarray
    shapes: np.ndarray
    tied: np.ndarray

    @property
    def f_hz(self):
        return self.omega / (2 * np.pi)


def stacked(matrices):
    """Block-diagonal sparse matrix of the bodies' matrices (stacked DOFs)."""
    return sp.block_diag(matrices, format="csr")


def tie_transform(model, assembled, pairing, tied) -> sp.csr_matrix:
    """``T`` with ``x_all = T x_reduced``: Dirichlet DOFs dropped, tied body-2 DOFs mapped
    onto their body-1 partners (node-to-node) or tied slave DOFs onto the projection of
    the master DOFs (mortar, :func:`_mpc_transform`)."""
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
    do the Dirichlet DOFs (a clamped master DOF contributes zero)."""
    off = model.dof_offsets()
    dim = model.dim
    n = off[-1]
    fixed = np.zeros(n, dtype=bool)
    for k, a in enumerate(assembled):
        fixed[off[k] + a.fixed] = True
    names = (model.interface.body1, model.interface.body2)
    s_off = off[model.body_index(names[pairing.slave - 1])]
    m_off = off[model.body_index(names[2 - pairing.slave])]
    tied = np.asarray(tied, dtype=bool)
    N = pairing.projection[tied].tocoo()
    snodes = pairing.contact_nodes[tied]
    mnodes = pairing.master_nodes
    rows, cols, vals = [], [], []
    slave_dofs = []
    for c in range(dim):
        sd = s_off + dim * snodes + c
        if fixed[sd].any():
            bad = snodes[fixed[sd]]
            raise InputError(f"interface slave node(s) {bad[:10].tolist()} are clamped and "
                             f"cannot be tied to the master surface; remove them from the "
                             f"interface set or from the clamp")
        slave_dofs.append(sd)
        rows.append(sd[N.row])
        cols.append(m_off + dim * mnodes[N.col] + c)
        vals.append(N.data)
    slave_dofs = np.concatenate(slave_dofs)
    is_slave = np.zeros(n, dtype=bool)
    is_slave[slave_dofs] = True
    free = np.flatnonzero(~is_slave)
    G = sp.coo_matrix((np.concatenate([np.ones(len(free))] + vals),
                       (np.concatenate([free] + rows), np.concatenate([free] + cols))),
                      shape=(n, n)).tocsc()
    keep = np.flatnonzero(~fixed & ~is_slave)
    return G[:, keep].tocsr()


def linear_modes(model, assembled, pairing, tied=None, n_modes=6) -> Modes:
    """First ``n_modes`` modes with the pairs in mask ``tied`` tied (default: all).

    Solves ``(T^T K T - w^2 T^T M T) phi_r = 0`` by shift-invert Lanczos about 0;
    shapes are mass-normalised (``phi^T M phi = 1``).
    """
    if tied is None:
        tied = np.ones(pairing.n_pairs, dtype=bool)
    tied = np.asarray(tied, dtype=bool)
    if tied.shape != (pairing.n_pairs,):
        raise InputError(f"tied mask must have {pairing.n_pairs} entries, got {tied.shape}")
    if not isinstance(n_modes, (int, np.integer)) or n_modes < 1:
        raise InputError(f"number of modes must be a positive integer, got {n_modes!r}")
    T = tie_transform(model, assembled, pairing, tied)
    K = (T.T @ stacked([a.K for a in assembled]) @ T).tocsc()
    M = (T.T @ stacked([a.M for a in assembled]) @ T).tocsc()
    k = min(n_modes, K.shape[0] - 2)
    solve = _factor(K, model, assembled, T)
    op = spla.LinearOperator(K.shape, matvec=solve, matmat=solve, dtype=float)
    try:
        lam, vec = spla.eigsh(K, k=k, M=M, sigma=0.0, which="LM", OPinv=op)
    except spla.ArpackNoConvergence as exc:
        raise AnalysisError(f"eigen solver did not converge ({len(exc.eigenvalues)} of {k} "
                            f"modes found)", partial=exc) from exc
    order = np.argsort(lam)
    lam, vec = lam[order], vec[:, order]
    _check_rigid(lam, K, M, model, assembled, T, vec)
    vec /= np.sqrt(np.einsum("ik,ik->k", vec, M @ vec))
    return Modes(np.sqrt(np.maximum(lam, 0.0)), T @ vec, tied.copy())


def _factor(K, model, assembled, T):
    """Factorised tied stiffness (PARDISO if installed, else SuperLU; qsma.linalg)."""
    from .linalg import spd_solver
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


def _check_rigid(lam, K, M, model, assembled, T, vec):
    scale = abs(K.diagonal()).max() / abs(M.diagonal()).max()
    if lam[0] < 1e-12 * scale:   # round-off level of a singular pencil
        full = T @ vec[:, 0]
        off = model.dof_offsets()
        share = [np.linalg.norm(full[off[k]:off[k + 1]]) for k in range(len(assembled))]
        worst = assembled[int(np.argmax(share))].body.name
        raise InputError(f"the tied assembly has a rigid-body mode (eigenvalue {lam[0]:.3e}, "
                         f"mostly in body {worst!r}): clamp that body or tie it to another.")


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
