"""Incompatible-mode quadrilaterals and hexahedra (CPE4I / CPS4I / C3D8I-like).

Wilson, Taylor, Doherty and Ghaboussi (1973) add to the bilinear (trilinear)
displacement of a 4-node quadrilateral (8-node hexahedron) the bubble modes

.. math::  u = \\sum_a N_a(\\xi) u_a + \\sum_{i=1}^{d} (1 - \\xi_i^2)\\, \\alpha_i,
   \\qquad \\alpha_i \\in \\mathbb{R}^d,

which represent the parabolic displacement of pure bending that the bilinear
element lacks (its parasitic shear makes coarse meshes far too stiff in bending).
The modes are discontinuous between elements, so their ``d * d`` parameters are
condensed element by element: with the element stiffness partitioned as
``[[K_uu, K_ua], [K_au, K_aa]]``,

.. math::  K_e = K_{uu} - K_{ua} K_{aa}^{-1} K_{au}.

Taylor, Beresford and Wilson (1976) evaluate the mode gradients with the Jacobian
at the element centre, ``grad P_i = (det J_0 / det J(xi)) J_0^{-T} grad_xi P_i``, so
that ``int_e grad P_i dV = det J_0 J_0^{-T} int grad_xi P_i dxi = 0``: a constant
strain does no work on the modes and the patch test passes on any distorted mesh
(tests/test_elements.py). Full 2x2 (2x2x2) Gauss quadrature; the modes carry no
mass (the consistent mass is the bilinear / trilinear one).

scikit-fem has no element with element-local condensed DOFs, so this stiffness is
assembled here by hand (vectorised over the elements with numpy); the mass matrix
and loads come from scikit-fem's Q1 basis.
"""
from __future__ import annotations

import numpy as np
import scipy.sparse as sp  # noqa: F401  (return annotation)

from ..mesh.celltypes import CELL_TYPES
from .batched import BATCH, block_pattern, isotropic_blocks, sum_into_csr
from .cache import per_mesh
from .elements import local_origin

_GAUSS = np.array([-1.0, 1.0]) / np.sqrt(3.0)      # 2-point Gauss-Legendre, weights 1
#: corner signs of the reference cell [-1, 1]^d in meshio order
_SIGNS = {2: np.array(CELL_TYPES["quad"].reference, dtype=float),
          3: np.array(CELL_TYPES["hexahedron"].reference, dtype=float)}


def gauss_points(dim):
    """2^dim Gauss points (tensor product, weights 1) on [-1, 1]^dim."""
    g = np.stack(np.meshgrid(*([_GAUSS] * dim), indexing="ij"), axis=-1)
    return g.reshape(-1, dim)


def corner_shape_gradients(xi):
    """Reference gradients of the bilinear (trilinear) shape functions,
    ``dN_a/dxi_j = s_aj / 2^d prod_{k != j} (1 + s_ak xi_k)``: shape ``(nq, 2^d, d)``."""
    nq, dim = xi.shape
    s = _SIGNS[dim]
    f = 1.0 + s[None, :, :] * xi[:, None, :]                 # (nq, na, d)
    out = np.empty((nq, len(s), dim))
    for j in range(dim):
        others = np.prod(np.delete(f, j, axis=2), axis=2)
        out[:, :, j] = s[None, :, j] * others / 2 ** dim
    return out


def mode_shape_values(xi):
    """Values of the modes ``P_i = 1 - xi_i^2``, shape ``(nq, d)``."""
    return 1.0 - xi ** 2


def mode_shape_gradients(xi):
    """Reference gradients of the modes ``P_i = 1 - xi_i^2``: ``dP_i/dxi_j =
    -2 xi_i delta_ij``, shape ``(nq, d, d)``."""
    nq, dim = xi.shape
    return -2.0 * xi[:, :, None] * np.eye(dim)[None]


def element_stiffness(X, lam, mu, modes=True, taylor=True, condensed=True):
    """Condensed stiffness of incompatible-mode elements with node coordinates ``X``
    (``(n_el, 2^d, d)``, meshio order), Lame parameters ``lam``, ``mu``.

    Returns ``(n_el, d 2^d, d 2^d)`` in node-major element DOF order (``d a + i``).
    ``modes=False`` gives the plain bilinear (trilinear) element and ``taylor=False``
    the original Wilson element (mode gradients with the local Jacobian ``J(xi)``,
    which fails the patch test on distorted meshes); ``condensed=False`` returns the
    full ``d (2^d + d)`` square matrix, mode parameters last (all test references).
    The element matrix is

    .. math:: K_{(a i)(b k)} = \\sum_q w_q \\det J_q \\left[\\lambda g_{a i} g_{b k}
       + \\mu (g_a \\cdot g_b\\, \\delta_{ik} + g_{a k} g_{b i})\\right]

    with ``g`` the physical gradients of the nodal functions and the modes.
    """
    ne, na, dim = X.shape
    xi = gauss_points(dim)
    dN = corner_shape_gradients(xi)                           # (nq, na, d)
    J = np.einsum("eai,qaj->eqij", X, dN)                     # dx_i / dxi_j
    detJ = np.linalg.det(J)
    if np.any(detJ <= 0):
        bad = int(np.flatnonzero((detJ <= 0).any(axis=1))[0])
        raise ValueError(f"element {bad} has a non-positive Jacobian determinant")
    Jinv = np.linalg.inv(J)                                   # (ne, nq, d, d): dxi_j/dx_i
    G = np.einsum("qaj,eqji->eqai", dN, Jinv)                 # physical gradients
    if modes:
        dN0 = corner_shape_gradients(np.zeros((1, dim)))[0]
        J0 = np.einsum("eai,aj->eij", X, dN0)
        J0inv = np.linalg.inv(J0)
        det0 = np.linalg.det(J0)
        dP = mode_shape_gradients(xi)                         # (nq, nm, d)
        if taylor:
            GP = np.einsum("qmj,eji->eqmi", dP, J0inv) * (det0[:, None] / detJ)[:, :, None, None]
        else:
            GP = np.einsum("qmj,eqji->eqmi", dP, Jinv)
        G = np.concatenate([G, GP], axis=2)
    K = isotropic_blocks(G, detJ, lam, mu)                    # Gauss weights are 1
    if not modes or not condensed:
        return K
    nu = na * dim
    Kuu, Kua, Kaa = K[:, :nu, :nu], K[:, :nu, nu:], K[:, nu:, nu:]
    return Kuu - Kua @ np.linalg.solve(Kaa, np.swapaxes(Kua, 1, 2))


@per_mesh
def _cached(mesh, lam, mu):
    X_all = mesh.points - local_origin(mesh.points)
    dim, cells = mesh.dim, mesh.cells
    na = cells.shape[1]
    Ke = np.concatenate([element_stiffness(X_all[cells[s:s + BATCH]], lam, mu)
                         for s in range(0, len(cells), BATCH)])
    K5 = Ke.reshape(len(cells), na, dim, na, dim)          # node-major element DOFs
    return sum_into_csr(lambda i, k: K5[:, :, i, :, k], block_pattern(cells, mesh.n_nodes),
                        dim)


def incompatible_stiffness(mesh, lam, mu) -> "sp.csr_matrix":
    """Global condensed stiffness of a quad / hexahedron mesh with incompatible modes,
    in qsma DOF order (``dim * node + component``), on coordinates relative to the
    bounding-box corner (:func:`qsma.fe.elements.local_origin`). Cached per mesh."""
    if mesh.cell_type not in ("quad", "hexahedron"):
        raise ValueError(f"incompatible modes need quad or hexahedron cells, not "
                         f"{mesh.cell_type!r}")
    return _cached(mesh, float(lam), float(mu)).copy()
