"""Bolts as finite element quantities (docs/theory.md section 11): the unit-tension load
on the washer areas of both bodies (consistent nodal forces of a uniform traction), the
pretension load, the locked bolt's stiffness ``k c c^T`` and its elongation
``ell = sum_j c_j . u_j`` as a functional of a reduced model. A meshed bolt cut by a
pretension section (:class:`qsma.model.SectionBolt`) is the same bolt with ``c`` and
``k`` from its mesh, on its body cut by the section (:mod:`qsma.fe.sections`)."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from .assembly import pressure_load
from .sections import section_terms, with_cut_bodies

__all__ = ["washer_weights", "bolt_vectors", "bolt_loads", "bolt_stiffness",
           "with_bolt_loads", "bolt_functionals", "LockedBolt", "locked_bolts"]


@dataclass(frozen=True)
class LockedBolt:
    """What locking needs of a bolt (:func:`qsma.reduction.pretension.lock`): its
    pattern, pretension ``N0`` and locked stiffness ``k``."""

    name: str
    pattern: str
    pretension: float
    stiffness: float


def locked_bolts(model) -> tuple:
    """A :class:`LockedBolt` per bolt of ``model``: a meshed bolt's stiffness is its
    section's ``gamma`` (:mod:`qsma.fe.sections`)."""
    return tuple(LockedBolt(b.name, b.pattern, b.pretension, _stiffness(model, b))
                 for b in model.bolts)


def _stiffness(model, bolt) -> float:
    if hasattr(bolt, "section"):
        return section_terms(model.body(bolt.body), bolt).gamma
    return bolt.stiffness


def washer_weights(body, set_name):
    """``(nodes, weights, outward normal, centroid)`` of a washer facet set: weights
    of the consistent nodal forces of a uniform traction (sum 1)."""
    f = pressure_load(body, set_name, 1.0).reshape(-1, body.dim)   # = -int N n
    nodes = np.unique(body.mesh.facet_sets[set_name])   # not the round-off elsewhere
    total = f[nodes].sum(axis=0)
    area = float(np.linalg.norm(total))
    if area == 0:
        raise InputError(f"body {body.name!r}: washer set {set_name!r} has no area")
    normal = -total / area
    w = (f[nodes] @ total) / area ** 2          # share of the resultant per node
    w /= w.sum()
    centroid = w @ body.mesh.points[nodes]
    return nodes, w, normal, centroid


def bolt_vectors(model, bolt):
    """Per body of ``model``, the full vector ``c_j`` with ``ell = sum_j c_j . u_j``
    (zero for a body the bolt does not touch), after checking the geometry."""
    if hasattr(bolt, "section"):                   # a meshed bolt: c = v / gamma
        out = [np.zeros(b.n_dofs) for b in model.bodies]
        out[model.body_index(bolt.body)] = section_terms(model.body(bolt.body), bolt).c
        return out
    ends = []
    for body_name, set_name in ((bolt.body_a, bolt.set_a), (bolt.body_b, bolt.set_b)):
        body = model.body(body_name)
        if set_name not in body.mesh.facet_sets:
            raise InputError(f"bolt {bolt.name!r}: body {body_name!r} has no facet set "
                             f"{set_name!r}; facet sets: {sorted(body.mesh.facet_sets)}")
        ends.append((body,) + washer_weights(body, set_name))
    axis = ends[1][4] - ends[0][4]
    length = float(np.linalg.norm(axis))
    if length == 0:
        raise InputError(f"bolt {bolt.name!r}: the two washer centroids coincide")
    n = axis / length
    for (body, _, _, normal, _), sign, other in ((ends[0], 1, bolt.body_b),
                                                   (ends[1], -1, bolt.body_a)):
        if sign * float(normal @ n) > -0.5:
            raise InputError(
                f"bolt {bolt.name!r}: the washer face on body {body.name!r} faces towards "
                f"body {other!r} (outward normal {np.round(normal, 3).tolist()}, bolt axis "
                f"{np.round(sign * n, 3).tolist()}): the pretension would pull the bodies "
                f"apart. Give the outer (head or nut) faces as washer sets")
    out = [np.zeros(b.n_dofs) for b in model.bodies]
    for (body, nodes, w, _, _), sign in ((ends[0], -1.0), (ends[1], 1.0)):
        k = model.body_index(body.name)
        dim = body.dim
        for c in range(dim):
            out[k][dim * nodes + c] += sign * w * n[c]
    return out


def bolt_loads(model):
    """``{pattern: [per-body full load]}`` of unit tension per bolt, and the per-body
    pretension load ``sum N0 f_{N=1}`` to add to the 'preload' pattern."""
    units, pre = {}, [np.zeros(b.n_dofs) for b in model.bodies]
    for bolt in model.bolts:
        c = bolt_vectors(model, bolt)
        units[bolt.pattern] = [-cj for cj in c]
        for p, cj in zip(pre, c):
            p -= bolt.pretension * cj
    return units, pre


def bolt_stiffness(model) -> sp.csr_matrix:
    """``sum_bolts k c c^T`` over the stacked DOFs of all bodies (the locked bolts)."""
    n = model.n_dofs
    K = sp.csr_matrix((n, n))
    for bolt in model.bolts:
        c = sp.csr_matrix(np.concatenate(bolt_vectors(model, bolt))[None, :])
        K = K + _stiffness(model, bolt) * (c.T @ c)
    return K.tocsr()


def with_bolt_loads(model, assembled):
    """The assembled bodies with the pretensions added to 'preload' and one
    unit-tension pattern per bolt; a body cut by pretension sections with its cut
    stiffness (:func:`qsma.fe.sections.with_cut_bodies`)."""
    units, pre = bolt_loads(model)
    out = []
    for k, a in enumerate(with_cut_bodies(model, assembled)):
        loads = dict(a.loads)
        loads["preload"] = loads.get("preload", np.zeros(a.n_dofs)) + pre[k]
        for name, per_body in units.items():
            loads[name] = per_body[k]
        out.append(replace(a, loads=loads))
    return out


def bolt_functionals(model, reduced, order):
    """``reduced`` with each bolt's elongation as the functional named by its pattern
    (``order``: model indices of the reduced model's bodies)."""
    defs = {}
    for bolt in model.bolts:
        c = bolt_vectors(model, bolt)
        defs[bolt.pattern] = tuple(c[k] for k in order)
    return reduced.with_functionals(defs)
