r"""Dissipation per cycle of the modal coordinate: computed loops and Masing's rules.

Two ways to the dissipation ``D`` of a cycle of modal-force amplitude ``A``
(docs/theory.md section 7):

* **the loop** (:func:`compute_loop`): from the state reached on the backbone at
  ``+A``, unload to ``-A`` and reload to ``+A`` with the history-dependent contact
  solver, repeated until the cycle repeats itself (the stabilised cycle,
  :mod:`.cycles`), then continued with one cycle per refinement round on halved
  increments until ``D`` settles (:mod:`.refinement`); ``D = \oint \alpha\,dq``;
* **Masing's rules** on the backbone ``alpha(q)`` (:mod:`.masing`):
  ``D = 8 \int_0^{q_a} \alpha\,dq - 4 A q_a``, exact only for joints whose
  unloading branch is the backbone scaled by two (see :func:`masing_checks`).

Every area is computed by the trapezoidal rule on the deviation from a linear
reference ``k_ref`` (:mod:`.loop`); each value carries an estimate of its integration
error (:mod:`.estimates`). The loops of several levels run on forked or Dask workers
(:mod:`.workers`).

Modules: ``loop`` (the :class:`Loop` record, the cycle's path and area), ``cycles``
(the cycle driver), ``refinement`` (:func:`compute_loop`), ``estimates`` (error
estimates), ``workers`` (:func:`map_loops`), ``masing`` (Masing's rules and their
checks). A constant is read where its module defines it: change it there.
"""
from .cycles import CONTRACTION, CYCLE_CEILING, STATE_RTOL
from .estimates import cycle_area_error
from .loop import LOOP_OUTCOMES, Loop, cycle_area, cycle_path
from .masing import (PRESSURE_RTOL, SECANT_RTOL, MasingChecks, MasingEstimate,
                     MasingResult, loop_area, masing_checks, masing_estimate, masing_loop)
from .refinement import LOCAL_SHARE, ONE_CYCLE_CONTRACTION, REFINE_ROUNDS, compute_loop
from .workers import SCHEDULER_TIMEOUT, map_loops, scheduler_client

__all__ = ["CONTRACTION", "CYCLE_CEILING", "LOCAL_SHARE", "LOOP_OUTCOMES",
           "ONE_CYCLE_CONTRACTION", "PRESSURE_RTOL", "REFINE_ROUNDS", "SCHEDULER_TIMEOUT",
           "SECANT_RTOL", "STATE_RTOL", "Loop", "MasingChecks", "MasingEstimate",
           "MasingResult", "compute_loop", "cycle_area", "cycle_area_error", "cycle_path",
           "loop_area", "map_loops", "masing_checks", "masing_estimate", "masing_loop",
           "scheduler_client"]
