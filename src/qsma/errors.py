"""Exceptions and warnings of qsma.

Every error a user can meet derives from :class:`QSMAError`; the CLI maps
:class:`InputError` to exit code 2 and :class:`AnalysisError` to exit code 1.
"""


class QSMAError(Exception):
    """Base class of every qsma error."""


class InputError(QSMAError, ValueError):
    """Bad input: a model, mesh file, configuration or parameter to fix."""


class MeshFileError(InputError):
    """A mesh file that cannot be read, with the file and, where known, the line."""


class OutputFolderBusy(InputError):
    """The output folder is locked by another live qsma run."""


class OutputWriteError(QSMAError):
    """Result files could not be written (full device, I/O error); the output folder
    keeps its previous contents."""


class AnalysisError(QSMAError, RuntimeError):
    """The analysis could not produce a valid answer (see ``partial``)."""

    def __init__(self, message, partial=None):
        super().__init__(message)
        self.partial = partial


class ContactConvergenceWarning(UserWarning):
    """A contact solve stopped without meeting its tolerance."""


class QSMAWarning(UserWarning):
    """A warning meant for the user (the CLI prints it as ``qsma: warning: ...``)."""


class TiedOnlyWarning(QSMAWarning):
    """A model whose interfaces are all tied: its run is linear, every level elastic."""


class InterfaceGapWarning(QSMAWarning):
    """Mortar surfaces that do not touch in the mesh: their gaps are the initial gaps of
    the contact problem."""


class PartialCoverageWarning(QSMAWarning):
    """Part of a mortar interface's slave surface faces no master facet (a hole, an
    offset edge) and is left out of the contact."""


class QuadraticFacetWarning(QSMAWarning):
    """An interface on serendipity quad8 facets (hexahedron20 cells): a uniform pressure
    needs the corner pairs to pull, so they open under a preload (docs/theory.md,
    section 5, "Pairs on quadratic faces")."""


class NearlyIncompressibleWarning(QSMAWarning):
    """Poisson's ratio close to 0.5: displacement elements lock (too stiff)."""


class UnitSystemWarning(QSMAWarning):
    """A model's numbers look like another unit system than the one it declares
    (:func:`qsma.units.check_model_units`)."""


class SerialSweepWarning(QSMAWarning):
    """A study asked for a local Dask cluster runs its cases one after the other: the
    optional ``distributed`` package (extra ``sweep``) is not installed."""
