"""A bolted joint with a meshed bolt cut by a pretension section (docs/theory.md
section 11): a bolt screwed into a tapped bottom plate clamps a top plate with a hole.

Body ``base`` is the bottom plate with the bolt's shank and head (one mesh: the
thread merged into the plate), body ``plate`` the top plate, held only by the joint.
One interface holds both contacts, head on plate and plate on plate. The section cuts
the shank in the middle of the top plate, its faces owned by the cells above (the
head's side). Hexahedra of one structured grid (mm, N, s, tonne):

    z: base plate 0..4, top plate 4..8, head 8..10
    x, y: plates 0..20, hole and shank 8..12, head 4..16
"""
from __future__ import annotations

import numpy as np

#: The joint (mm, N): steel, pretension N0, friction coefficient.
MESHED_BOLT = dict(E=210000.0, nu=0.3, rho=7.85e-9, pretension=2000.0, mu=0.3,
                   z_cut=6.0)


def _grid(refine):
    """The grid's axes: 4 mm cells in the plane (2 mm in the shank), 2 mm through the
    thickness, each halved ``refine - 1`` times."""
    def axis(*breaks_and_sizes):
        pts = [breaks_and_sizes[0]]
        for stop, size in zip(breaks_and_sizes[1::2], breaks_and_sizes[2::2]):
            n = int(round((stop - pts[-1]) / size)) * 2 ** (refine - 1)
            pts += list(np.linspace(pts[-1], stop, n + 1)[1:])
        return np.array(pts)
    plane = axis(0.0, 4.0, 4.0, 8.0, 4.0, 12.0, 2.0, 16.0, 4.0, 20.0, 4.0)
    return plane, axis(0.0, 10.0, 2.0)


def _body_mesh(grid, keep):
    """The cells of ``grid`` in mask ``keep``, on their own nodes."""
    from ..mesh import Mesh
    used, cells = np.unique(grid.cells[keep], return_inverse=True)
    return Mesh(grid.points[used], cells.reshape(-1, 8), "hexahedron")


def meshed_bolt_joint(refine: int = 1, mu: float | None = None,
                      pretension: float | None = None):
    """The model (module docstring): the base clamped on its bottom face, the top plate
    held only by the joint, one :class:`qsma.model.SectionBolt`; the tip is the top
    plate's free corner edge (x = y = 20), along z."""
    from ..mesh.generate import cell_faces, structured_mesh
    from ..model import Body, Clamp, Interface, Material, Model, Probe, SectionBolt
    s = MESHED_BOLT
    plane, z = _grid(refine)
    grid = structured_mesh(plane, plane, z)
    c = grid.points[grid.cells].mean(axis=1)
    inside = lambda lo, hi: ((c[:, 0] > lo) & (c[:, 0] < hi) & (c[:, 1] > lo)
                             & (c[:, 1] < hi))
    shank = inside(8, 12) & (c[:, 2] > 4) & (c[:, 2] < 8)
    head = inside(4, 16) & (c[:, 2] > 8)
    base = _body_mesh(grid, (c[:, 2] < 4) | shank | head)
    plate = _body_mesh(grid, (c[:, 2] > 4) & (c[:, 2] < 8) & ~shank)
    eps = 1e-9
    at_z = lambda z0: (lambda p: np.abs(p[:, 2] - z0) < eps)
    under_head = lambda p: (np.abs(p[:, 0] - 10) < 6 + eps) & (np.abs(p[:, 1] - 10) < 6 + eps)
    pc = base.points[base.cells].mean(axis=1)
    above = np.flatnonzero((np.abs(pc[:, 0] - 10) < 2) & (np.abs(pc[:, 1] - 10) < 2)
                           & (pc[:, 2] > s["z_cut"]) & (pc[:, 2] < 8))
    base = base.with_sets(
        facet_sets={"contact": np.concatenate([
            base.boundary_facets_where(at_z(4.0)),
            base.boundary_facets_where(lambda p: at_z(8.0)(p) & under_head(p))]),
            "bottom": base.boundary_facets_where(at_z(0.0)),
            "cut": cell_faces(base, above, at_z(s["z_cut"]))})
    corner = np.flatnonzero((plate.points[:, 0] > 20 - eps) & (plate.points[:, 1] > 20 - eps))
    plate = plate.with_sets(node_sets={"corner": corner}, facet_sets={"contact": np.concatenate([
        plate.boundary_facets_where(at_z(4.0)),
        plate.boundary_facets_where(lambda p: at_z(8.0)(p) & under_head(p))])})
    steel = Material(s["E"], s["nu"], s["rho"])
    bodies = (Body("base", base, steel, clamps=(Clamp("bottom"),)),
              Body("plate", plate, steel))
    bolt = SectionBolt("bolt", "base", "cut",
                       s["pretension"] if pretension is None else pretension)
    return Model(bodies=bodies, interface=Interface("base", "contact", "plate", "contact"),
                 bolts=(bolt,), mu=s["mu"] if mu is None else mu, units="mm-N-s-tonne",
                 tip=Probe(sets=(("plate", "corner"),), direction=(0.0, 0.0, 1.0)),
                 name=f"meshed-bolt (refine={refine})")
