"""Parameter studies on top of a QSMA run: sweeps (:mod:`.sweep`, on Dask), fits to
measured data (:mod:`.fit`), their figures (:mod:`.plots`) and the reduced-order model
export (:mod:`qsma.study.rom`)."""
from .sweep import (Case, CaseOutcome, SweepResult, grid, parse_values, read_table,
                    run_case, study_table, sweep)
from .fit import FitResult, Measured, fit, read_measured

__all__ = ["sweep", "grid", "parse_values", "Case", "CaseOutcome", "SweepResult",
           "run_case", "study_table", "read_table", "fit", "read_measured", "Measured", "FitResult"]
