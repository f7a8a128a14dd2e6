"""Structured meshes (quadrilaterals in 2D, hexahedra in 3D) on tensor grids."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .mesh import Mesh


def graded_axis(*segments):
    """Concatenate ``(start, stop, n_elements)`` segments into one sorted coordinate axis."""
    parts = [np.linspace(a, b, n + 1) for a, b, n in segments]
    return np.concatenate([parts[0]] + [p[1:] for p in parts[1:]])


def structured_mesh(*axes) -> Mesh:
    """Tensor-product mesh of the grid ``axes`` (2 axes: quads, 3 axes: hexahedra).

    Node ``(i, j[, k])`` has index ``i + nx * (j + ny * k)``; cells are counter-clockwise
    (positive Jacobian) in meshio order.

    The axes must increase strictly: then every cell is a box with positive Jacobian,
    which is all :func:`~qsma.model.validate.validate_mesh` would check (at no cost here).
    """
    for k, a in enumerate(axes):
        a = np.asarray(a, dtype=float)
        if a.ndim != 1 or len(a) < 2 or not np.all(np.diff(a) > 0):
            raise InputError(f"axis {k} of a structured mesh must be at least 2 strictly "
                             f"increasing coordinates, got {a.tolist()}; sort it and remove "
                             f"repeated values")
    shape = [len(a) for a in axes]
    grids = np.meshgrid(*axes, indexing="ij")
    points = np.stack([g.ravel(order="F") for g in grids], axis=1)
    idx = np.arange(np.prod(shape)).reshape(shape, order="F")
    if len(axes) == 2:
        a = idx[:-1, :-1]
        cells = np.stack([a, idx[1:, :-1], idx[1:, 1:], idx[:-1, 1:]], axis=-1)
        return Mesh(points, cells.reshape(-1, 4, order="F"), "quad")
    a = idx[:-1, :-1, :-1]
    bottom = [a, idx[1:, :-1, :-1], idx[1:, 1:, :-1], idx[:-1, 1:, :-1]]
    top = [idx[:-1, :-1, 1:], idx[1:, :-1, 1:], idx[1:, 1:, 1:], idx[:-1, 1:, 1:]]
    cells = np.stack(bottom + top, axis=-1)
    # bottom face normal must point away from the top face (-z): order (0,1,2,3) with
    # x then y is counter-clockwise seen from +z, giving a positive hexahedron Jacobian.
    return Mesh(points, cells.reshape(-1, 8, order="F"), "hexahedron")


def box_facets(mesh: Mesh, predicate) -> np.ndarray:
    """Boundary facets whose nodes all satisfy ``predicate(points)``."""
    return mesh.boundary_facets_where(predicate)


def box_nodes(mesh: Mesh, predicate) -> np.ndarray:
    return np.flatnonzero(predicate(mesh.points))
