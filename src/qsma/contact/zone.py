r"""Exact elimination of pairs that stay open: solve on the contact zone only.

In a bolted joint most interface pairs are open (sandwich-2d: 48 of 65 after the
preload, sandwich-3d: 412 of 561) and stay open over the load ramp. With the
pairs split into the zone ``A`` and the open rest ``O`` (``lam_O = 0``)::

    d_O   = -K_OO^-1 (K_OA d_A + lam_w_O)
    lam_A = (K_AA - K_AO K_OO^-1 K_OA) d_A + (lam_w_A - K_AO K_OO^-1 lam_w_O)

which is again a problem ``lam = K d + lam_w`` (the Schur complement is SPD), of
the size of the zone. This is exact while the eliminated pairs stay open
(``w_O >= 0``); when one would close it joins the zone and the level is solved
again. Every answer is expanded to all pairs and judged by the public residual
of the full problem.

One elimination (:class:`Elimination`) costs a Cholesky factorisation of ``K_OO``
and two triangular solves with the zone's columns, ``O(n_O^3 + n_O^2 n_A)``; a
zone inside a zone already built is an elimination on the small zone problem,
``O(n_A^3)``. So the preload is solved on a predicted zone (:func:`solve_preload`),
and the ramp's zone, the pairs closed after the preload, is carved out of it
(:func:`zone_from_state` finds the last elimination built on the problem, that of
the preload or of a zone grown since, cached on it; any of them is exact). A pair
closing outside the outer elimination borders it (:meth:`Elimination.bordered`):
the new pairs join its zone through ``k`` solves with the factor already built,
``O(k n_O^2)``, not a new factorisation.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg as sla

from .problem import ContactProblem
from .registry import (DEFAULT_TOL, Iterate, _result, accepted_guess, checked_guess,
                       chosen_method, guess_measures, solve)
from .residual import FORCE_TOL, measures
from .state import OPEN_CODE as OPEN, STUCK_CODE as STUCK, ContactState

#: Tolerance factor of the second zone solve of a level whose zone answer met ``tol``
#: on the zone but not on the full problem. sandwich-3d refine 1 with ``active_set``:
#: residual 9.9e-11 on the zone, 1.02e-10 on the full problem (level 17); a factor
#: 100 leaves room above the round-off floor of the residual (~1e-15).
RETRY_TOL = 1e-2
#: Borderings of one elimination (:meth:`Elimination.bordered`) before the next growth
#: builds a new one. Each adds a correction of rank ``3 k`` to every solve with the
#: eliminated block, so a chain costs a little more per solve and carries the round-off
#: of each step (agreement with a fresh elimination measured in tests/contact/test_zone.py).
MAX_BORDERS = 16
#: A level's zone is narrowed to the pairs closed in its starting state
#: (:func:`fitted_zone`) when at least this fraction of its pairs is open there: the zone
#: only grows within a level, and a joint that lifts over the ramp would otherwise carry
#: its opened pairs (3 unknowns each in 3D) into every block step. lap-3d refine 2
#: (651 pairs): zones of 233 to 304 pairs of which about 140 closed.
NARROW_FRACTION = 0.25
#: Most blocks (row runs x column runs) that :func:`_place` copies as slices; above,
#: one fancy-indexed assignment is cheaper than the Python loop over the blocks.
PLACE_MAX_BLOCKS = 256


@dataclass(frozen=True, eq=False)
class _CholeskyInverse:
    """``K_OO^-1 x`` from the lower Cholesky factor ``L`` of ``K_OO``."""

    L: np.ndarray

    @property
    def depth(self):
        return 0

    def solve(self, x):
        return sla.cho_solve((self.L, True), x, check_finite=False)


@dataclass(frozen=True, eq=False)
class _BorderedInverse:
    r"""``K_{O'O'}^{-1} x`` for ``O'`` = the eliminated set ``O`` less the rows ``G``,
    from the inverse on ``O`` (``H = K_OO^{-1}``, never formed):

    .. math:: K_{O'O'}^{-1} = H_{O'O'} - H_{O'G} H_{GG}^{-1} H_{GO'} ,

    the inverse of a principal block written with the inverse of the whole.

    Attributes
    ----------
    parent : the inverse on ``O``
    rows : positions of ``O'`` in ``O``
    HG : ``H_{O'G}`` (n_O' x k)
    C : ``H_{GG}^{-1}`` (k x k)
    """

    parent: object
    rows: np.ndarray
    HG: np.ndarray
    C: np.ndarray
    n_parent: int

    @property
    def depth(self):
        return self.parent.depth + 1

    def solve(self, x):
        x = np.asarray(x, dtype=float)
        padded = np.zeros((self.n_parent,) + x.shape[1:])
        padded[self.rows] = x
        return self.parent.solve(padded)[self.rows] - self.HG @ (self.C @ (self.HG.T @ x))


@dataclass(frozen=True, eq=False)
class Elimination:
    """The open pairs of ``problem`` outside ``keep`` eliminated exactly.

    Attributes
    ----------
    problem : ContactProblem
    keep : (n_pairs,) bool, the zone
    sub : ContactProblem on the zone, stiffness ``S = K_AA - K_AO K_OO^-1 K_OA``
    iA, iO : flat indices of the zone and of the eliminated unknowns
    inverse : ``K_OO^-1`` as an object with ``solve(x)``: the Cholesky factor of
        ``K_OO`` (:meth:`build`) or a bordered one (:meth:`bordered`); ``None`` if
        nothing is eliminated
    Bt : ``K_OO^-1 K_OA`` (eliminated unknowns x zone unknowns)
    """

    problem: ContactProblem
    keep: np.ndarray
    sub: ContactProblem
    iA: np.ndarray
    iO: np.ndarray
    inverse: object
    Bt: np.ndarray
    _loads: dict = field(default_factory=dict, repr=False)

    @classmethod
    def build(cls, problem: ContactProblem, keep) -> "Elimination":
        r"""Eliminate the pairs outside ``keep``.

        With ``K_OO = L L^T`` and ``W = L^-1 K_OA``:

        .. math:: S = K_{AA} - W^T W, \qquad K_{OO}^{-1} K_{OA} = L^{-T} W .
        """
        keep = np.asarray(keep, dtype=bool).copy()
        flat = np.repeat(keep, problem.dim)
        iA, iO = np.flatnonzero(flat), np.flatnonzero(~flat)
        if len(iO) == 0:
            return cls(problem, keep, problem, iA, iO, None, np.zeros((0, len(iA))))
        K = problem.K
        L = sla.cholesky(K[np.ix_(iO, iO)], lower=True, overwrite_a=True, check_finite=False)
        W = sla.solve_triangular(L, K[np.ix_(iO, iA)], lower=True, overwrite_b=True,
                                 check_finite=False)
        S = K[np.ix_(iA, iA)]
        S -= W.T @ W
        Bt = sla.solve_triangular(L, W, lower=True, trans="T", overwrite_b=True,
                                  check_finite=False)
        sub = ContactProblem.derived(S, problem.mu[keep], problem.gap0[keep], problem.dim,
                                     overwrite=True)
        return cls(problem, keep, sub, iA, iO, _CholeskyInverse(L), Bt)

    def bordered(self, pairs) -> "Elimination":
        r"""This elimination with the eliminated ``pairs`` taken back into the zone,
        from what it holds (no new factorisation of the eliminated block).

        With the zone ``A``, the rows ``G`` of ``pairs`` and ``O' = O \ G``,
        ``H = K_OO^{-1}``, ``B = K_OO^{-1} K_OA`` (``Bt``) and
        ``C = H_GG^{-1}``: if the pairs of ``G`` carry a force, ``d_O = -B d_A -
        u + H_{OG} lam_G`` and so ``lam_G = C (d_G + B_G d_A + u_G)``; the zone
        problem of ``A u G`` is

        .. math::
            S' = \begin{bmatrix} S + B_G^T C B_G & B_G^T C \\ C B_G & C
                 \end{bmatrix}, \qquad
            B' = \begin{bmatrix} B_{O'} - H_{O'G} C B_G & -H_{O'G} C \end{bmatrix},

        exactly the elimination of ``O'`` (the Schur complement of the bordered
        system). Cost: ``k`` solves with ``H`` and products with ``k`` columns,
        ``O(k n_O^2 + k n_O n_A)`` for ``k = len(G)``, instead of a new
        ``O(n_O^3)`` factorisation.
        """
        pairs = np.asarray(pairs, dtype=bool) & ~self.keep
        if not pairs.any():
            return self
        p, keep = self.problem, self.keep | pairs
        flat = np.repeat(keep, p.dim)
        iA, iO = np.flatnonzero(flat), np.flatnonzero(~flat)
        in_O = np.full(p.size, -1)
        in_O[self.iO] = np.arange(len(self.iO))
        g = in_O[np.flatnonzero(np.repeat(pairs, p.dim))]       # rows G within O
        rows = in_O[iO]                                          # rows O' within O
        unit = np.zeros((len(self.iO), len(g)))
        unit[g, np.arange(len(g))] = 1.0
        H = self.inverse.solve(unit)                             # H_{O G}
        C = _spd_inverse(H[g])
        CB = C @ self.Bt[g]
        HG = H[rows]
        at_A = np.searchsorted(iA, self.iA)                      # old zone within the new
        at_G = np.searchsorted(iA, self.iO[g])
        S_AA = self.Bt[g].T @ CB
        S_AA += self.sub.K
        S = np.empty((len(iA), len(iA)))
        _place(S, at_A, at_A, S_AA)
        _place(S, at_A, at_G, CB.T)
        _place(S, at_G, at_A, CB)
        _place(S, at_G, at_G, C)
        B_A = HG @ CB
        np.subtract(self.Bt[rows], B_A, out=B_A)
        Bt = np.empty((len(iO), len(iA)))
        _place(Bt, None, at_A, B_A)
        _place(Bt, None, at_G, -HG @ C)
        sub = ContactProblem.derived(S, p.mu[keep], p.gap0[keep], p.dim, overwrite=True)
        inverse = (_BorderedInverse(self.inverse, rows, HG, C, len(self.iO))
                   if len(iO) else None)
        return Elimination(p, keep, sub, iA, iO, inverse, Bt)

    def load(self, lam_w, basis=None):
        """The zone's welded force ``lam_w_A - K_AO K_OO^-1 lam_w_O`` (flat) and the
        eliminated displacement at ``d_A = 0``, ``u = K_OO^-1 lam_w_O``.

        ``basis = (Wb, a)`` with ``lam_w = Wb a``: both are taken from the columns of
        ``Wb`` eliminated once (cached by the identity of ``Wb``), so a load level costs
        no solve with ``K_OO``. Returns ``(welded, u, basis of the zone problem or None)``.
        """
        if self.inverse is None:
            return lam_w, np.zeros(0), basis
        if basis is not None:
            WA, U = self._basis(basis[0])
            a = np.asarray(basis[1], dtype=float)
            return WA @ a, U @ a, (WA, a)
        lw_O = lam_w[self.iO]
        return lam_w[self.iA] - self.Bt.T @ lw_O, self.inverse.solve(lw_O), None

    def _basis(self, Wb):
        cached = self._loads.get("basis")
        if cached is None or cached[0] is not Wb:
            Wb_O = Wb[self.iO]
            cached = (Wb, Wb[self.iA] - self.Bt.T @ Wb_O, self.inverse.solve(Wb_O))
            self._loads["basis"] = cached
        return cached[1], cached[2]

    def expand(self, d_A, u):
        """Displacements of all unknowns (flat) from the zone's, ``d_O = -Bt d_A - u``."""
        d = np.empty(self.problem.size)
        d[self.iA] = d_A
        if len(self.iO):
            d[self.iO] = -(self.Bt @ d_A) - u
        return d


def _runs(positions):
    """Runs of consecutive values in the increasing ``positions``: a list of
    ``(first index in positions, first value, length)``."""
    positions = np.asarray(positions)
    if positions.size == 0:
        return []
    starts = np.concatenate(([0], np.flatnonzero(np.diff(positions) != 1) + 1))
    lengths = np.diff(np.concatenate((starts, [positions.size])))
    return list(zip(starts.tolist(), positions[starts].tolist(), lengths.tolist()))


def _place(out, rows, cols, block):
    """``out[np.ix_(rows, cols)] = block`` (``rows = None``: all rows), block by block
    over the runs of ``rows`` and ``cols`` (:func:`_runs`) as slices: the same numbers
    moved without numpy's element-wise fancy indexing, several times faster when the
    index sets are a few runs (a zone bordered by a few pairs: the old zone is as many
    runs as there are groups of new pairs, plus one). Many runs: fancy indexing."""
    row_runs = [(0, 0, out.shape[0])] if rows is None else _runs(rows)
    col_runs = _runs(cols)
    if len(row_runs) * len(col_runs) > PLACE_MAX_BLOCKS:
        out[np.ix_(np.arange(out.shape[0]) if rows is None else rows, cols)] = block
        return
    for at_r, first_r, n_r in row_runs:
        for at_c, first_c, n_c in col_runs:
            out[first_r:first_r + n_r, first_c:first_c + n_c] = \
                block[at_r:at_r + n_r, at_c:at_c + n_c]


def _spd_inverse(A):
    """Inverse of a symmetric positive definite matrix through its Cholesky factor."""
    L = sla.cholesky(0.5 * (A + A.T), lower=True, check_finite=False)
    inv = sla.cho_solve((L, True), np.eye(len(A)), check_finite=False)
    return 0.5 * (inv + inv.T)


@dataclass(frozen=True, eq=False)
class ContactZone:
    """A problem reduced to the pairs of ``keep`` (the others open).

    The reduction is a chain of at most two eliminations: the first on the full
    problem (the expensive one, shared), the second, if any, on the first one's zone
    problem (a zone carved out of a larger one).

    Attributes
    ----------
    full : ContactProblem
    keep : (n_pairs,) bool, the zone
    steps : tuple of :class:`Elimination`, outermost first
    """

    full: ContactProblem
    keep: np.ndarray
    steps: tuple

    @classmethod
    def build(cls, problem: ContactProblem, keep) -> "ContactZone":
        """One elimination of the pairs outside ``keep`` (cached on ``problem`` for
        :func:`zone_from_state`)."""
        step = Elimination.build(problem, keep)
        zone = cls(problem, step.keep, (step,))
        problem.__dict__["_zone_outer"] = zone
        return zone

    @property
    def sub(self) -> ContactProblem:
        """The contact problem of the zone."""
        return self.steps[-1].sub

    @property
    def n_eliminated(self):
        return int((~self.keep).sum())

    def narrowed(self, keep) -> "ContactZone":
        """The zone of ``keep`` (a subset of this zone's pairs) carved out of this
        zone's outermost elimination: an elimination on its zone problem only."""
        keep = np.asarray(keep, dtype=bool)
        outer = self.steps[0]
        if np.any(keep & ~outer.keep):
            raise ValueError("narrowed: the new zone must lie inside the outer zone")
        inner = keep[outer.keep]
        if inner.all():
            return ContactZone(self.full, outer.keep, (outer,))
        return ContactZone(self.full, keep.copy(), (outer, Elimination.build(outer.sub, inner)))

    def grown(self, pairs) -> "ContactZone":
        """This zone with ``pairs`` added. Inside the outer elimination: the inner
        elimination (on the outer zone problem) bordered by them, or the zone carved out
        of the outer one; else the outer elimination bordered by the pairs outside it
        (:meth:`Elimination.bordered`, cached on the problem like :meth:`build`), or, after
        :data:`MAX_BORDERS` borderings in a row, a new elimination of the full problem."""
        keep = self.keep | np.asarray(pairs, dtype=bool)
        outer = self.steps[0]
        outside = keep & ~outer.keep
        if not outside.any():
            inner = self.steps[-1] if len(self.steps) == 2 else None
            if (inner is None or keep[outer.keep].all()
                    or inner.inverse.depth >= MAX_BORDERS):
                return self.narrowed(keep)
            return ContactZone(self.full, keep.copy(),
                               (outer, inner.bordered(keep[outer.keep])))
        if outer.inverse.depth >= MAX_BORDERS:
            return ContactZone.build(self.full, keep)
        step = outer.bordered(outside)
        grown = ContactZone(self.full, step.keep, (step,))
        self.full.__dict__["_zone_outer"] = grown
        return grown.narrowed(keep)

    def loads(self, lam_w, basis=None):
        """Per elimination step, the eliminated displacement ``u`` at zero zone
        displacement; and the zone problem's welded force ``(n_zone, dim)``."""
        lw = np.asarray(lam_w, dtype=float).ravel()
        us = []
        for step in self.steps:
            lw, u, basis = step.load(lw, basis)
            us.append(u)
        return us, lw.reshape(-1, self.full.dim)

    def welded(self, lam_w, basis=None):
        """Welded force of the zone problem."""
        return self.loads(lam_w, basis)[1]

    def expand(self, d_A, lam_w, basis=None, us=None):
        """Relative displacements of all pairs from those of the zone (``us`` from
        :meth:`loads` if already computed)."""
        us = self.loads(lam_w, basis)[0] if us is None else us
        d = np.asarray(d_A, dtype=float).ravel()
        for step, u in zip(self.steps[::-1], us[::-1]):
            d = step.expand(d, u)
        return d.reshape(-1, self.full.dim)

    def restrict(self, state: ContactState) -> ContactState:
        return ContactState(state.d[self.keep], state.lam[self.keep], state.status[self.keep])


def zone_from_state(problem, state: ContactState) -> ContactZone:
    """The zone of the pairs that are not open in ``state``.

    Carved out of the last elimination built on ``problem`` (the preload's, or a
    zone grown since) when it contains them; else a new elimination. Every
    elimination of the same problem is exact, so which one is reused changes the
    cost only. The cached elimination (its Cholesky factor) lives until
    :func:`release_zones` or as long as the problem."""
    keep = np.asarray(state.status) != OPEN
    outer = problem.__dict__.get("_zone_outer")
    if outer is not None and not np.any(keep & ~outer.keep):
        return outer.narrowed(keep)
    return ContactZone.build(problem, keep)


def release_zones(problem):
    """Drop the elimination cached on ``problem`` (:func:`zone_from_state`).

    The cache and the problem refer to each other, so without this call the Cholesky
    factors of a dropped problem wait for the cycle collector; a run that owns its
    problem calls it when the problem is no longer needed."""
    problem.__dict__.pop("_zone_outer", None)


def fitted_zone(zone: ContactZone, state: ContactState) -> ContactZone:
    """``zone`` narrowed to the pairs closed in ``state`` if at least
    :data:`NARROW_FRACTION` of its pairs are open there (and the closed ones lie in its
    outer elimination), else ``zone`` itself.

    Exact either way: a pair eliminated here that closes during the level joins the
    zone again (:func:`solve_in_zone`). The narrowing is an elimination on the outer
    zone problem, ``O(n_outer^3)``; it pays when the open pairs would otherwise be
    unknowns of every block step of the level."""
    closed = np.asarray(state.status) != OPEN
    surplus = int(np.count_nonzero(zone.keep & ~closed))
    if (not closed.any() or surplus < NARROW_FRACTION * zone.keep.sum()
            or np.any(closed & ~zone.steps[0].keep)):
        return zone
    return zone.narrowed(closed)


def expected_closing(problem, d_before, d_last, ratio):
    """Pairs that close at the next level of a ramp by linear extrapolation of their
    opening ``w = d_n + g0`` from the two levels before it: ``w_last + ratio (w_last -
    w_before) < 0``, with ``ratio`` the next load increment over the last one. A guess
    for :func:`solve_in_zone` (``closing``): a pair that closes in fact but was not
    expected still joins the zone when the solve finds it closing.

    On the Gmsh tetrahedral lap joint's ramps (753 pairs) this takes 208 of the 1310
    zone solves away (docs/performance.md); in the computed loops, whose increments
    turn back at every reversal, it let in far more pairs than closed, and the loops
    take the pairs closed a cycle before instead (:mod:`qsma.hysteresis`)."""
    gap0 = problem.gap0
    w_before = np.asarray(d_before)[:, -1] + gap0
    w_last = np.asarray(d_last)[:, -1] + gap0
    return w_last + ratio * (w_last - w_before) < 0


def predicted_zone(problem, lam_w):
    """Pairs that may be closed after the preload: those pressed in the welded
    solution (``lam_w,n > 0``) or overlapping (``g0 < 0``); all pairs if none is."""
    lam_w = np.asarray(lam_w, dtype=float)
    keep = (lam_w[:, -1] > 0) | (problem.gap0 < 0)
    return keep if keep.any() else np.ones(problem.n_pairs, bool)


def solve_preload(problem, lam_w, *, method="basket", tol=DEFAULT_TOL, maxiter=None,
                  basis=None, max_growth=20):
    """The first load level from the undeformed reference, solved on a zone.

    The zone starts as :func:`predicted_zone` and grows exactly as in
    :func:`solve_in_zone` when an eliminated pair would close; the answer is judged
    on the full problem. Returns ``(ContactResult over all pairs, zone)``.
    """
    zone = ContactZone.build(problem, predicted_zone(problem, lam_w))
    return solve_in_zone(zone, lam_w, ContactState.reference(problem), method=method, tol=tol,
                         maxiter=maxiter, max_growth=max_growth, basis=basis)


def solve_in_zone(zone: ContactZone, lam_w, state: ContactState, *, method="basket",
                  tol=DEFAULT_TOL, maxiter=None, max_growth=20, basis=None, guess=None,
                  closing=None):
    """Solve one level on the zone (narrowed first by :func:`fitted_zone`), growing it
    when an eliminated pair would close.

    ``closing``, optional: (n_pairs,) bool, pairs expected to close at this level
    (:func:`expected_closing`); those the zone eliminates join it before the first
    solve, so that the level is not solved once more after finding them closed. The
    elimination is exact either way (a pair of the zone that stays open is a zone
    unknown with no force): the same solution to the tolerance, not the same bits.

    ``basis = (Wb, a)``, optional: ``lam_w = Wb a`` (see :meth:`Elimination.load`).
    ``guess``, optional: a state of all pairs to start the zone solve from (see
    :func:`qsma.contact.solve`); the zone is not narrowed below its closed pairs.
    Returns ``(ContactResult over all pairs, zone)``; the zone returned is the one
    to use for the next level. ``success`` is judged on the full problem, by one
    evaluation of the measures (:func:`qsma.contact.residual.measures`). A zone answer
    that meets ``tol`` on the zone but not on the full problem (the round-off of the
    elimination, seen with ``active_set``, whose Newton iterate stops just below
    ``tol``) is solved again on the zone to ``RETRY_TOL * tol``, then to that in the
    stiffness scale of the full problem (:func:`_zone_tolerances`). ``method="auto"`` is
    chosen on the full problem (:func:`qsma.contact.registry.chosen_method`), not on
    the zone, so that every zone of a run is solved by the same method.
    """
    full = zone.full
    method = chosen_method(method, full)
    lam_w = np.asarray(lam_w, dtype=float)
    if guess is not None:
        guess = checked_guess(guess, zone.full)
        held = _held_guess(zone, lam_w, state, guess, method, tol)
        if held is not None:
            return held
    zone = fitted_zone(zone, state if guess is None else _closed_in_either(state, guess))
    if closing is not None and np.any(closing & ~zone.keep):
        zone = zone.grown(closing & ~zone.keep)
    nit = 0
    for sub_tol in _zone_tolerances(zone, tol):
        zone, sub, d, closing, n = _settled(zone, lam_w, state, method, sub_tol, maxiter,
                                            max_growth, basis, guess)
        nit += n
        lam = np.zeros_like(d)
        lam[zone.keep] = sub.lam
        out = Iterate(d, lam, nit, bool(sub.success and not closing.any()),
                      _message(sub, zone, closing))
        checked = _full_measures(zone, sub, lam_w, d, lam, state)
        if not out.converged or (checked[0] <= tol and checked[1] <= FORCE_TOL):
            break
    return _result(full, lam_w, state, out, method, tol, fallback=sub.fallback,
                   measures=checked), zone


def _full_measures(zone, sub, lam_w, d, lam, state):
    """The measures of ``(d, lam)`` on the full problem. A zone that eliminates nothing
    is the full problem itself (:meth:`Elimination.build`), and the zone solve has
    just measured this very iterate on it (in units scaled by powers of two, which
    change no measure): those measures are the full problem's."""
    if zone.sub is zone.full and np.isfinite(sub.residual):
        return sub.residual, sub.residual_force, sub.residual_legacy
    return measures(zone.full, lam_w, d, lam, state)


def _zone_tolerances(zone, tol):
    """The tolerances of the zone solves of one level, each tried while the answer does
    not meet ``tol`` on the full problem: ``tol``, ``RETRY_TOL * tol``, and that times
    the ratio of the stiffness scales ``kappa`` (mean of the diagonal) of the zone
    problem and the full problem when it is below 1. The residual's natural map weighs a
    stuck pair's slip increment by ``kappa``: where the eliminated pairs held most of
    the stiffness (a body left standing on one corner, its other pairs open), the zone's
    ``kappa`` is decades smaller, and a slip the zone's check lets pass is a force
    error on the full problem (CalculiX's contact18 deck: ratio 3e-7, a stuck pair's
    slip increment of 3.4e-7 mm, force check 1.3e-6)."""
    ratio = zone.sub.kappa / zone.full.kappa
    return (tol, RETRY_TOL * tol) + ((RETRY_TOL * tol * ratio,) if ratio < 1.0 else ())


def _held_guess(zone, lam_w, state, guess, method, tol):
    """``(result, zone)`` of ``guess`` if it already is this level's answer on the full
    problem (:func:`qsma.contact.registry.guess_measures`), the zone grown by the
    closed pairs outside it, of the answer as classified or as the guess labels them
    (the next level starts from a zone that holds them); else None."""
    checked = guess_measures(zone.full, lam_w, state, guess, tol)
    if checked is None:
        return None
    res = _result(zone.full, lam_w, state, accepted_guess(guess), method, tol,
                  measures=checked)
    closed = (np.asarray(res.status) != OPEN) | (np.asarray(guess.status) != OPEN)
    outside = closed & ~zone.keep
    if outside.any():
        zone = zone.grown(outside)
    return res, zone


def _closed_in_either(state, guess):
    """A state whose open pairs are those open in both ``state`` and ``guess``."""
    both_open = (np.asarray(state.status) == OPEN) & (np.asarray(guess.status) == OPEN)
    return ContactState(state.d, state.lam, np.where(both_open, OPEN, STUCK))


def _settled(zone, lam_w, state, method, tol, maxiter, max_growth, basis, guess=None):
    """Solve on the zone, grown until no eliminated pair closes (or ``max_growth``
    solves): ``(zone, zone result, d of all pairs, closing pairs, iterations)``."""
    nit = 0
    for attempt in range(max_growth):
        us, welded = zone.loads(lam_w, basis)
        sub = solve(zone.sub, welded, zone.restrict(state), method=method, tol=tol,
                    maxiter=maxiter, guess=None if guess is None else zone.restrict(guess))
        nit += sub.nit
        d = zone.expand(sub.d, lam_w, us=us)
        closing = (~zone.keep) & (d[:, -1] + zone.full.gap0 < 0)
        if not closing.any() or attempt == max_growth - 1:
            break
        zone = zone.grown(closing)
    return zone, sub, d, closing, nit


def _message(sub, zone, closing):
    msg = sub.message + (f" (zone of {int(zone.keep.sum())} pairs, "
                         f"{zone.n_eliminated} open pairs eliminated)")
    if closing.any():         # max_growth rebuilds and still an eliminated pair closing
        msg += f"; {int(closing.sum())} eliminated pair(s) still closing, zone not settled"
    return msg
