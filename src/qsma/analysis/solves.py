"""The contact solve of one load level: the interface's layer and contact zone, the
retry of a nonlinear law at the level's own pressures, and what a level's interface
displacements mean as modal amplitude and tip deflection."""
from __future__ import annotations

import warnings

import numpy as np

from .._infra.threads import CONTACT_BLAS_THREADS
from ..contact import DEFAULT_TOL
from ..contact import solve as contact_solve
from ..contact.layer import MAX_LAW_ITERATIONS, Layer, solve_layered
from ..contact.zone import solve_in_zone, solve_preload, zone_from_state
from ..errors import ContactConvergenceWarning
from ..reduction.rigid import held_by_joint
from .result import load_factors as _load_factors


def _contact_threads(opts):
    """BLAS thread limit of the contact solves: one under ``blas_threads="auto"``
    (:data:`qsma._threads.CONTACT_BLAS_THREADS`), else the run's own setting."""
    return CONTACT_BLAS_THREADS if opts.blas_threads == "auto" else None


class _Response:
    """Modal amplitude and tip deflection of interface displacements ``d`` at modal force
    ``alpha``, measured from the preload state. Computed from the increments
    ``d - d_preload`` and ``alpha`` (never as the difference of two totals), so a level
    whose interface has not moved gets exactly the linear answer."""

    def __init__(self, reduced, pre):
        self.d0 = pre.d.ravel()
        self.j = reduced.patterns.index("modal")
        self.cq, self.aq = reduced.functionals["q"][0], reduced.functionals["q"][1][self.j]
        self.ct, self.at = reduced.functionals["tip"][0], reduced.functionals["tip"][1][self.j]

    def q(self, d, alpha):
        return float(self.cq @ (np.asarray(d).ravel() - self.d0) + self.aq * alpha)

    def tip(self, d, alpha):
        return float(self.ct @ (np.asarray(d).ravel() - self.d0) + self.at * alpha)


def _solve(layer, reduced, alpha, state, method, opts, where, zone=None, guess=None,
           closing=None, law_iterations=MAX_LAW_ITERATIONS):
    """One contact solve at modal force ``alpha``; returns ``(result, zone)``.

    ``layer``: the interface's :class:`qsma.contact.layer.Layer` (a plain
    :class:`ContactProblem` is the rigid interface); ``state``, ``guess`` and the result
    are physical, the solves see the slider (:func:`qsma.contact.layer.solve_layered`).
    ``zone``: None (the whole interface), ``"preload"`` (from the reference state on the
    predicted zone, :func:`qsma.contact.zone.solve_preload`) or a
    :class:`qsma.contact.zone.ContactZone` of ``layer.problem``. ``guess``: a state to
    start the iteration from (the slip is measured from ``state``; see
    :func:`qsma.contact.solve`). ``closing``: pairs expected to close (a zone's
    ``closing``, see :func:`qsma.contact.zone.solve_in_zone`)."""
    layer = layer if isinstance(layer, Layer) else Layer.identity(layer)
    factors = _load_factors(reduced, alpha)
    W = layer.welded_basis(reduced.W)
    lam_w = (W @ factors).reshape(-1, layer.problem.dim)
    at = {"zone": zone}

    def once(load, st, gs):
        z = at["zone"]
        basis = (W, factors) if load is lam_w else None   # lam_w = W a: eliminated once
        if z is None:
            res = contact_solve(layer.problem, load, st, method=method, guess=gs, **opts)
        elif isinstance(z, str):
            res, z = solve_preload(layer.problem, load, method=method, basis=basis, **opts)
        else:
            res, z = solve_in_zone(z, load, st, method=method, basis=basis, guess=gs,
                                   closing=closing, **opts)
        at["zone"] = z
        return res

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        res = solve_layered(layer, once, lam_w, state, guess,
                            opts.get("tol") or DEFAULT_TOL, law_iterations)
    if not res.success:
        warnings.warn(f"contact solve at {where} did not converge: {res.message} "
                      f"(residual {res.residual:.2e})", ContactConvergenceWarning,
                      stacklevel=3)
    return res, at["zone"]


class _Solver:
    """The contact solve of a load level, with the open-pair elimination if enabled."""

    def __init__(self, layer, reduced, method, opts, zone):
        self.layer = layer if isinstance(layer, Layer) else Layer.identity(layer)
        self.reduced, self.method, self.opts = reduced, method, opts
        self.zone = zone
        self.guess = None       # a state to start the next solve from (set by _ramp)

    @property
    def problem(self):
        """The contact problem the solves see (the slider's of a compliant interface)."""
        return self.layer.problem

    def __call__(self, alpha, state, where, closing=None):
        guess, self.guess = self.guess, None
        res, self.zone = _solve(self.layer, self.reduced, alpha, state, self.method,
                                self.opts, where, self.zone, guess, closing)
        if not res.success and res.law_residual:
            # a nonlinear law whose chord iteration stalled: linearise at this level's
            # pressures (kept for the levels after it) and solve the level again
            layer = self.layer.relinearised(res.P)
            zone = None if self.zone is None else zone_from_state(layer.problem, res.state)
            again, zone = _solve(layer, self.reduced, alpha, state, self.method, self.opts,
                                 where, zone, guess, closing)
            if again.success:
                res, self.layer, self.zone = again, layer, zone
        if res.success:
            res = held_by_joint(self.reduced, res, _load_factors(self.reduced, alpha), where)
        return res
