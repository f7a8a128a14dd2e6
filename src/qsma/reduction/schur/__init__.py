r"""Static condensation of a sparse SPD stiffness onto a set of DOFs.

For ``K`` (n x n, sparse, symmetric positive definite), interface DOFs ``C`` and
the rest ``E = np.setdiff1d(np.arange(n), C)`` (sorted)::

    Kc = K_CC - K_CE K_EE^-1 K_EC            (the Schur complement of K_EE)
    solver(b) = K_EE^-1 b                    (recovery, condensed loads)

Several backends compute the same two objects, one module each in this package;
:data:`SCHUR_BACKENDS` (:mod:`.registry`) maps a name to its function and
``backend="auto"`` takes the first available one of :data:`AUTO_ORDER` (fastest first,
measured by ``benchmarks/bench_schur.py``; the numbers are in ``docs/schur.md``):

``"pardiso"``
    Intel MKL PARDISO through ``pypardiso``'s ``mkl_rt``: nested-dissection
    ordering and the Schur complement computed during the factorisation
    (``iparm(36) = 1``), plus a plain Cholesky of ``K_EE`` for the solver.
``"multifrontal"``
    our own Cholesky of ``K_EE`` with dense fronts on a METIS separator tree of its
    node graph (:mod:`.multifrontal`, ``pymetis``): the interface rows ride along
    in every front and their updates sum to ``K_CE K_EE^-1 K_EC``; the factor (one
    triangle) solves with ``K_EE`` (the default for 3D solids without PARDISO).
``"metis_superlu"``
    METIS nested dissection of ``K_EE`` (``pymetis``) on its node graph and one SuperLU
    factorisation of the bordered matrix ``[[K_EE, K_EC], [0, I]]`` in that order,
    without pivoting: ``Kc = K_CC - U_EC^T D^-1 U_EC`` by blocked BLAS products, and
    the same factor solves with ``K_EE`` (the default for 2D and scalar problems
    without PARDISO).
``"cholmod"``
    CHOLMOD (supernodal Cholesky, from the ``cvxopt`` wheel) of ``K`` ordered
    ``[E by AMD, C last]``: ``K = L L^T`` with ``Kc = L_CC L_CC^T``.
``"superlu_schur"``
    scipy only, the same partial factorisation with SuperLU: ``K`` ordered
    ``[E by SuperLU's MMD, C last]`` factorised without pivoting, so that
    ``Kc = U_CC^T D_C^-1 U_CC``.
``"splu"``
    scipy only: ``X = K_EE^-1 K_EC`` by a dense multi-RHS
    solve (in column blocks of bounded memory), ``Kc = K_CC - K_EC^T X``.

Every backend checks that ``K_EE`` is positive definite through its pivots:
the smallest pivot relative to its diagonal entry, ``min_i d_i / (K_EE)_ii``,
must exceed :data:`PIVOT_RATIO_MIN`; otherwise :class:`~qsma.errors.InputError`
(a body not held against rigid-body motion apart from the interface).
"""
from __future__ import annotations

from .registry import (AUTO_ORDER, MULTIFRONTAL_MIN_DOFS_PER_NODE, PIVOT_RATIO_MIN,
                       SCHUR_BACKENDS, SYMMETRY_TOL, EESolver, SchurBackend, SchurParts,
                       available_backends, ee_rhs, register_backend, schur_complement,
                       suits_multifrontal)
# Importing the backend modules registers them, in this order, in SCHUR_BACKENDS.
from . import splu, superlu_schur, metis_superlu  # noqa: F401  isort: skip
from . import multifrontal, cholmod, pardiso  # noqa: F401  isort: skip
from .ordering import nested_dissection, node_graph, supervariables  # noqa: E402
from .spd import spd_solver  # noqa: E402
from .superlu import SOLVE_MIN_COLUMNS, solved_by_columns  # noqa: E402

__all__ = ["schur_complement", "spd_solver", "SCHUR_BACKENDS", "AUTO_ORDER",
           "available_backends", "register_backend", "SchurBackend", "SchurParts",
           "EESolver", "ee_rhs", "PIVOT_RATIO_MIN", "SYMMETRY_TOL",
           "MULTIFRONTAL_MIN_DOFS_PER_NODE", "suits_multifrontal", "nested_dissection",
           "node_graph", "supervariables", "solved_by_columns", "SOLVE_MIN_COLUMNS"]
