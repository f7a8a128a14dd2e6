"""The stages of a run before its load ramps: assembly, static condensation, the
bolt preload with frictional contact (a nonlinear interface law through secant
iterations) and the loaded tied mode."""
from __future__ import annotations

import warnings

import numpy as np

from .._infra.forked import fork_refusal, second_core_refusal
from .._infra.threads import CONTACT_BLAS_THREADS, blas_threads as threads_limited
from ..contact import ContactProblem, OPEN
from ..contact.layer import Anderson, Layer, interface_springs
from ..contact.pairlaws import LOW_PRESSURE, LOW_SECANT
from ..errors import AnalysisError, ContactConvergenceWarning, InputError
from ..fe import assemble_body
from ..fe.bolts import bolt_functionals, locked_bolts, with_bolt_loads
from ..modal import leading_modes, probe_vector
from ..model.pairing import (MultiPairing, body_order, pair_gaps, pair_laws, pair_mu,
                             warn_closed_gaps)
from ..reduction.multibody import held_by_ties, reduce_model
from ..reduction.pretension import lock
from ..reduction.rigid import ANCHOR_ROUNDS, anchored, elastic_probe, held_by_joint
from ..reduction.two_bodies import reduce_two_bodies
from .clock import StageClock
from .result import load_factors as _load_factors
from .solves import _solve

#: Mortar surfaces closer than this fraction of the interface size count as coincident
#: (coordinates written with ~10 significant digits); farther apart their gaps are the
#: initial gaps of the contact problem, and reported.
GAP_REPORT_RTOL = 1e-9


def _warn_closed_gaps(model, pairing):
    """Say so when the mortar coupling found surfaces that are apart (or overlap) in the
    mesh (up to half an element apart, docs/theory.md section 8): the contact
    problem starts from these gaps."""
    warn_closed_gaps(model, pairing, GAP_REPORT_RTOL)


def preload(model, assembled, pairing, *, method="auto", opts=None, schur_backend="auto",
            clock=None, reduced=None, eliminate_open=True,
            contact_threads=CONTACT_BLAS_THREADS):
    """Condense the assembled bodies and solve the bolt preload with frictional contact.

    ``reduced``: the condensed model if already made (:func:`prepare`), else it is made.
    ``eliminate_open``: solve on the predicted contact zone, the other pairs eliminated
    exactly (:func:`qsma.contact.zone.solve_preload`; the answer is judged on the whole
    interface either way). ``contact_threads``: BLAS thread limit of the contact solve
    (``None``: as set around the call). Returns ``(reduced, layer, result)``, ``layer``
    the :class:`qsma.contact.layer.Layer` of the ramps (the interface laws linearised at
    the preload; a rigid interface's problem, unchanged, in ``layer.problem``). Raises
    :class:`AnalysisError` if the solve fails or leaves no pair in contact (tied modes
    of a disconnected assembly would be meaningless).
    """
    clock = StageClock() if clock is None else clock
    if reduced is None:
        reduced = _condense(model, assembled, pairing, schur_backend, clock)
    with clock.stage("condensation"):
        problem = _contact_problem(model, pairing, reduced.K)
        laws = pair_laws(model, pairing)
    zone = "preload" if eliminate_open else None
    with clock.stage("contact"), threads_limited(contact_threads):
        layer = _first_layer(problem, laws, reduced, method, opts or {}, zone)
        pre, layer = _preload_solve(layer, reduced, method, opts or {}, zone)
        for _ in range(ANCHOR_ROUNDS if getattr(reduced, "ghost", None) else 0):
            if not pre.success:                    # docs/theory.md section 10
                break
            reduced = anchored(reduced, pre.d)
            pre, layer = _preload_solve(layer, reduced, method, opts or {}, zone)
    if pre.success:
        pre = held_by_joint(reduced, pre, _load_factors(reduced, 0.0), "the preload")
    if not pre.success:
        raise AnalysisError(f"the preload contact solve failed: {pre.message} "
                            f"(residual {pre.residual:.2e})", partial=pre)
    bolts = getattr(model, "bolts", ())
    if bolts or layer.nonlinear or (laws is not None and laws.plastic().any()):
        with clock.stage("condensation"):
            if bolts:                                      # bolts locked from here on
                reduced = lock(reduced, locked_bolts(model), pre.d)
                problem = _contact_problem(model, pairing, reduced.K)   # same mu, gaps
            # the layer of the ramps: linearised at the preload's pressures, a plastic
            # one frozen on its elastic unloading from there
            layer = Layer(problem, laws, P_ref=pre.P, frozen=True)
    if np.all(pre.status == OPEN):
        raise AnalysisError("the preload leaves no interface pair in contact: the bodies "
                            "separate, and tied modes of a disconnected assembly would be "
                            "meaningless. Check the sign and location of the bolt pressure.",
                            partial=pre)
    _check_every_interface_closed(pairing, pre)
    return reduced, layer, pre


#: Secant iterations of the preload of a nonlinear interface law (:func:`_preload_solve`),
#: the chord iterations of its first attempt (from the rigid preload's pressures: a
#: mild law converges there, a strongly nonlinear one does not, and each failed chord
#: costs a Newton step on the closed pairs) and of each tangent attempt, and the law
#: residual of a secant iterate from which the tangent is tried.
PRELOAD_SECANTS = 100
PRELOAD_FIRST_CHORDS = 3
PRELOAD_CHORDS = 8
PRELOAD_SWITCH = 1e-3


def _first_layer(problem, laws, reduced, method, opts, zone):
    """The layer the preload starts from: a nonlinear law linearised at the pressures of
    the rigid interface's preload (a linear one needs no pressures)."""
    if laws is None or laws.linear:
        return Layer(problem, laws)
    rigid, _ = _solve(problem, reduced, 0.0, None, method, opts, "preload", zone)
    return Layer(problem, laws, P_ref=rigid.P if rigid.success else None)


def _preload_solve(layer, reduced, method, opts, zone):
    """The preload solve. For a nonlinear interface law whose chord iteration does not
    converge from the rigid preload's linearisation, secant iterations: the layer
    linearised by its secants at the pressures ``P`` (exact there), one solve, ``P``
    the new pressures (Anderson-accelerated, :class:`qsma.contact.layer.Anderson`;
    :data:`PRELOAD_SECANTS` at most; each secant layer after the first by a low-rank
    update of its normal compliance, the tangential one kept from the first, which the
    tangent's chord then makes exact). Pairs below a floor pressure are linearised at
    the floor, lowered tenfold each time the law's residual stalls, from
    :data:`qsma.contact.pairlaws.LOW_PRESSURE` to :data:`qsma.contact.pairlaws.LOW_SECANT`
    of the mean pressure. Once the law's residual is below :data:`PRELOAD_SWITCH`, the
    tangent's chord is tried from the secant's state (converging quadratically there).
    (A tangent linearisation started from the undeformed state shifts the unloaded
    pairs apart and can end in another contact set; the secant is exact where it is
    taken.) Returns ``(result, layer)``."""
    if not layer.nonlinear:
        pre, _ = _solve(layer, reduced, 0.0, None, method, opts, "preload", zone)
        return pre, layer
    with warnings.catch_warnings():       # attempts; a failure is preload()'s AnalysisError
        warnings.simplefilter("ignore", ContactConvergenceWarning)
        return _preload_attempts(layer, reduced, method, opts, zone)


def _preload_attempts(layer, reduced, method, opts, zone):
    pre, _ = _solve(layer, reduced, 0.0, None, method, opts, "preload", zone,
                    law_iterations=PRELOAD_FIRST_CHORDS)
    if pre.success or not pre.law_residual:
        return pre, layer
    P = layer.P_ref                              # the rigid preload's (_first_layer)
    accelerate, low, best, secant = Anderson(), LOW_PRESSURE, np.inf, None
    tried = PRELOAD_SWITCH * 10.0        # the tangent again only a decade closer
    for _ in range(PRELOAD_SECANTS):
        if secant is None:
            secant = Layer(layer.physical, layer.laws, P_ref=P, secant=True, low=low)
        else:                                      # only the normal compliance changes
            secant = secant.with_normal_compliance(
                layer.laws.compliance(P, secant=True, low=low)[:, -1])
        res, _ = _solve(secant, reduced, 0.0, None, method, opts, "preload", zone,
                        law_iterations=1)
        if not res.success and not res.law_residual:   # the contact solve itself failed
            return res, secant
        if res.success or res.law_residual < 0.1 * tried:
            # close enough for the tangent: its chord from this state, on the whole
            # interface (a zone solve would start from the undeformed state)
            tried = res.law_residual
            tangent = Layer(layer.physical, layer.laws, P_ref=res.P)
            done, _ = _solve(tangent, reduced, 0.0, None, method, opts, "preload", None,
                             guess=res.state, law_iterations=PRELOAD_CHORDS)
            if done.success:
                return done, tangent
        if res.law_residual > 0.9 * best and low > LOW_SECANT:
            low, best = max(0.1 * low, LOW_SECANT), np.inf    # stalled on the floor
        best = min(best, res.law_residual)
        P = np.maximum(accelerate(P, np.maximum(res.P, 0.0), ((res.P > 0).tobytes(), low)),
                       0.0)
    return res, layer


def _check_every_interface_closed(pairing, pre):
    """Several interfaces: refuse a preload that leaves one of them without a pair in
    contact. Its bodies then vibrate apart, so the tied modes and every level would
    describe a structure the joint does not hold together (as for two bodies)."""
    if not isinstance(pairing, MultiPairing):
        return
    rows = pairing.rows
    for k, itf in enumerate(pairing.interfaces):
        if np.all(pre.status[rows[k]:rows[k + 1]] == OPEN):
            raise AnalysisError(
                f"the preload leaves no pair of interface {itf.label} in contact: its "
                f"bodies separate there, and tied modes of that assembly would describe "
                f"bodies the joint does not hold together. Check the sign and location "
                f"of the bolt pressures", partial=pre)


def _contact_problem(model, pairing, K):
    """The contact problem of stiffness ``K`` with the friction coefficient and the
    initial gap of every pair (each interface's own mu, mortar gaps)."""
    return ContactProblem(K, pair_mu(model, pairing), dim=model.dim,
                          gap0=pair_gaps(model, pairing, GAP_REPORT_RTOL))


def _condense(model, assembled, pairing, schur_backend, clock):
    """The reduced model with the 'preload' pattern (static condensation): two bodies
    (with their bolts' patterns), or every body and interface
    (:func:`qsma.multibody.reduce_model`)."""
    bolts = getattr(model, "bolts", ())
    with clock.stage("condensation"):
        patterns = ("preload",) + tuple(b.pattern for b in bolts)
        if isinstance(pairing, MultiPairing):
            reduced = reduce_model(model, assembled, pairing, backend=schur_backend,
                                   patterns=patterns)
            held = held_by_ties(reduced.bodies, pairing.tied)
            free = [b.name for b, cb, h in zip(model.bodies, reduced.bodies, held)
                    if not h]
            cut = {b.body for b in bolts if hasattr(b, "section")}
            if free and free[0] in cut and model.body(free[0]).clamps:
                raise InputError(
                    f"body {free[0]!r} is cut by a pretension section, whose opening is "
                    f"held in the preload only through the interfaces: with several "
                    f"interfaces this is not supported yet (two bodies with one "
                    f"interface are). Fix: model the joint as two bodies with one "
                    f"interface (the bolt meshed with the body its thread holds)")
            if free:
                raise InputError(
                    f"body {free[0]!r} is held only through its interfaces (it has "
                    f"rigid-body freedom without clamps): with several interfaces this "
                    f"is not supported yet (only two bodies with one interface are). "
                    f"Fix: clamp {free[0]!r} where the real structure is supported, or "
                    f"model the joint as two bodies with one interface")
        else:
            i1, i2 = body_order(model, pairing)
            reduced = reduce_two_bodies(assembled[i1], assembled[i2], pairing,
                                        patterns=patterns, backend=schur_backend)
        order = body_order(model, pairing)
        return bolt_functionals(model, reduced, order) if bolts else reduced


def _assemble(model, clock, keep=None):
    """Assembled bodies; ``keep[k]``, if given and not None, is reused for body ``k``."""
    keep = [None] * len(model.bodies) if keep is None else list(keep)
    with clock.stage("assembly"):
        assembled = [assemble_body(b) if a is None else a for b, a in zip(model.bodies, keep)]
        for a in assembled:
            for name, F in a.loads.items():
                if name != "preload":
                    raise InputError(f"body {a.body.name!r}: pressure load pattern {name!r} "
                                     f"is not used by QSMA, which applies the 'preload' "
                                     f"pattern and then the modal load; set load = "
                                     f"'preload' (the default) or remove the pressure")
                if not np.all(np.isfinite(F)):
                    raise InputError(f"load {name!r} of body {a.body.name!r} is not finite")
        if getattr(model, "bolts", ()):
            assembled = with_bolt_loads(model, assembled)
    return assembled


def _mode(model, assembled, pairing, closed, opts, clock, reduced=None, layer=None):
    """The loaded mode: ``(modes, phi, phi_tip, omega0, ltip)``, tip deflection positive,
    ``modes`` a :class:`qsma.modal.ModesToCome` (the modes up to the loaded one are
    known; the others are finished on a forked process while the ramps run, where
    ``parallel_ramps`` and the platform allow it, else when asked for).
    ``reduced``: the condensed model of the preload, whose factors the shift-invert of
    the tied modes reuses (:func:`qsma.modal.linear_modes`). ``layer``: the interface
    layer of the ramps; a compliant one holds the closed pairs by its springs
    (:func:`qsma.contact.layer.interface_springs`) instead of tying them."""
    mode = opts.mode
    with clock.stage("modal"):
        nm = max(6, mode + 1) if opts.n_modes is None else opts.n_modes
        fork = (opts.execution.parallel_ramps and fork_refusal() is None
                and second_core_refusal() is None)
        pending = leading_modes(model, assembled, pairing, closed, nm, reduced,
                                interface_springs(layer, closed), mode + 1, fork)
        try:
            phi, phi_tip, ltip = _loaded_mode(model, assembled, pending.leading, mode)
        except BaseException:
            pending.cancel()
            raise
    modes = pending.leading
    return pending, phi, phi_tip, float(modes.omega[modes.n_rigid + mode]), ltip


def _loaded_mode(model, assembled, modes, mode):
    """``(phi, phi_tip, ltip)`` of elastic mode ``mode`` of ``modes``, checked to exist
    and to move the tip."""
    n_el = len(modes.omega) - modes.n_rigid
    if mode >= n_el:
        raise InputError(f"mode index {mode} is beyond the {n_el} computed modes "
                         f"(0..{n_el - 1}, elastic modes: rigid-body modes are not "
                         f"counted); raise n_modes")
    phi = modes.shapes[:, modes.n_rigid + mode].copy()
    raw = probe_vector(model)
    ltip = elastic_probe(raw, model, assembled)     # free-free: centre-of-mass frame
    phi_tip = float(ltip @ phi)
    if phi_tip < 0:
        phi, phi_tip = -phi, -phi_tip
    probe_nodes = raw != 0
    rms = float(np.sqrt(np.mean(phi[probe_nodes] ** 2)))
    if abs(phi_tip) < 1e-6 * rms or rms == 0:
        f_mode = modes.f_hz[modes.n_rigid + mode]
        raise InputError(f"mode {mode} ({f_mode:.4g} Hz) has no tip deflection "
                         f"along the probe direction (|phi_tip| = {abs(phi_tip):.2e}, "
                         f"RMS of the mode at the tip nodes {rms:.2e}); choose a mode "
                         f"that moves the tip: the load levels are scaled by it")
    return phi, phi_tip, ltip
