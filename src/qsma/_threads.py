"""Moved to :mod:`qsma._infra.threads`; this path keeps working for one release, with a
DeprecationWarning."""
from ._infra.deprecation import forward

forward(__name__,
        'qsma._infra.threads')
