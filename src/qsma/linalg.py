"""Moved to the Schur backends of :mod:`qsma.reduction.schur` and the dense helpers of
:mod:`qsma._infra.dense`; this path keeps working for one release, with a
DeprecationWarning."""
from ._infra.deprecation import forward

forward(__name__,
        'qsma.reduction.schur',
        'qsma.reduction.schur.registry',
        'qsma.reduction.schur.ordering',
        'qsma.reduction.schur.superlu',
        'qsma.reduction.schur.splu',
        'qsma.reduction.schur.superlu_schur',
        'qsma.reduction.schur.metis_superlu',
        'qsma.reduction.schur.multifrontal',
        'qsma.reduction.schur.cholmod',
        'qsma.reduction.schur.pardiso',
        'qsma.reduction.schur.spd',
        'qsma._infra.dense')
