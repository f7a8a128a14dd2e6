"""Meshes: what qsma knows about each cell type (:mod:`.celltypes`)."""
from .celltypes import CELL_TYPES, TYPES, CellType, cell_type

__all__ = ["CELL_TYPES", "TYPES", "CellType", "cell_type"]
