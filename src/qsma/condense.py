"""Moved to :mod:`qsma.reduction.condensation` (one body), :mod:`qsma.reduction.two_bodies`
(the two-body problem) and :mod:`qsma.reduction.rigid`; this path keeps working for one
release, with a DeprecationWarning."""
from ._infra.deprecation import forward

forward(__name__,
        'qsma.reduction.condensation',
        'qsma.reduction.two_bodies',
        'qsma.reduction.rigid')
