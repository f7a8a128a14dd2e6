"""The run: :func:`run` and :func:`run_prepared`, the stages in order (preload, tied
mode, modal load pattern, ramps, dissipation per level, checks) and the result."""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import replace
import warnings

import numpy as np

from .._infra import resources as _resources
from .._infra.threads import blas_threads as threads_limited, threads_for
from ..contact import DEFAULT_TOL, OPEN, SLIPPING, STUCK
from ..contact.laws import InterfaceLaw
from ..contact.registry import chosen_method
from ..contact.zone import release_zones, zone_from_state
from ..errors import InputError, QSMAWarning
from ..hysteresis import scheduler_client
from ..model.pairing import body_order
from ..progress import reporter
from ..reduction.multibody import held_by_ties
from ..reduction.rigid import support_share
from .checks import _flags, _outcome, _settle_dissipation
from .clock import StageClock
from .dissipation import _direct_loop, level_dissipation, _with_closed
from .levels import spec_levels
from .linear import tied_only_run
from .options import RunOptions
from .prepared import Prepared, _start
from .ramps import _NegativeRamp, _refined_backbone
from .result import (LEVEL_FIELDS, LevelCosts, LevelStates, QSMAResult,
                     load_factors as _load_factors)
from .solves import _contact_threads, _Response, _Solver
from .stages import _assemble, _mode, preload


def _counts(status):
    return [int(np.sum(status == s)) for s in (STUCK, SLIPPING, OPEN)]


def run(model, options: RunOptions | None = None, *, progress=None, **overrides) -> QSMAResult:
    """Quasi-static modal analysis of ``model``.

    Parameters
    ----------
    model : :class:`qsma.model.Model` with a tip probe: two bodies and one interface, or
        any number of bodies and interfaces (``Model(interfaces=...)``, one contact
        problem over all of them, :mod:`qsma.multibody`)
    options : :class:`qsma.analysis.options.RunOptions`, optional
        Every option of the run (defaults: :class:`RunOptions` ``()``).
    progress : :class:`qsma.progress.Progress` or callable, optional
        Told of each stage and of the load levels, refinement rounds and loops as they
        are solved; a callable ``progress(k, n)`` is called after each level of the
        user's grid (:func:`qsma.progress.reporter`).
    **overrides
        Fields of :class:`RunOptions` to change, e.g. ``mode=1, dissipation="loop"``.

    Returns
    -------
    QSMAResult

    Examples
    --------
    >>> import qsma
    >>> from qsma.examples import sandwich_2d
    >>> res = qsma.run(sandwich_2d(1), levels=qsma.Levels.log("tip", 1e-6, 1e-3, 11))
    >>> res.success, round(res.f0_hz, 1)
    (True, 212.5)
    """
    try:
        opts = replace(options or RunOptions(), **overrides)
    except TypeError as exc:
        raise InputError(f"qsma.run: {exc}; valid options: "
                         f"{sorted(RunOptions.__dataclass_fields__)}") from None
    with _kept_warnings() as kept:
        clock, pairing, limit = _start(model, opts)
        with threads_limited(limit):
            res = _run(model, pairing, opts, progress, clock)
    return replace(res, warnings=tuple(kept))


@contextmanager
def _kept_warnings():
    """Collect the messages of qsma's own warnings (:class:`qsma.errors.QSMAWarning`)
    raised inside the block into the yielded list, for the result (report.html shows
    them), and pass every warning on to the caller's filters as if not caught."""
    kept, caught = [], []
    try:
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            try:
                yield kept
            finally:
                caught = list(seen)
    finally:                          # also when the run raises: nothing is swallowed
        for w in caught:
            if issubclass(w.category, QSMAWarning) and str(w.message) not in kept:
                kept.append(str(w.message))
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def run_prepared(prepared: Prepared, options: RunOptions | None = None, *, progress=None,
                 **overrides) -> QSMAResult:
    """The stages of :func:`run` after the condensation (preload, tied modes, ramps,
    hysteresis) on a :class:`Prepared`; equals ``run(prepared.model, options)``.

    ``options.schur_backend`` is that of the preparation. The stage timings of the
    result count only the work done here (assembly and condensation are 0).
    """
    try:
        opts = replace(options or RunOptions(), **overrides)
    except TypeError as exc:
        raise InputError(f"qsma.run_prepared: {exc}; valid options: "
                         f"{sorted(RunOptions.__dataclass_fields__)}") from None
    clock = StageClock()
    model, pairing = prepared.model, prepared.pairing
    limit = threads_for(pairing.n_pairs * model.dim) if opts.blas_threads == "auto" \
        else opts.blas_threads
    with _kept_warnings() as kept:
        with threads_limited(limit):
            res = _run(model, pairing, opts, progress, clock, prepared)
    return replace(res, warnings=tuple(kept))


def _run(model, pairing, opts, progress, clock, prepared=None):
    if not pairing.n_pairs:                      # tied interfaces only: linear
        return tied_only_run(model, pairing, opts, clock, prepared)
    report = clock.report = reporter(progress)
    if opts.execution.loop_scheduler is not None:   # a wrong address: told before the ramps
        scheduler_client(opts.execution.loop_scheduler).close()
    order = body_order(model, pairing)
    sopts = opts.solver_options
    if prepared is None:
        assembled = _assemble(model, clock)
        reduced, layer, pre = preload(model, assembled, pairing, method=opts.method,
                                      opts=sopts, schur_backend=opts.schur_backend,
                                      clock=clock, contact_threads=_contact_threads(opts))
        closed = pre.status != OPEN
        pending, phi, phi_tip, omega0, ltip = _mode(model, assembled, pairing, closed,
                                                    opts, clock, reduced, layer)
    else:
        assembled = prepared.assembled
        reduced, layer, pre = prepared.preloaded(opts, clock)
        closed = pre.status != OPEN
        pending, phi, phi_tip, omega0, ltip = prepared.mode(closed, opts, clock, reduced,
                                                            layer)
    problem = layer.problem
    try:
        with clock.stage("condensation"):
            off = model.dof_offsets()
            Mphi = [a.M @ phi[off[k]:off[k + 1]] for k, a in enumerate(assembled)]
            part = lambda v, k: v[off[k]:off[k + 1]]
            reduced = reduced.add_pattern("modal", *(Mphi[i] for i in order))
            reduced = reduced.with_functionals({
                "q": tuple(Mphi[i] for i in order),
                "tip": tuple(part(ltip, i) for i in order),
            })
        response = _Response(reduced, pre)
        levels = spec_levels(model.units) if opts.levels is None else opts.levels
        alpha = levels.alpha(omega0, phi_tip)
        k_ref = omega0 ** 2

        contact_limit = _contact_threads(opts)
        with clock.stage("contact"), threads_limited(contact_limit):
            solver = _Solver(layer, reduced, opts.method, sopts,
                             zone_from_state(problem, pre.state) if opts.eliminate_open
                             else None)
            negative = _NegativeRamp(solver, response, pre,
                                     opts.execution.parallel_ramps)
            try:
                grid, user, pos = _refined_backbone(solver, alpha, pre, opts, report,
                                                    response, k_ref, negative.start)
                n_ok = len(user)
                neg = negative.result(grid[:pos.n])
            finally:
                negative.cancel()
            solver.zone = _with_closed(solver.zone, neg.status)
        with clock.stage("modal"):            # the modes beyond the loaded one
            modes = pending.result()

        with clock.stage("hysteresis"), threads_limited(contact_limit):
            hyst = level_dissipation(solver, response, grid[:pos.n], user, pos, neg, pre,
                                     opts, k_ref, report, contact_limit)
    finally:
        pending.cancel()            # a forked iteration of the modes left by an error
        if prepared is None:        # the problem dies with this run: free its zones now,
            release_zones(problem)  # not at the next collection of the cycle collector

    with clock.stage("postprocess"):
        columns = _backbone_columns(alpha[:n_ok], pos, neg, user, hyst, omega0, phi_tip)
        al, q = columns["alpha"], columns["q"]
        gross = [k for k in range(n_ok)
                 if columns["n_stuck"][k] == 0 and columns["n_slip"][k] > 0]
        shape = (n_ok, pairing.n_pairs, model.dim)
        states = LevelStates(pos.d[user].reshape(shape), pos.lam[user].reshape(shape),
                             pos.status[user], pos.residual[user], pos.nit[user])
        flags = _flags(al, q, columns["tip"], hyst, omega0, opts)
        _settle_dissipation(hyst, flags, al, q)
        success, message = _outcome(pos, flags, hyst.loops)

    loop = None
    if opts.direct_loop and n_ok:
        with clock.stage("hysteresis"), threads_limited(contact_limit):
            loop = _direct_loop(solver, response, grid[:pos.n], user[-1], pos,
                                float(hyst.dissipation_masing[-1]))

    timings = clock.done()
    return QSMAResult(
        success=success, message=message,
        model_info=dict(name=model.name, n_nodes=model.n_nodes, n_dofs=model.n_dofs,
                        n_pairs=pairing.n_pairs, dim=model.dim,
                        n_tied_pairs=getattr(pairing, "n_tied", 0),
                        mu=_mu_info(model), n_interfaces=len(model.interface_list),
                        n_closed_after_preload=int(closed.sum()),
                        elements={a.body.name: a.formulation for a in assembled},
                        coupling=pairing.coupling,
                        interface_laws=_law_info(model),
                        linear_damping=None if model.damping is None
                        else model.damping.as_dict(),
                        **_rigid_info(reduced, modes, pos, grid, user, pairing)),
        mode_index=opts.mode, omega0=omega0, phi_tip=phi_tip,
        **columns, **hyst.columns(LEVEL_FIELDS), flags=flags, states=states,
        loops=hyst.loops, backbone_alpha=grid[:pos.n],
        backbone_states=LevelStates(pos.d, pos.lam, pos.status, pos.residual, pos.nit),
        backbone_index=user,
        preload=pre, modes=modes, reduced=reduced, pairing=pairing, model=model,
        options=opts,
        solver=dict(method=chosen_method(opts.method, problem),
                    tol=opts.tol or DEFAULT_TOL, maxiter=opts.maxiter,
                    fallback_levels=[int(np.searchsorted(user, g)) for g in pos.fallback
                                     if g in set(user.tolist())],
                    open_pairs_eliminated=bool(opts.eliminate_open),
                    dissipation=opts.dissipation, dissipation_rtol=opts.dissipation_rtol,
                    backbone_points=int(pos.n), loop_solves=int(hyst.n_solves),
                    negative_ramp_levels=int(neg.n)),
        timings_s=timings, resources=_resources.snapshot(), direct_loop=loop,
        gross_slip_level=gross[0] if gross else None,
        level_costs=_level_costs(grid[user], pos.work, neg.work, hyst.loops))


def _backbone_columns(alpha, pos, neg, user, hyst, omega0, phi_tip) -> dict:
    """The level-table columns (:class:`qsma.analysis.result.LevelTable`) that come from the
    ramps at the user's levels (``user``: their indices on the refined grid): the
    load, the modal amplitudes of both backbones, the tip and the pair states."""
    n = len(alpha)
    q, tip = pos.q[user], pos.tip[user]
    q_neg = np.full(n, np.nan)
    nn = min(neg.n, pos.n)
    good_neg = np.zeros(pos.n, bool)
    good_neg[:nn] = neg.ok[:nn]
    has_neg = good_neg[user]
    q_neg[has_neg] = neg.q[user[has_neg]]
    counts = np.array([_counts(s) for s in pos.status[user]]).reshape(n, 3)
    omega = 2 * np.pi * hyst.f_hz
    return dict(alpha=alpha, tip_lin=alpha * phi_tip / omega0 ** 2, q=q, tip=tip,
                q_neg=q_neg, asymmetry=(q + q_neg) / q, tip_velocity=omega * np.abs(tip),
                n_stuck=counts[:, 0], n_slip=counts[:, 1], n_open=counts[:, 2])


def _level_costs(levels, pos_work, neg_work, loops) -> LevelCosts:
    """:class:`LevelCosts` of the user's ``levels`` from the ramps' tallies
    (:class:`_Tally`) and the loops (level index -> :class:`qsma.hysteresis.Loop`)."""
    n = len(levels)
    solves, seconds = np.zeros(n, int), np.zeros(n)
    for work in (pos_work, neg_work):
        if work is not None:
            k, t = work.per_level(levels)
            solves += k
            seconds += t
    loop = lambda get, dtype: np.array([get(loops[k]) if k in loops else 0
                                        for k in range(n)], dtype=dtype)
    return LevelCosts(solves, seconds, loop(lambda lp: lp.n_solves, int),
                      loop(lambda lp: lp.n_cycles + lp.refinement_cycles, int),
                      loop(lambda lp: lp.seconds, float))


def _law_info(model):
    """Each interface's law (its table, :meth:`InterfaceLaw.as_dict`) and whether a gap
    field shapes it; None where every interface is rigid and flat."""
    itfs = model.interface_list
    if all(i.law is None and i.gap is None for i in itfs):
        return None
    return [dict((i.law or InterfaceLaw()).as_dict(), interface=i.label,
                 gap_field=None if i.gap is None else getattr(i.gap, "source", "function"))
            for i in itfs]


def _mu_info(model):
    """The model's mu, or the list of the interfaces' when any sets its own (the tied
    interfaces, which have none, left out)."""
    itfs = [i for i in model.interface_list if not i.tied]
    if all(i.mu is None for i in itfs):
        return model.mu
    return [model.mu if i.mu is None else i.mu for i in itfs]


def _rigid_info(reduced, modes, pos, grid, user, pairing):
    """Rigid-body freedom of the run for model_info (docs/theory.md section 10): the
    rigid modes skipped (``mode`` counts elastic modes), the bodies held only by the
    joint and the largest share of their load held by the regularising spring."""
    share = [support_share(reduced, pos.d[g], _load_factors(reduced, grid[g]))
             for g in user] if getattr(reduced, "ghost", None) is not None else []
    return dict(rigid_modes=int(modes.n_rigid), mode_counts="elastic modes",
                held_by_joint=[b.name for b, held in zip(reduced.bodies, held_by_ties(
                    reduced.bodies, getattr(pairing, "tied", ()))) if not held],
                joint_spring_share_max=float(max(share, default=0.0)))
