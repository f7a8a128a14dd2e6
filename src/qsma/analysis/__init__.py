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
run's outcome), ``clock`` (stages and their seconds). A name is patched or changed
where its module defines it.
"""
from .checks import STUCK_FREQUENCY_RTOL, ZETA_NEGLIGIBLE, ZETA_ZERO
from .clock import STAGES
from .dissipation import MIN_LOOP_STEPS, Dissipation
from .driver import run, run_prepared
from .prepared import STUDY_MU_FIX, Prepared, prepare
from .ramps import EXPECT_MAX_RATIO, LEVEL_REFINE_ROUNDS
from .stages import GAP_REPORT_RTOL, preload

# the private helpers that tests and benchmarks reach for, by their old names
from .checks import _flags, _negligible_negative, _outcome, _settle_dissipation  # noqa: F401
from .clock import _Timer  # noqa: F401
from .dissipation import _linear_end, _loop_fractions  # noqa: F401
from .prepared import _scaled_preload  # noqa: F401
from .ramps import _expected_closing, _NegativeRamp, _ramp  # noqa: F401
from .solves import _contact_threads, _load_factors, _Response, _solve, _Solver  # noqa: F401
from .stages import _contact_problem  # noqa: F401

__all__ = ["run", "run_prepared", "prepare", "Prepared", "preload", "Dissipation",
           "STAGES", "STUDY_MU_FIX", "ZETA_ZERO", "ZETA_NEGLIGIBLE", "STUCK_FREQUENCY_RTOL",
           "EXPECT_MAX_RATIO", "LEVEL_REFINE_ROUNDS", "GAP_REPORT_RTOL", "MIN_LOOP_STEPS"]
