"""Moved to :mod:`qsma.deck`; this path keeps working for one release, with a
DeprecationWarning."""
from ..._infra.deprecation import forward

forward(__name__,
        'qsma.deck',
        'qsma.deck.records',
        'qsma.deck.reader',
        'qsma.deck.loads',
        'qsma.deck.toml')
