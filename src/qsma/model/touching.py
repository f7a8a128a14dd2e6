"""Contact interfaces whose facet sets are found, not named: the faces where two bodies
touch (:func:`qsma.mesh.touching.touching_facets`), as Abaqus' general contact finds
them. A TOML interface with ``touching = true`` (and no ``set1``/``set2``) and a deck's
``*CONTACT INCLUSIONS, ALL EXTERIOR`` use it."""
from __future__ import annotations

from dataclasses import replace

from ..errors import InputError
from ..mesh.touching import TOUCH_ANGLE, TOUCH_GAP, touching_facets


def touching_set_name(other: str) -> str:
    """Name of the facet set of one body where it touches body ``other``."""
    return f"touching:{other}"


def touching_sets(a, b) -> tuple:
    """``(a', b', set of a', set of b')``: bodies ``a`` and ``b`` with a facet set each
    of the boundary facets where they touch the other. :class:`InputError` when they
    do not touch."""
    fa, fb = touching_facets(a.mesh, b.mesh)
    if not len(fa) or not len(fb):
        raise InputError(
            f"bodies {a.name!r} and {b.name!r} do not touch: no boundary facet of one lies "
            f"on a boundary facet of the other facing it (within {TOUCH_GAP:g} of the "
            f"facet size, normals opposed within {TOUCH_ANGLE:g} degrees). Name the "
            f"contact faces (set1, set2), or check the bodies' placement and units")
    sa, sb = touching_set_name(b.name), touching_set_name(a.name)
    return (replace(a, mesh=a.mesh.with_sets(facet_sets={sa: fa})),
            replace(b, mesh=b.mesh.with_sets(facet_sets={sb: fb})), sa, sb)


def with_touching_sets(bodies, pairs) -> list:
    """``bodies`` (a list) with the touching facet sets of each ``(body1, body2)`` name
    pair added, in place; returns ``[(set1, set2)]`` per pair."""
    index = {b.name: k for k, b in enumerate(bodies)}
    out = []
    for n1, n2 in pairs:
        for n in (n1, n2):
            if n not in index:
                raise InputError(f"interface with touching = true: no body named {n!r}; "
                                 f"bodies: {sorted(index)}")
        if n1 == n2:
            raise InputError(f"interface with touching = true: body1 and body2 are both "
                             f"{n1!r}; an interface joins two bodies")
        a, b, s1, s2 = touching_sets(bodies[index[n1]], bodies[index[n2]])
        bodies[index[n1]], bodies[index[n2]] = a, b
        out.append((s1, s2))
    return out
