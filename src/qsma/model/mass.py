r"""Point masses: lumped masses on a body's node or facet set (bolt heads, nuts, washers,
sensors), added to the mass matrix.

A :class:`PointMass` of total mass ``m`` on a set gives node ``i`` of the set the share
``s_i`` (``sum s_i = 1``, the shares of :func:`qsma.model.spring.spring_shares`:
tributary areas of a facet set, equal shares of a node set), in every direction:

.. math:: M_p = \sum_i \sum_c s_i\, m\, e_{i,c} e_{i,c}^T ,

a diagonal term (``e_{i,c}`` the unit vector of DOF ``dim i + c``). A rigid
translation ``t`` of the set then carries the kinetic energy ``m |t'|^2 / 2``: the
set moves with the mass ``m`` in each direction. The rotary inertia of the part the
mass stands for is not modelled (its mass sits on the nodes of the set; the nodes'
spread gives some rotary inertia, ``sum s_i m |x_i - x_c|^2``, which need not be the
part's own).
"""
from __future__ import annotations

from dataclasses import dataclass
import math

import numpy as np
import scipy.sparse as sp

from ..errors import InputError


@dataclass(frozen=True)
class PointMass:
    """A lumped mass on the nodes of set ``set``.

    Parameters
    ----------
    set : str
        A node set (equal shares) or a facet set (shares by tributary area) of the
        body.
    mass : float
        Total mass, kg (kg per metre of depth in 2D), finite and > 0.
    """

    set: str
    mass: float

    def __post_init__(self):
        m = self.mass
        if (not isinstance(m, (int, float, np.integer, np.floating)) or isinstance(m, bool)
                or not math.isfinite(m) or m <= 0):
            raise InputError(f"point mass on {self.set!r}: mass must be a finite number > 0 "
                             f"(kg; kg per metre of depth in 2D), got {m!r}")
        object.__setattr__(self, "mass", float(m))


def check_masses(body) -> None:
    """Each point mass of ``body`` names a set of it with nodes (or area)."""
    from .spring import set_shares
    names = body.mesh.set_names()
    for pm in body.masses:
        if not isinstance(pm, PointMass):
            raise InputError(f"body {body.name!r}: masses must be PointMass objects, got "
                             f"{pm!r}")
        if pm.set not in names:
            raise InputError(f"body {body.name!r}: point mass on unknown set {pm.set!r}; "
                             f"available sets: {names}")
        set_shares(body, pm.set, "point mass")


def point_mass_matrix(body) -> sp.csr_matrix:
    """The diagonal mass ``M_p`` of the body's point masses (its DOF order)."""
    from .spring import set_shares
    diag = np.zeros(body.n_dofs)
    for pm in body.masses:
        nodes, shares = set_shares(body, pm.set, "point mass")
        for c in range(body.dim):
            np.add.at(diag, body.dim * nodes + c, pm.mass * shares)
    return sp.diags(diag, format="csr")
