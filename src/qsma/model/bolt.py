r"""Bolts: an axial elastic member between two washer areas, pretensioned then locked
(docs/theory.md section 11).

Each end of a bolt is a reference point tied to a washer (bearing) facet set of one
body by a distributing coupling (RBE3-like): with ``w_i`` the weights of the
consistent nodal forces of a uniform traction on the washer (``sum w_i = 1``) and
``n`` the bolt axis from end a to end b, the reference point moves by
``ubar = sum_i w_i u_i`` and a force ``F`` at it is spread as ``w_i F`` over the
washer nodes. The bolt elongation and the unit-tension load are

.. math:: \ell = n \cdot (\bar u_b - \bar u_a) = c^T u, \qquad
          f_{N=1} = -c, \qquad c = [-b_a;\; b_b], \quad b_j = w \otimes n .

**Preload** (force controlled, like a pretension section in its first step): the
pretension ``N0`` is part of the 'preload' load pattern, ``N0 f_{N=1}``.
**Locked** afterwards: the bolt is a spring of stiffness ``k`` (``EA / L``) at the
length the preload left, ``N = N0 + k (\ell - \ell_{pre})``; the tied modes include
its stiffness ``k c c^T``.
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
import scipy.sparse as sp

from ..errors import InputError


@dataclass(frozen=True)
class Bolt:
    """A pretensioned bolt between the washer facet set ``set_a`` of ``body_a`` (head)
    and ``set_b`` of ``body_b`` (nut).

    Parameters
    ----------
    name : str
    body_a, set_a, body_b, set_b : the two ends (different bodies)
    pretension : float
        Bolt tension N0 after tightening, N (N per metre of depth in 2D), > 0.
    stiffness : float
        Axial stiffness ``E A / L`` of the locked bolt, N/m (N/m per metre in 2D), > 0.
    """

    name: str
    body_a: str
    set_a: str
    body_b: str
    set_b: str
    pretension: float
    stiffness: float

    def __post_init__(self):
        for field_name in ("pretension", "stiffness"):
            v = getattr(self, field_name)
            if (not isinstance(v, (int, float, np.integer, np.floating))
                    or isinstance(v, bool) or not math.isfinite(v)):
                raise InputError(f"bolt {self.name!r}: {field_name} must be a finite "
                                 f"number, got {v!r}")
            object.__setattr__(self, field_name, float(v))
        if self.pretension <= 0:
            raise InputError(f"bolt {self.name!r}: pretension must be > 0 (the tension "
                             f"that clamps the plates, N), got {self.pretension:g}; a bolt "
                             f"cannot push the plates apart: give the magnitude")
        if self.stiffness <= 0:
            raise InputError(f"bolt {self.name!r}: stiffness must be > 0 (E A / L of the "
                             f"shank, N/m), got {self.stiffness:g}")
        if self.body_a == self.body_b:
            raise InputError(f"bolt {self.name!r}: both ends are on body {self.body_a!r}; "
                             f"a bolt joins two bodies: put set_b on the other body")

    @property
    def pattern(self) -> str:
        """Name of its unit-tension load pattern."""
        return f"bolt:{self.name}"


def washer_weights(body, set_name):
    """``(nodes, weights, outward normal, centroid)`` of a washer facet set: weights
    of the consistent nodal forces of a uniform traction (sum 1)."""
    from ..fe.assembly import pressure_load
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
        K = K + bolt.stiffness * (c.T @ c)
    return K.tocsr()


def with_bolt_loads(model, assembled):
    """The assembled bodies with the pretensions added to 'preload' and one
    unit-tension pattern per bolt."""
    from dataclasses import replace
    units, pre = bolt_loads(model)
    out = []
    for k, a in enumerate(assembled):
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
