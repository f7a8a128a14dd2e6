"""Converged contact states and solver results."""
from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum

import numpy as np

from ..errors import InputError


class PairState(IntEnum):
    """State of a node pair (``ContactResult.status`` holds these codes)."""

    STUCK = 0
    SLIPPING = 1
    OPEN = 2


#: Module-level aliases of the members (``status == OPEN`` works on int arrays).
STUCK, SLIPPING, OPEN = PairState.STUCK, PairState.SLIPPING, PairState.OPEN
STATUS_NAMES = {state: state.name.lower() for state in PairState}
#: The same codes as plain ints, for the array operations of the solvers' inner loops:
#: numpy looks up its array protocols on an ``IntEnum`` member through the enum's
#: metaclass, about 5 us per comparison or ``np.where`` (against 1 us with an int), and
#: a loop solve of the Brake-Reuss beam made some seventy of them.
STUCK_CODE, SLIPPING_CODE, OPEN_CODE = (int(state) for state in PairState)


class Outcome(Enum):
    """How a contact solve ended (``ContactResult.outcome``).

    ``CONVERGED``: the residual and the force check passed (``success``).
    ``NOT_CONVERGED``: the method stopped (iteration cap, stall, cycling,
    singular block, failed line search) without meeting the tolerance.
    ``REJECTED``: the method claimed convergence but :func:`solve`'s own
    re-check (residual or force check) failed.
    ``NUMERICAL_ERROR``: the method raised a floating-point or linear-algebra
    error, or returned non-finite values; the result holds the previous state.
    """

    CONVERGED = "converged"
    NOT_CONVERGED = "not_converged"
    REJECTED = "rejected"
    NUMERICAL_ERROR = "numerical_error"


@dataclass(frozen=True, eq=False, repr=False)
class ContactState:
    """A converged contact state, the history a load level starts from.

    Attributes
    ----------
    d : (n_pairs, dim)
        Relative displacement of body 2 with respect to body 1, local frames.
        Its tangential part is the reference of the next slip increment.
    lam : (n_pairs, dim)
        Contact force on body 2.
    status : (n_pairs,) int
        ``0`` stuck, ``1`` slipping, ``2`` open; the initial guess of the next
        level.
    """

    d: np.ndarray
    lam: np.ndarray
    status: np.ndarray

    @classmethod
    def reference(cls, problem):
        """The undeformed reference: ``d = 0``, ``lam = 0``, every pair stuck."""
        zeros = np.zeros((problem.n_pairs, problem.dim))
        return cls(zeros, zeros.copy(), np.full(problem.n_pairs, STUCK))

    def __post_init__(self):
        for name in ("d", "lam", "status"):
            value = np.array(getattr(self, name), dtype=int if name == "status" else float)
            value.flags.writeable = False
            object.__setattr__(self, name, value)

    def check_against(self, problem):
        """Raise :class:`InputError` if this state does not belong to ``problem``."""
        shape = (problem.n_pairs, problem.dim)
        for name in ("d", "lam"):
            if getattr(self, name).shape != shape:
                raise InputError(f"state.{name} must have shape {shape} (n_pairs, dim), "
                                 f"got {getattr(self, name).shape}")
        if self.status.shape != shape[:1] or self.status.min(initial=0) < 0 \
                or self.status.max(initial=0) > 2:
            raise InputError(f"state.status must be {shape[0]} codes in {{0, 1, 2}}, "
                             f"got shape {self.status.shape}")
        if not (np.all(np.isfinite(self.d)) and np.all(np.isfinite(self.lam))):
            raise InputError("state.d and state.lam must be finite")
        return self

    def __repr__(self):
        return f"ContactState(n_pairs={len(self.status)}, {_count_text(self.status)})"


@dataclass(frozen=True, eq=False, repr=False)
class ContactResult:
    """Outcome of one contact solve (one load level).

    Attributes
    ----------
    d, lam : (n_pairs, dim)
        Relative displacement and contact force on body 2, local frames.
    status : (n_pairs,) int
        ``0`` stuck, ``1`` slipping, ``2`` open (see :func:`qsma.contact.law.classify`).
    success : bool
        True only if ``residual <= tol``.
    nit : int
        Iterations of the method (block solves, Newton steps or sweeps).
    residual : float
        :func:`qsma.contact.residual` of ``(d, lam)`` (the acceptance test).
    message : str
    method : str
        The method that ran (``"auto"`` resolved, see
        :func:`qsma.contact.registry.chosen_method`; a fallback is in ``fallback``).
    state : ContactState
        ``(d, lam, status)``, to pass to the next load level.
    outcome : Outcome
        How the solve ended (``Outcome.CONVERGED`` iff ``success``).
    fallback : str or None
        The method that took over when ``method`` failed (set by
        :func:`qsma.contact.solve` only), else None.
    residual_force : float
        :func:`qsma.contact.force_residual`, the force-only check.
    residual_legacy : float
        :func:`qsma.contact.residual.legacy_residual`, the earlier scale-relative
        measure (for comparison).
    law_residual : float
        For a nonlinear interface law, the consistency of its layer with the pressures
        found (:meth:`qsma.contact.layer.Layer.law_residual`; part of ``residual``);
        0 where the law is linear or was not evaluated.
    """

    d: np.ndarray
    lam: np.ndarray
    status: np.ndarray
    success: bool
    nit: int
    residual: float
    message: str
    method: str
    state: ContactState
    outcome: Outcome = Outcome.CONVERGED
    fallback: str | None = None
    residual_force: float = 0.0
    residual_legacy: float = 0.0
    law_residual: float = 0.0

    @property
    def P(self):
        """Normal contact pressure per pair, compressive positive, ``(n_pairs,)``."""
        return self.lam[:, -1]

    @property
    def Q(self):
        """Tangential contact force per pair, ``(n_pairs, dim-1)``."""
        return self.lam[:, :-1]

    @property
    def n_stuck(self):
        return int(np.count_nonzero(self.status == STUCK))

    @property
    def n_slipping(self):
        return int(np.count_nonzero(self.status == SLIPPING))

    @property
    def n_open(self):
        return int(np.count_nonzero(self.status == OPEN))

    def __repr__(self):
        return (f"ContactResult(success={self.success}, method={self.method!r}, nit={self.nit}, "
                f"residual={self.residual:.3e}, n_pairs={len(self.status)}, "
                f"{_count_text(self.status)}, outcome={self.outcome.name}, "
                f"fallback={self.fallback!r}, message={self.message!r})")


def _count_text(status):
    return ", ".join(f"{name}={np.count_nonzero(status == code)}"
                     for code, name in STATUS_NAMES.items())
