"""Contact interface: node pairs matched by coordinates or a mortar projection, and
the local frames of the contact points."""
from __future__ import annotations

from dataclasses import dataclass
import warnings

import numpy as np
import scipy.sparse as sp
from scipy.spatial import cKDTree

from .._infra.deprecation import forward
from ..contact.laws import InterfaceLaw
from ..errors import InputError, QuadraticFacetWarning
from ..mesh.facets import facet_node_weights, facet_normals
from ..mesh.mesh import Mesh, facet_index
from .coupling import mortar_operator
from .friction import check_mu

#: Node-to-node pairing: two nodes are the same point when they are closer than this
#: fraction of the smallest interface facet edge at either node. It is far above the
#: round-off of coordinates written with 10 or more significant digits (1e-10 of the
#: part size, i.e. <= 1e-7 h for parts up to 1000 elements across) and far below any
#: meshing difference: nodes farther apart are not snapped, they need the mortar coupling.
NODE_MATCH_FRACTION = 1e-6

#: Couplings of an :class:`Interface`.
COUPLINGS = ("node", "mortar", "auto")


@dataclass(frozen=True)
class Interface:
    """A contact interface: facet set ``set1`` of ``body1`` against facet set ``set2``
    of ``body2``. The contact normal points from body 1 into body 2.

    Parameters
    ----------
    coupling : {"node", "mortar", "auto"}
        ``"node"``: node-to-node pairs, the two meshes must have coincident interface
        nodes (within :data:`NODE_MATCH_FRACTION` of the local element size).
        ``"mortar"``: the two sides may be meshed independently; the contact unknowns
        live at the nodes of the slave side and the master side enters through the dual
        mortar projection (:mod:`qsma.model.coupling`). ``"auto"``: node-to-node when
        every node has a coincident partner, otherwise mortar.
    slave : name of the body whose interface nodes carry the contact unknowns (mortar
        only). ``None``: the side with more interface nodes (the finer one, as mortar
        theory recommends), body 1 on a tie; if that side is not covered by the other,
        the other side, and where neither is covered, the one with the smaller share
        uncovered.
    tol : node-to-node match tolerance (absolute, m). It can only tighten the default
        (:data:`NODE_MATCH_FRACTION` of the local element size); a larger value is
        refused: mismatched meshes are coupled by ``coupling="mortar"``, never snapped.
    mu : Coulomb friction coefficient of this interface; ``None``: the model's ``mu``.
    law : :class:`qsma.contact.laws.InterfaceLaw` of this interface (normal and
        tangential compliance); ``None``: hard contact with rigid stick.
    gap : initial normal gap added at every contact point (m, positive apart, negative
        overlapping): where the surfaces touch is an input, not an accident of the
        mesh. A callable of the contact points' coordinates ``(n, dim) -> (n,)``, or a
        :class:`qsma.model.gapfield.GapField` (e.g. a measured height map,
        :func:`qsma.model.gapfield.read_gap_field`). ``None``: flat (the mesh's own gaps).
    adjust : the meshed surfaces' gaps and overlaps within this distance (m) are zero,
        as Abaqus' and CalculiX's ``*CONTACT PAIR, ADJUST=`` moves the slave nodes onto
        the master surface before the analysis; a string: a node set of the slave body,
        whose contact points' gaps are zero (``ADJUST=`` a node set); ``None``: the
        gaps as meshed. The gap field ``gap`` is added after, unadjusted.
    """

    body1: str
    set1: str
    body2: str
    set2: str
    tol: float | None = None
    coupling: str = "auto"
    slave: str | None = None
    mu: float | None = None
    law: object = None
    gap: object = None
    adjust: float | str | None = None

    @property
    def label(self) -> str:
        """``body1.set1 / body2.set2``, how messages name the interface."""
        return f"{self.body1}.{self.set1} / {self.body2}.{self.set2}"

    def __post_init__(self):
        if self.mu is not None and (isinstance(self.mu, bool)
                                    or not isinstance(self.mu, (int, float, np.number))
                                    or not np.isfinite(self.mu) or self.mu < 0):
            raise InputError(f"interface {self.label}: friction coefficient mu must be a "
                             f"finite number >= 0, got {self.mu!r}")
        if self.mu is not None:
            check_mu(self.mu, f"interface {self.label}: ")
        if self.law is not None:
            if not isinstance(self.law, InterfaceLaw):
                raise InputError(f"interface {self.label}: law must be a "
                                 f"qsma.contact.laws.InterfaceLaw, got "
                                 f"{type(self.law).__name__}")
        if self.gap is not None and not callable(self.gap):
            raise InputError(f"interface {self.label}: gap must be a function of the "
                             f"contact points' coordinates or a GapField, got "
                             f"{type(self.gap).__name__}")
        if self.adjust is not None and not isinstance(self.adjust, str) and (
                isinstance(self.adjust, bool)
                or not isinstance(self.adjust, (int, float, np.number))
                or not np.isfinite(self.adjust) or self.adjust < 0):
            raise InputError(f"interface {self.label}: adjust must be a finite distance "
                             f">= 0 (m), the gaps and overlaps to close, or a node "
                             f"set of the slave body, got "
                             f"{self.adjust!r}")
        if self.coupling not in COUPLINGS:
            raise InputError(f"interface coupling must be one of {list(COUPLINGS)}, "
                             f"got {self.coupling!r}")
        if self.slave is not None and self.slave not in (self.body1, self.body2):
            raise InputError(f"interface slave must name one of its bodies "
                             f"({self.body1!r}, {self.body2!r}), got {self.slave!r}")
        if self.tol is not None:
            if isinstance(self.tol, bool) or not isinstance(self.tol, (int, float)):
                raise InputError(f"interface pairing tolerance tol must be a number, "
                                 f"got {self.tol!r}")
            if not np.isfinite(self.tol):
                raise InputError(f"interface pairing tolerance tol must be finite, got "
                                 f"{self.tol!r} (leave it out for the default)")
            if self.tol <= 0:
                raise InputError(f"interface pairing tolerance tol must be > 0, got "
                                 f"{self.tol!r}")


@dataclass(frozen=True, eq=False)
class Pairing:
    """The contact points of an interface and how both bodies see them.

    Node-to-node (``projection is None``): contact point i is the pair
    ``(nodes1[i], nodes2[i])``. Mortar: the contact points are the interface nodes of
    the slave body (``nodes1`` if ``slave == 1`` else ``nodes2``, in contact-point
    order); the other body's interface nodes (its condensed DOFs) are the master nodes,
    and ``projection @ u_master`` interpolates a master nodal field at the contact
    points (one weight per master node, the same for each component).

    Attributes
    ----------
    nodes1, nodes2 : node indices in body 1 and body 2 (the condensation sets)
    x : (n_pairs, dim) contact point coordinates
    frames : (n_pairs, dim, dim) rows are the local axes, ``(t, n)`` in 2D and
        ``(t1, t2, n)`` in 3D, normal from body 1 into body 2, fixed in the undeformed
        configuration
    area : (n_pairs,) tributary area (length in 2D, per unit depth) of each contact
        point; the contact traction is ``lam / area``
    coupling : "node" or "mortar"
    slave : 1 or 2, the body carrying the contact points
    projection : (n_pairs, n_master) sparse ``P = D^-1 M`` or None
    gap : (n_pairs,) weighted normal gap of the undeformed mortar surfaces (reported,
        taken as zero), None for node-to-node
    slave_basis : None, or the :class:`qsma.model.dual_basis.SlaveBasis` of a mortar slave
        on mixed quadratic facets: the contact point's displacement is then the
        coefficient ``u~_i`` of its mixed function, ``u_slave = to_nodes @ u~``, and
        ``projection @ u_master`` is what ``u~`` is tied to
    """

    nodes1: np.ndarray
    nodes2: np.ndarray
    x: np.ndarray
    frames: np.ndarray
    area: np.ndarray
    coupling: str = "node"
    slave: int = 1
    projection: sp.csr_matrix | None = None
    gap: np.ndarray | None = None
    slave_basis: object = None

    @property
    def n_pairs(self):
        return len(self.x)

    @property
    def contact_nodes(self):
        """Nodes of the slave body at the contact points."""
        return self.nodes1 if self.slave == 1 else self.nodes2

    @property
    def master_nodes(self):
        """Interface nodes of the master body (node-to-node: the partners)."""
        return self.nodes2 if self.slave == 1 else self.nodes1

    @property
    def normals(self):
        return self.frames[:, -1, :]


def pair_nodes(mesh1: Mesh, set1: str, mesh2: Mesh, set2: str, tol=None, names=("1", "2")):
    """Match the nodes of two facet sets by coordinates (node-to-node coupling).

    Two nodes match when they are closer than :data:`NODE_MATCH_FRACTION` times the
    smallest facet edge at either node (``tol``, if given, may only be smaller).
    Returns ``(nodes1, nodes2)`` sorted along the interface (lexicographic in the
    coordinates). Raises :class:`InputError` naming unmatched nodes and their distance
    to the nearest candidate, pointing to the mortar coupling.
    """
    match = node_match(mesh1, set1, mesh2, set2, tol)
    if match.error is None:
        return match.nodes1, match.nodes2
    raise InputError(match.message(set1, set2, names))


@dataclass(frozen=True, eq=False)
class _Match:
    nodes1: np.ndarray | None
    nodes2: np.ndarray | None
    error: str | None = None
    detail: tuple = ()

    def message(self, set1, set2, names):
        if self.error == "tol":
            tol, bound = self.detail
            return (f"interface {set1!r} / {set2!r}: the node matching tolerance tol={tol:.3e} "
                    f"m exceeds {NODE_MATCH_FRACTION:g} x the smallest interface element "
                    f"({bound:.3e} m): node-to-node contact cannot glue meshes whose nodes "
                    f"do not coincide. Fix: remove tol, or set coupling = \"mortar\" (or "
                    f"\"auto\") on the interface to couple non-matching meshes.")
        if self.error == "duplicate":
            return (f"interface {set1!r} / {set2!r}: several nodes of body {names[0]} "
                    f"coincide with the same node of body {names[1]}; duplicate nodes? "
                    f"Fix: merge the duplicate nodes of body {names[0]}.")
        bad1, bad2, x1, x2, n1, n2, d12, d21, tol = self.detail
        lines = [f"  body {names[0]} node {n1[k]} at {x1[k].tolist()}: nearest node of "
                 f"body {names[1]} set {set2!r} is {d12[k]:.3e} away" for k in bad1[:10]]
        lines += [f"  body {names[1]} node {n2[k]} at {x2[k].tolist()}: nearest node of "
                  f"body {names[0]} set {set1!r} is {d21[k]:.3e} away" for k in bad2[:10]]
        more = len(bad1) + len(bad2) - len(lines)
        return (f"interface {set1!r} / {set2!r}: {len(bad1) + len(bad2)} node(s) have no "
                f"partner within {NODE_MATCH_FRACTION:g} x the local element size "
                f"(node-to-node contact needs coincident nodes; nodes are never snapped):\n"
                + "\n".join(lines) + (f"\n  ... and {more} more" if more > 0 else "")
                + "\nFix: if the two sides are meshed independently, set coupling = "
                  "\"mortar\" (or \"auto\") on the interface; otherwise check that the "
                  "sets name the touching faces of the two bodies.")


def _local_size(mesh, facets, nodes):
    """Smallest facet edge length at each of ``nodes``."""
    p = mesh.points[facets]
    edge = np.linalg.norm(p - np.roll(p, 1, axis=1), axis=2)          # edge k: k-1 -> k
    h = np.full(mesh.n_nodes, np.inf)
    np.minimum.at(h, facets.ravel(), edge.ravel())
    np.minimum.at(h, np.roll(facets, 1, axis=1).ravel(), edge.ravel())
    return h[nodes]


def node_match(mesh1, set1, mesh2, set2, tol=None) -> _Match:
    """Try the node-to-node match; the outcome as data (``error`` None on success)."""
    n1, n2 = mesh1.nodes(set1), mesh2.nodes(set2)
    x1, x2 = mesh1.points[n1], mesh2.points[n2]
    h1 = _local_size(mesh1, mesh1.facets(set1), n1)
    h2 = _local_size(mesh2, mesh2.facets(set2), n2)
    dist12, j = cKDTree(x2).query(x1)
    dist21, i = cKDTree(x1).query(x2)
    lim1 = NODE_MATCH_FRACTION * np.minimum(h1, h2[j])
    lim2 = NODE_MATCH_FRACTION * np.minimum(h2, h1[i])
    if tol is not None:
        bound = float(min(lim1.min(), lim2.min()))
        if tol > bound:
            return _Match(None, None, "tol", (tol, bound / NODE_MATCH_FRACTION))
        lim1, lim2 = np.minimum(lim1, tol), np.minimum(lim2, tol)
    bad1 = np.flatnonzero(dist12 > lim1)
    bad2 = np.flatnonzero(dist21 > lim2)
    if bad1.size or bad2.size:
        return _Match(None, None, "unmatched",
                      (bad1, bad2, x1, x2, n1, n2, dist12, dist21, tol))
    if len(np.unique(j)) != len(j):
        return _Match(None, None, "duplicate")
    order = np.lexsort(x1.T[::-1])
    return _Match(n1[order], n2[j[order]])


def local_frames(normals: np.ndarray) -> np.ndarray:
    """Orthonormal frames with the unit normal last: ``(t, n)`` in 2D with t = n rotated
    by -90 degrees (n = +y gives t = +x); ``(t1, t2, n)`` in 3D with t1 the projection of
    +x (of +z when n is nearly along x) and t2 = t1 x n (n = +y gives t1 = +x, t2 = +z)."""
    n = normals / np.linalg.norm(normals, axis=1, keepdims=True)
    if n.shape[1] == 2:
        t = np.stack([n[:, 1], -n[:, 0]], axis=1)
        return np.stack([t, n], axis=1)
    ref = np.where(np.abs(n[:, :1]) > 0.9, [[0.0, 0.0, 1.0]], [[1.0, 0.0, 0.0]])
    t1 = ref - np.einsum("ij,ij->i", ref, n)[:, None] * n
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(t1, n)
    return np.stack([t1, t2, n], axis=1)


def pair_interface(model, interface=None) -> Pairing:
    """The contact points of ``interface`` (default: ``model.interface``): node pairs or
    the mortar coupling (``Interface.coupling``), with their local frames. Several
    interfaces: :func:`qsma.model.pairing.make_pairing`."""
    itf = model.interface if interface is None else interface
    b1, b2 = model.body(itf.body1), model.body(itf.body2)
    facets1 = b1.mesh.facets(itf.set1)
    facets2 = b2.mesh.facets(itf.set2)
    _check_boundary(b1.mesh, facets1, b1.name, itf.set1)
    if itf.coupling != "node":
        _check_boundary(b2.mesh, facets2, b2.name, itf.set2)
    if itf.coupling == "mortar":
        return mortar_pairing(model, itf)
    match = node_match(b1.mesh, itf.set1, b2.mesh, itf.set2, itf.tol)
    if match.error is not None:
        if itf.coupling == "auto" and match.error != "tol":
            return mortar_pairing(model, itf)
        raise InputError(match.message(itf.set1, itf.set2, (b1.name, b2.name)))
    nodes1, nodes2 = match.nodes1, match.nodes2
    _warn_quad8(itf, b1, b2)
    weighted = facet_normals(b1.mesh, facets1)          # outward normal x facet area
    nvf = facets1.shape[1]
    normal_sum = np.zeros((b1.mesh.n_nodes, b1.dim))
    np.add.at(normal_sum, facets1.ravel(), np.repeat(weighted / nvf, nvf, axis=0))
    area = np.zeros(b1.mesh.n_nodes)
    if b1.mesh.facet_type in ("line", "triangle", "quad"):     # equal shares (as before)
        np.add.at(area, facets1.ravel(), np.repeat(np.linalg.norm(weighted, axis=1) / nvf,
                                                   nvf))
    else:                        # quadratic facets: positive (HRZ) tributary weights
        np.add.at(area, facets1.ravel(),
                  facet_node_weights(b1.mesh.points, facets1, b1.mesh.facet_type).ravel())
    _check_opposed(b2, facets2, nodes2, normal_sum[nodes1], itf)
    planes = _clamped_axes(b1, nodes1) & _clamped_axes(b2, nodes2)
    frames = local_frames(on_symmetry_planes(normal_sum[nodes1], b1.mesh.points[nodes1],
                                             planes))
    return Pairing(nodes1, nodes2, b1.mesh.points[nodes1].copy(), frames, area[nodes1])


#: A node on a plane clamped on both sides has its normal taken in that plane when the
#: normal's lean out of the plane is at most this many times the turn of the normals
#: to the nearest node off the plane: on a smooth surface cut by a symmetry plane the
#: lean of the one-sided average is about that turn (the two are equal on a uniform
#: mesh, twice as large where the facets shrink away from the plane), on a face that
#: is inclined to the clamp the turn is nothing and the normal is kept.
SYMMETRY_LEAN = 2.5
#: Distance, relative to the interface's extent, within which a node lies on a plane.
PLANE_RTOL = 1e-6


def on_symmetry_planes(normals, points, planes):
    """``normals`` (at ``points``) with their component along each axis in ``planes``
    ((n, dim) mask: the node is clamped along that axis on both sides, the plane normal
    to the axis cuts the contact face) removed where it is the lean of a one-sided
    average (:data:`SYMMETRY_LEAN`). On a symmetry plane the whole structure's normal
    lies in the plane; the cut model averages the facets of one side only, and its
    normal would lean out of the plane, making the clamp oblique to the contact frame
    (docs/theory.md section 13)."""
    n = np.array(normals, dtype=float)
    if not planes.any():
        return n
    unit = n / np.linalg.norm(n, axis=1, keepdims=True)
    tol = PLANE_RTOL * max(float(np.ptp(points, axis=0).max(initial=0.0)), 1e-300)
    for i, c in zip(*np.nonzero(planes & (unit != 0.0))):
        off = np.flatnonzero(np.abs(points[:, c] - points[i, c]) > tol)
        if not off.size:
            continue
        j = off[np.argmin(np.linalg.norm(points[off] - points[i], axis=1))]
        turn = np.linalg.norm(unit[j] - unit[i])
        if abs(unit[i, c]) <= SYMMETRY_LEAN * turn:
            n[i, c] = 0.0
    return n


def _clamped_axes(body, nodes) -> np.ndarray:
    """(len(nodes), dim) mask of the axes a clamp of ``body`` holds at ``nodes``."""
    dim = body.dim
    held = np.zeros(body.n_dofs, dtype=bool)
    held[body.clamped_dofs()] = True
    return held[(dim * np.asarray(nodes)[:, None] + np.arange(dim)).ravel()].reshape(-1, dim)


def symmetry_axes(slave, snodes, master, mnodes, projection=None) -> np.ndarray:
    """(len(snodes), dim) mask of the axes along which a mortar slave node and the master
    surface at its place are clamped (a symmetry plane through both bodies): the slave
    node is clamped along axis c, and the master's nodes on the plane through it normal
    to c (those of its row of ``projection`` if given, else any interface node; at least
    one) are all clamped along c (docs/theory.md section 13)."""
    cs = _clamped_axes(slave, snodes)
    out = np.zeros_like(cs)
    if not cs.any():
        return out
    cm = _clamped_axes(master, mnodes)
    xs, xm = slave.mesh.points[snodes], master.mesh.points[mnodes]
    tol = PLANE_RTOL * max(float(np.ptp(xs, axis=0).max(initial=0.0)), 1e-300)
    N = None if projection is None else sp.csr_matrix(projection)
    for i, c in zip(*np.nonzero(cs)):
        near = np.arange(len(mnodes)) if N is None else N.indices[N.indptr[i]:N.indptr[i + 1]]
        on = near[np.abs(xm[near, c] - xs[i, c]) <= tol]
        out[i, c] = bool(len(on) and cm[on, c].all())
    return out


def _check_opposed(body2, facets2, nodes2, normals1, itf):
    """Node-to-node: the outward normals of the two sides must face each other at every
    pair (a facet set on the wrong face of a body, or a body inside the other, points
    them the same way)."""
    weighted = facet_normals(body2.mesh, facets2)
    nvf = facets2.shape[1]
    n2 = np.zeros((body2.mesh.n_nodes, body2.dim))
    np.add.at(n2, facets2.ravel(), np.repeat(weighted / nvf, nvf, axis=0))
    n2 = n2[nodes2]
    cos = np.einsum("ij,ij->i", normals1, n2) / (np.linalg.norm(normals1, axis=1)
                                                 * np.linalg.norm(n2, axis=1))
    bad = np.flatnonzero(cos > 0)
    if bad.size:
        k = bad[0]
        raise InputError(
            f"interface {itf.label}: the outward normals of the two surfaces point the "
            f"same way at {len(bad)} of {len(cos)} node pair(s), e.g. node {nodes2[k]} of "
            f"body {itf.body2!r} at {np.round(body2.mesh.points[nodes2[k]], 12).tolist()}, "
            f"so they cannot be in contact (inverted normals). Fix: name the faces that "
            f"touch each other (check the facet sets {itf.set1!r} and {itf.set2!r}), and "
            f"check that the bodies do not overlap")


def mortar_pairing(model, interface=None) -> Pairing:
    """The mortar coupling of ``interface`` (default ``model.interface``;
    :mod:`qsma.model.coupling`).

    The slave is ``Interface.slave`` if given, else the side with more interface nodes
    (body 1 on a tie); if the master does not cover it, the other side is tried.
    """
    itf = model.interface if interface is None else interface
    sides = [(1, model.body(itf.body1), itf.set1), (2, model.body(itf.body2), itf.set2)]
    if itf.slave is not None:
        order = [0, 1] if itf.slave == itf.body1 else [1, 0]
        candidates = [order]
    else:
        n = [len(b.mesh.nodes(s)) for _, b, s in sides]
        first = [0, 1] if n[0] >= n[1] else [1, 0]
        candidates = [first, first[::-1]]
    error, best = None, None
    for s, m in candidates:
        k, sb, ss = sides[s]
        _, mb, ms = sides[m]
        try:
            op = mortar_operator(sb.mesh, sb.mesh.facets(ss), mb.mesh, mb.mesh.facets(ms),
                                 names=(sb.name, ss, mb.name, ms))
        except InputError as exc:
            error = error or exc
            continue
        if best is None or op.unmatched_fraction < best[0].unmatched_fraction:
            best = (op, k, sb, ss)
        if op.fully_covered:
            break
    if best is None:
        raise error
    op, k, sb, ss = best
    if not op.fully_covered:
        _warn_partial(itf, op, sb.name, ss)
    normals = op.normals if k == 1 else -op.normals            # from body 1 into body 2
    mb = model.body(itf.body2 if k == 1 else itf.body1)
    normals = on_symmetry_planes(normals, sb.mesh.points[op.slave_nodes],
                                 symmetry_axes(sb, op.slave_nodes, mb, op.master_nodes, op.P))
    nodes = (op.slave_nodes, op.master_nodes) if k == 1 else (op.master_nodes,
                                                              op.slave_nodes)
    return Pairing(nodes[0], nodes[1], sb.mesh.points[op.slave_nodes].copy(),
                   local_frames(normals), op.area, "mortar", k, op.P, op.gap, op.basis)


def _warn_partial(itf, op, body, name):
    """Name the part of the slave surface that faces no master facet."""
    from ..errors import PartialCoverageWarning
    warnings.warn(PartialCoverageWarning(
        f"interface {itf.label}: {100 * op.unmatched_fraction:.3g} % of the slave surface "
        f"(body {body!r} set {name!r}: {op.unmatched_area:.4g} of its area "
        f"{op.slave_area:.4g}) faces no master facet and is left out of the contact (the "
        f"edges of holes or of offset surfaces meshed apart); if the two surfaces should "
        f"cover each other, check their facet sets"), stacklevel=4)


def _warn_quad8(itf, *bodies):
    """Say so when an interface lies on quad8 facets, whose corner pairs cannot carry
    their (negative) consistent share of a uniform pressure."""
    on = [b.name for b in bodies if b.mesh.facet_type == "quad8"]
    if on:
        warnings.warn(QuadraticFacetWarning(
            f"interface {itf.label}: body {on[0]!r} meets it with quad8 facets "
            f"(hexahedron20 cells); the corner pairs of such facets open under a uniform "
            f"pressure and the midside pairs carry the load. Prefer hexahedron27 or "
            f"incompatible-mode hexahedra (C3D8I) at contact surfaces, or set coupling = "
            f"\"mortar\" on the interface (its dual basis gives every contact point a "
            f"positive share of a pressure)"),
        stacklevel=4)                        # the caller of make_pairing


def _check_boundary(mesh, facets, body, name):
    """Every facet of the interface set must be a boundary facet of its body."""
    inner = facets[facet_index(mesh).find(facets) < 0].tolist()
    if inner:
        raise InputError(f"body {body!r}: facet set {name!r} contains {len(inner)} facet(s) "
                         f"not on the boundary of this body, e.g. nodes {inner[0]}; is the "
                         f"interface set defined on the wrong body?")


def check_interfaces(model):
    """Refuse a model whose interfaces cannot form one contact problem: an interface
    listed twice, two interfaces sharing facets of one body (overlapping surfaces), a
    body in no interface (it would float free of the others)."""
    itfs = model.interface_list
    seen = {}
    for itf in itfs:
        key = frozenset(((itf.body1, itf.set1), (itf.body2, itf.set2)))
        if key in seen:
            raise InputError(f"interface {itf.label} is listed twice (as "
                             f"{seen[key].label}). Fix: remove one of the two entries; "
                             f"give each pair of touching surfaces once")
        seen[key] = itf
    _check_overlaps(model, itfs)
    used = {b for itf in itfs for b in (itf.body1, itf.body2)}
    lonely = [b.name for b in model.bodies if b.name not in used]
    if lonely:
        raise InputError(f"body {lonely[0]!r} belongs to no interface: it is not connected "
                         f"to the other bodies. Fix: add an interface joining it to another "
                         f"body (interfaces: {[i.label for i in itfs]}), or remove it from "
                         f"the model")


def _check_overlaps(model, itfs):
    """Two interfaces may not use the same facet of a body: the surface would carry two
    contact problems (one of them would be the wrong pair of bodies)."""
    sides = [(itf, body, name) for itf in itfs
             for body, name in ((itf.body1, itf.set1), (itf.body2, itf.set2))]
    for i, (itf_a, body_a, set_a) in enumerate(sides):
        for itf_b, body_b, set_b in sides[i + 1:]:
            if body_a != body_b or itf_a is itf_b:
                continue
            mesh = model.body(body_a).mesh
            if set_a not in mesh.facet_sets or set_b not in mesh.facet_sets:
                continue                       # the pairing names the unknown set
            fa = {tuple(sorted(f)) for f in mesh.facets(set_a).tolist()}
            common = [f for f in mesh.facets(set_b).tolist() if tuple(sorted(f)) in fa]
            if common:
                raise InputError(
                    f"interfaces {itf_a.label} and {itf_b.label} overlap: facet sets "
                    f"{set_a!r} and {set_b!r} of body {body_a!r} share {len(common)} "
                    f"facet(s), e.g. nodes {common[0]}. Fix: a surface belongs to one "
                    f"interface; split the facet sets so that each touches one other body")


# ``make_pairing`` of several interfaces moved to :mod:`qsma.model.pairing`; the old path
# keeps working for one release, with a DeprecationWarning.
forward(__name__, names={"make_pairing": "qsma.model.pairing"})
