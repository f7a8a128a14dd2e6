"""Abaqus / CalculiX ``.inp`` files, one concern per module: :mod:`.lexer` (keyword
cards, fields, numbers), :mod:`.reader` (the mesh and its sets, and what a deck names
besides), :mod:`.instances` (parts placed in an assembly made flat), :mod:`.faces` (the
``S<k>`` face numbering), :mod:`.writer`."""
from .faces import element_face_facets
from .lexer import ABAQUS_ELEMENT_TYPES
from .reader import _abaqus_file_mesh, _read_abaqus
from .writer import CALCULIX_ENTRIES, CALCULIX_FIELD, _format_abaqus

__all__ = ["element_face_facets", "ABAQUS_ELEMENT_TYPES", "CALCULIX_FIELD",
           "CALCULIX_ENTRIES"]
