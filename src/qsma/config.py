"""Moved to :mod:`qsma.analysis.config`; this path keeps working for one release, with a
DeprecationWarning."""
from ._infra.deprecation import forward

forward(__name__,
        'qsma.analysis.config')
