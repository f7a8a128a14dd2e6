"""Moved to :mod:`qsma.mesh.io.abaqus.instances`; this path keeps working for one release,
with a DeprecationWarning."""
from ..._infra.deprecation import forward

forward(__name__,
        'qsma.mesh.io.abaqus.instances')
