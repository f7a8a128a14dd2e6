"""Moved to :mod:`qsma.mesh.io.abaqus`; this path keeps working for one release, with a
DeprecationWarning."""
from ..._infra.deprecation import forward

forward(__name__,
        'qsma.mesh.io.abaqus',
        'qsma.mesh.io.abaqus.lexer',
        'qsma.mesh.io.abaqus.reader',
        'qsma.mesh.io.abaqus.writer',
        'qsma.mesh.io.abaqus.faces',
        'qsma.mesh.celltypes',
        'qsma.mesh._legacy')
