"""qsma: quasi-static modal analysis of jointed structures with frictional contact,
solved on a model statically condensed to the contact interface.

Pipeline: :mod:`qsma.model` -> :mod:`qsma.fe` -> :mod:`qsma.reduction` ->
:mod:`qsma.contact` -> :mod:`qsma.analysis` (ramps) -> :mod:`qsma.hysteresis` ->
:mod:`qsma.output.files`.
"""
from .version import __version__
from .analysis.levels import Levels
from .analysis.options import RunOptions


def run(model, options=None, **overrides):
    """Quasi-static modal analysis of ``model``; see :func:`qsma.analysis.run`."""
    from .analysis import run as _run
    return _run(model, options, **overrides)


def sweep(model_or_config, vary, options=None, **kwargs):
    """A parameter study over ``vary``; see :func:`qsma.study.sweep`."""
    from .study import sweep as _sweep
    return _sweep(model_or_config, vary, options, **kwargs)


def fit(model_or_config, measured, params, options=None, **kwargs):
    """Fit parameters to measured frequency and damping; see :func:`qsma.study.fit`."""
    from .study import fit as _fit
    return _fit(model_or_config, measured, params, options, **kwargs)


def __getattr__(name):
    """Lazy access to the heavier public names (they import scikit-fem, meshio)."""
    if name == "QSMAResult":
        from .analysis.result import QSMAResult
        return QSMAResult
    if name in ("Model", "read_mesh"):
        from . import model
        return getattr(model, name)
    if name == "write_all":
        from .output.files import write_all
        return write_all
    raise AttributeError(f"module 'qsma' has no attribute {name!r}")


__all__ = ["run", "sweep", "fit", "RunOptions", "Levels", "QSMAResult", "Model", "read_mesh", "write_all",
           "__version__"]
