"""Frictional contact of two bodies condensed to the interface (method.md sections 3-5).

The problem of one load level is ``lam = K d + lam_w`` with every node pair
open, stuck or slipping (Coulomb friction, 2D or 3D)::

    from qsma.contact import ContactProblem, solve

    problem = ContactProblem(K, mu=0.6)
    state = None
    for lam_w in ramp:                      # (n_pairs, dim) welded forces
        result = solve(problem, lam_w, state)
        state = result.state                # history: slip is measured from here

Methods (:data:`METHODS`): ``"basket"`` (default, block Gauss-Seidel with
baskets), ``"active_set"`` (semismooth Newton, Alart-Curnier), ``"nodal_gs"``
(one pair at a time, the baseline). All of them are judged by the same
:func:`residual` and the force check :func:`force_residual`.
"""
from .problem import ContactProblem
from .registry import DEFAULT_TOL, FALLBACKS, METHODS, Iterate, register_method, solve
from .residual import (FORCE_TOL, ResidualComponents, force_residual, legacy_residual, residual,
                       residual_components)
from .state import (OPEN, SLIPPING, STATUS_NAMES, STUCK, ContactResult, ContactState, Outcome,
                    PairState)

# Importing the method modules registers them in METHODS.
from . import active_set, basket, nodal_gs  # noqa: E402,F401  isort: skip

__all__ = [
    "ContactProblem", "ContactResult", "ContactState", "ResidualComponents", "METHODS",
    "DEFAULT_TOL", "Iterate", "register_method", "solve", "residual", "residual_components",
    "STUCK", "SLIPPING", "OPEN", "STATUS_NAMES", "PairState", "Outcome", "FALLBACKS",
    "FORCE_TOL", "force_residual", "legacy_residual",
]
