"""The checks of a mortar coupling's geometry (:mod:`qsma.model.coupling`): how far apart
or into each other the two surfaces may be, how much of the slave surface the master must
cover, and the refusals, naming the bodies, sets and the fix, of surfaces that do not
face each other."""
from __future__ import annotations

import numpy as np

from ..errors import InputError

#: A slave node counts as covered when the master covers every slave facet around it
#: to all but this fraction of the facet's area: six orders above double round-off of
#: the clipped areas, far below any intended overhang (half an element is 0.5).
COVERAGE_TOL = 1e-6

#: A slave facet covered by the master on less than this fraction of its area is left
#: out of the coupling (its covered sliver counted as unmatched): the dual basis is
#: built on the covered part of each facet, and its mass matrix's condition grows like
#: 1 / fraction^2 on bilinear facets (1e4 here).
MIN_FACET_COVER = 1e-2

#: Largest overlap (interpenetration) of the two surfaces, as a fraction of the local
#: slave element size, accepted as an initial overclosure: a chord of length h on a
#: radius R deviates from the arc by h^2 / (8 R), below 0.1 h for any mesh with
#: h < 0.8 R. Deeper the surfaces overlap: refused, never snapped.
GAP_FRACTION = 0.1

#: Largest initial gap (surfaces apart), as a fraction of the local slave element size:
#: the gap is the initial gap g0 of the contact problem, which the preload closes or
#: leaves open (a punch on a block touches along a line, and its surface lies apart
#: from the block elsewhere). The points of the two sides are matched once, along the
#: slave normal in the undeformed mesh (small displacements): where the normals differ
#: by an angle theta a gap g shifts the matched point by g tan(theta), below 0.1 h at
#: g = 0.5 h and theta < 11 degrees. A facet set on the wrong face of the other body is
#: at least one element (the body's thickness) away, so farther than half an element
#: the surfaces are taken as not facing each other: refused, never snapped.
GAP_APART_FRACTION = 0.5


def check_gap(gap, x, size, names):
    """Refuse surfaces farther apart than :data:`GAP_APART_FRACTION` (or overlapping more
    than :data:`GAP_FRACTION`) of the local element ``size`` at some point, named at the
    first point of the worst gap (relative to its bound; slave facet order, ties to
    round-off)."""
    bound = np.where(gap > 0, GAP_APART_FRACTION, GAP_FRACTION)
    ratio = np.abs(gap) / size
    sbody, sset, mbody, mset = names
    if not np.all(np.isfinite(ratio)):
        k = int(np.flatnonzero(~np.isfinite(ratio))[0])
        raise InputError(
            f"interface body {sbody!r} set {sset!r} / body {mbody!r} set {mset!r}: the gap "
            f"between the surfaces is not finite at {np.round(x[k], 12).tolist()} (a "
            f"degenerate facet: zero area or collapsed edges). Fix: check the mesh of the "
            f"interface surfaces there.")
    excess = ratio / bound
    if not len(ratio) or excess.max() <= 1.0:
        return
    k = int(np.flatnonzero(excess >= excess.max() * (1.0 - 1e-12))[0])
    if gap[k] > 0:
        raise InputError(
            f"interface body {sbody!r} set {sset!r} / body {mbody!r} set {mset!r}: the "
            f"two surfaces are {gap[k]:.3e} m apart at {np.round(x[k], 12).tolist()}, "
            f"{ratio[k]:.2f} of the local element size; initial gaps up to "
            f"{GAP_APART_FRACTION} of an element are taken as gaps the preload may close, "
            f"farther apart the surfaces do not face each other (a set on the wrong face, "
            f"or bodies placed apart). Fix: check that the sets name the facing surfaces, "
            f"restrict the slave set to the part of the surface that can come into contact, "
            f"or move the bodies so that the surfaces touch or nearly touch.")
    raise InputError(
        f"interface body {sbody!r} set {sset!r} / body {mbody!r} set {mset!r}: the two "
        f"surfaces overlap (interpenetrate) by {-gap[k]:.3e} m at "
        f"{np.round(x[k], 12).tolist()}, {ratio[k]:.2f} of the local element size (at "
        f"most {GAP_FRACTION} is taken as an initial overclosure). Fix: move the bodies "
        f"so that the interface surfaces touch in the undeformed configuration, or check "
        f"that the sets name the facing surfaces.")


def refuse_partly_covered(xs, sf, covered, kind, names):
    """Refuse a quadratic slave surface whose every facet the master covers only in part,
    too little for the facet's mixed shape functions (``weak_shares``): nothing is left
    to couple, though the surfaces face each other."""
    sbody, sset, mbody, mset = names
    k = int(np.argmax(covered))
    raise InputError(
        f"interface body {sbody!r} set {sset!r} (slave) / body {mbody!r} set {mset!r} "
        f"(master): every one of the {len(sf)} {kind} slave facet(s) is only partly "
        f"covered by the master (at most {100 * covered[k]:.1f} %, the facet at "
        f"{np.round(xs[sf[k]].mean(axis=0), 12).tolist()}); on the covered part of a "
        f"quadratic facet the shape functions of the nodes outside integrate to almost "
        f"nothing, so the dual basis cannot be built there and no facet is left to couple. "
        f"Fix: make the other surface the slave (swap the surfaces of the *CONTACT PAIR "
        f"row, or Interface(slave=...) / 'slave' in TOML), so that the slave is the one "
        f"the other covers, or mesh the slave surface so that its facets lie within the "
        f"master.")


def check_coverage(xs, snodes, node_cover, names, same_way_nodes, any_covered):
    """Refuse surfaces that do not face each other: the uncovered slave nodes all face
    master facets whose normals point the same way, or no slave facet is covered."""
    sbody, sset, mbody, mset = names
    frac = node_cover[snodes]
    bad = snodes[frac < 1.0 - COVERAGE_TOL]
    if len(bad) == 0 or (any_covered and not np.isin(bad, same_way_nodes).all()):
        return
    if np.isin(bad, same_way_nodes).all():
        raise InputError(
            f"interface body {sbody!r} set {sset!r} / body {mbody!r} set {mset!r}: the "
            f"outward normals of the two surfaces point the same way where they meet "
            f"({len(bad)} slave node(s), e.g. node {bad[0]} at "
            f"{np.round(xs[bad[0]], 12).tolist()}), so they cannot be in contact (inverted "
            f"or mis-assigned surface). Fix: name the facet set on the face of each body "
            f"that touches the other body (outward normals opposed).")
    lines = [f"  node {k} at {np.round(xs[k], 12).tolist()}: an adjacent facet is "
             f"{100 * node_cover[k]:.1f} % covered" for k in bad[:8]]
    more = f"\n  ... and {len(bad) - 8} more" if len(bad) > 8 else ""
    raise InputError(
        f"interface body {sbody!r} set {sset!r} (slave) projects nowhere onto body "
        f"{mbody!r} set {mset!r} (master): no slave facet faces a master facet (at most "
        f"{100 * MIN_FACET_COVER:g} % of one is covered):\n" + "\n".join(lines) + more +
        "\nFix: check that the sets name the two surfaces that touch (outward normals "
        "opposed, within half an element of each other).")
