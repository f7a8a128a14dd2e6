"""Parameter studies on top of a QSMA run: sweeps (:mod:`.sweep`; the cases a study
makes, :mod:`.cases`; where they run, :mod:`.runners`, on forked processes or Dask;
the study table, :mod:`.table`), fits to measured data (:mod:`.fit`), several modes
of one model (:mod:`.modes`), their figures (:mod:`.plots`) and the reduced-order
models fitted to a backbone (:mod:`.rom`)."""
from .cases import Case, grid, parse_values
from .runners import CaseOutcome, run_case
from .sweep import SweepResult, sweep
from .table import read_table, study_table
from .fit import FitResult, Measured, fit, read_measured

__all__ = ["sweep", "grid", "parse_values", "Case", "CaseOutcome", "SweepResult",
           "run_case", "study_table", "read_table", "fit", "read_measured", "Measured", "FitResult"]
