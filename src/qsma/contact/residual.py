r"""The public residual: distance of ``(d, lam)`` from equilibrium and the contact law.

Three measures, all dimensionless (docs/contact.md, "The residual"):

* :func:`residual`, the acceptance test of every method: equilibrium as a
  componentwise backward error, and each pair's natural map in its own
  stiffness, less the floating-point uncertainty of its force, relative to
  the reaction scale ``max|lam|``;
* :func:`force_residual`, the force-only check that every success must also
  pass (:data:`FORCE_TOL`): equilibrium and the contact law against the
  applied forces ``max(|lam_w|, |lam|)``;
* :func:`legacy_residual`, the measure of qsma <= 0.x (force unit inflated by
  ``max(|K| |d|)``), reported for comparison only: on ill-conditioned
  problems it reads 1e-11 for a force error of 3 %.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .law import natural_map, pair_quantities

#: Floor of every scale, so that an unloaded problem has a finite residual.
TINY_FORCE = np.finfo(float).tiny
EPS = np.finfo(float).eps
#: Round-off allowance of a pair's force, in units of ``eps`` times the size of
#: the terms of ``lam_i = K_i d + lam_w,i``, per ``sqrt(N)`` (N unknowns: the
#: statistical growth of the rounding error of a dot product of length N); 8 is a
#: margin on that estimate, not a fit. The sandwich-2d ramp converges on every level
#: with any factor from 0 to 8 (python benchmarks/bench_contact_roundoff.py): the
#: allowance matters only when the load dwarfs the reaction (docs/contact.md).
ROUNDOFF = 8.0
#: Tolerance of :func:`force_residual` that every success must meet: the
#: largest value seen on exact answers is 2.5e-10 (sandwich-2d, every pair
#: open, cond(K) = 8.6e6, round-off of ``K d``); 1e-6 leaves a factor 4000 and
#: still flags a force error of 1e-6 of the load.
FORCE_TOL = 1e-6


@dataclass(frozen=True, eq=False)
class ResidualComponents:
    """The parts of :func:`residual`.

    Attributes
    ----------
    equilibrium : float
        ``max_j |lam - K d - lam_w|_j / e_j`` with ``e = |K| |d| + |lam_w|``
        (componentwise backward error).
    normal, tangential : (n_pairs,)
        Natural-map residuals of each pair in its own stiffness ``c_i``, less the
        round-off allowance ``a_i``, relative to ``force_scale``.
    force_scale : float
        ``F = max(max|lam|, tiny)``, the reaction scale.
    stiffness_scale : (n_pairs,)
        ``c_i = trace(K_ii) / dim``, each pair's own stiffness.
    roundoff : (n_pairs,)
        ``a_i = ROUNDOFF sqrt(N) eps max_{j in i} e_j`` (force units).
    """

    equilibrium: float
    normal: np.ndarray
    tangential: np.ndarray
    force_scale: float
    stiffness_scale: np.ndarray
    roundoff: np.ndarray

    @property
    def total(self):
        """The residual, the largest of all parts."""
        return float(max(self.equilibrium, np.max(self.normal, initial=0.0),
                         np.max(self.tangential, initial=0.0)))

    @property
    def worst_pair(self):
        """Index of the pair with the largest contact-law residual."""
        return int(np.argmax(np.maximum(self.normal, self.tangential)))


def pair_stiffness(problem):
    """``c_i = trace(K_ii) / dim``: the stiffness that turns pair ``i``'s displacements
    into its forces in the natural map (computed once per problem)."""
    return problem.cached("pair_stiffness",
                           lambda p: np.einsum("kii->k", p.diagonal_blocks) / p.dim)


def force_scale(lam_w, lam):
    """``max(max|lam_w|, max|lam|, tiny)``, the force unit of :func:`force_residual`."""
    return float(max(np.abs(lam_w).max(initial=0.0), np.abs(lam).max(initial=0.0), TINY_FORCE))


def reaction_scale(lam):
    """``max(max|lam|, tiny)``, the force unit of :func:`residual`."""
    return float(max(np.abs(lam).max(initial=0.0), TINY_FORCE))


def roundoff_allowance(problem, lam_w, d, abs_Kd=None):
    """Per pair ``a_i = ROUNDOFF sqrt(N) eps max_{j in i} (|K| |d| + |lam_w|)_j``.

    ``lam_i = K_i d + lam_w,i`` cannot be computed (nor satisfied by a linear
    solve) closer than a few ``eps`` times the size of its terms.
    ``abs_Kd``, optional: ``|K| |d|`` if the caller holds it already.
    """
    with np.errstate(over="ignore"):
        size = problem.abs_product(d) if abs_Kd is None else abs_Kd
        return _allowance(problem, size + np.abs(lam_w.ravel()))


def _allowance(problem, terms):
    """``a_i`` from the sizes ``e`` of the terms of every equation (flat)."""
    return ROUNDOFF * np.sqrt(problem.size) * EPS * terms.reshape(problem.n_pairs, -1).max(axis=1)


def products(problem, d):
    r"""``(K d, |K| |d|)``: the two matrix-vector products every measure needs.

    :func:`measures` computes them once for the three measures of a solve; ``|K| |d|``,
    a size, in single precision on large problems
    (:meth:`qsma.contact.ContactProblem.abs_product`). (Forming ``|K|`` block by block
    in the cache instead was measured slower with numpy: 7.5 ms against 2.5 ms for the
    two double products at N = 1683.) Both read one triangle of the symmetric ``K``
    (:meth:`qsma.contact.ContactProblem.product`): half the memory traffic of the full
    check after every zone solve.
    """
    x = np.asarray(d, dtype=float).ravel()
    with np.errstate(over="ignore", invalid="ignore"):
        return problem.product(x), problem.abs_product(x, symmetric=True)


def residual_components(problem, lam_w, d, lam, previous_state=None, known_products=None):
    r"""Scale-honest residual of ``(d, lam)``, part by part.

    With ``e = |K| |d| + |lam_w|`` (size of the terms of each equation), the
    pair stiffness ``c_i = trace(K_ii)/dim``, the round-off allowance
    ``a_i = 8 sqrt(N) eps max_{j in i} e_j`` and the reaction scale
    ``F = max|lam|``:

    .. math::
        r_{eq} = \max_j \frac{|\lambda - K d - \lambda_w|_j}{e_j}, \quad
        r_{n,i} = \frac{(|P_i - \max(0, P_i - c_i w_i)| - a_i)^+}{F}, \quad
        r_{t,i} = \frac{(\lVert Q_i - \mathrm{proj}_{\mu_i \max(P_i, 0)}
                  (Q_i - c_i\, dv_i) \rVert - a_i)^+}{F}

    where ``w = d_n + g0`` is the opening and ``dv = d_t - d_t_prev`` the slip
    increment since ``previous_state`` (``None``: ``d_prev = 0``). Each pair is
    judged in its own stiffness, the forces against the reaction (never
    against ``|K| |d|`` or ``|lam_w|``, which can exceed the reaction by many
    orders), and only what exceeds the floating-point uncertainty of the
    pair's force counts. Invariant under a change of units and under a
    scaling of ``K`` or of the load.

    Parameters
    ----------
    problem : ContactProblem
    lam_w, d, lam : (n_pairs, dim)
    previous_state : ContactState or None
    known_products : tuple, optional
        ``(K d, |K| |d|)`` of this ``d`` already formed by :func:`products` (a method
        that checks its iterate and then reports its :func:`measures` from one pass).

    Returns
    -------
    ResidualComponents
    """
    lam_w, d, lam = (np.asarray(a, dtype=float) for a in (lam_w, d, lam))
    return _components(problem, lam_w, d, lam, _previous_displacement(problem, previous_state),
                       products(problem, d) if known_products is None else known_products)


def _components(problem, lam_w, d, lam, d_prev, Kd_aKd):
    """:func:`residual_components` from the products ``(K d, |K| |d|)``."""
    Kd, aKd = Kd_aKd
    c = pair_stiffness(problem)
    with np.errstate(over="ignore", invalid="ignore"):
        terms = aKd + np.abs(lam_w.ravel())
        miss = np.abs(lam.ravel() - Kd - lam_w.ravel())
        eq = _max_ratio(miss, terms)
        a = _allowance(problem, terms)
        r_n, r_t = natural_map(pair_quantities(problem, d, lam, d_prev), problem.mu, c)
        F = reaction_scale(lam)
        normal = np.maximum(r_n - a, 0.0) / F
        tangential = np.maximum(r_t - a, 0.0) / F
    normal, tangential = _nan_to_inf(normal), _nan_to_inf(tangential)
    return ResidualComponents(eq, normal, tangential, F, c, a)


def _max_ratio(num, den):
    """``max num/den`` with ``0/0 = 0`` and ``x/0 = inf``; NaN counts as inf."""
    ratio = np.where(num == 0.0, 0.0, num / np.where(den > 0, den, TINY_FORCE))
    return float(np.max(_nan_to_inf(ratio), initial=0.0))


def _nan_to_inf(x):
    return np.where(np.isnan(x), np.inf, x)


def residual(problem, lam_w, d, lam, previous_state=None):
    """The single measure of how far ``(d, lam)`` is from a solution.

    The largest of :func:`residual_components`: equilibrium
    ``lam = K d + lam_w`` (componentwise backward error) and every contact
    condition of every pair in its own units (docs/contact.md). Every
    method of :data:`qsma.contact.METHODS` stops on it and reports it;
    ``success`` means ``residual <= tol`` and ``force_residual <= FORCE_TOL``.

    Returns
    -------
    float
    """
    return residual_components(problem, lam_w, d, lam, previous_state).total


def force_residual(problem, lam_w, d, lam, previous_state=None):
    r"""Force-only check: violations relative to the applied forces.

    With ``F = max(max|lam_w|, max|lam|)`` and ``kappa = mean(diag K)``:

    .. math:: \max\left(\max|\lambda - K d - \lambda_w|,\;
              \max_i |P_i - \max(0, P_i - \kappa w_i)|,\;
              \max_i \lVert Q_i - \mathrm{proj}_{\mu_i \max(P_i,0)}(Q_i - \kappa\, dv_i)
              \rVert\right) / F

    No allowance for round-off and no inflation by ``|K| |d|``: tension,
    penetration, an overloaded or wrongly directed shear show up at their
    size relative to the load. Every success must satisfy it to
    :data:`FORCE_TOL`.
    """
    lam_w, d, lam = (np.asarray(a, dtype=float) for a in (lam_w, d, lam))
    d_prev = _previous_displacement(problem, previous_state)
    with np.errstate(over="ignore", invalid="ignore"):
        Kd = problem.product(d)
    return _force_and_legacy(problem, lam_w, d, lam, d_prev, Kd, None)[0]


def _force_and_legacy(problem, lam_w, d, lam, d_prev, Kd, aKd):
    """``(force_residual, legacy_residual)`` from ``K d`` (and ``|K| |d|`` for the
    legacy measure; ``None``: not computed). They share the imbalance and the natural
    map in ``kappa``."""
    with np.errstate(over="ignore", invalid="ignore"):
        imbalance = np.abs(lam.ravel() - Kd - lam_w.ravel()).max()
        r_n, r_t = natural_map(pair_quantities(problem, d, lam, d_prev), problem.mu,
                               problem.kappa)
        worst = max(imbalance, r_n.max(initial=0.0), r_t.max(initial=0.0))
        force = worst / force_scale(lam_w, lam)
        legacy = (None if aKd is None else
                  worst / max(force_scale(lam_w, lam), float(aKd.max(initial=0.0))))
    as_float = lambda v: None if v is None else float(np.inf if np.isnan(v) else v)
    return as_float(force), as_float(legacy)


def measures(problem, lam_w, d, lam, previous_state=None, known_products=None,
             known_residual=None):
    """``(residual, force_residual, legacy_residual)`` of ``(d, lam)`` from one pass
    over ``K`` (:func:`products`): the three numbers a solve reports, each equal to its
    function's value.

    ``known_products``, optional: ``(K d, |K| |d|)`` of this ``d`` already computed by
    the caller with :func:`products` or the same two products (a method that holds them
    for its iterate), so that they are not formed twice. ``known_residual``, optional:
    :func:`residual` of this very iterate, evaluated by the caller from these products.
    """
    lam_w, d, lam = (np.asarray(a, dtype=float) for a in (lam_w, d, lam))
    d_prev = _previous_displacement(problem, previous_state)
    Kd_aKd = products(problem, d) if known_products is None else known_products
    r = (_components(problem, lam_w, d, lam, d_prev, Kd_aKd).total
         if known_residual is None else known_residual)
    return (r, *_force_and_legacy(problem, lam_w, d, lam, d_prev, *Kd_aKd))


def legacy_residual(problem, lam_w, d, lam, previous_state=None):
    """The earlier, scale-relative residual, kept for comparison only.

    ``max(r_eq, r_n, r_t)`` with every part divided by
    ``max(max|lam_w|, max|lam|, max(|K| |d|))`` and the natural map in
    ``kappa = mean(diag K)``. The ``|K| |d|`` term excuses round-off but on an
    ill-conditioned K it also hides real errors (docs/contact.md).
    """
    lam_w, d, lam = (np.asarray(a, dtype=float) for a in (lam_w, d, lam))
    d_prev = _previous_displacement(problem, previous_state)
    return _force_and_legacy(problem, lam_w, d, lam, d_prev, *products(problem, d))[1]


def _previous_displacement(problem, previous_state):
    if previous_state is None:
        return np.zeros((problem.n_pairs, problem.dim))
    return previous_state.d
