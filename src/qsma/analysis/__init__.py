"""Quasi-static modal analysis: preload, tied modes, modal load ramps, hysteresis.

The pipeline as the code runs it (docs/theory.md)::

    model -> assembly -> condensation -> preload contact -> tied modes      (stages)
          -> modal load pattern M phi (condensed) -> ramps of contact solves for +alpha
             and -alpha (levels refined where the integration needs it)    (ramps)
          -> per level: Masing's rules where they are verified, else the stabilised
             loop                                                        (dissipation)
          -> checks of what the physics guarantees                           (checks)
          -> QSMAResult                                                      (driver)

Modules: ``driver`` (:func:`run`, :func:`run_prepared`), ``prepared`` (:class:`Prepared`,
:func:`prepare`: what a study shares between cases), ``stages`` (assembly,
condensation, :func:`preload`, the tied mode), ``solves`` (the contact solve of one
level), ``ramps``, ``dissipation`` (:class:`Dissipation`), ``checks`` (flags and the
run's outcome), ``clock`` (stages and their seconds); what a run takes and gives:
``options`` (:class:`RunOptions`), ``levels`` (:class:`Levels`), ``config`` (the TOML
configuration), ``result`` (:class:`QSMAResult` and its level table). A name is
patched or changed where its module defines it.

The names below are loaded when first asked for: ``import qsma`` reads the options and
levels from here without importing the solvers (PEP 562).
"""
import importlib

#: Public name -> the module of this package that defines it.
_NAMES = {
    "run": "driver", "run_prepared": "driver",
    "prepare": "prepared", "Prepared": "prepared", "STUDY_MU_FIX": "prepared",
    "preload": "stages", "GAP_REPORT_RTOL": "stages",
    "Dissipation": "dissipation", "MIN_LOOP_STEPS": "dissipation",
    "ZETA_ZERO": "checks", "ZETA_NEGLIGIBLE": "checks", "STUCK_FREQUENCY_RTOL": "checks",
    "STAGES": "clock", "StageClock": "clock",
    "EXPECT_MAX_RATIO": "ramps", "LEVEL_REFINE_ROUNDS": "ramps",
    "RunOptions": "options", "Execution": "options", "EXECUTION_FIELDS": "options",
    "Levels": "levels", "QSMAResult": "result", "LevelTable": "result",
    "LEVEL_FIELDS": "result",
}
#: The private helpers that tests and benchmarks reach for by their old names.
_PRIVATE = {
    "_flags": "checks", "_negligible_negative": "checks", "_outcome": "checks",
    "_settle_dissipation": "checks", "_linear_end": "dissipation",
    "_loop_fractions": "dissipation", "_scaled_preload": "prepared",
    "_expected_closing": "ramps", "_NegativeRamp": "ramps", "_ramp": "ramps",
    "_contact_threads": "solves", "_load_factors": "solves", "_Response": "solves",
    "_solve": "solves", "_Solver": "solves", "_contact_problem": "stages",
}
_MODULES = ("checks", "clock", "config", "dissipation", "driver", "levels", "options",
            "prepared", "ramps", "result", "solves", "stages")


def __getattr__(name):
    if name in _MODULES:
        return importlib.import_module(f"{__name__}.{name}")
    home = _NAMES.get(name) or _PRIVATE.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f"{__name__}.{home}"), name)


def __dir__():
    return sorted(set(globals()) | set(_NAMES) | set(_MODULES))


__all__ = sorted(_NAMES)
