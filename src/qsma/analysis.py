"""Quasi-static modal analysis: preload, tied modes, modal load ramps, hysteresis.

The pipeline as the code runs it (docs/theory.md)::

    model -> assembly -> condensation -> preload contact -> tied modes
          -> modal load pattern M phi (condensed) -> ramps of contact solves for +alpha
             and -alpha (levels refined where the integration needs it)
          -> per level: Masing's rules where they are verified, else the stabilised
             loop -> checks of what the physics guarantees -> QSMAResult
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, replace
import logging
import time
import warnings

import numpy as np

from ._infra.forked import ChildFailed, ForkedCall, fork_refusal, second_core_refusal
from ._infra.threads import CONTACT_BLAS_THREADS, blas_threads as threads_limited, threads_for
from .condense import reduce_two_bodies, refactorised_bodies
from .contact import DEFAULT_TOL, ContactProblem, ContactState, OPEN, SLIPPING, STUCK
from .contact import solve as contact_solve
from .contact.laws import InterfaceLaw
from .contact.layer import (LOW_PRESSURE, LOW_SECANT, MAX_LAW_ITERATIONS, Anderson, Layer,
                            interface_springs, solve_layered)
from .contact.registry import chosen_method, method_for
from .contact.zone import (ContactZone, expected_closing, release_zones, solve_in_zone,
                           solve_preload, zone_from_state)
from .errors import (AnalysisError, ContactConvergenceWarning, InputError,
                     InterfaceGapWarning, QSMAWarning)
from .fe import assemble_body
from .hysteresis import (SECANT_RTOL, compute_loop, map_loops, masing_checks,
                         masing_estimate, scheduler_client)
from .hysteresis import loop_area
from .levels import spec_levels
from .modal import linear_modes, probe_vector
from .model import make_pairing
from .multibody import (MultiPairing, body_order, multi_pairing, pair_gaps, pair_laws,
                        pair_mu, reduce_model, warn_closed_gaps)
from ._infra import resources as _resources
from .options import RunOptions
from .progress import Progress, reporter
from .model.bolt import bolt_functionals, with_bolt_loads
from .pretension import lock
from .rigid import ANCHOR_ROUNDS, anchored, elastic_probe, held_by_joint, support_share
from .units import check_model_units
from .result import (FAILURE_FIXES, FAILURE_FLAGS, LEVEL_FIELDS,  # noqa: F401
                     DirectLoop, LevelCosts, LevelStates, QSMAResult,
                     load_factors as _load_factors)

log = logging.getLogger("qsma")

STAGES = ("model", "assembly", "modal", "condensation", "contact", "hysteresis",
          "postprocess", "total")
#: Rounds of backbone level refinement (each inserts midpoints where needed).
LEVEL_REFINE_ROUNDS = 3
#: Largest ratio of a ramp's next load increment to its last one over which the pairs
#: about to close are extrapolated (:func:`_expected_closing`): the refined grids step
#: by 0.5 to 2 times the last increment; across a larger jump a straight line says
#: little.
EXPECT_MAX_RATIO = 4.0
#: A damping ratio below this in magnitude is zero to the precision of the contact
#: solves (tol 1e-10 on forces; the stuck sandwich-2d levels give |zeta| ~ 1e-12).
ZETA_ZERO = 1e-8
#: Relative deviation of the secant frequency from f0 accepted while the interface has
#: not moved from its preload state (stuck sandwich-2d levels: 2.5e-10).
STUCK_FREQUENCY_RTOL = 1e-6


def _counts(status):
    return [int(np.sum(status == s)) for s in (STUCK, SLIPPING, OPEN)]


class _Timer:
    """Seconds per stage of :data:`STAGES`; a stage may be entered several times. Each
    entry is told to ``report`` (:class:`qsma.progress.Progress`)."""

    def __init__(self):
        self.t = dict.fromkeys(STAGES, 0.0)
        self.t0 = time.perf_counter()
        self.report = Progress()

    @contextmanager
    def stage(self, name):
        self.report.stage(name)
        start = time.perf_counter()
        try:
            yield
        finally:
            self.t[name] += time.perf_counter() - start

    def done(self):
        self.t["total"] = time.perf_counter() - self.t0
        return dict(self.t)


def run(model, options: RunOptions | None = None, *, progress=None, **overrides) -> QSMAResult:
    """Quasi-static modal analysis of ``model``.

    Parameters
    ----------
    model : :class:`qsma.model.Model` with a tip probe: two bodies and one interface, or
        any number of bodies and interfaces (``Model(interfaces=...)``, one contact
        problem over all of them, :mod:`qsma.multibody`)
    options : :class:`qsma.options.RunOptions`, optional
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


def _start(model, opts):
    """``(clock, pairing, BLAS thread limit)`` of a run: the interface pairing (timed as
    stage "model"; every interface of a model with several) and the thread limit of its
    size."""
    clock = _Timer()
    with clock.stage("model"):
        pairing = make_pairing(model) if model.interface is not None \
            else multi_pairing(model)
    _warn_closed_gaps(model, pairing)
    check_model_units(model)
    limit = threads_for(pairing.n_pairs * model.dim) if opts.blas_threads == "auto" \
        else opts.blas_threads
    return clock, pairing, limit


#: What to change when a study varies or fits the model-wide friction coefficient of
#: a model whose interfaces set their own (:meth:`qsma.model.Model.check_mu_reaches`).
STUDY_MU_FIX = ("a study varies the model's mu only where no interface sets its own "
                "(Interface(mu=None) in Python, one [interface] table in a configuration); "
                "for the interfaces of a [[interfaces]] list, run one configuration per "
                "value of their mu")


@dataclass(frozen=True, eq=False)
class Prepared:
    r"""The part of a run that a parameter study shares between its cases.

    Assembly and static condensation do not depend on the friction coefficient nor on
    the scale of the preload: the condensed loads are linear in the applied pressures,
    so scaling the 'preload' pattern by :math:`s` scales its columns of
    :math:`F_c` and of the welded contact force :math:`W` by :math:`s`. The tied modes
    depend only on the pairs closed by the preload: they are cached by that mask.
    Pickled (to a Dask worker, or from one worker to another) it keeps the condensed
    model as computed, nothing is condensed again: see :meth:`__reduce__`.

    Attributes
    ----------
    model : the model of the cases (its ``mu`` and preload pressures are the case's)
    pairing, assembled : interface pairing and the assembled bodies
    reduced : :class:`qsma.condense.ReducedModel` with the 'preload' pattern
    preload_scale : factor applied to the 'preload' pattern of the model it was made from
    schur_backend : condensation backend used
    timings_s : seconds per stage of the preparation
    """

    model: object
    pairing: object
    assembled: tuple
    reduced: object
    preload_scale: float = 1.0
    schur_backend: str = "auto"
    timings_s: dict = None
    cache: dict = None

    def __reduce__(self):
        r"""The model, pairing and assembled bodies with the condensed model as
        computed here (``K``, ``W``, the condensed loads and functionals, the factor of
        the welded pair, each body's ``Kc``); each body's sparse factor of
        :math:`K_{EE}` (not picklable) becomes a
        :class:`qsma.condense.RefactorisedEE`, which factorises :math:`K_{EE}` of the
        shipped assembled body when a solve first asks for it. A process receiving it
        (again) thus does one sparse factorisation per body, never the condensation;
        the cache (preload solves, tied modes) stays behind."""
        reduced = replace(self.reduced, bodies=refactorised_bodies(self.reduced.bodies,
                                                                   self.assembled))
        return (Prepared, (self.model, self.pairing, self.assembled, reduced,
                           self.preload_scale, self.schur_backend, self.timings_s, {}))

    def with_mu(self, mu) -> "Prepared":
        """The same preparation for friction coefficient ``mu`` (nothing recomputed).
        Refused when an interface sets a friction coefficient of its own (other than
        ``mu``): the model's ``mu`` would not reach it."""
        return replace(self, model=self.model.with_mu(mu, STUDY_MU_FIX))

    def with_preload_scale(self, scale) -> "Prepared":
        """The same preparation with every pressure of the 'preload' pattern multiplied
        by ``scale`` relative to the model it was prepared from (no re-assembly)."""
        if not (np.isfinite(scale) and scale > 0):
            raise InputError(f"the preload scale must be a positive finite number, "
                             f"got {scale!r}")
        factor = scale / self.preload_scale
        j = self.reduced.patterns.index("preload")
        col = lambda A: np.column_stack([A[:, i] * factor if i == j else A[:, i]
                                         for i in range(A.shape[1])])
        Fc = self.reduced.Fc          # per body (two bodies), or stacked (several)
        reduced = replace(self.reduced, W=col(self.reduced.W),
                          Fc=col(Fc) if isinstance(Fc, np.ndarray) else
                          tuple(col(F) for F in Fc),
                          loads=tuple(col(L) for L in self.reduced.loads))
        return replace(self, model=_scaled_preload(self.model, factor), reduced=reduced,
                       preload_scale=float(scale))

    def preloaded(self, opts, clock):
        """``(reduced, problem, preload result)`` for this model's mu and preload scale,
        cached (the preload does not depend on the load levels nor on the mode)."""
        method = method_for(opts.method, self.model.dim, self.pairing.n_pairs)
        key = ("preload", float(self.model.mu), self.preload_scale, method,
               tuple(sorted(opts.solver_options.items())))
        if key not in self.cache:
            out = preload(self.model, self.assembled, self.pairing, method=method,
                          opts=opts.solver_options, clock=clock, reduced=self.reduced,
                          contact_threads=_contact_threads(opts))
            self.cache[key] = out, out[1].problem.__dict__.get("_zone_outer")
        out, zone = self.cache[key]
        # every run starts from the elimination of the preload, whatever the zones of
        # earlier runs grew to (qsma.contact.zone.zone_from_state reads the last one
        # cached on the problem): the same bits in every run, in any order, whether
        # its ramps and loops grew the zones in this process or in forked ones
        if zone is None:
            out[1].problem.__dict__.pop("_zone_outer", None)
        else:
            out[1].problem.__dict__["_zone_outer"] = zone
        return out

    def mode(self, closed, opts, clock, reduced=None, layer=None):
        """:func:`_mode` cached by the mask of closed pairs, the mode, ``n_modes`` and the
        interface springs of a compliant layer."""
        springs = interface_springs(layer, closed)
        key = ("mode", np.asarray(closed, bool).tobytes(), opts.mode, opts.n_modes,
               None if springs is None else springs.tobytes())
        if key not in self.cache:
            self.cache[key] = _mode(self.model, self.assembled, self.pairing, closed, opts,
                                    clock, reduced, layer)
        return self.cache[key]


def _scaled_preload(model, factor):
    """``model`` with every pressure and nodal force of the 'preload' pattern and every
    bolt's pretension multiplied by ``factor``."""
    from .model import Pressure
    bodies = tuple(replace(b, pressures=tuple(
        Pressure(p.set, p.p * factor, p.load) if p.load == "preload" else p
        for p in b.pressures), forces=tuple(
        replace(f, force=tuple(v * factor for v in f.force)) if f.load == "preload" else f
        for f in b.forces)) for b in model.bodies)
    bolts = tuple(replace(b, pretension=b.pretension * factor)
                  for b in getattr(model, "bolts", ()))      # part of 'preload' too
    return replace(model, bodies=bodies, bolts=bolts)


def prepare(model, options: RunOptions | None = None, *, assembled=None) -> Prepared:
    """Pairing, assembly and static condensation of ``model``: the work a parameter
    study does once (:class:`Prepared`; :func:`run_prepared` does the rest).

    ``assembled``: per body, an :class:`qsma.fe.AssembledBody` to reuse (``None``
    entries are assembled), e.g. when only one body's material changes.
    """
    opts = options or RunOptions()
    clock, pairing, limit = _start(model, opts)
    with threads_limited(limit):
        assembled = _assemble(model, clock, keep=assembled)
        reduced = _condense(model, assembled, pairing, opts.schur_backend, clock)
    return Prepared(model, pairing, tuple(assembled), reduced, 1.0, opts.schur_backend,
                    clock.done(), {})


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
    clock = _Timer()
    model, pairing = prepared.model, prepared.pairing
    limit = threads_for(pairing.n_pairs * model.dim) if opts.blas_threads == "auto" \
        else opts.blas_threads
    with _kept_warnings() as kept:
        with threads_limited(limit):
            res = _run(model, pairing, opts, progress, clock, prepared)
    return replace(res, warnings=tuple(kept))


#: Mortar surfaces closer than this fraction of the interface size count as coincident
#: (coordinates written with ~10 significant digits); farther apart their gaps are the
#: initial gaps of the contact problem, and reported.
GAP_REPORT_RTOL = 1e-9


def _warn_closed_gaps(model, pairing):
    """Say so when the mortar coupling found surfaces that are apart (or overlap) in the
    mesh (gaps up to a tenth of an element, docs/theory.md section 8): the contact
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
    clock = _Timer() if clock is None else clock
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
                reduced = lock(reduced, model.bolts, pre.d)
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
    :data:`qsma.contact.layer.LOW_PRESSURE` to :data:`qsma.contact.layer.LOW_SECANT`
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
            free = [b.name for b, cb in zip(model.bodies, reduced.bodies)
                    if cb.rigid is not None]
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
    """The loaded mode: ``(modes, phi, phi_tip, omega0, ltip)``, tip deflection positive.
    ``reduced``: the condensed model of the preload, whose factors the shift-invert of
    the tied modes reuses (:func:`qsma.modal.linear_modes`). ``layer``: the interface
    layer of the ramps; a compliant one holds the closed pairs by its springs
    (:func:`qsma.contact.layer.interface_springs`) instead of tying them."""
    mode = opts.mode
    with clock.stage("modal"):
        nm = max(6, mode + 1) if opts.n_modes is None else opts.n_modes
        modes = linear_modes(model, assembled, pairing, tied=closed, n_modes=nm,
                             reduced=reduced, springs=interface_springs(layer, closed))
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
    return modes, phi, phi_tip, float(modes.omega[modes.n_rigid + mode]), ltip


def _contact_threads(opts):
    """BLAS thread limit of the contact solves: one under ``blas_threads="auto"``
    (:data:`qsma._threads.CONTACT_BLAS_THREADS`), else the run's own setting."""
    return CONTACT_BLAS_THREADS if opts.blas_threads == "auto" else None


def _run(model, pairing, opts, progress, clock, prepared=None):
    report = clock.report = reporter(progress)
    if opts.loop_scheduler is not None:    # a wrong address is told before the ramps
        scheduler_client(opts.loop_scheduler).close()
    order = body_order(model, pairing)
    sopts = opts.solver_options
    if prepared is None:
        assembled = _assemble(model, clock)
        reduced, layer, pre = preload(model, assembled, pairing, method=opts.method,
                                      opts=sopts, schur_backend=opts.schur_backend,
                                      clock=clock, contact_threads=_contact_threads(opts))
        closed = pre.status != OPEN
        modes, phi, phi_tip, omega0, ltip = _mode(model, assembled, pairing, closed, opts,
                                                  clock, reduced, layer)
    else:
        assembled = prepared.assembled
        reduced, layer, pre = prepared.preloaded(opts, clock)
        closed = pre.status != OPEN
        modes, phi, phi_tip, omega0, ltip = prepared.mode(closed, opts, clock, reduced,
                                                          layer)
    problem = layer.problem

    with clock.stage("condensation"):
        off = model.dof_offsets()
        Mphi = [a.M @ phi[off[k]:off[k + 1]] for k, a in enumerate(assembled)]
        part = lambda v, k: v[off[k]:off[k + 1]]
        reduced = reduced.add_pattern("modal", *(Mphi[i] for i in order)).with_functionals({
            "q": tuple(Mphi[i] for i in order),
            "tip": tuple(part(ltip, i) for i in order),
        })
    response = _Response(reduced, pre)
    levels = spec_levels(model.units) if opts.levels is None else opts.levels
    alpha = levels.alpha(omega0, phi_tip)
    k_ref = omega0 ** 2

    contact_limit = _contact_threads(opts)
    try:
        with clock.stage("contact"), threads_limited(contact_limit):
            solver = _Solver(layer, reduced, opts.method, sopts,
                             zone_from_state(problem, pre.state) if opts.eliminate_open
                             else None)
            negative = _NegativeRamp(solver, response, pre, opts.parallel_ramps)
            try:
                grid, user, pos = _refined_backbone(solver, alpha, pre, opts, report,
                                                    response, k_ref, negative.start)
                n_ok = len(user)
                neg = negative.result(grid[:pos.n])
            finally:
                negative.cancel()
            solver.zone = _with_closed(solver.zone, neg.status)

        with clock.stage("hysteresis"), threads_limited(contact_limit):
            hyst = _hysteresis(solver, response, grid[:pos.n], user, pos, neg, pre, opts,
                               k_ref, report, contact_limit)
    finally:
        if prepared is None:        # the problem dies with this run: free its zones now,
            release_zones(problem)  # not at the next collection of the cycle collector

    with clock.stage("postprocess"):
        al = alpha[:n_ok]
        q = pos.q[user]
        tip = pos.tip[user]
        q_neg = np.full(n_ok, np.nan)
        nn = min(neg.n, pos.n)
        good_neg = np.zeros(pos.n, bool)
        good_neg[:nn] = neg.ok[:nn]
        has_neg = good_neg[user]
        q_neg[has_neg] = neg.q[user[has_neg]]
        status = pos.status[user]
        counts = np.array([_counts(s) for s in status]).reshape(n_ok, 3)
        gross = [k for k in range(n_ok) if counts[k, 0] == 0 and counts[k, 1] > 0]
        shape = (n_ok, pairing.n_pairs, model.dim)
        states = LevelStates(pos.d[user].reshape(shape), pos.lam[user].reshape(shape), status,
                             pos.residual[user], pos.nit[user])
        omega = np.where(hyst["use_loop"], 2 * np.pi * hyst["f_hz_loop"],
                         2 * np.pi * hyst["f_hz_masing"])
        flags = _flags(al, q, tip, hyst, omega0, opts)
        _settle_dissipation(hyst, flags, al, q)
        success, message = _outcome(pos, flags, hyst["loops"])

    loop = None
    if opts.direct_loop and n_ok:
        with clock.stage("hysteresis"), threads_limited(contact_limit):
            loop = _direct_loop(solver, response, grid[:pos.n], user[-1], pos,
                                float(hyst["dissipation_masing"][-1]))

    timings = clock.done()
    return QSMAResult(
        success=success, message=message,
        model_info=dict(name=model.name, n_nodes=model.n_nodes, n_dofs=model.n_dofs,
                        n_pairs=pairing.n_pairs, dim=model.dim,
                        mu=_mu_info(model), n_interfaces=len(model.interface_list),
                        n_closed_after_preload=int(closed.sum()),
                        elements={a.body.name: a.formulation for a in assembled},
                        coupling=pairing.coupling,
                        interface_laws=_law_info(model),
                        linear_damping=None if model.damping is None
                        else model.damping.as_dict(),
                        **_rigid_info(reduced, modes, pos, grid, user)),
        mode_index=opts.mode, omega0=omega0, phi_tip=phi_tip,
        alpha=al, tip_lin=al * phi_tip / omega0 ** 2, q=q, tip=tip,
        q_neg=q_neg, asymmetry=(q + q_neg) / q,
        f_hz=np.where(hyst["use_loop"], hyst["f_hz_loop"], hyst["f_hz_masing"]),
        zeta=np.where(hyst["use_loop"], hyst["zeta_loop"], hyst["zeta_masing"]),
        dissipation=np.where(hyst["use_loop"], hyst["dissipation_loop"],
                             hyst["dissipation_masing"]),
        dissipation_error=np.where(hyst["use_loop"], hyst["loop_error"],
                                   hyst["masing_error"]),
        dissipation_method=np.where(hyst["use_loop"], "loop", "masing").astype(object),
        method_reason=hyst["reason"],
        f_hz_masing=hyst["f_hz_masing"], zeta_masing=hyst["zeta_masing"],
        dissipation_masing=hyst["dissipation_masing"], f_hz_loop=hyst["f_hz_loop"],
        zeta_loop=hyst["zeta_loop"], dissipation_loop=hyst["dissipation_loop"],
        dissipation_first_cycle=hyst["first"], loop_cycles=hyst["cycles"],
        shakedown=hyst["shakedown"], tip_velocity=omega * np.abs(tip),
        n_stuck=counts[:, 0], n_slip=counts[:, 1], n_open=counts[:, 2], flags=flags,
        states=states, loops=hyst["loops"], backbone_alpha=grid[:pos.n],
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
                    backbone_points=int(pos.n), loop_solves=int(hyst["n_solves"]),
                    negative_ramp_levels=int(neg.n)),
        timings_s=timings, resources=_resources.snapshot(), direct_loop=loop,
        gross_slip_level=gross[0] if gross else None,
        level_costs=_level_costs(grid[user], pos.work, neg.work, hyst["loops"]))


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
    """The model's mu, or the list of the interfaces' when any sets its own."""
    itfs = model.interface_list
    if all(i.mu is None for i in itfs):
        return model.mu
    return [model.mu if i.mu is None else i.mu for i in itfs]


def _rigid_info(reduced, modes, pos, grid, user):
    """Rigid-body freedom of the run for model_info (docs/theory.md section 10): the
    rigid modes skipped (``mode`` counts elastic modes), the bodies held only by the
    joint and the largest share of their load held by the regularising spring."""
    share = [support_share(reduced, pos.d[g], _load_factors(reduced, grid[g]))
             for g in user] if getattr(reduced, "ghost", None) is not None else []
    return dict(rigid_modes=int(modes.n_rigid), mode_counts="elastic modes",
                held_by_joint=[b.name for b in reduced.bodies if b.rigid is not None],
                joint_spring_share_max=float(max(share, default=0.0)))


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


@dataclass
class _RampOut:
    """A ramp's solutions, one row per point of its grid that was solved."""

    d: np.ndarray
    lam: np.ndarray
    status: np.ndarray
    residual: np.ndarray
    nit: np.ndarray
    ok: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    fallback: list
    success: bool
    message: str
    failed_at: int | None
    work: "_Tally | None" = None

    @property
    def n(self):
        return len(self.q)

    def state(self, k):
        return ContactState(self.d[k], self.lam[k], self.status[k])


def _ramp(solver, alpha, start, keep_going, progress, where="load level", response=None,
          prefix=None, guesses=None, work=None):
    """Monotonic ramp through ``alpha`` from ``start``; ``prefix`` (a :class:`_RampOut`
    and its length) reuses levels already solved on the same path; ``guesses`` maps a
    level to a state to start its iteration from (the same level solved on a coarser
    grid: the path differs, so the level is solved again, but from near its answer),
    handed to a :class:`_Solver` as its ``guess``. ``work``: the :class:`_Tally` each
    solve is counted in (a new one if None), returned as the ramp's ``work``."""
    work = _Tally() if work is None else work
    rows = {k: [] for k in ("d", "lam", "status", "residual", "nit", "ok", "q", "tip")}
    fallback, success, message, failed = [], True, "all levels converged", None
    state, first = start, 0
    if prefix is not None:
        old, first = prefix
        for name in rows:
            rows[name] = list(getattr(old, name)[:first])
        fallback = [k for k in old.fallback if k < first]
        if first:
            state = old.state(first - 1)
    for k in range(first, len(alpha)):
        a = alpha[k]
        if guesses is not None:
            solver.guess = guesses.get(float(a))      # read (and cleared) by the solve
        started = time.perf_counter()
        res = solver(a, state, f"{where} {k} (alpha={a:.4g})",
                     _expected_closing(solver.problem, alpha, k, rows))
        work.add(a, time.perf_counter() - started)
        if not res.success:
            success = False
            failed = k if failed is None else failed
            message = (f"contact solve failed at {where} {k} (alpha={a:.6g}): "
                       f"{res.message}; residual {res.residual:.2e}")
            if not keep_going:
                break
        if res.fallback is not None:          # set by the contact method registry
            fallback.append(k)
            log.info("%s %d: solver fell back: %s", where, k, res.message)
        for name, v in (("d", res.d), ("lam", res.lam), ("status", res.status),
                        ("residual", res.residual), ("nit", res.nit), ("ok", res.success)):
            rows[name].append(v)
        rows["q"].append(response.q(res.d, a) if response else np.nan)
        rows["tip"].append(response.tip(res.d, a) if response else np.nan)
        state = res.state
        if progress is not None:
            progress(k + 1, len(alpha))
    n = len(rows["q"])
    arr = {k: np.array(v) for k, v in rows.items()}
    shape = (n,) + start.d.shape
    return _RampOut(arr["d"].reshape(shape), arr["lam"].reshape(shape),
                    arr["status"].reshape(n, len(start.status)).astype(int),
                    arr["residual"].astype(float), arr["nit"].astype(int),
                    arr["ok"].astype(bool), arr["q"].astype(float),
                    arr["tip"].astype(float), fallback, success, message, failed, work)


class _Tally:
    """The contact solves of a ramp, by the modal force of each: its level's share of
    the run's work (:func:`_level_costs`); a refinement round's re-solves count again."""

    def __init__(self):
        self.alpha, self.seconds = [], []

    def add(self, alpha, seconds):
        self.alpha.append(abs(float(alpha)))
        self.seconds.append(float(seconds))

    def per_level(self, levels):
        """``(solves, seconds)`` per level of the increasing ``levels``: each solve
        counts at the first level at or above its ``|alpha|`` (the interval it refines
        or reaches the level through); solves beyond the last level are not counted."""
        at = np.searchsorted(np.asarray(levels, float), self.alpha, side="left")
        inside = at < len(levels)
        solves = np.bincount(at[inside], minlength=len(levels))
        seconds = np.bincount(at[inside], np.asarray(self.seconds)[inside],
                              minlength=len(levels))
        return solves.astype(int), seconds.astype(float)


def _expected_closing(problem, alpha, k, rows):
    """Pairs expected to close at level ``k`` of a ramp, extrapolated from the two
    converged levels before it (:func:`qsma.contact.zone.expected_closing`), or None
    (fewer than two, a failed one, or a next increment that is not 0 to
    :data:`EXPECT_MAX_RATIO` times the last one: a grid that turns back or jumps)."""
    if k < 2 or not (rows["ok"][k - 1] and rows["ok"][k - 2]):
        return None
    last = alpha[k - 1] - alpha[k - 2]
    ratio = (alpha[k] - alpha[k - 1]) / last if last != 0 else 0.0
    if not 0 < ratio <= EXPECT_MAX_RATIO:
        return None
    return expected_closing(problem, rows["d"][k - 2], rows["d"][k - 1], ratio)


class _NegativeRamp:
    """The -alpha ramp on the final backbone grid, from the contact zone that the
    +alpha ramp had when it chose that grid.

    The last refinement round of the +alpha ramp and this ramp need the same grid and
    nothing of each other. :meth:`start`, called with the grid of the last round before
    that round is solved, forks a child process that solves this ramp while the round
    runs here (``RunOptions.parallel_ramps``, on Linux where
    :func:`qsma._forked.fork_refusal` allows it). :meth:`result` takes the child's
    ramp if it was solved on the grid finally kept, and otherwise (no last round, a
    round that failed and kept the coarser grid, no fork, a child that failed) solves
    it here from the same zone: either way the same floating-point operations, the
    same bits. The ramp has a solver of its own; the pairs it closed join the +alpha
    ramp's zone afterwards (:func:`_with_closed`), which the loops start from."""

    def __init__(self, solver, response, pre, fork):
        self.solver, self.response, self.pre, self.fork = solver, response, pre, fork
        self.zone = self.grid = self.child = None

    def start(self, grid):
        self.zone, self.grid = self.solver.zone, np.array(grid, dtype=float)
        if not self.fork:
            return
        why_not = fork_refusal() or second_core_refusal()
        if why_not is not None:
            log.info("negative ramp solved after the positive one: %s", why_not)
            return
        self.child = ForkedCall(lambda: self._solved(self.grid))

    def result(self, grid):
        """The -alpha ramp on ``grid``."""
        if self.grid is None:                    # no last round: the zone is the last one
            self.zone = self.solver.zone
        if self.child is not None and np.array_equal(grid, self.grid):
            try:
                return self.child.result()
            except ChildFailed as exc:
                log.warning("negative ramp solved again in this process: %s", exc)
            finally:
                self.child = None
        self.cancel()
        return self._solved(grid)

    def cancel(self):
        if self.child is not None:
            self.child.cancel()
            self.child = None

    def _solved(self, grid):
        s = self.solver
        solver = _Solver(s.layer, s.reduced, s.method, s.opts, self.zone)
        return _ramp(solver, -np.asarray(grid, dtype=float), self.pre.state, True, None,
                     "negative load level", response=self.response)


def _refined_backbone(solver, alpha, pre, opts, report, response, k_ref, last_round=None):
    """The +alpha ramp on the user's levels, then on a grid refined where the Masing
    integral needs it (pair states change in an interval, or the error estimate exceeds
    ``dissipation_rtol``). Returns ``(grid, user_index, ramp)``: ``grid[user_index]``
    are the user's levels that were solved. ``last_round(grid)``, optional, is called
    with the grid of the last refinement round before that round is solved (the
    grid kept unless the round fails)."""
    grid = np.asarray(alpha, float)
    report.task("levels", len(alpha))
    tick = lambda k, n: report.advance("levels", min(k, len(alpha)), len(alpha))
    out = _ramp(solver, grid, pre.state, opts.continue_on_failure, tick, response=response)
    work = out.work
    rounds = LEVEL_REFINE_ROUNDS if opts.refine_levels and out.success else 0
    for r in range(rounds):
        new = _insert_levels(grid, out, k_ref, opts.dissipation_rtol, pre.status)
        if new is None:
            break
        first = int(np.flatnonzero(new[:len(grid)] != grid)[0]) if not np.array_equal(
            new[:len(grid)], grid) else len(grid)
        if last_round is not None and r == rounds - 1:
            last_round(new)
        report.task("refinement", len(new))
        trial = _ramp(solver, new, pre.state, False,
                      lambda k, n: report.advance("refinement", k, n), response=response,
                      prefix=(out, first),
                      guesses={float(grid[j]): out.state(j) for j in range(first, out.n)
                               if out.ok[j]}, work=work)
        if not trial.success:          # keep the converged coarser grid
            break
        grid, out = new, trial
        log.info("backbone refined to %d points", len(grid))
    user = np.flatnonzero(np.isin(grid, np.asarray(alpha, float)))
    user = user[user < out.n]
    if not opts.continue_on_failure and not out.success:
        user = user[user < out.failed_at] if out.failed_at is not None else user
    return grid, user, out


def _insert_levels(grid, out, k_ref, rtol, pre_status):
    """The grid with midpoints inserted where the backbone needs them, or None.

    The interval ending at point ``k`` is ``(k-1, k]``, the first one ``(0, alpha_0]``
    from the preload; it is halved where a pair changed state across it or where the
    error estimate at ``k`` (which covers ``(k-2, k]``) or at ``k+1`` is too large."""
    n = out.n
    est = masing_estimate(grid[:n], out.q, k_ref)
    atol = ZETA_ZERO * 2 * np.pi * grid[:n] * np.abs(out.q)
    need = est.error > rtol * np.abs(est.dissipation) + atol
    before = np.concatenate([pre_status[None, :], out.status[:-1]])
    changed = np.any(out.status != before, axis=1)
    pick = need | changed
    pick[:-1] |= need[1:]
    if not pick.any():
        return None
    lo = np.concatenate([[0.0], grid[:n - 1]])
    return np.union1d(grid, 0.5 * (lo + grid[:n])[pick])


def _hysteresis(solver, response, grid, user, pos, neg, pre, opts, k_ref, report=None,
                threads=None):
    """Masing estimates, checks and loops at the user's levels (see module docstring);
    ``threads``: the BLAS thread limit of the loops' contact solves."""
    n_ok, n = len(user), pos.n
    est = masing_estimate(grid, pos.q, k_ref)
    nn = min(n, neg.n)
    q_neg = np.full(n, np.nan)
    q_neg[:nn] = neg.q[:nn]
    P_pre, open_pre = pre.lam[:, -1], pre.status == OPEN
    P_neg = np.full((n, len(P_pre)), np.nan)
    P_neg[:nn] = neg.lam[:nn, :, -1]
    neg_status = np.broadcast_to(pre.status, (n, len(P_pre))).copy()
    neg_status[:nn] = neg.status[:nn]
    open_neg = neg_status == OPEN
    atol = ZETA_ZERO * 2 * np.pi * grid * np.abs(pos.q)
    linear = _untouched(pos.status, pre) & _untouched(neg_status, pre)
    checks = masing_checks(grid, pos.q, np.where(np.isnan(q_neg), -pos.q, q_neg),
                           pos.lam[:, :, -1], np.where(np.isnan(P_neg), P_pre, P_neg), P_pre,
                           pos.status == OPEN, open_neg, open_pre, k_ref,
                           opts.dissipation_rtol, atol, linear=linear)
    valid = checks.valid.copy()
    valid[nn:] = False                 # no negative backbone there: nothing verified
    reason = np.where(valid, np.where(linear, "linear: no pair has left its preload state",
                                      "Masing's assumptions verified"),
                      checks.reason).astype(object)
    reason[~valid & (checks.reason == "")] = "negative ramp failed: symmetry not verified"
    if opts.dissipation == "masing":
        use_loop = np.zeros(n, bool)
        reason = np.array([r if v else f"forced by dissipation='masing' although {r}"
                           for r, v in zip(reason, valid)], dtype=object)
    elif opts.dissipation == "loop":
        use_loop = np.ones(n, bool)
        reason = np.full(n, "forced by dissipation='loop'", dtype=object)
    else:
        use_loop = ~valid
    nan = np.full(n_ok, np.nan)
    out = dict(f_hz_masing=est.omega[user] / (2 * np.pi), zeta_masing=est.zeta[user],
               dissipation_masing=est.dissipation[user], masing_error=est.error[user],
               f_hz_loop=nan.copy(), zeta_loop=nan.copy(), dissipation_loop=nan.copy(),
               loop_error=nan.copy(), first=nan.copy(), cycles=np.zeros(n_ok, int),
               shakedown=np.zeros(n_ok, bool), use_loop=use_loop[user],
               reason=reason[user], loops={}, n_solves=0,
               no_slip=_no_rubbing(solver.problem.mu, pos.status, neg_status, nn)[user],
               linear=linear[user])
    todo = np.flatnonzero(out["use_loop"])
    job = _LevelLoops(solver.layer, _InterfaceLoads.of(solver.reduced), solver.method,
                      solver.opts, _outermost(solver.zone), response, grid, user, pos,
                      neg_status,
                      _linear_end(pos, pre), opts, k_ref, threads)
    report = report or Progress()
    report.task("loops", len(todo))
    done = lambda j: report.advance("loops", j, len(todo))
    loops = map_loops(job, todo, opts.loop_worker_count, done, opts.loop_scheduler)
    for i, lp in zip(todo, loops):
        out["loops"][i] = lp
        out["n_solves"] += lp.n_solves
        log.info("level %d: loop at A=%.4g, %s, %d solves in %d cycles, %.2f s, "
                 "D=%.4g +- %.1g", i, lp.amplitude, lp.message, lp.n_solves,
                 lp.n_cycles + lp.refinement_cycles, lp.seconds, lp.dissipation, lp.error)
        out["cycles"][i] = lp.n_cycles
        if lp.success:
            out["f_hz_loop"][i] = lp.omega / (2 * np.pi)
            out["zeta_loop"][i] = lp.zeta
            out["dissipation_loop"][i] = lp.dissipation
            out["loop_error"][i] = lp.error
            out["first"][i] = lp.first_dissipation
            out["shakedown"][i] = lp.shakedown or _first_loading_differs(
                lp, pos.q[user[i]], q_neg[user[i]], opts.dissipation_rtol)
    return out


@dataclass(frozen=True, eq=False)
class _InterfaceLoads:
    """What the contact solves of a run read of its reduced model: the welded force per
    load pattern (``W``, ``patterns``) and the regularising spring of bodies held only
    by the joint with their names (:func:`qsma.rigid.held_by_joint`). Small enough to
    ship to another process, where the bodies' factorisations could not go."""

    W: np.ndarray
    patterns: tuple
    ghost: object
    bodies: tuple

    @classmethod
    def of(cls, reduced):
        bodies = tuple(_HeldBody(b.name, getattr(b, "rigid", None))
                       for b in getattr(reduced, "bodies", ()))
        return cls(reduced.W, tuple(reduced.patterns), getattr(reduced, "ghost", None),
                   bodies)


@dataclass(frozen=True)
class _HeldBody:
    """A body's name and its rigid motions free of clamps (None: clamped)."""

    name: str
    rigid: object


@dataclass(frozen=True, eq=False)
class _LevelLoops:
    """The loop of a level given the backbones: a job of
    :func:`qsma.hysteresis.map_loops`, called with the level's index.

    Holds everything a loop reads: the interface's contact problem (in ``layer``),
    the ramps' contact zone with its eliminations, the backbone states and the options;
    not the bodies or their factorisations, so that it can be shipped to the workers of
    a Dask scheduler as it is (pickled; nothing is condensed again there). Every loop
    starts from a solver of its own on the ramps' zone and layer, so that its bits do
    not depend on the loops solved before it, nor on the process solving it.
    """

    layer: object
    loads: _InterfaceLoads
    method: str
    solver_options: dict
    zone: object
    response: object
    grid: np.ndarray
    user: np.ndarray
    pos: object
    neg_status: np.ndarray
    linear_end: int
    opts: RunOptions
    k_ref: float
    threads: object

    def __call__(self, i):
        g = self.user[i]
        A = self.grid[g]
        u = _loop_fractions(self.grid, g, self.linear_end, self.opts.loop_steps)
        zone = _loop_zone(self.zone, self.pos.status[:g + 1], self.neg_status[:g + 1])
        solver = _Solver(self.layer, self.loads, self.method, self.solver_options, zone)

        def step(a, s, closing=None, guess=None):
            solver.guess = guess        # the state at this load a cycle before, or None
            return solver(a, s, f"loop at A={A:.4g} (alpha={a:.4g})", closing)

        started = time.perf_counter()
        with threads_limited(self.threads):
            lp = compute_loop(step, self.response.q, A, self.pos.state(g), u,
                              k_ref=self.k_ref, max_cycles=self.opts.max_cycles,
                              rtol=self.opts.dissipation_rtol,
                              atol=ZETA_ZERO * 2 * np.pi * A * abs(self.pos.q[g]),
                              expect_closing=True, warm_start=True)
        return replace(lp, seconds=time.perf_counter() - started)


def _no_rubbing(mu, pos_status, neg_status, n_neg) -> np.ndarray:
    """Per ramp point: no pair with friction (mu > 0) slips on either ramp up to it. A
    cycle within that range is elastic (opening and closing store energy, only
    friction dissipates), so its dissipation is exactly zero. Points beyond the
    ``n_neg`` solved points of the -alpha ramp are not known to be so."""
    rubbing = np.broadcast_to(np.asarray(mu, float) > 0, pos_status.shape[1:])
    slips = np.any((pos_status == SLIPPING) & rubbing, axis=1) | \
        np.any((neg_status == SLIPPING) & rubbing, axis=1)
    slips[n_neg:] = True
    return ~np.logical_or.accumulate(slips)


def _settle_dissipation(hyst, flags, alpha, q):
    """The dissipation as reported, where it is zero to the precision it was computed
    with: exactly 0 where no pair with friction slipped (``hyst["no_slip"]``), and 0 for
    a negative value within the round-off bound ``ZETA_ZERO 2 pi alpha |q|`` of the
    contact solves it comes from (a cycle cannot create energy). A negative value
    beyond that bound is flagged ``negative_dissipation`` (:func:`_flags`) and kept, as
    is every value of a level with a failure flag."""
    bound = ZETA_ZERO * 2 * np.pi * np.asarray(alpha) * np.abs(q)
    sound = np.array([not set(f) & set(FAILURE_FLAGS) for f in flags], bool)
    for method in ("masing", "loop"):
        D, zeta = hyst[f"dissipation_{method}"], hyst[f"zeta_{method}"]
        err = hyst[f"{method}_error"]
        negligible = np.array([_negligible_negative(*x) for x in zip(D, err, alpha, q)],
                              bool)
        zero = sound & np.isfinite(D) & (hyst["no_slip"] | ((D < 0) & (-D <= bound))
                                         | negligible)
        D[zero] = 0.0
        zeta[zero] = 0.0


#: A damping ratio below which a joint's damping is negligible to an engineer (a
#: hundredth of the least a bolted joint gives, about 1e-2 at its microslip levels).
ZETA_NEGLIGIBLE = 1e-4


def _negligible_negative(D, error, alpha, q) -> bool:
    """Whether a negative dissipation ``D`` is zero within its own error estimate and
    that estimate, as a damping ratio, is negligible (:data:`ZETA_NEGLIGIBLE`): then
    the level's damping is reported as 0 with its estimate (a cycle cannot create
    energy, and the true value lies between 0 and the estimate). lap-3d refine 1 at
    its level 12: D = -1.2e-9 J within its estimate 1.6e-8 J (zeta 3.6e-5) between
    neighbours of +4e-7 and +2e-7. A negative value beyond its estimate, or with an
    estimate that is not negligible, stays a failure (``negative_dissipation``)."""
    scale = 2 * np.pi * abs(alpha) * abs(q)
    return bool(np.isfinite(D) and np.isfinite(error) and D < 0 and -D <= error
                and error <= ZETA_NEGLIGIBLE * scale)


def _first_loading_differs(lp, q_top, q_bottom, rtol) -> bool:
    """Whether the stabilised loop turns elsewhere than the first loadings to ``+A`` and
    ``-A`` (the backbones' ``q_top``, ``q_bottom``) by more than ``rtol`` of its
    half-range: the ramps slipped where the cycle does not (pairs left at the friction
    limit by the preload slide once, then the cycle is elastic). The level's ``q`` and
    ``tip`` are then those of the first loading and its ``f`` and ``zeta`` those of the
    settled cycle: a shakedown, flagged as one."""
    off = max(abs(lp.q_top - q_top), abs(lp.q_bottom - q_bottom) if np.isfinite(q_bottom)
              else 0.0)
    return bool(off > rtol * abs(lp.q_amplitude))


def _with_closed(zone, status):
    """``zone`` grown by the pairs closed at some point of ``status`` (a ramp's states,
    levels x pairs) outside it: the -alpha ramp is solved with a solver of its own
    (:class:`_NegativeRamp`), so the pairs only it closed join the ramps' zone here,
    before the loops are carved out of it (:func:`_loop_zone`)."""
    if zone is None or isinstance(zone, str) or len(status) == 0:
        return zone
    outside = np.any(np.asarray(status) != OPEN, axis=0) & ~zone.keep
    return zone.grown(outside) if outside.any() else zone


def _outermost(zone):
    """``zone`` reduced to its outermost elimination, all the loops carve theirs from
    (:func:`_loop_zone`): what a loop needs of it, and no more to ship."""
    if zone is None or isinstance(zone, str):
        return zone
    outer = zone.steps[0]
    return ContactZone(zone.full, outer.keep, (outer,))


def _loop_zone(zone, *statuses):
    """The zone of a loop: the pairs closed anywhere on either backbone up to its
    amplitude, carved out of the ramps' zone (which holds every pair closed on them).
    The elimination is exact; a pair that closes only within the loop joins the zone
    when it closes (:func:`qsma.contact.zone.solve_in_zone`)."""
    if zone is None or isinstance(zone, str):
        return zone
    keep = np.zeros_like(zone.keep)
    for status in statuses:
        keep |= np.any(np.asarray(status) != OPEN, axis=0)
    return zone.narrowed(keep & zone.steps[0].keep)


def _untouched(status, pre):
    """Per ramp point: no pair has left its preload state (status) up to it; a slipping
    pair in the preload counts as moved."""
    same = np.all(status == pre.status[None, :], axis=1) & \
        np.all(status != SLIPPING, axis=1)
    return np.cumprod(same).astype(bool)


def _linear_end(pos, pre):
    """Index of the last ramp point before any pair left its preload state (the
    backbone is the tied linear response up to it), or -1."""
    same = np.all(pos.status == pre.status[None, :], axis=1) & \
        np.all(pos.status != SLIPPING, axis=1)
    moved = np.flatnonzero(~same)
    return (moved[0] if moved.size else pos.n) - 1


#: Fewest increments per loop branch: a loop at one of the first backbone points has
#: few points below it to mirror, and a branch of one increment has no area.
MIN_LOOP_STEPS = 8


def _loop_fractions(grid, g, linear_end, steps):
    """Branch increments of the loop at grid point ``g`` as fractions of ``2A``: the
    backbone points below it (Masing's construction unloads by twice each), from the
    end of the linear range, thinned to at most ``steps``, with at least
    :data:`MIN_LOOP_STEPS` (uniform ones added where the backbone has fewer)."""
    start = max(min(linear_end, g - 1), 0)
    u = grid[start:g + 1] / grid[g]
    if len(u) > steps:
        keep = np.unique(np.round(np.linspace(0, len(u) - 1, steps)).astype(int))
        u = u[keep]
    if len(u) < MIN_LOOP_STEPS:
        u = np.union1d(u, np.linspace(0.0, 1.0, MIN_LOOP_STEPS + 1)[1:])
    return u


def _flags(alpha, q, tip, hyst, omega0, opts):
    """Per level, what the physics forbids (failures) and what it allows but a reader
    should know (information); see :data:`FAILURE_FLAGS`."""
    n = len(alpha)
    use_loop = hyst["use_loop"]
    f = np.where(use_loop, hyst["f_hz_loop"], hyst["f_hz_masing"])
    zeta = np.where(use_loop, hyst["zeta_loop"], hyst["zeta_masing"])
    err = np.where(use_loop, hyst["loop_error"], hyst["masing_error"])
    D = np.where(use_loop, hyst["dissipation_loop"], hyst["dissipation_masing"])
    f0 = omega0 / (2 * np.pi)
    # no pair has left its preload state on either ramp up to the level (every point
    # of both refined ramps): the +alpha states of the output levels alone would call
    # a level whose -alpha ramp slips untouched, and its damping a misfire
    untouched = hyst["linear"]
    out = []
    for k in range(n):
        fl = []
        if not (np.isfinite(f[k]) and np.isfinite(zeta[k])):
            lp = hyst["loops"].get(k)
            fl.append("not_finite" if lp is None else
                      "loop_not_stabilised" if lp.outcome == "not_stabilised" else
                      "loop_failed")
        elif D[k] < -ZETA_ZERO * 2 * np.pi * alpha[k] * abs(q[k]) and not \
                _negligible_negative(D[k], err[k], alpha[k], q[k]):
            fl.append("negative_dissipation")       # beyond round-off and not negligible
        if hyst["zeta_masing"][k] < -ZETA_ZERO and use_loop[k]:
            fl.append("masing_negative")
        hard = f[k] > f0 * (1 + STUCK_FREQUENCY_RTOL) or (
            k > 0 and q[k] * alpha[k - 1] * (1 + SECANT_RTOL) < q[k - 1] * alpha[k])
        if hard:
            fl.append("hardening" if use_loop[k] else "masing_on_hardening")
        if untouched[k] and (abs(f[k] / f0 - 1) > STUCK_FREQUENCY_RTOL
                             or abs(zeta[k]) > ZETA_ZERO):
            fl.append("stuck_not_linear")
        if k > 0 and not q[k] > q[k - 1]:
            fl.append("q_not_increasing")
        if k > 0 and not tip[k] > tip[k - 1]:
            fl.append("tip_not_increasing")
        if np.isfinite(err[k]) and np.isfinite(D[k]) and \
                err[k] > opts.dissipation_rtol * abs(D[k]) + \
                ZETA_ZERO * 2 * np.pi * alpha[k] * abs(q[k]):
            fl.append("integration_error_above_rtol")
        if hyst["shakedown"][k]:
            fl.append("shakedown")
        out.append(tuple(fl))
    return tuple(out)


def _outcome(pos, flags, loops=None):
    """``(success, message)`` of the run from the ramp and the level flags: per failure
    flag its levels and what to change (:data:`qsma.result.FAILURE_FIXES`), with the
    message of the first loop that failed or did not stabilise (``loops``: level ->
    :class:`qsma.hysteresis.Loop`)."""
    parts = [] if pos.success else [pos.message]
    for name in FAILURE_FLAGS:
        ks = [k for k, f in enumerate(flags) if name in f]
        if not ks:
            continue
        text = (f"{name} at level(s) {ks[:12]}{' ...' if len(ks) > 12 else ''}: "
                f"{FAILURE_FIXES[name]}")
        lp = (loops or {}).get(ks[0])
        if name in ("loop_failed", "loop_not_stabilised") and lp is not None:
            text += f" (level {ks[0]}: {lp.message})"
        parts.append(text)
    if not parts:
        return True, "all levels converged"
    return False, "; ".join(parts)


def _direct_loop(solver, response, grid, top, pos, d_masing):
    """The first cycle at the largest level: unload from +alpha_max to -alpha_max and
    reload, by twice each backbone point below it (Masing's construction), so that its
    area equals Masing's wherever Masing is exact. Stops at the first step whose contact
    solve fails: the points before it are kept, no area is given."""
    amax = grid[top]
    steps = np.concatenate([[0.0], 2 * grid[:top + 1]])
    path = np.concatenate([amax - steps, -amax + steps[1:]])
    state, qs, ts = pos.state(top), [], []
    for a in path:
        res = solver(a, state, f"direct loop (alpha={a:.4g})")
        if not res.success:
            n = len(qs)
            return DirectLoop(path[:n], np.array(qs), np.array(ts), None, d_masing, False,
                              f"direct loop stopped at alpha={a:.6g} (step {n} of "
                              f"{len(path)}): {res.message}; residual {res.residual:.2e}")
        state = res.state
        qs.append(response.q(res.d, a))
        ts.append(response.tip(res.d, a))
    qs, ts = np.array(qs), np.array(ts)
    return DirectLoop(path, qs, ts, loop_area(qs, path), d_masing, True, "loop closed")
