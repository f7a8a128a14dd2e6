"""Moved to :mod:`qsma.mesh.validate`; this path keeps working for one release, with a
DeprecationWarning."""
from .._infra.deprecation import forward

forward(__name__,
        'qsma.mesh.validate',
        'qsma.mesh._legacy')
