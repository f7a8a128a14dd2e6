r"""Grounded springs: a body's node or facet set tied to the ground by linear springs
(docs/theory.md section 10).

A :class:`Spring` gives the total stiffness ``k_c`` of the set in each global
direction ``c``; node ``i`` of the set gets the share ``s_i`` (``sum s_i = 1``), so
the springs add

.. math:: K_s = \sum_i \sum_c s_i\, k_c\, e_{i,c} e_{i,c}^T

to the body's stiffness matrix, a diagonal term (``e_{i,c}`` the unit vector of DOF
``dim i + c``). A rigid translation ``t`` of the set is resisted by the force
``-k_c t_c``: the spring's stiffness is the set's. The shares are

* a facet set: the tributary areas (:func:`qsma.mesh.facets.facet_node_weights`,
  the consistent shares ``int N_i dA`` of linear facets) divided by the set's area
  ``A``: the springs act as an elastic foundation of stiffness ``k_c / A`` per area;
* a node set: equal shares ``1 / n``.

The springs are part of the stiffness everywhere (preload, condensation, tied
modes, recovery). A direction with ``k_c > 0`` counts as held in the check of
rigid-body freedom (:func:`qsma.reduction.rigid.free_motions`), so a body on springs is no
longer held "only by the joint"; the limit ``k -> 0`` of such a body is the body held
only by the joint (tests/test_springs.py).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
import scipy.sparse as sp

from ..errors import InputError
from ..mesh.facets import facet_node_weights


@dataclass(frozen=True)
class Spring:
    """Springs from the nodes of set ``set`` to the ground.

    Parameters
    ----------
    set : str
        A node set (equal shares) or a facet set (shares by tributary area) of the
        body.
    stiffness : tuple of float
        Total stiffness of the set in x, y (and z), N/m (N/m per metre of depth in
        2D), each finite and >= 0; 0 leaves that direction free.
    """

    set: str
    stiffness: tuple

    def __post_init__(self):
        k = self.stiffness
        if isinstance(k, (str, bytes)) or not hasattr(k, "__len__"):
            raise InputError(f"spring on {self.set!r}: stiffness must be a list of one "
                             f"value per direction (N/m), got {k!r}")
        for v in k:
            if (not isinstance(v, (int, float, np.integer, np.floating))
                    or isinstance(v, bool) or not math.isfinite(v) or v < 0):
                raise InputError(f"spring on {self.set!r}: stiffness must be finite "
                                 f"numbers >= 0 (N/m, one per direction; 0 leaves the "
                                 f"direction free), got {list(k)!r}")
        object.__setattr__(self, "stiffness", tuple(float(v) for v in k))


def check_springs(body) -> None:
    """Each spring of ``body`` names a set of it and gives one stiffness per
    direction."""
    names = body.mesh.set_names()
    for s in body.springs:
        if not isinstance(s, Spring):
            raise InputError(f"body {body.name!r}: springs must be Spring objects, got "
                             f"{s!r}")
        if s.set not in names:
            raise InputError(f"body {body.name!r}: spring on unknown set {s.set!r}; "
                             f"available sets: {names}")
        if len(s.stiffness) != body.dim:
            raise InputError(f"body {body.name!r}: spring on {s.set!r} needs "
                             f"{body.dim} stiffness values (x, y{', z' if body.dim == 3 else ''}), "
                             f"got {len(s.stiffness)}")
        spring_shares(body, s)             # an empty set or one without area: refused


def spring_shares(body, spring) -> tuple:
    """``(nodes, shares)`` of a spring's set (:func:`set_shares`)."""
    return set_shares(body, spring.set, "spring")


def set_shares(body, name, what) -> tuple:
    """``(nodes, shares)`` of set ``name`` of ``body``: tributary areas of a facet set,
    equal shares of a node set (a set that is both: its facets); shares sum to 1.
    ``what`` (a spring, a point mass) names the user of the set in the messages."""
    if name in body.mesh.facet_sets:
        facets = body.mesh.facet_sets[name]
        with np.errstate(invalid="ignore", divide="ignore"):   # degenerate: refused below
            w = facet_node_weights(body.mesh.points, facets, body.mesh.facet_type)
        area = np.bincount(facets.ravel(), w.ravel(), minlength=body.mesh.n_nodes)
        nodes = np.unique(facets)
        total = area[nodes].sum()
        if not (np.isfinite(total) and total > 0):
            raise InputError(f"body {body.name!r}: {what} on {name!r}: the facet set "
                             f"has no area (empty or degenerate facets); name a set of "
                             f"facets with an area, or a node set")
        return nodes, area[nodes] / total
    nodes = np.unique(body.mesh.nodes(name))
    if len(nodes) == 0:
        raise InputError(f"body {body.name!r}: {what} on {name!r}: the set has no "
                         f"nodes; name a set with nodes")
    return nodes, np.full(len(nodes), 1.0 / len(nodes))


def spring_matrix(body) -> sp.csr_matrix:
    """The diagonal stiffness ``K_s`` of the body's springs (its DOF order)."""
    diag = np.zeros(body.n_dofs)
    for s in body.springs:
        nodes, shares = spring_shares(body, s)
        for c, k in enumerate(s.stiffness):
            np.add.at(diag, body.dim * nodes + c, k * shares)
    return sp.diags(diag, format="csr")


def held_dofs(body) -> np.ndarray:
    """The DOFs a spring of ``body`` holds (stiffness > 0), sorted."""
    out = [body.dim * spring_shares(body, s)[0] + c
           for s in body.springs for c, k in enumerate(s.stiffness) if k > 0]
    return np.unique(np.concatenate(out)) if out else np.zeros(0, dtype=np.int64)
