"""The options of a QSMA run: one frozen, validated object.

:class:`RunOptions` is the single source of every option of :func:`qsma.run`: the
TOML ``[analysis]`` table (:meth:`RunOptions.from_table`), the command-line
overrides (:func:`dataclasses.replace`) and the ``options`` block of results.json
(:meth:`RunOptions.as_dict`) are all derived from its fields.

Its fields are of two kinds. Most say *what* is computed (the physics and the
numerics: mode, levels, contact solver and tolerances, dissipation model, ...); a
change of one changes the results. The :data:`EXECUTION_FIELDS` say only *how* the
run is executed (processes for the loops, a Dask scheduler, the -alpha ramp on a
second process): the results are the same bits for any value of them, so a study's
fingerprint leaves them out and a sweep does not vary them. They are read together as
:attr:`RunOptions.execution`, an :class:`Execution` record. Both kinds stay keywords of
the one constructor (and keys of one TOML table, flags of one command line).
"""
from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
import math
import typing

import numpy as np

from ..errors import InputError
from .levels import Levels

#: How the dissipation per cycle is obtained at each level (docs/theory.md section 7).
DISSIPATION_METHODS = ("auto", "masing", "loop")
#: Largest loop cycles per amplitude before a level is declared not stabilised.
MAX_CYCLES_LIMIT = 100
#: Largest ``loop_steps``: beyond it a loop costs more solves than a 10^4-level ramp.
MAX_LOOP_STEPS = 10000
#: Largest ``loop_workers``: a guard against a typo starting thousands of processes.
MAX_LOOP_WORKERS = 256


def _execution(default):
    """A field of :class:`RunOptions` that says how the run is executed, not what it
    computes (one of :data:`EXECUTION_FIELDS`)."""
    return field(default=default, metadata={"execution": True})


@dataclass(frozen=True)
class Execution:
    """How a run is executed: settings that change no result (the same bits for any
    value), read from :class:`RunOptions` as :attr:`RunOptions.execution`.

    Attributes
    ----------
    loop_workers : int or None
        Processes that compute the levels' loops (``None``: :attr:`loop_worker_count`).
    loop_scheduler : str or None
        Address of a Dask scheduler whose workers compute the loops.
    parallel_ramps : bool
        The -alpha ramp on a second process while the +alpha ramp's last round runs.
    """

    loop_workers: int | None = _execution(None)
    loop_scheduler: str | None = _execution(None)
    parallel_ramps: bool = _execution(True)

    def __post_init__(self):
        if self.loop_workers is not None:
            _integer("loop_workers", self.loop_workers, minimum=1, maximum=MAX_LOOP_WORKERS)
        if self.loop_scheduler is not None:
            if not isinstance(self.loop_scheduler, str) or not self.loop_scheduler.strip():
                raise InputError(f"loop_scheduler must be the address of a Dask scheduler "
                                 f"(e.g. 'tcp://host:8786'), got {self.loop_scheduler!r}")
            if self.loop_workers is not None:
                raise InputError("loop_workers sets the local processes of the loops; with "
                                 "loop_scheduler the scheduler's workers compute them: "
                                 "give one of the two")
        if not isinstance(self.parallel_ramps, (bool, np.bool_)):
            raise InputError(f"parallel_ramps must be true or false, got "
                             f"{self.parallel_ramps!r}")

    @property
    def loop_worker_count(self) -> int:
        """``loop_workers``, or for ``None`` one process per core this one may use
        (:func:`qsma._infra.threads.usable_cores`), on Linux (one elsewhere:
        :func:`qsma._infra.forked.second_core_refusal`)."""
        if self.loop_workers is not None:
            return int(self.loop_workers)
        from .._infra.forked import second_core_refusal
        from .._infra.threads import usable_cores
        return 1 if second_core_refusal() else min(usable_cores(), MAX_LOOP_WORKERS)


@dataclass(frozen=True)
class RunOptions:
    """Every option of a QSMA run, validated on creation.

    Parameters that change the results (physics and numerics) come first; the last
    three (:data:`EXECUTION_FIELDS`, read together as :attr:`execution`) change none.

    Parameters
    ----------
    mode : int
        Index (0 = lowest elastic mode) of the tied structure's mode to load.
    levels : Levels or None
        Load levels; ``None`` takes the 51 levels of the sandwich benchmark
        (linear tied tip deflection 1 um to 1 mm, log spaced).
    method : str
        Contact solver, a key of :data:`qsma.contact.METHODS`, or ``"auto"`` (default):
        ``active_set`` on 3D interfaces of at least
        :data:`qsma.contact.registry.AUTO_ACTIVE_SET_PAIRS` pairs, ``basket`` on the
        others (chosen by measurement, docs/contact.md "Default method").
    tol, maxiter : float or None, int or None
        Contact solver tolerance and iteration cap (``None``: the solver's defaults).
    dissipation : {"auto", "masing", "loop"}
        ``"masing"``: Masing's rules on the backbone at every level; ``"loop"``: the
        stabilised quasi-static loop computed at every level; ``"auto"``: Masing where
        its assumptions are verified at that level, no loop where they are not but no
        pair with friction slipped (the cycle is elastic, ``dissipation_method``
        "elastic"), the loop elsewhere.
    dissipation_rtol : float
        Target of the estimated integration error of each dissipation, relative to it:
        levels and loop increments are inserted until the estimate is below it.
    max_cycles : int
        Loop cycles per amplitude before a level is declared not stabilised (more
        while the loop's shakedown converges geometrically fast enough, up to
        :data:`qsma.hysteresis.CYCLE_CEILING` times as many; see
        :data:`qsma.hysteresis.cycles.CONTRACTION`).
    refine_levels : bool
        Insert backbone levels where the estimate of the Masing integral exceeds
        ``dissipation_rtol`` or the pair states change (the output grid stays ``levels``).
    direct_loop : bool
        Also report the first loop at the largest amplitude beside Masing (kept for
        compatibility; ``dissipation="loop"`` supersedes it).
    n_modes : int or None
        Modes computed (default ``max(6, mode + 1)``).
    continue_on_failure : bool
        Keep ramping after a level whose contact solve failed.
    schur_backend : str
        Static condensation backend (:data:`qsma.reduction.schur.SCHUR_BACKENDS` or ``"auto"``).
    blas_threads : "auto", int or None
        BLAS thread limit; ``"auto"``: one thread for small interface problems and,
        whatever the size, for the contact ramps and loops
        (:data:`qsma._infra.threads.CONTACT_BLAS_THREADS`); an integer or ``None`` (as the
        process is set) applies to the whole run.
    loop_steps : int
        Largest number of increments per loop branch before refinement (the branch
        mirrors the backbone levels below the amplitude, thinned to this count); the
        refinement rounds halve them where pair states change.
    eliminate_open : bool
        Solve the ramp on the pairs closed after the preload, the open ones eliminated
        exactly (a pair that would close joins the zone).

    Execution (the same results for any value)

    loop_workers : int or None
        Processes that compute the levels' loops (1: in this process; ``None``, the
        default: one per core this process may use, on Linux, see
        :attr:`loop_worker_count`). The loops of the levels are independent given the
        backbone; the results are the same bits for any count
        (:func:`qsma.hysteresis.map_loops`; forked workers, Linux and macOS; elsewhere
        the loops run in this process).
    loop_scheduler : str or None
        Address of a Dask scheduler (``tcp://host:8786``) whose workers compute the
        loops instead of local processes: the interface's contact problem and the
        backbone states are sent to each worker once (nothing is condensed there), then
        each level's loop is a task. The same bits as in this process where the workers
        run the same numpy and BLAS.
    parallel_ramps : bool
        Solve the -alpha ramp on a second process (forked, on Linux) while the
        last refinement round of the +alpha ramp runs in this one; the results are the
        same bits either way (``qsma.analysis.ramps._NegativeRamp``).
    """

    mode: int = 0
    levels: Levels | None = None
    method: str = "auto"
    tol: float | None = None
    maxiter: int | None = None
    dissipation: str = "auto"
    dissipation_rtol: float = 5e-3
    max_cycles: int = 8
    loop_steps: int = 16
    refine_levels: bool = True
    direct_loop: bool = False
    n_modes: int | None = None
    continue_on_failure: bool = False
    schur_backend: str = "auto"
    blas_threads: typing.Any = "auto"
    eliminate_open: bool = True
    loop_workers: int | None = _execution(None)
    loop_scheduler: str | None = _execution(None)
    parallel_ramps: bool = _execution(True)

    def __post_init__(self):
        from ..contact.registry import method_names
        _integer("mode", self.mode, minimum=0)
        if self.levels is not None and not isinstance(self.levels, Levels):
            raise InputError(f"levels must be a qsma.Levels, got {type(self.levels).__name__}")
        if self.method not in method_names():
            raise InputError(f"unknown contact method {self.method!r}; valid: {method_names()}")
        if self.tol is not None:
            _positive("tol", self.tol)
            if self.tol >= 1e-2:
                raise InputError(f"tol = {self.tol:g} is not a convergence tolerance (it is "
                                 f"relative to the contact forces): use a value below 1e-2, "
                                 f"e.g. 1e-10")
        if self.maxiter is not None:
            _integer("maxiter", self.maxiter, minimum=1)
        if self.dissipation not in DISSIPATION_METHODS:
            raise InputError(f"dissipation must be one of {DISSIPATION_METHODS}, "
                             f"got {self.dissipation!r}")
        _positive("dissipation_rtol", self.dissipation_rtol)
        if self.dissipation_rtol >= 1:
            raise InputError(f"dissipation_rtol must be below 1 (a relative error), got "
                             f"{self.dissipation_rtol:g}")
        _integer("max_cycles", self.max_cycles, minimum=1, maximum=MAX_CYCLES_LIMIT)
        _integer("loop_steps", self.loop_steps, minimum=2, maximum=MAX_LOOP_STEPS)
        self.execution                   # validated there
        if self.n_modes is not None:
            _integer("n_modes", self.n_modes, minimum=1)
        for name in ("refine_levels", "direct_loop", "continue_on_failure", "eliminate_open"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise InputError(f"{name} must be true or false, got {getattr(self, name)!r}")
        if not isinstance(self.schur_backend, str):
            raise InputError(f"schur_backend must be a name, got {self.schur_backend!r}")
        bt = self.blas_threads
        if not (bt is None or bt == "auto"):
            _integer("blas_threads", bt, minimum=1)

    @property
    def execution(self) -> Execution:
        """The options that say how the run is executed (:data:`EXECUTION_FIELDS`)."""
        return Execution(**{name: getattr(self, name) for name in EXECUTION_FIELDS})

    @property
    def loop_worker_count(self) -> int:
        """:attr:`Execution.loop_worker_count` of :attr:`execution`."""
        return self.execution.loop_worker_count

    def results_options(self) -> dict:
        """The options that change the results (:meth:`as_dict` without the
        :data:`EXECUTION_FIELDS`): what a study's fingerprint holds."""
        return {k: v for k, v in self.as_dict().items() if k not in EXECUTION_FIELDS}

    @property
    def solver_options(self) -> dict:
        """Keyword options of :func:`qsma.contact.solve` (only those set)."""
        return {k: v for k, v in (("tol", self.tol), ("maxiter", self.maxiter))
                if v is not None}

    def as_dict(self) -> dict:
        """JSON-ready options (the ``options`` of results.json); levels as kind and count."""
        out = {f.name: getattr(self, f.name) for f in fields(self) if f.name != "levels"}
        return out

    @classmethod
    def table_keys(cls) -> dict:
        """Keys allowed in the TOML ``[analysis]`` table and their Python types."""
        hints = typing.get_type_hints(cls)
        return {f.name: hints[f.name] for f in fields(cls) if f.name != "levels"}

    @classmethod
    def from_table(cls, table: dict, where: str = "analysis", **extra) -> "RunOptions":
        """Options from a TOML ``[analysis]`` table; unknown keys are named with the
        allowed ones, values are validated by the constructor."""
        if not isinstance(table, dict):
            raise InputError(f"{where}: expected a table, got {type(table).__name__}")
        allowed = cls.table_keys()
        for key in table:
            if key not in allowed:
                raise InputError(f"{where}: unknown key {key!r}; allowed keys: "
                                 f"{sorted(allowed)}")
        try:
            return cls(**table, **extra)
        except InputError as exc:
            raise InputError(f"{where}: {exc}") from exc
        except TypeError as exc:
            raise InputError(f"{where}: {exc}") from exc

    def replace(self, **changes) -> "RunOptions":
        """A new validated object with ``changes`` (``None`` values are ignored)."""
        return replace(self, **{k: v for k, v in changes.items() if v is not None})


def _integer(name, value, minimum=None, maximum=None):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"{name} must be an integer, got {value!r}")
    if minimum is not None and value < minimum:
        raise InputError(f"{name} must be >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise InputError(f"{name} must be <= {maximum}, got {value}")


def _positive(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not math.isfinite(value) or value <= 0:
        raise InputError(f"{name} must be a positive finite number, got {value!r}")


#: The fields of :class:`RunOptions` that say how a run is executed, not what it
#: computes: the results are the same bits for any value of them.
EXECUTION_FIELDS = tuple(f.name for f in fields(RunOptions) if f.metadata.get("execution"))

__all__ = ["RunOptions", "Execution", "EXECUTION_FIELDS", "DISSIPATION_METHODS"]
