"""Moved to :mod:`qsma.mesh.io`; this path keeps working for one release, with a
DeprecationWarning."""
from ..._infra.deprecation import forward

forward(__name__,
        'qsma.mesh.io',
        'qsma.mesh._legacy')
