r"""Exact elimination of pairs that stay open: solve on the contact zone only.

In a bolted joint most interface pairs are open (sandwich-2d: 48 of 65 after the
preload, sandwich-3d: 412 of 561) and stay open over the load ramp. With the
pairs split into the zone ``A`` and the open rest ``O`` (``lam_O = 0``)::

    d_O   = -K_OO^-1 (K_OA d_A + lam_w_O)
    lam_A = (K_AA - K_AO K_OO^-1 K_OA) d_A + (lam_w_A - K_AO K_OO^-1 lam_w_O)

which is again a problem ``lam = K d + lam_w`` (the Schur complement is SPD), of
the size of the zone. This is exact while the eliminated pairs stay open
(``w_O >= 0``); when one would close it joins the zone and the level is solved
again. Every answer is expanded to all pairs and judged by the public residual
of the full problem.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg as sla

from .law import pair_quantities, classify
from .problem import ContactProblem
from .registry import Iterate, _result, solve
from .residual import residual
from .state import OPEN, ContactState


@dataclass(frozen=True, eq=False)
class ContactZone:
    """A problem reduced to the pairs of ``keep`` (the others open).

    Attributes
    ----------
    full : ContactProblem
    keep : (n_pairs,) bool, the zone
    sub : ContactProblem on the zone
    B : ``K_AO K_OO^-1`` (zone unknowns x eliminated unknowns)
    """

    full: ContactProblem
    keep: np.ndarray
    sub: ContactProblem
    B: np.ndarray
    cho_OO: object
    iA: np.ndarray
    iO: np.ndarray

    @classmethod
    def build(cls, problem: ContactProblem, keep) -> "ContactZone":
        keep = np.asarray(keep, dtype=bool).copy()
        dim = problem.dim
        flat = np.repeat(keep, dim)
        iA, iO = np.flatnonzero(flat), np.flatnonzero(~flat)
        K = problem.K
        if len(iO) == 0:
            return cls(problem, keep, problem, np.zeros((len(iA), 0)), None, iA, iO)
        cho = sla.cho_factor(K[np.ix_(iO, iO)])
        B = sla.cho_solve(cho, K[np.ix_(iO, iA)]).T
        S = K[np.ix_(iA, iA)] - B @ K[np.ix_(iO, iA)]
        sub = ContactProblem(0.5 * (S + S.T), problem.mu[keep], problem.gap0[keep], dim)
        return cls(problem, keep, sub, B, cho, iA, iO)

    @property
    def n_eliminated(self):
        return int((~self.keep).sum())

    def welded(self, lam_w):
        """Welded force of the zone problem."""
        lw = np.asarray(lam_w, dtype=float).ravel()
        out = lw[self.iA] - (self.B @ lw[self.iO] if len(self.iO) else 0.0)
        return out.reshape(-1, self.full.dim)

    def expand(self, d_A, lam_w):
        """Relative displacements of all pairs from those of the zone."""
        lw = np.asarray(lam_w, dtype=float).ravel()
        d = np.zeros(self.full.n_pairs * self.full.dim)
        d[self.iA] = d_A.ravel()
        if len(self.iO):
            d[self.iO] = -(self.B.T @ d_A.ravel()) - sla.cho_solve(self.cho_OO, lw[self.iO])
        return d.reshape(-1, self.full.dim)

    def restrict(self, state: ContactState) -> ContactState:
        return ContactState(state.d[self.keep], state.lam[self.keep], state.status[self.keep])


def zone_from_state(problem, state: ContactState) -> ContactZone:
    """The zone of the pairs that are not open in ``state``."""
    return ContactZone.build(problem, state.status != OPEN)


def solve_in_zone(zone: ContactZone, lam_w, state: ContactState, *, method="basket",
                  tol=1e-10, maxiter=None, max_growth=20):
    """Solve one level on the zone, growing it when an eliminated pair would close.

    Returns ``(ContactResult over all pairs, zone)``; the zone returned is the one
    to use for the next level. ``success`` is judged on the full problem.
    """
    full = zone.full
    lam_w = np.asarray(lam_w, dtype=float)
    nit = 0
    for attempt in range(max_growth):
        sub = solve(zone.sub, zone.welded(lam_w), zone.restrict(state), method=method,
                    tol=tol, maxiter=maxiter)
        nit += sub.nit
        d = zone.expand(sub.d, lam_w)
        closing = (~zone.keep) & (d[:, -1] + full.gap0 < 0)
        if not closing.any() or attempt == max_growth - 1:
            break
        zone = ContactZone.build(full, zone.keep | closing)
    lam = np.zeros_like(d)
    lam[zone.keep] = sub.lam
    msg = sub.message + (f" (zone of {int(zone.keep.sum())} pairs, "
                         f"{zone.n_eliminated} open pairs eliminated)")
    if closing.any():         # max_growth rebuilds and still an eliminated pair closing
        msg += f"; {int(closing.sum())} eliminated pair(s) still closing, zone not settled"
    out = Iterate(d, lam, nit, bool(sub.success and not closing.any()), msg)
    return _result(full, lam_w, state, out, method, tol, fallback=sub.fallback), zone
