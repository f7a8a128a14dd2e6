"""Moved to :mod:`qsma.mesh.io.gmsh`; this path keeps working for one release, with a
DeprecationWarning."""
from ..._infra.deprecation import forward

forward(__name__,
        'qsma.mesh.io.gmsh',
        'qsma.mesh.io.gmsh.types',
        'qsma.mesh.io.gmsh.reader',
        'qsma.mesh.io.gmsh.writer')
