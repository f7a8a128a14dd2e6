"""Quasi-static modal analysis: preload, tied modes, modal load ramp, Masing.

The pipeline (``shared/spec/method.md`` section 1)::

    model -> assembly -> condensation -> preload contact -> tied modes
          -> modal load pattern M phi (condensed) -> ramp of contact solves -> Masing
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass
import time
import warnings

import numpy as np

from . import __version__
from ._threads import blas_threads as threads_limited, threads_for
from .condense import reduce_two_bodies
from .contact import DEFAULT_TOL, ContactProblem, ContactState, METHODS, solve as contact_solve
from .contact.zone import solve_in_zone, zone_from_state
from .errors import AnalysisError, ContactConvergenceWarning, InputError
from .fe import assemble_body
from .levels import Levels, spec_levels
from .masing import loop_area, masing
from .modal import linear_modes, probe_vector
from .model import make_pairing

STAGES = ("model", "assembly", "modal", "condensation", "contact", "postprocess", "total")


@dataclass(frozen=True, eq=False)
class LevelStates:
    """Contact solution per level: ``d``, ``lam`` (n_levels, n_pairs, dim), ``status``."""

    d: np.ndarray
    lam: np.ndarray
    status: np.ndarray
    residual: np.ndarray
    iterations: np.ndarray

    def state(self, k) -> ContactState:
        """The contact state of level ``k`` (the history the next level starts from)."""
        return ContactState(self.d[k], self.lam[k], self.status[k])


@dataclass(frozen=True, eq=False)
class DirectLoop:
    """A hysteresis loop computed directly: unloading from +alpha_max to -alpha_max and
    reloading to +alpha_max with the history-dependent solver."""

    alpha: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    dissipation: float | None      # None when the loop could not be closed
    dissipation_masing: float
    success: bool
    message: str = ""


@dataclass(frozen=True, eq=False)
class QSMAResult:
    """Everything a QSMA run produced. Arrays under "levels" have one entry per solved
    level; ``success`` is False when a level failed (``message`` says which)."""

    success: bool
    message: str
    model_info: dict
    mode_index: int
    omega0: float
    phi_tip: float
    alpha: np.ndarray
    tip_lin: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    f_hz: np.ndarray
    zeta: np.ndarray
    dissipation: np.ndarray
    tip_velocity: np.ndarray
    n_stuck: np.ndarray
    n_slip: np.ndarray
    n_open: np.ndarray
    states: LevelStates
    preload: object
    modes: object
    reduced: object
    pairing: object
    model: object
    solver: dict
    timings_s: dict
    direct_loop: DirectLoop | None = None
    gross_slip_level: int | None = None
    version: str = __version__

    @property
    def f0_hz(self):
        return self.omega0 / (2 * np.pi)

    @property
    def n_levels(self):
        return len(self.alpha)

    @property
    def iterations(self):
        return self.states.iterations

    def fields(self, k):
        """Full displacement vectors per body at level ``k`` (``k=None``: the preload),
        measured from the undeformed configuration."""
        if k is None:
            return self.reduced.recover(self.preload.d, self._a(0.0))
        return self.reduced.recover(self.states.d[k], self._a(self.alpha[k]))

    def _a(self, alpha):
        return _load_factors(self.reduced, alpha)

    def levels_table(self) -> dict:
        """Per-level arrays by name (the ``levels`` block of results.json)."""
        return {k: getattr(self, k) for k in LEVEL_FIELDS}


LEVEL_FIELDS = ("alpha", "tip_lin", "q", "tip", "f_hz", "zeta", "dissipation",
                "tip_velocity", "n_stuck", "n_slip", "n_open", "iterations")


def _load_factors(reduced, alpha):
    a = np.zeros(len(reduced.patterns))
    a[reduced.patterns.index("preload")] = 1.0
    if "modal" in reduced.patterns:
        a[reduced.patterns.index("modal")] = alpha
    return a


def _counts(status):
    return [int(np.sum(status == s)) for s in (0, 1, 2)]


class _Timer:
    """Seconds per stage of :data:`STAGES`; a stage may be entered several times."""

    def __init__(self):
        self.t = dict.fromkeys(STAGES, 0.0)
        self.t0 = time.perf_counter()

    @contextmanager
    def stage(self, name):
        start = time.perf_counter()
        try:
            yield
        finally:
            self.t[name] += time.perf_counter() - start

    def done(self):
        self.t["total"] = time.perf_counter() - self.t0
        return dict(self.t)


def run(model, *, mode=0, levels: Levels | None = None, method="basket", tol=None,
        maxiter=None, direct_loop=False, n_modes=None, continue_on_failure=False,
        progress=None, schur_backend="auto", blas_threads="auto",
        eliminate_open=True) -> QSMAResult:
    """Quasi-static modal analysis of ``model``.

    Parameters
    ----------
    model : :class:`qsma.model.Model` with two bodies, one interface and a tip probe
    mode : index of the mode (0 = lowest) of the tied structure to load
    levels : :class:`qsma.levels.Levels` (default: the 51 levels of sandwich-2d)
    method, tol, maxiter : contact solver options (``qsma.contact.solve``)
    direct_loop : also compute the hysteresis loop at the largest level directly
    continue_on_failure : keep ramping after a level whose contact solve failed
    progress : callable ``progress(k, n)`` called after each level
    schur_backend : static condensation backend (:data:`qsma.linalg.SCHUR_BACKENDS`)
    blas_threads : BLAS thread limit; ``"auto"``: one thread for interface problems of
        up to :data:`qsma._threads.SMALL_PROBLEM` unknowns, ``None``: no limit
    eliminate_open : solve the ramp on the pairs closed after the preload, the open ones
        eliminated exactly (:mod:`qsma.contact.zone`; a pair that would close joins)

    Returns
    -------
    QSMAResult
    """
    if method not in METHODS:
        raise InputError(f"unknown contact method {method!r}; valid: {sorted(METHODS)}")
    if len(model.bodies) != 2:
        raise InputError(f"QSMA needs exactly two bodies joined by the interface, "
                         f"got {len(model.bodies)}")
    if not isinstance(mode, (int, np.integer)) or mode < 0:
        raise InputError(f"mode index must be an integer >= 0, got {mode!r}")
    levels = spec_levels() if levels is None else levels
    opts = {k: v for k, v in (("tol", tol), ("maxiter", maxiter)) if v is not None}
    clock = _Timer()
    with clock.stage("model"):
        pairing = make_pairing(model)
    limit = threads_for(pairing.n_pairs * model.dim) if blas_threads == "auto" else blas_threads
    with threads_limited(limit):
        return _run(model, pairing, mode, levels, method, opts, direct_loop, n_modes,
                    continue_on_failure, progress, schur_backend, clock, eliminate_open)


def preload(model, assembled, pairing, *, method="basket", opts=None, schur_backend="auto",
            clock=None):
    """Condense the assembled bodies and solve the bolt preload with frictional contact.

    Returns ``(reduced, problem, result)``. Raises :class:`AnalysisError` if the solve
    fails or leaves no pair in contact (tied modes of a disconnected assembly would be
    meaningless).
    """
    clock = _Timer() if clock is None else clock
    i1 = model.body_index(model.interface.body1)
    i2 = model.body_index(model.interface.body2)
    with clock.stage("condensation"):
        reduced = reduce_two_bodies(assembled[i1], assembled[i2], pairing,
                                    backend=schur_backend)
        problem = ContactProblem(reduced.K, model.mu, dim=model.dim)
    with clock.stage("contact"):
        pre, _ = _solve(problem, reduced, 0.0, None, method, opts or {}, "preload")
    if not pre.success:
        raise AnalysisError(f"the preload contact solve failed: {pre.message} "
                            f"(residual {pre.residual:.2e})", partial=pre)
    if np.all(pre.status == 2):
        raise AnalysisError("the preload leaves no interface pair in contact: the bodies "
                            "separate, and tied modes of a disconnected assembly would be "
                            "meaningless. Check the sign and location of the bolt pressure.",
                            partial=pre)
    return reduced, problem, pre


def _run(model, pairing, mode, levels, method, opts, direct_loop, n_modes,
         continue_on_failure, progress, schur_backend, clock, eliminate_open):

    i1 = model.body_index(model.interface.body1)
    i2 = model.body_index(model.interface.body2)
    with clock.stage("assembly"):
        assembled = [assemble_body(b) for b in model.bodies]
        for a in assembled:
            for name, F in a.loads.items():
                if name != "preload":
                    raise InputError(f"body {a.body.name!r}: pressure load pattern {name!r} "
                                     f"is not used by QSMA, which applies the 'preload' "
                                     f"pattern and then the modal load; set load = "
                                     f"'preload' (the default) or remove the pressure")
                if not np.all(np.isfinite(F)):
                    raise InputError(f"load {name!r} of body {a.body.name!r} is not finite")
    reduced, problem, pre = preload(model, assembled, pairing, method=method, opts=opts,
                                    schur_backend=schur_backend, clock=clock)
    closed = pre.status != 2

    with clock.stage("modal"):
        nm = max(6, mode + 1) if n_modes is None else n_modes
        modes = linear_modes(model, assembled, pairing, tied=closed, n_modes=nm)
        if mode >= len(modes.omega):
            raise InputError(f"mode index {mode} is beyond the {len(modes.omega)} computed "
                             f"modes (0..{len(modes.omega) - 1}); raise n_modes")
        phi = modes.shapes[:, mode].copy()
        ltip = probe_vector(model)
        phi_tip = float(ltip @ phi)
        if phi_tip < 0:
            phi, phi_tip = -phi, -phi_tip
        probe_nodes = ltip != 0
        rms = float(np.sqrt(np.mean(phi[probe_nodes] ** 2)))
        if abs(phi_tip) < 1e-6 * rms or rms == 0:
            raise InputError(f"mode {mode} ({modes.f_hz[mode]:.4g} Hz) has no tip deflection "
                             f"along the probe direction (|phi_tip| = {abs(phi_tip):.2e}, "
                             f"RMS of the mode at the tip nodes {rms:.2e}); choose a mode "
                             f"that moves the tip: the load levels are scaled by it")
        omega0 = float(modes.omega[mode])

    with clock.stage("condensation"):
        off = model.dof_offsets()
        Mphi = [a.M @ phi[off[k]:off[k + 1]] for k, a in enumerate(assembled)]
        part = lambda v, k: v[off[k]:off[k + 1]]
        reduced = reduced.add_pattern("modal", Mphi[i1], Mphi[i2]).with_functionals({
            "q": (Mphi[i1], Mphi[i2]),
            "tip": (part(ltip, i1), part(ltip, i2)),
        })

    alpha = levels.alpha(omega0, phi_tip)
    with clock.stage("contact"):
        solver = _Solver(problem, reduced, method, opts,
                         zone_from_state(problem, pre.state) if eliminate_open else None)
        ramp = _ramp(solver, alpha, pre, continue_on_failure, progress)
    n_ok = len(ramp["d"])

    with clock.stage("postprocess"):
        q0 = reduced.evaluate("q", pre.d, _load_factors(reduced, 0.0))
        t0 = reduced.evaluate("tip", pre.d, _load_factors(reduced, 0.0))
        al = alpha[:n_ok]
        q = np.array([reduced.evaluate("q", d, _load_factors(reduced, a))
                      for d, a in zip(ramp["d"], al)]) - q0
        tip = np.array([reduced.evaluate("tip", d, _load_factors(reduced, a))
                        for d, a in zip(ramp["d"], al)]) - t0
        ms = masing(al, q)
        status = np.array(ramp["status"], dtype=int).reshape(n_ok, pairing.n_pairs)
        counts = np.array([_counts(s) for s in status]).reshape(n_ok, 3)
        gross = [k for k in range(n_ok) if counts[k, 0] == 0 and counts[k, 1] > 0]

        shape = (n_ok, pairing.n_pairs, model.dim)
        states = LevelStates(np.array(ramp["d"]).reshape(shape),
                             np.array(ramp["lam"]).reshape(shape), status,
                             np.array(ramp["residual"], dtype=float),
                             np.array(ramp["nit"], dtype=int))

    loop = None
    if direct_loop and n_ok:
        with clock.stage("contact"):
            loop = _direct_loop(solver, al, states.state(n_ok - 1), q0, t0,
                                float(ms.dissipation[-1]))

    timings = clock.done()
    return QSMAResult(
        success=ramp["success"], message=ramp["message"],
        model_info=dict(name=model.name, n_nodes=model.n_nodes, n_dofs=model.n_dofs,
                        n_pairs=pairing.n_pairs, mu=model.mu, dim=model.dim,
                        n_closed_after_preload=int(closed.sum())),
        mode_index=mode, omega0=omega0, phi_tip=phi_tip,
        alpha=al, tip_lin=al * phi_tip / omega0 ** 2, q=q, tip=tip,
        f_hz=ms.f_hz, zeta=ms.zeta, dissipation=ms.dissipation,
        tip_velocity=ms.omega * np.abs(tip),
        n_stuck=counts[:, 0], n_slip=counts[:, 1], n_open=counts[:, 2],
        states=states, preload=pre, modes=modes, reduced=reduced, pairing=pairing,
        model=model, solver=dict(method=method, tol=opts.get("tol", DEFAULT_TOL),
                                 maxiter=opts.get("maxiter"),
                                 fallback_levels=ramp["fallback"],
                                 open_pairs_eliminated=bool(eliminate_open)),
        timings_s=timings, direct_loop=loop,
        gross_slip_level=gross[0] if gross else None)


def _solve(problem, reduced, alpha, state, method, opts, where, zone=None):
    """One contact solve at modal force ``alpha``; returns ``(result, zone)``."""
    lam_w = reduced.welded_contact_force(_load_factors(reduced, alpha))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        if zone is None:
            res = contact_solve(problem, lam_w, state, method=method, **opts)
        else:
            res, zone = solve_in_zone(zone, lam_w, state, method=method, **opts)
    if not res.success:
        warnings.warn(f"contact solve at {where} did not converge: {res.message} "
                      f"(residual {res.residual:.2e})", ContactConvergenceWarning,
                      stacklevel=3)
    return res, zone


class _Solver:
    """The contact solve of a load level, with the open-pair elimination if enabled."""

    def __init__(self, problem, reduced, method, opts, zone):
        self.problem, self.reduced, self.method, self.opts = problem, reduced, method, opts
        self.zone = zone

    def __call__(self, alpha, state, where):
        res, self.zone = _solve(self.problem, self.reduced, alpha, state, self.method,
                                self.opts, where, self.zone)
        return res


def _ramp(solver, alpha, pre, keep_going, progress):
    out = {k: [] for k in ("d", "lam", "status", "residual", "nit", "fallback")}
    state, success, message = pre.state, True, "all levels converged"
    for k, a in enumerate(alpha):
        res = solver(a, state, f"load level {k} (alpha={a:.4g})")
        if not res.success:
            success = False
            message = (f"contact solve failed at load level {k} (alpha={a:.6g}): "
                       f"{res.message}; residual {res.residual:.2e}")
            if not keep_going:
                break
        if "fell back to" in res.message:
            out["fallback"].append(k)
        for name, v in (("d", res.d), ("lam", res.lam), ("status", res.status),
                        ("residual", res.residual), ("nit", res.nit)):
            out[name].append(v)
        state = res.state
        if progress is not None:
            progress(k + 1, len(alpha))
    out["success"], out["message"] = success, message
    return out


def _direct_loop(solver, alpha, top_state, q0, t0, d_masing):
    """Unload from +alpha_max to -alpha_max, reload to +alpha_max; the steps mirror the
    Masing construction (unloading by twice each backbone level). Stops at the first
    step whose contact solve fails: the points before it are kept, no area is given."""
    amax = alpha[-1]
    steps = np.concatenate([[0.0], 2 * alpha])
    path = np.concatenate([amax - steps, -amax + steps[1:]])
    reduced = solver.reduced
    state, qs, ts = top_state, [], []
    for a in path:
        res = solver(a, state, f"direct loop (alpha={a:.4g})")
        if not res.success:
            n = len(qs)
            return DirectLoop(path[:n], np.array(qs), np.array(ts), None, d_masing, False,
                              f"direct loop stopped at alpha={a:.6g} (step {n} of "
                              f"{len(path)}): {res.message}; residual {res.residual:.2e}")
        state = res.state
        af = _load_factors(reduced, a)
        qs.append(reduced.evaluate("q", res.d, af) - q0)
        ts.append(reduced.evaluate("tip", res.d, af) - t0)
    qs, ts = np.array(qs), np.array(ts)
    return DirectLoop(path, qs, ts, loop_area(qs, path), d_masing, True, "loop closed")
