"""The outcome of a QSMA run as typed data: :class:`QSMAResult` and its parts.

The per-level quantities are named once, in :data:`LEVEL_FIELDS`; results.json,
results.csv (:mod:`qsma.output.files`) and the study tables follow that tuple. The writers
live in :mod:`qsma.output.files`; this module holds data only.
"""
from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING

import numpy as np

from .contact import ContactState
from .options import RunOptions
from .version import __version__

if TYPE_CHECKING:  # types only: no import cost or cycle at run time
    from .condense import ReducedModel
    from .contact import ContactResult
    from .hysteresis import Loop
    from .modal import Modes
    from .model import Model, Pairing

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
class QSMAResult:
    """Everything a QSMA run produced.

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
    alpha: np.ndarray
    tip_lin: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    q_neg: np.ndarray
    asymmetry: np.ndarray
    f_hz: np.ndarray
    zeta: np.ndarray
    dissipation: np.ndarray
    dissipation_error: np.ndarray
    dissipation_method: np.ndarray
    method_reason: np.ndarray
    f_hz_masing: np.ndarray
    zeta_masing: np.ndarray
    dissipation_masing: np.ndarray
    f_hz_loop: np.ndarray
    zeta_loop: np.ndarray
    dissipation_loop: np.ndarray
    dissipation_first_cycle: np.ndarray
    loop_cycles: np.ndarray
    shakedown: np.ndarray
    tip_velocity: np.ndarray
    n_stuck: np.ndarray
    n_slip: np.ndarray
    n_open: np.ndarray
    flags: tuple[tuple[str, ...], ...]
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

    @property
    def units(self):
        """The model's :class:`qsma.units.UnitSystem` (every result is in it)."""
        from .units import unit_system
        return unit_system(getattr(self.model, "units", "SI"))

    @property
    def f0_hz(self):
        return self.omega0 / (2 * np.pi)

    @property
    def n_levels(self):
        return len(self.alpha)

    @property
    def zeta_structure(self):
        """Linear damping ratio of the structure besides the joint at each level's
        frequency (``model.damping``; zero without it)."""
        damping = getattr(self.model, "damping", None)
        if damping is None:
            return np.zeros_like(np.asarray(self.zeta, dtype=float))
        return damping.zeta(2 * np.pi * np.asarray(self.f_hz, dtype=float))

    @property
    def zeta_total(self):
        """The joint's damping ratio plus the structure's (``zeta + zeta_structure``):
        what a test of the assembly measures."""
        return np.asarray(self.zeta, dtype=float) + self.zeta_structure

    @property
    def iterations(self):
        return self.states.iterations

    @property
    def residual(self):
        return self.states.residual

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


#: The per-level quantities, in the order of results.csv (docs/results.md has units).
LEVEL_FIELDS = ("alpha", "tip_lin", "q", "tip", "q_neg", "asymmetry", "f_hz", "zeta",
                "zeta_structure", "zeta_total", "dissipation", "dissipation_error", "dissipation_method", "f_hz_masing",
                "zeta_masing", "dissipation_masing", "f_hz_loop", "zeta_loop",
                "dissipation_loop", "dissipation_first_cycle", "loop_cycles", "shakedown",
                "tip_velocity", "n_stuck", "n_slip", "n_open", "iterations", "residual",
                "method_reason", "flags")


def load_factors(reduced, alpha) -> np.ndarray:
    """Factors of the reduced model's load patterns at modal load ``alpha``: the
    preload pattern at 1, the modal pattern (if present) at ``alpha``."""
    a = np.zeros(len(reduced.patterns))
    a[reduced.patterns.index("preload")] = 1.0
    if "modal" in reduced.patterns:
        a[reduced.patterns.index("modal")] = alpha
    return a
