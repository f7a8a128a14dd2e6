"""Moved to :mod:`qsma.mesh.io.common`; this path keeps working for one release, with a
DeprecationWarning."""
from ..._infra.deprecation import forward

forward(__name__,
        'qsma.mesh.io.common')
