"""The public residual: distance of ``(d, lam)`` from equilibrium and the contact law."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .law import natural_map, pair_quantities

#: Floor of the force scale, so that an unloaded problem has a finite residual.
TINY_FORCE = np.finfo(float).tiny


@dataclass(frozen=True, eq=False)
class ResidualComponents:
    """The parts of :func:`residual`, each relative to the force scale.

    Attributes
    ----------
    equilibrium : float
        ``max|lam - K d - lam_w| / F``.
    normal, tangential : (n_pairs,)
        Natural-map residuals ``r_n / F`` and ``r_t / F`` of each pair.
    force_scale : float
        ``F = max(max|lam_w|, max|lam|, max(|K| |d|), tiny)``.
    stiffness_scale : float
        ``kappa = mean(diag K)``.
    """

    equilibrium: float
    normal: np.ndarray
    tangential: np.ndarray
    force_scale: float
    stiffness_scale: float

    @property
    def total(self):
        """The residual, the largest of all parts."""
        return float(max(self.equilibrium, np.max(self.normal, initial=0.0),
                         np.max(self.tangential, initial=0.0)))

    @property
    def worst_pair(self):
        """Index of the pair with the largest contact-law residual."""
        return int(np.argmax(np.maximum(self.normal, self.tangential)))


def force_scale(lam_w, lam):
    """``F = max(max|lam_w|, max|lam|, tiny)``, the force unit of the residual."""
    return float(max(np.abs(lam_w).max(), np.abs(lam).max(), TINY_FORCE))


def residual_components(problem, lam_w, d, lam, previous_state=None):
    """Relative residual of ``(d, lam)``, part by part.

    With the force scale ``F = max(max|lam_w|, max|lam|, max(|K| |d|), tiny)`` (the
    last term: the size of the terms of ``K d``, see ``_parts``) and the
    stiffness scale ``kappa = mean(diag K)``:

    .. math::
        r_{eq} = \\max|\\lambda - K d - \\lambda_w| / F, \\quad
        r_{n,i} = |P_i - \\max(0, P_i - \\kappa w_i)| / F, \\quad
        r_{t,i} = \\lVert Q_i - \\mathrm{proj}_{\\mu_i \\max(P_i, 0)}
                  (Q_i - \\kappa\\, dv_i) \\rVert / F

    where ``w = d_n + g0`` is the opening and ``dv = d_t - d_t_prev`` the slip
    increment since ``previous_state`` (``None``: the undeformed reference,
    ``d_prev = 0``). Everything is relative to the problem's own scales, so a
    change of units leaves it unchanged.

    Parameters
    ----------
    problem : ContactProblem
    lam_w, d, lam : (n_pairs, dim)
    previous_state : ContactState or None

    Returns
    -------
    ResidualComponents
    """
    lam_w, d, lam = (np.asarray(a, dtype=float) for a in (lam_w, d, lam))
    d_prev = _previous_displacement(problem, previous_state)
    F, imbalance, r_n, r_t = _parts(problem, lam_w, d, lam, d_prev)
    return ResidualComponents(imbalance / F, r_n / F, r_t / F, F, problem.kappa)


def _parts(problem, lam_w, d, lam, d_prev):
    """The force unit of the residual and the absolute residuals.

    The unit is ``max(F, max(|K| |d|))``: the force scale, or the size of the terms of
    ``K d`` when they are larger. ``lam = K d + lam_w`` can only be computed to
    ``eps |K| |d|``; when pairs open widely ``K d`` nearly cancels ``lam_w`` and that
    round-off reaches ``cond(K) eps F`` (seen: 2.5e-10 with every sandwich-2d pair open,
    in the equilibrium and in the pressure of the open pairs). Measured in ``F`` alone,
    exact answers would be called unconverged.
    """
    F = force_scale(lam_w, lam)
    dv = d.ravel()
    imbalance = np.abs(lam.ravel() - problem.K @ dv - lam_w.ravel()).max()
    unit = max(F, float((np.abs(problem.K) @ np.abs(dv)).max()))
    r_n, r_t = natural_map(pair_quantities(problem, d, lam, d_prev), problem.mu, problem.kappa)
    return unit, float(imbalance), r_n, r_t


def residual(problem, lam_w, d, lam, previous_state=None):
    """The single measure of how far ``(d, lam)`` is from a solution.

    The largest of :func:`residual_components`: equilibrium
    ``lam = K d + lam_w`` and every contact condition of method.md section 4,
    relative to the force scale. Every method of :data:`qsma.contact.METHODS`
    stops on it and reports it; ``success`` means ``residual <= tol``.

    Returns
    -------
    float
    """
    lam_w, d, lam = (np.asarray(a, dtype=float) for a in (lam_w, d, lam))
    F, imbalance, r_n, r_t = _parts(problem, lam_w, d, lam,
                                    _previous_displacement(problem, previous_state))
    return float(max(imbalance, r_n.max(initial=0.0), r_t.max(initial=0.0)) / F)


def _previous_displacement(problem, previous_state):
    if previous_state is None:
        return np.zeros((problem.n_pairs, problem.dim))
    return previous_state.d
