"""qsma: quasi-static modal analysis of jointed structures with frictional contact,
solved on a model statically condensed to the contact interface.

Pipeline: :mod:`qsma.model` -> :mod:`qsma.fe` -> :mod:`qsma.condense` ->
:mod:`qsma.contact` -> :mod:`qsma.analysis` -> :mod:`qsma.results`.
"""

__version__ = "0.1.0"


def run(model, **options):
    """Quasi-static modal analysis of ``model``; see :func:`qsma.analysis.run`."""
    from .analysis import run as _run
    return _run(model, **options)


__all__ = ["run", "__version__"]
