r"""A meshed bolt cut by a pretension section (docs/theory.md section 11).

The section ``S`` (faces through the shank, oriented out of the cells that own them,
side B) cuts the body: side B's cells take copies ``u'_i`` of the section's nodes,
held to the originals by ``u'_i = u_i + delta n`` (tangential components tied, one
uniform opening ``delta`` along the unit normal ``n``, out of side B). The cut body's
energy in ``(u, delta)`` is that of the bordered matrix

.. math:: \begin{bmatrix} K & v \\ v^T & \gamma \end{bmatrix}, \qquad
          v = K_B[:, S]\, N, \quad \gamma = N^T K_B[S, S]\, N,

``K`` the uncut body's stiffness, ``K_B`` that of side B's cells that own the faces,
``N`` the normal ``n`` at every node of ``S``. A tension ``N0`` across the section is
the generalised force ``N0`` on ``delta`` (``delta > 0``: side B's faces pushed into
side A, the shank shortened): ``K u + v delta = f``, ``v^T u + gamma delta = N0``.
The section's normal force is ``N = v^T u + gamma delta``. With ``delta`` free
(preload) it is eliminated:

.. math:: (K - v v^T / \gamma)\, u = f - N_0\, v / \gamma ,

a bolt of :mod:`qsma.fe.bolts` with ``c = v / \gamma`` (elongation ``ell = c^T u``, a
tension ``N`` loads the body with ``-N c``) and locked stiffness ``k = \gamma`` on the
cut body ``K - v v^T / \gamma``: locking adds ``k c c^T`` and gives back ``K``. The cut
body has one motion more than its rigid ones, the opening: side B moving by ``n``
(:attr:`SectionTerms.opening`), held in the preload only by the joint.
"""
from __future__ import annotations

from dataclasses import dataclass, replace
import weakref

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..errors import InputError
from ..mesh import Mesh
from ..mesh.celltypes import CELL_TYPES, TYPES
from ..model.body import Body
from .assembly import stiffness_matrix
from .elements import block_dofs, scatter_matrix
from .formulation import resolve_formulations

__all__ = ["SectionTerms", "section_terms", "cut_stiffness", "with_cut_bodies",
           "cells_stiffness"]


@dataclass(frozen=True, eq=False)
class SectionTerms:
    """The cut of one pretension section (module docstring).

    Attributes
    ----------
    v : (n_dofs,) float array, ``K_B[:, S] N``
    gamma : float, ``N^T K_B[S, S] N`` (the locked stiffness)
    normal : (dim,) unit normal, out of the owner cells
    nodes : the section's nodes
    owners : the cells that own its faces (side B next to the cut)
    opening : (n_dofs,) the cut body's opening motion (``n`` on side B, 0 elsewhere)
    area : the section's area (length in 2D)
    face_owners : the cell that owns each face of the set, in the set's order
    """

    v: np.ndarray
    gamma: float
    normal: np.ndarray
    nodes: np.ndarray
    owners: np.ndarray
    opening: np.ndarray
    area: float
    face_owners: np.ndarray = None

    @property
    def c(self) -> np.ndarray:
        """``ell = c^T u``, ``c = v / gamma``."""
        return self.v / self.gamma


#: mesh -> {(section, normal, material, element): SectionTerms}
_CACHE = weakref.WeakKeyDictionary()


def section_terms(body, bolt) -> SectionTerms:
    """The :class:`SectionTerms` of ``bolt`` (a :class:`qsma.model.SectionBolt`) on its
    body ``body`` (cached per mesh)."""
    key = (bolt.section, bolt.normal, repr(body.material), body.mesh.element)
    cache = _CACHE.setdefault(body.mesh, {})
    if key not in cache:
        cache[key] = _terms(body, bolt)
    return cache[key]


def _terms(body, bolt) -> SectionTerms:
    mesh = body.mesh
    where = f"bolt {bolt.name!r}: section {bolt.section!r} of body {body.name!r}"
    if bolt.section not in mesh.facet_sets:
        raise InputError(f"{where} is no facet set of the body; facet sets: "
                         f"{sorted(mesh.facet_sets)}")
    if mesh.is_mixed:
        raise InputError(f"{where}: a section through a mesh of several cell types is not "
                         f"supported; mesh the bolt with one cell type")
    rows = np.asarray(mesh.facet_sets[bolt.section])
    face_owners = _owner_cells(mesh, rows, where)
    owners = np.unique(face_owners)
    area_normals = _area_normals(mesh, rows, face_owners)
    area = float(np.linalg.norm(area_normals, axis=1).sum())
    mean = area_normals.sum(axis=0)
    if np.linalg.norm(mean) <= 1e-6 * area:
        raise InputError(f"{where}: its faces' normals cancel (a closed or folded "
                         f"surface); the section must be a cut through the shank")
    n = mean / np.linalg.norm(mean)
    if bolt.normal is not None:
        given = np.asarray(bolt.normal, dtype=float)
        if given.size != body.dim:
            raise InputError(f"{where}: normal {list(bolt.normal)} has {given.size} "
                             f"components for a {body.dim}D body")
        given = given / np.linalg.norm(given)
        if given @ n <= 0:
            raise InputError(f"{where}: the given normal {np.round(given, 3).tolist()} "
                             f"points into the cells that own the faces (their outward "
                             f"normal is {np.round(n, 3).tolist()}): the pretension would "
                             f"push. Reverse the normal")
        n = given
    nodes = np.unique(rows)
    dim = body.dim
    dofs = (dim * nodes[:, None] + np.arange(dim)).ravel()
    N = np.tile(n, len(nodes))
    K_B = cells_stiffness(body, owners)
    v = np.asarray(K_B[:, dofs] @ N).ravel()
    gamma = float(N @ v[dofs])
    if not gamma > 0:
        raise InputError(f"{where}: the cells that own the faces do not resist the "
                         f"opening (gamma = {gamma:g})")
    opening = _opening(mesh, nodes, owners, n, where)
    return SectionTerms(v, gamma, n, nodes, owners, opening, area, face_owners)


def cells_stiffness(body, cells) -> sp.csc_matrix:
    """The stiffness of the given cells of ``body`` alone, over the body's DOFs (the
    owners' ``K_B``; a slab's internal forces in the tests)."""
    mesh = body.mesh
    used, local = np.unique(mesh.cells[cells], return_inverse=True)
    sub = Body(body.name, Mesh(mesh.points[used], local.reshape(len(cells), -1),
                               mesh.cell_type, element=mesh.element), body.material)
    K = stiffness_matrix(sub, resolve_formulations(mesh))
    return scatter_matrix(K, block_dofs(used, body.dim), body.n_dofs).tocsc()


def _canonical(corners: np.ndarray) -> tuple:
    """A facet's corner cycle from its smallest node (its orientation kept); a line's
    two nodes as they are."""
    if len(corners) == 2:
        return tuple(corners)
    k = int(np.argmin(corners))
    return tuple(np.roll(corners, -k))


def _owner_cells(mesh, rows, where) -> np.ndarray:
    """Per face of the section, the cell whose local face it is with the same
    orientation; refused where a face is not shared by two cells (on the boundary, or
    no face of the mesh)."""
    ct = CELL_TYPES[mesh.cell_type]
    nc = TYPES[ct.facet_type].corners
    local = [list(f) for f in ct.facets]
    faces = np.concatenate([mesh.cells[:, f] for f in local])
    cells = np.tile(np.arange(len(mesh.cells)), len(local))
    by_nodes = {}
    for i, key in enumerate(map(tuple, np.sort(faces[:, :nc], axis=1))):
        by_nodes.setdefault(key, []).append(i)
    owners = []
    for r in rows:
        found = by_nodes.get(tuple(np.sort(r[:nc])), [])
        if len(found) != 2:
            raise InputError(
                f"{where}: face {(r + 1).tolist()} (node numbers from 1) is "
                f"{'on the boundary' if found else 'no face of the mesh'}; a pretension "
                f"section is made of internal faces (each between two cells) across the "
                f"shank")
        same = [i for i in found if _canonical(faces[i, :nc]) == _canonical(r[:nc])]
        if len(same) != 1:
            raise InputError(f"{where}: face {(r + 1).tolist()} (node numbers from 1) "
                             f"does not have the orientation of either of its cells")
        owners.append(cells[same[0]])
    return np.array(owners, dtype=np.int64)


def _area_normals(mesh, rows, face_owners) -> np.ndarray:
    """Each face's normal scaled by its area (length in 2D), pointing out of its owner
    cell (away from the cell's centroid)."""
    ct = CELL_TYPES[mesh.cell_type]
    nc = TYPES[ct.facet_type].corners
    x = mesh.points[rows[:, :nc]]
    if mesh.dim == 2:
        t = x[:, 1] - x[:, 0]
        a = np.stack([t[:, 1], -t[:, 0]], axis=1)
    else:
        a = 0.5 * np.cross(x, np.roll(x, -1, axis=1)).sum(axis=1)
    own = mesh.points[mesh.cells[face_owners][:, :ct.corners]].mean(axis=1)
    sign = np.sign(np.einsum("ij,ij->i", a, x.mean(axis=1) - own))
    return a * sign[:, None]


def _opening(mesh, nodes, owners, n, where) -> np.ndarray:
    """The opening motion of the cut body: ``n`` on side B (the nodes joined to the
    copies once the owner cells take them), 0 elsewhere; refused when the section
    does not cut the body in two."""
    n_nodes = len(mesh.points)
    copy_of = np.full(n_nodes, -1)
    copy_of[nodes] = n_nodes + np.arange(len(nodes))
    cells = mesh.cells.copy()
    own = cells[owners]
    cut = copy_of[own] >= 0
    own[cut] = copy_of[own[cut]]
    cells[owners] = own
    total = n_nodes + len(nodes)
    rows = np.repeat(np.arange(len(cells)), cells.shape[1])
    inc = sp.csr_matrix((np.ones(cells.size), (rows, cells.ravel())),
                        shape=(len(cells), total))
    _, label = connected_components(inc.T @ inc, directed=False)
    side_b = np.unique(label[n_nodes:])
    if np.isin(label[nodes], side_b).any():
        raise InputError(f"{where} does not cut the body in two: "
                         + _joined_by(mesh, nodes, owners, n))
    moved = np.flatnonzero(np.isin(label[:n_nodes], side_b))
    dim = mesh.dim
    out = np.zeros(dim * n_nodes)
    for c in range(dim):
        out[dim * moved + c] = n[c]
    return out


def _joined_by(mesh, nodes, owners, n) -> str:
    """Why the two sides stay joined: cells on the owners' side that touch the section
    without a face on it (they keep its nodes, as CalculiX leaves them: tetrahedra
    meeting the cut at an edge or a corner), else a section short of the edge."""
    ct = CELL_TYPES[mesh.cell_type]
    touching = np.flatnonzero(np.isin(mesh.cells, nodes).any(axis=1))
    others = np.setdiff1d(touching, owners)
    centre = mesh.points[mesh.cells[others][:, :ct.corners]].mean(axis=1)
    behind = others[(centre - mesh.points[nodes].mean(axis=0)) @ n < 0]
    if len(behind):
        return (f"{len(behind)} cell(s) on the side of the cells that own its faces "
                f"touch it without a face on it (cell {int(behind[0]) + 1}, counted from "
                f"1), so they keep the section's nodes and join the two sides, as "
                f"CalculiX would leave them (tetrahedra meeting the cut at an edge or a "
                f"corner). Mesh the shank so that the cells on that side meet the section "
                f"with whole faces (hexahedra or a swept layer of wedges there)")
    return ("the cells on both sides of it are joined around its edge. Extend the "
            "section over the whole cross-section of the shank")


def cut_stiffness(K, terms: SectionTerms) -> sp.csr_matrix:
    """``K - v v^T / gamma``: the body cut by the section, its opening free."""
    idx = np.flatnonzero(terms.v)
    w = terms.v[idx]
    rows = np.repeat(idx, len(idx))
    cols = np.tile(idx, len(idx))
    update = sp.csr_matrix((np.outer(w, w).ravel() / terms.gamma, (rows, cols)),
                           shape=K.shape)
    return (K - update).tocsr()


def with_cut_bodies(model, assembled) -> list:
    """The assembled bodies with every pretension section cut (:func:`cut_stiffness`)
    and its opening among the body's free motions (``AssembledBody.openings``)."""
    out = list(assembled)
    for bolt in getattr(model, "bolts", ()):
        if not hasattr(bolt, "section"):
            continue
        k = model.body_index(bolt.body)
        a = out[k]
        terms = section_terms(a.body, bolt)
        opening = terms.opening[:, None]
        more = opening if a.openings is None else np.column_stack([a.openings, opening])
        out[k] = replace(a, K=cut_stiffness(a.K, terms), openings=more)
    return out
