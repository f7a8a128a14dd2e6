"""The run of a model whose interfaces are all tied: no interface can open or slip, so
its QSMA is linear and every level elastic (docs/theory.md, "Tied interfaces").

The tied mode is computed as in any run; the levels' static responses to the modal load
``alpha M phi`` come from the condensed model (no contact unknowns: ``d`` is empty), so
``q`` and the tip are the linear answers, the secant frequency is that of the static
response (f0 to the accuracy of the eigen solve), and the dissipation and damping are
zero exactly: nothing can slip.
"""
from __future__ import annotations

import warnings

import numpy as np

from .._infra import resources as _resources
from ..contact import ContactResult, ContactState
from ..errors import TiedOnlyWarning
from ..reduction.pretension import lock
from .levels import spec_levels
from .result import LevelCosts, LevelStates, QSMAResult, load_factors
from .stages import _assemble, _condense, _mode

#: Why every level of such a run is elastic (the levels' ``method_reason``, the warning).
ALL_TIED = ("every interface is tied: no interface can open or slip, so the structure "
            "is linear, its frequency the tied f0 at every amplitude and its dissipation "
            "zero")


def tied_only_run(model, pairing, opts, clock, prepared=None) -> QSMAResult:
    """The :class:`QSMAResult` of a model of tied interfaces only (module docstring)."""
    warnings.warn(TiedOnlyWarning(f"{ALL_TIED}: every level is elastic (f = f0, "
                                  f"zeta = 0); for a QSMA of a joint give its contact "
                                  f"surfaces as a frictional interface"), stacklevel=3)
    if prepared is None:
        assembled = _assemble(model, clock)
        reduced = _condense(model, assembled, pairing, opts.schur_backend, clock)
    else:
        assembled, reduced = prepared.assembled, prepared.reduced
    none = np.zeros((0, model.dim))
    pre = ContactResult(none, none, np.zeros(0, int), True, 0, 0.0,
                        "no contact unknowns: every interface is tied", "none",
                        ContactState(none, none, np.zeros(0, int)))
    if getattr(model, "bolts", ()):
        reduced = lock(reduced, model.bolts, none)        # locked at the preload
    pending, phi, phi_tip, omega0, ltip = _mode(model, assembled, pairing,
                                                np.zeros(0, bool), opts, clock, reduced)
    with clock.stage("modal"):
        modes = pending.result()
    with clock.stage("condensation"):
        off = model.dof_offsets()
        Mphi = [a.M @ phi[off[k]:off[k + 1]] for k, a in enumerate(assembled)]
        reduced = reduced.add_pattern("modal", *Mphi).with_functionals({
            "q": tuple(Mphi), "tip": tuple(ltip[off[k]:off[k + 1]]
                                           for k in range(len(assembled)))})
    levels = spec_levels(model.units) if opts.levels is None else opts.levels
    alpha = np.asarray(levels.alpha(omega0, phi_tip), dtype=float)
    with clock.stage("postprocess"):
        columns = _linear_columns(reduced, alpha, omega0, phi_tip)
    n = len(alpha)
    states = LevelStates(np.zeros((n, 0, model.dim)), np.zeros((n, 0, model.dim)),
                         np.zeros((n, 0), int), np.zeros(n), np.zeros(n, int))
    return QSMAResult(
        success=True, message=f"{ALL_TIED}; every level elastic",
        model_info=dict(name=model.name, n_nodes=model.n_nodes, n_dofs=model.n_dofs,
                        n_pairs=0, dim=model.dim, n_tied_pairs=pairing.n_tied, mu=None,
                        n_interfaces=len(model.interface_list), n_closed_after_preload=0,
                        elements={a.body.name: a.formulation for a in assembled},
                        coupling="tied", interface_laws=None,
                        linear_damping=None if model.damping is None
                        else model.damping.as_dict(),
                        rigid_modes=int(modes.n_rigid), mode_counts="elastic modes",
                        held_by_joint=[], joint_spring_share_max=0.0),
        mode_index=opts.mode, omega0=omega0, phi_tip=phi_tip, **columns, states=states,
        loops={}, backbone_alpha=alpha, backbone_states=states,
        backbone_index=np.arange(n), preload=pre, modes=modes, reduced=reduced,
        pairing=pairing, model=model, options=opts,
        solver=dict(method="none", tol=None, maxiter=opts.maxiter, fallback_levels=[],
                    open_pairs_eliminated=False, dissipation="elastic",
                    dissipation_rtol=opts.dissipation_rtol, backbone_points=n,
                    loop_solves=0, negative_ramp_levels=0),
        timings_s=clock.done(), resources=_resources.snapshot(),
        level_costs=LevelCosts(np.zeros(n, int), np.zeros(n), np.zeros(n, int),
                               np.zeros(n, int), np.zeros(n)))


def _linear_columns(reduced, alpha, omega0, phi_tip) -> dict:
    """The level table of a linear structure: q and tip of the static response to
    ``alpha M phi`` (the condensed model's functionals, ``d`` empty), the secant
    frequency of that response, zero dissipation and damping, every level elastic."""
    d = np.zeros(0)
    q = np.array([reduced.evaluate("q", d, load_factors(reduced, a)) -
                  reduced.evaluate("q", d, load_factors(reduced, 0.0)) for a in alpha])
    tip = np.array([reduced.evaluate("tip", d, load_factors(reduced, a)) -
                    reduced.evaluate("tip", d, load_factors(reduced, 0.0)) for a in alpha])
    n = len(alpha)
    zero, nan = np.zeros(n), np.full(n, np.nan)
    f = np.sqrt(alpha / q) / (2 * np.pi)
    columns = dict(
        alpha=alpha, tip_lin=alpha * phi_tip / omega0 ** 2, q=q, tip=tip, q_neg=-q,
        asymmetry=zero.copy(), f_hz=f, zeta=zero.copy(), dissipation=zero.copy(),
        dissipation_error=zero.copy(), dissipation_method=np.array(["elastic"] * n, object),
        f_hz_masing=f.copy(), zeta_masing=zero.copy(), dissipation_masing=zero.copy(),
        f_hz_loop=nan.copy(), zeta_loop=nan.copy(), dissipation_loop=nan.copy(),
        dissipation_first_cycle=nan.copy(), loop_cycles=np.zeros(n, int),
        shakedown=np.zeros(n, bool), tip_velocity=2 * np.pi * f * np.abs(tip),
        n_stuck=np.zeros(n, int), n_slip=np.zeros(n, int), n_open=np.zeros(n, int),
        method_reason=np.array([ALL_TIED] * n, object), flags=tuple(() for _ in range(n)))
    return columns
