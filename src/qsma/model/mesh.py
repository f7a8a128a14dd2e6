"""Moved to :mod:`qsma.mesh.mesh`, :mod:`qsma.mesh.facets` and :mod:`qsma.mesh.celltypes`;
this path keeps working for one release, with a DeprecationWarning."""
from .._infra.deprecation import forward

forward(__name__,
        'qsma.mesh.mesh',
        'qsma.mesh.facets',
        'qsma.mesh.celltypes',
        'qsma.mesh._legacy')
