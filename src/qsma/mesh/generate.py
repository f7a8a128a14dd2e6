"""Structured meshes (quadrilaterals in 2D, hexahedra in 3D, linear or quadratic) on
tensor grids."""
from __future__ import annotations

import numpy as np

from ..errors import InputError
from .celltypes import CELL_TYPES, reference_nodes
from .mesh import Mesh


def graded_axis(*segments):
    """Concatenate ``(start, stop, n_elements)`` segments into one sorted coordinate axis."""
    parts = [np.linspace(a, b, n + 1) for a, b, n in segments]
    return np.concatenate([parts[0]] + [p[1:] for p in parts[1:]])


def structured_mesh(*axes, cell_type=None) -> Mesh:
    """Tensor-product mesh of the grid ``axes`` (2 axes: quads, 3 axes: hexahedra).

    ``cell_type`` ``None`` (``"quad"`` / ``"hexahedron"``): linear cells, node
    ``(i, j[, k])`` has index ``i + nx * (j + ny * k)``. ``"quad8"``, ``"quad9"``,
    ``"hexahedron20"``, ``"hexahedron27"``: quadratic cells on the same grid cells,
    midside nodes at the middle of each interval (nodes no cell uses are dropped).
    Cells are counter-clockwise (positive Jacobian) in meshio order.

    The axes must increase strictly: then every cell is a box with positive Jacobian,
    which is all :func:`~qsma.mesh.validate.validate_mesh` would check (at no cost here).
    """
    for k, a in enumerate(axes):
        a = np.asarray(a, dtype=float)
        if a.ndim != 1 or len(a) < 2 or not np.all(np.diff(a) > 0):
            raise InputError(f"axis {k} of a structured mesh must be at least 2 strictly "
                             f"increasing coordinates, got {a.tolist()}; sort it and remove "
                             f"repeated values")
    linear = {2: "quad", 3: "hexahedron"}[len(axes)]
    if cell_type not in (None, linear):
        return _quadratic_structured(axes, cell_type)
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


def _quadratic_structured(axes, cell_type) -> Mesh:
    ct = CELL_TYPES.get(cell_type)
    if ct is None or ct.linear not in ("quad", "hexahedron") or ct.is_linear \
            or ct.dim != len(axes):
        raise ValueError(f"no {len(axes)}D structured mesh of {cell_type!r} cells")
    # grid offsets (0, 1, 2 per axis: start, middle, end of the cell) of the local
    # nodes: the reference coordinates in [-1, 1], shifted
    offsets = (reference_nodes(cell_type) + 1).astype(int).tolist()
    fine = []
    for a in axes:
        a = np.asarray(a, dtype=float)
        f = np.empty(2 * len(a) - 1)
        f[0::2], f[1::2] = a, 0.5 * (a[:-1] + a[1:])
        fine.append(f)
    shape = [len(a) for a in fine]
    grids = np.meshgrid(*fine, indexing="ij")
    points = np.stack([g.ravel(order="F") for g in grids], axis=1)
    idx = np.arange(np.prod(shape)).reshape(shape, order="F")
    ncell = [(n - 1) // 2 for n in shape]
    cols = []
    for off in offsets:
        sl = tuple(slice(o, o + 2 * n, 2) for o, n in zip(off, ncell))
        cols.append(idx[sl].ravel(order="F"))
    cells = np.stack(cols, axis=1)
    used, cells = np.unique(cells, return_inverse=True)
    return Mesh(points[used], cells.reshape(-1, len(offsets)), cell_type)


def box_facets(mesh: Mesh, predicate) -> np.ndarray:
    """Boundary facets whose nodes all satisfy ``predicate(points)``."""
    return mesh.boundary_facets_where(predicate)


def box_nodes(mesh: Mesh, predicate) -> np.ndarray:
    return np.flatnonzero(predicate(mesh.points))


def cell_faces(mesh: Mesh, cells, predicate) -> np.ndarray:
    """The faces of the given cells whose nodes all satisfy ``predicate(points)``, each
    in the orientation of its cell (corners counter-clockwise seen from outside it):
    internal faces too, e.g. a pretension section (:class:`qsma.model.SectionBolt`)
    owned by the cells on one side of it."""
    ct = CELL_TYPES[mesh.cell_type]
    on = np.asarray(predicate(mesh.points), dtype=bool)
    rows = [mesh.cells[np.asarray(cells)][:, list(f)] for f in ct.facets]
    rows = np.concatenate(rows)
    return rows[on[rows].all(axis=1)]
