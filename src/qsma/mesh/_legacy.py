"""The cell tables as they were before the records of :mod:`qsma.mesh.celltypes`, derived
from the records, for code written against them. Read through the old paths only
(``qsma.model.mesh.CELL_FACETS``, ...), which warn that they go in the next release."""
from __future__ import annotations

from .celltypes import CELL_TYPES, TYPES

#: facet type -> nodes per facet
FACET_TYPES = {name: t.n_nodes for name, t in TYPES.items() if 1 <= t.dim <= 2}
#: facet type -> corner nodes per facet
FACET_CORNERS = {name: t.corners for name, t in TYPES.items() if 1 <= t.dim <= 2}
#: cell type -> local nodes of each facet
CELL_FACETS = {name: [tuple(f) for f in t.facets] for name, t in CELL_TYPES.items()}
#: cell type -> (linear type of its corners, corner groups whose mean is each further node)
HIGHER_NODES = {name: (t.linear, [tuple(g) for g in t.higher_nodes])
                for name, t in CELL_TYPES.items()}
#: Abaqus face numbering of the linear types
ABAQUS_FACES = {name: [tuple(f) for f in t.abaqus_faces] for name, t in TYPES.items()
                if t.abaqus_faces}


def __getattr__(name):
    """``SKFEM_ELEMENTS`` (cell type -> scikit-fem mesh class, element class, quadrature
    order) imports scikit-fem when first read."""
    if name == "SKFEM_ELEMENTS":
        import skfem
        return {ct: (getattr(skfem, t.skfem[0]), getattr(skfem, t.skfem[1]), t.skfem[2])
                for ct, t in CELL_TYPES.items()}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
