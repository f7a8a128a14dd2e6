"""Moved to :mod:`qsma.analysis.result`; this path keeps working for one release, with a
DeprecationWarning."""
from ._infra.deprecation import forward

forward(__name__,
        'qsma.analysis.result')
