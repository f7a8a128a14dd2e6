"""The outcome of a QSMA run as typed data: :class:`QSMAResult` and its parts.

The per-level quantities are the fields of :class:`LevelTable`, each with its meaning,
its physical quantity (its unit in the model's system) and how the writers treat it
(:func:`column`); results.json, results.csv (:mod:`qsma.output.files`), the report's
table and the study tables follow them in their order (:data:`LEVEL_FIELDS`). The
writers live in :mod:`qsma.output.files`; this module holds data only.
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import TYPE_CHECKING

import numpy as np

from ..contact import ContactState
from ..units import QUANTITIES, SI, quantity_unit, unit_system
from ..version import __version__
from .options import RunOptions

if TYPE_CHECKING:  # types only: no import cost or cycle at run time
    from ..reduction.two_bodies import ReducedModel
    from ..contact import ContactResult
    from ..hysteresis import Loop
    from ..modal import Modes
    from ..model import Model, Pairing

#: Flags that make a level a failure (the others are information).
FAILURE_FLAGS = ("negative_dissipation", "not_finite", "loop_failed", "loop_not_stabilised",
                 "masing_on_hardening", "stuck_not_linear", "q_not_increasing")
#: Per failure flag, what it means and what to change (the run's message quotes it).
FAILURE_FIXES = {
    "negative_dissipation": "the dissipation is negative beyond the round-off of the "
                            "contact solves: if dissipation = 'masing' was forced, use "
                            "'auto' or 'loop'; otherwise lower tol (the contact solves "
                            "are not accurate enough for this model: look for "
                            "stiffnesses many decades apart)",
    "not_finite": "a frequency or damping is not a finite number: check the units and "
                  "material constants of the model",
    "loop_failed": "a contact solve inside the level's loop failed (the first such "
                   "loop's message follows; every loop's is in qsma.log): raise maxiter "
                   "or loosen tol",
    "loop_not_stabilised": "the level's loop did not repeat within max_cycles cycles: "
                           "raise max_cycles (qsma run --max-cycles, [analysis] "
                           "max_cycles) as its message says, unless it ratchets",
    "masing_on_hardening": "the joint stiffens there, where Masing's rules do not hold: "
                           "use dissipation = 'auto' or 'loop' (computed loops)",
    "stuck_not_linear": "the modal response of these levels is below the numerical "
                        "resolution of the preload state (about 1e-9 of the preload "
                        "displacements): raise the smallest load level, or check the "
                        "units of the bolt load",
    "q_not_increasing": "the modal amplitude does not grow with the load: check the "
                        "contact solves of these levels (tol, maxiter) and the levels",
}


def column(doc, quantity=None, *, optional=False, nan_when_flagged=False, report=None,
           derived=False):
    """A field of :class:`LevelTable`: one column of results.json's ``levels``, of
    results.csv and of the study tables.

    Parameters
    ----------
    doc : str
        What the column holds (docs/results.md says it to the user).
    quantity : str or None
        Its physical quantity (:data:`qsma.units.QUANTITIES`), which gives its unit in
        the model's system; ``None`` for counts, names and flags.
    optional : bool
        NaN where it was not computed (a loop at a level that used Masing, the -alpha
        ramp beyond a failure): written as null / an empty cell.
    nan_when_flagged : bool
        Comes from the frequency, the damping or the loop: NaN at a level flagged
        ``not_finite``, ``loop_failed`` or ``loop_not_stabilised`` is written as null
        beside the flag (:data:`qsma.output.files.NAN_FLAGS`); any other NaN is refused.
    report : (heading, format) or None
        Its column in the report's per-level table, if it has one.
    derived : bool
        Computed by :class:`QSMAResult` from its other fields (not a constructor
        argument).
    """
    return field(init=not derived, metadata=dict(
        doc=doc, quantity=quantity, optional=optional, nan_when_flagged=nan_when_flagged,
        report=report))


@dataclass(frozen=True, eq=False)
class LevelTable:
    """The per-level results, one entry per solved level of the user's grid: each field
    is a column (:func:`column` holds its meaning, unit and treatment), in the order of
    results.csv. A new column is a field here and its value where it is computed (the
    run's backbone columns in :mod:`qsma.analysis.driver`, the dissipation's in
    :class:`qsma.analysis.dissipation.Dissipation`, a derived one in
    :meth:`QSMAResult.__post_init__`), and its line in docs/results.md."""

    alpha: np.ndarray = column("modal force of the level", "modal_force")
    tip_lin: np.ndarray = column("tip deflection of the linear tied structure at alpha",
                                 "length", report=("linear tip", "{:.3e}"))
    q: np.ndarray = column("modal amplitude on the +alpha backbone, from the preload "
                           "state", "modal_amplitude")
    tip: np.ndarray = column("tip deflection (probe) on the +alpha backbone, from the "
                             "preload state", "length", report=("peak tip", "{:.3e}"))
    q_neg: np.ndarray = column("modal amplitude on the -alpha backbone", "modal_amplitude",
                               optional=True)
    asymmetry: np.ndarray = column("(q + q_neg) / q: 0 for a symmetric joint",
                                   "dimensionless", optional=True)
    f_hz: np.ndarray = column("secant frequency of the method used at this level",
                              "frequency", nan_when_flagged=True, report=("f", "{:.4f}"))
    zeta: np.ndarray = column("equivalent viscous damping ratio of the method used",
                              "dimensionless", nan_when_flagged=True,
                              report=("zeta", "{:.3e}"))
    zeta_structure: np.ndarray = column(
        "linear damping ratio of the structure besides the joint at the level's "
        "frequency (model.damping; zero without it)", "dimensionless",
        nan_when_flagged=True, derived=True)
    zeta_total: np.ndarray = column(
        "zeta + zeta_structure: what a test of the assembly measures", "dimensionless",
        nan_when_flagged=True, derived=True)
    dissipation: np.ndarray = column("energy dissipated per cycle, method used", "energy",
                                     nan_when_flagged=True,
                                     report=("dissipation", "{:.3e}"))
    dissipation_error: np.ndarray = column("estimate of the integration error of "
                                           "dissipation", "energy", optional=True)
    dissipation_method: np.ndarray = column("masing, loop or elastic (no loop needed: no "
                                            "pair with friction slipped)",
                                            report=("dissipation by", "{}"))
    f_hz_masing: np.ndarray = column("Masing's rules on the +alpha backbone: frequency",
                                     "frequency")
    zeta_masing: np.ndarray = column("Masing's rules: damping ratio", "dimensionless")
    dissipation_masing: np.ndarray = column("Masing's rules: dissipation per cycle",
                                            "energy")
    f_hz_loop: np.ndarray = column("the stabilised computed loop: frequency", "frequency",
                                   optional=True)
    zeta_loop: np.ndarray = column("the stabilised computed loop: damping ratio",
                                   "dimensionless", optional=True)
    dissipation_loop: np.ndarray = column("the stabilised computed loop: dissipation",
                                          "energy", optional=True)
    dissipation_first_cycle: np.ndarray = column("the loop's first cycle's dissipation",
                                                 "energy", optional=True)
    loop_cycles: np.ndarray = column("cycles on the initial increments until the loop "
                                     "settled (0: no loop)")
    shakedown: np.ndarray = column("the first cycle or the first loadings differ from "
                                   "the stabilised cycle")
    tip_velocity: np.ndarray = column("peak tip velocity, w times the tip deflection",
                                      "velocity", nan_when_flagged=True)
    n_stuck: np.ndarray = column("pairs stuck on the +alpha backbone",
                                 report=("stuck", "{}"))
    n_slip: np.ndarray = column("pairs slipping on the +alpha backbone",
                                report=("slip", "{}"))
    n_open: np.ndarray = column("pairs open on the +alpha backbone",
                                report=("open", "{}"))
    iterations: np.ndarray = column("contact solver iterations of the level",
                                    report=("iterations", "{}"), derived=True)
    residual: np.ndarray = column("public residual of the level's contact solve",
                                  "dimensionless", report=("residual", "{:.1e}"),
                                  derived=True)
    method_reason: np.ndarray = column("why the method was used")
    flags: tuple = column("the level's flags (FAILURE_FLAGS are failures)")


#: The per-level quantities, in the order of results.csv (docs/results.md has units).
LEVEL_FIELDS = tuple(f.name for f in fields(LevelTable))
#: Each per-level field's :func:`column` metadata, by name.
LEVEL_COLUMNS = {f.name: f.metadata for f in fields(LevelTable)}
#: The quantity of each per-level field (:data:`qsma.units.QUANTITIES`); ``None`` for
#: counts, names and flags, which have no unit.
LEVEL_QUANTITIES = {name: c["quantity"] for name, c in LEVEL_COLUMNS.items()}


def level_units(units=SI, dim=3) -> dict:
    """Per-level field name -> unit text (``None`` for counts, names and flags)."""
    return {k: None if q is None else quantity_unit(q, units, dim)
            for k, q in LEVEL_QUANTITIES.items()}


def units_block(units=SI, dim=3) -> dict:
    """The ``units`` block of results.json: the system's name, its base and derived
    units (per depth in 2D), and the unit of every per-level field."""
    u = unit_system(units)
    base = {q: quantity_unit(q, u, dim) for q in QUANTITIES if q != "dimensionless"}
    return {"system": u.name, "time": u.time, **base, "per_unit_depth": dim == 2,
            "levels": level_units(u, dim)}


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
class LevelCosts:
    """Where a run's contact work went, per level of the user's grid.

    Attributes
    ----------
    ramp_solves, ramp_seconds : (n_levels,) arrays
        Contact solves of both ramps whose modal force lies in the level's interval
        (above the level before it, up to the level), the +alpha ramp's refinement
        rounds included (a level solved again on a finer grid counts again), and the
        wall-clock seconds they took.
    loop_solves, loop_cycles, loop_seconds : (n_levels,) arrays
        The level's computed loop (zero where Masing's rules were used): its contact
        solves, its cycles (those on the initial increments plus those of its
        refinement rounds) and its wall-clock seconds.

    Seconds are those of the process that did the work: the -alpha ramp and the
    loops may run on other processes at the same time, so the seconds can add up to
    more than the wall time of their stages (``timings_s``).
    """

    ramp_solves: np.ndarray
    ramp_seconds: np.ndarray
    loop_solves: np.ndarray
    loop_cycles: np.ndarray
    loop_seconds: np.ndarray

    def as_dict(self) -> dict:
        """Per-level lists by field name (results.json ``level_costs``)."""
        return {f.name: np.asarray(getattr(self, f.name)).tolist() for f in fields(self)}


@dataclass(frozen=True, eq=False)
class DirectLoop:
    """The first loop at the largest amplitude, on increments mirroring the backbone
    (``direct_loop=True``): unloading from +alpha_max to -alpha_max and reloading."""

    alpha: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    dissipation: float | None      # None when the loop could not be closed
    dissipation_masing: float
    success: bool
    message: str = ""


@dataclass(frozen=True, eq=False)
class QSMAResult(LevelTable):
    """Everything a QSMA run produced: the per-level columns of :class:`LevelTable`
    and the run's own fields below.

    Arrays under "levels" (:data:`LEVEL_FIELDS`) have one entry per solved level of the
    user's grid. The +alpha ramp was solved through ``backbone_alpha`` (the user's
    levels plus those inserted for the integrals; ``backbone_index`` maps each user
    level to it); ``backbone_states`` holds every point, the history of each level is
    the point before it there. ``f_hz``, ``zeta``, ``dissipation`` are those of the method named in
    ``dissipation_method`` at each level; the Masing and loop values are kept beside
    them (NaN where not computed). ``success`` is False when a level failed to converge
    or holds a value the physics forbids (``flags``; ``message`` says which).
    """

    success: bool
    message: str
    model_info: dict[str, object]
    mode_index: int
    omega0: float
    phi_tip: float
    states: LevelStates
    loops: dict[int, Loop]
    backbone_alpha: np.ndarray
    backbone_states: LevelStates
    backbone_index: np.ndarray
    preload: ContactResult
    modes: Modes
    reduced: ReducedModel
    pairing: Pairing
    model: Model
    options: RunOptions
    solver: dict[str, object]
    timings_s: dict[str, float]
    #: process peak resident memory (MiB, None where not reported) and CPU seconds at
    #: the end of the run (:func:`qsma._infra.resources.snapshot`)
    resources: dict[str, float | None] = None
    direct_loop: DirectLoop | None = None
    #: messages of qsma's own warnings raised during the run (e.g. mortar gaps taken as
    #: initial gaps, quad8 interface facets), each once
    warnings: tuple[str, ...] = ()
    gross_slip_level: int | None = None
    #: contact solves, loop cycles and seconds per level (:class:`LevelCosts`)
    level_costs: LevelCosts | None = None
    version: str = __version__

    def __post_init__(self):
        """The derived columns of :class:`LevelTable` from the other fields."""
        damping = getattr(self.model, "damping", None)
        zeta = np.asarray(self.zeta, dtype=float)
        structure = np.zeros_like(zeta) if damping is None else \
            damping.zeta(2 * np.pi * np.asarray(self.f_hz, dtype=float))
        for name, value in (("zeta_structure", structure), ("zeta_total", zeta + structure),
                            ("iterations", self.states.iterations),
                            ("residual", self.states.residual)):
            object.__setattr__(self, name, value)

    @property
    def units(self):
        """The model's :class:`qsma.units.UnitSystem` (every result is in it)."""
        return unit_system(getattr(self.model, "units", "SI"))

    @property
    def f0_hz(self):
        return self.omega0 / (2 * np.pi)

    @property
    def n_levels(self):
        return len(self.alpha)

    @property
    def failed_levels(self) -> list:
        """Levels holding a failure flag (:data:`FAILURE_FLAGS`)."""
        return [k for k, f in enumerate(self.flags) if set(f) & set(FAILURE_FLAGS)]

    def fields(self, k):
        """Full displacement vectors per body at level ``k`` (``k=None``: the preload),
        measured from the undeformed configuration."""
        if k is None:
            return self.reduced.recover(self.preload.d, load_factors(self.reduced, 0.0))
        return self.reduced.recover(self.states.d[k], load_factors(self.reduced,
                                                                    self.alpha[k]))

    def levels_table(self) -> dict:
        """Per-level arrays by name (the ``levels`` block of results.json)."""
        return {k: getattr(self, k) for k in LEVEL_FIELDS}



def load_factors(reduced, alpha) -> np.ndarray:
    """Factors of the reduced model's load patterns at modal load ``alpha``: the
    preload pattern at 1, the modal pattern (if present) at ``alpha``."""
    a = np.zeros(len(reduced.patterns))
    a[reduced.patterns.index("preload")] = 1.0
    if "modal" in reduced.patterns:
        a[reduced.patterns.index("modal")] = alpha
    return a
