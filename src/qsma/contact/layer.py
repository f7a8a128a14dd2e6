r"""A compliant interface solved as the contact problem of its Coulomb slider.

Every interface law of :mod:`qsma.contact.laws` is a layer in series with a rigid
Coulomb slider (docs/theory.md, "Interface laws"). With the layer linearised about a
state, its deformation is ``C lam + s`` (``C`` diagonal per contact-point component:
``1/(A k_t)`` tangential, ``1/(A k_n)`` normal, zero where the law is rigid; ``s`` the
normal part the linearisation misses). The slider's relative displacement is

.. math:: d' = d + C\lambda, \qquad
          \lambda = K d + \lambda_w = K' d' + \lambda_w',\quad
          K' = (K^{-1} + C)^{-1},\quad \lambda_w' = (I - K' C)\,\lambda_w ,

with the slider's normal opening ``w' = d'_n + g_0 + h_0 + s`` (``h_0`` the onset of
the law). This is again a problem ``lam = K d + lam_w`` with a rigid Coulomb law, so
every solver, the open-pair elimination, the ramps and the loops apply to it unchanged.
For a linear law (hard, linear penalty, elastic stick) ``s = 0`` and one solve is the
exact answer. For a nonlinear normal law, ``s = h(P/A) - h_0 - C_n P`` depends on the
answer's pressure: :func:`solve_layered` repeats the solve with ``s`` updated until it
is consistent with the pressures (a chord iteration), and judges the answer by the
slider's residual and by the law's own (:func:`law_residual`).

States passed in and results handed out are physical (``d`` the relative displacement
of the bodies); only the solves see the slider.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import scipy.linalg as sla
from scipy.linalg import blas as sla_blas

from ..errors import InputError
from .pairlaws import PairLaws
from .problem import ContactProblem
from .residual import EPS, ROUNDOFF, reaction_scale
from .state import OPEN_CODE as OPEN, ContactResult, ContactState, Outcome

#: Chord iterations of a nonlinear normal law in one solve before it is reported as not
#: converged (the caller may then linearise the layer again at the pressures reached).
MAX_LAW_ITERATIONS = 30
#: Interface stiffness against the structure's own: a layer whose stiffness per pair is
#: below ``UNIT_RATIO_MIN`` or above ``UNIT_RATIO_MAX`` times the pair's stiffness in
#: ``K`` is refused as a likely error of units (a factor 1e9 between N/mm^3 and N/m^3).
#: Inside this range the layer changes the answer by 1e-8 to 1e8 of the structure's
#: compliance, which covers every physical interface.
UNIT_RATIO_MIN = 1e-8
UNIT_RATIO_MAX = 1e8
def series_stiffness(K, c):
    r"""``K' = (K^{-1} + diag(c))^{-1}`` for a symmetric positive definite ``K`` and
    ``c >= 0``, exactly symmetric: on the components ``J`` with ``c > 0``, with
    ``S = diag(sqrt(c_J))`` and ``B = I + S K_JJ S = L L^T``,

    .. math:: K' = K - Y^T Y,\qquad Y = L^{-1} S K_{J,:}

    (Woodbury). Components with ``c = 0`` keep their rigid coupling; ``K`` itself is
    returned when no component is compliant."""
    c = np.asarray(c, dtype=float).ravel()
    J = np.flatnonzero(c > 0)
    if not len(J):
        return K
    s = np.sqrt(c[J])
    B = K[np.ix_(J, J)] * s[:, None] * s[None, :]
    B[np.diag_indices_from(B)] += 1.0
    L = sla.cholesky(B, lower=True, overwrite_a=True, check_finite=False)
    Y = sla.solve_triangular(L, s[:, None] * K[J, :], lower=True, overwrite_b=True,
                             check_finite=False)
    # K - Y^T Y by a symmetric rank-k update (BLAS syrk: one triangle, half the flops
    # of the product), the other triangle mirrored
    out = sla_blas.dsyrk(-1.0, np.asfortranarray(Y), beta=1.0, c=np.array(K, order="F"),
                         trans=1, lower=1)
    lower = np.tril(out)
    return lower + np.tril(out, -1).T


def check_units(laws: PairLaws, K, c):
    """Refuse a layer whose stiffness per pair is off the structure's by more than
    :data:`UNIT_RATIO_MIN` / :data:`UNIT_RATIO_MAX` (a unit error, not a joint)."""
    diag = np.abs(np.diag(K)).reshape(laws.n_pairs, laws.dim)
    c = np.asarray(c).reshape(laws.n_pairs, laws.dim)
    with np.errstate(divide="ignore"):
        ratio = np.where(c > 0, 1.0 / (c * diag), np.nan)
    if not np.any(np.isfinite(ratio)):
        return
    lo, hi = np.nanmin(ratio), np.nanmax(ratio)
    if lo < UNIT_RATIO_MIN or hi > UNIT_RATIO_MAX:
        what = "soft" if lo < UNIT_RATIO_MIN else "stiff"
        r = lo if lo < UNIT_RATIO_MIN else hi
        raise InputError(
            f"interface law: the layer is {r:.1e} times as stiff as the structure at a "
            f"contact point (accepted: {UNIT_RATIO_MIN:g} to {UNIT_RATIO_MAX:g}); that is "
            f"a unit error, not a joint: stiffnesses are per unit area (Pa/m = N/m^3 in "
            f"SI; 1 N/mm^3 = 1e9 N/m^3) and pressures in Pa. Fix the law's values, or "
            f"use normal = \"hard\" / tangential = \"rigid\" for a {what} limit")


class Layer:
    r"""The slider's contact problem of an interface with its laws linearised at a state.

    ``Layer.identity(problem)``: the rigid interface (no layer, no conversion).

    Attributes
    ----------
    problem : :class:`ContactProblem` of the slider (``K'``, gaps ``g_0 + h_0``)
    c : (n_pairs, dim) compliance of the linearised layer (zeros: rigid)
    laws : :class:`PairLaws` or None
    physical : the :class:`ContactProblem` of the bodies (``K``, gaps ``g_0``)
    P_ref : (n_pairs,) the pair forces it is linearised at
    """

    def __init__(self, physical, laws=None, P_ref=None, p_ref=None, frozen=False,
                 secant=False, low=None):
        self.physical, self.laws = physical, laws
        n, dim = physical.n_pairs, physical.dim
        self.s_fixed = np.zeros(n)
        self.P_ref = np.zeros(n)
        if laws is None or laws.rigid:
            self.c = np.zeros((n, dim))
            self.problem = physical
            self.laws = None
            self.frozen = self.curved = np.zeros(n, bool)
            return
        P_ref = np.zeros(n) if P_ref is None else np.maximum(np.asarray(P_ref, float), 0.0)
        self.P_ref = P_ref
        self.c = laws.compliance(P_ref, p_ref, secant=secant, low=low)
        check_units(laws, physical.K, laws.scale_compliance())
        self.frozen = ~laws.linear_pairs() if frozen else np.zeros(n, bool)
        if self.frozen.any():
            # linear about the state reached: the law's tangent there (a plastic law's
            # elastic unloading), through the layer's deformation at that state; a pair
            # without pressure keeps the tangent at the floor (the chord's) and no shift
            f = self.frozen & laws.plastic() & (P_ref > 0)
            self.c[f, -1] = laws.unloading_compliance(P_ref)[f]
            f = self.frozen
            self.s_fixed[f] = laws.layer_deformation(P_ref)[f] - self.c[f, -1] * P_ref[f]
        self.curved = ~laws.linear_pairs() & ~self.frozen
        K = series_stiffness(physical.K, self.c.ravel())
        self.problem = ContactProblem.derived(K, physical.mu, physical.gap0 + laws.onset(),
                                              dim)
        self._welded = {}

    @classmethod
    def identity(cls, problem):
        return cls(problem)

    def with_normal_compliance(self, c_n):
        r"""This layer with the normal compliance ``c_n`` (per pair) in place of its own,
        the tangential kept: ``K'`` updated on the normal components that change,
        ``D = diag(c_n - C_n)`` on them (``N``),

        .. math:: K'' = (K'^{-1} + N D N^T)^{-1}
                      = K' - K'_{:N} D (I + K'_{NN} D)^{-1} K'_{N:},

        ``O(n n_N^2 + n^2 n_N)`` instead of a new ``O(n^3)`` layer (the secant iterations
        of a preload change only the normal compliance)."""
        c_n = np.asarray(c_n, dtype=float)
        change = np.flatnonzero(c_n != self.c[:, -1])
        new = object.__new__(Layer)
        new.__dict__.update({k: v for k, v in self.__dict__.items()
                             if k not in ("_flexibility", "_closed", "_welded")})
        new._welded = {}
        new.c = self.c.copy()
        new.c[:, -1] = c_n
        if not len(change):
            return new
        K = self.problem.K
        N = self.problem.normal_index[change]
        D = c_n[change] - self.c[change, -1]
        A = np.eye(len(N)) + K[np.ix_(N, N)] * D[None, :]
        X = np.linalg.solve(A, K[N, :])
        Kn = K - (K[:, N] * D[None, :]) @ X
        new.problem = ContactProblem.derived(Kn, self.problem.mu, self.problem.gap0,
                                             self.problem.dim)
        return new

    def relinearised(self, P):
        """This layer linearised again at pair forces ``P``, its frozen pairs kept as
        they are."""
        new = Layer(self.physical, self.laws, P_ref=P)
        if self.frozen.any():
            f = self.frozen
            new.c[f] = self.c[f]
            new.s_fixed[f] = self.s_fixed[f]
            new.frozen, new.curved = f.copy(), new.curved & ~f
            K = series_stiffness(self.physical.K, new.c.ravel())
            new.problem = ContactProblem.derived(K, self.physical.mu, self.problem.gap0,
                                                 self.problem.dim)
        return new

    @property
    def rigid(self) -> bool:
        return self.laws is None

    @property
    def nonlinear(self) -> bool:
        """Some pair follows a nonlinear law that is not frozen: the chord iterates."""
        return self.laws is not None and bool(self.curved.any())

    def welded_basis(self, W):
        """``W' = (I - K' C) W``, the welded force basis of the slider (cached by ``W``)."""
        if self.rigid:
            return W
        hit = self._welded.get("W")
        if hit is None or hit[0] is not W:
            Wp = W - self.problem.K @ (self.c.reshape(-1, 1) * W)
            hit = (W, Wp)
            self._welded["W"] = hit
        return hit[1]

    def shift_force(self, s):
        """``K' s`` of a shift ``s`` of the normal components (n_pairs,), flat: the force
        that takes the shift into the welded force. Kept for the last ``s`` (the same
        product, the same bits): a frozen layer shifts by the same ``s`` at every level
        of a loop, and the product gathers a column of ``K'`` per shifted pair."""
        hit = self._welded.get("shift")
        if hit is None or not np.array_equal(hit[0], s):
            on = np.flatnonzero(s)
            hit = (np.array(s), self.problem.K[:, self.problem.normal_index[on]] @ s[on])
            self._welded["shift"] = hit
        return hit[1]

    def shift(self, P):
        """``s(P)``, the normal deformation of the layer its linearisation misses: the
        fixed deformation of a frozen pair, the nonlinear remainder of a curved one,
        zero elsewhere."""
        s = self.s_fixed.copy()
        if self.nonlinear:
            c = self.curved
            Pc = np.maximum(np.asarray(P, dtype=float)[c], 0.0)
            s[c] = self.laws.layer_deformation(np.asarray(P, float))[c] - self.c[c, -1] * Pc
        return s

    def to_slider(self, state, s=None):
        """A physical state as the slider's (``d' = d + C lam``, plus the shift ``s`` on
        the normal components)."""
        if state is None or self.rigid:
            return state
        d = state.d + self.c * state.lam
        if s is not None:
            d = d.copy()
            d[:, -1] += s
        return ContactState(d, state.lam, state.status)

    def to_physical(self, res, s=None):
        """A slider result as the bodies' (``d = d' - s - C lam``)."""
        if self.rigid:
            return res
        d = res.d - self.c * res.lam
        if s is not None:
            d[:, -1] -= s
        return replace(res, d=d, state=ContactState(d, res.lam, res.status))

    def law_residual(self, res, start=None):
        """The law's own residual of a physical result: ``max_i |P_i - A_i p(h_i)| / F``
        with ``h_i = -w_i`` the overclosure of the bodies: the force by which the
        pressure misses the pressure-overclosure law, dimensionless like
        :func:`qsma.contact.residual` (hard pairs: 0, the slider's residual covers them).
        ``F`` is the largest change of a contact force from the state ``start`` (its
        ``lam``; ``None``: from zero, so ``F = max|lam|``): a level's increment is then
        as accurate as the level itself, however small against the preload (a modal
        load of 1e-6 of the bolts' must not be lost in a tolerance of the bolts')."""
        if not self.nonlinear:
            return 0.0
        P = np.maximum(res.lam[:, -1], 0.0)
        h = -(res.d[:, -1] + self.physical.gap0)
        curved = self.curved
        miss = np.where(curved, np.abs(P - self.laws.pair_pressure(h)), 0.0)
        # round-off of h: the sum of the terms it is computed from, eps each, times the
        # law's slope there
        terms = (np.abs(res.d[:, -1]) + np.abs(self.physical.gap0)
                 + np.abs(self.c[:, -1] * P) + np.abs(h - self.laws.onset()))
        # and of P itself: a contact force is computed no closer than the round-off of
        # the largest one (residual.roundoff_allowance's growth with the size)
        allowance = ROUNDOFF * EPS * (terms * self.laws.pair_stiffness(h)
                                      + np.sqrt(self.problem.size) * np.abs(res.lam).max())
        F = reaction_scale(res.lam if start is None else res.lam - start.lam)
        excess = np.maximum(miss - allowance, 0.0)
        check = curved & (excess > 0)
        if check.any():
            # where the pressure misses, the distance to the law's graph (a vertical
            # segment of the law holds any pressure at its closure): inverse evaluated
            # only there
            with np.errstate(divide="ignore"):
                k = np.where(self.c[:, -1] > 0, 1.0 / self.c[:, -1], np.inf)
            excess[check] = np.maximum(self.laws.graph_distance(P, h, k, check)[check]
                                       - allowance[check], 0.0)
        return float(np.max(excess, initial=0.0) / F)

    @property
    def flexibility(self):
        """``K'^{-1}``, the slider's flexibility (built on first use, ``O(n^3)``): its
        block on the closed pairs inverts to their stiffness with the open pairs free
        (no force), what the chord's Newton step needs."""
        F = self.__dict__.get("_flexibility")
        if F is None:
            F = sla.cho_solve(sla.cho_factor(self.problem.K, lower=True, check_finite=False),
                              np.eye(self.problem.size), check_finite=False)
            self._flexibility = F
        return F

    def _closed_stiffness(self, closed):
        """The normal-normal block of the slider stiffness of the pairs ``closed`` with
        the others free (cached for the last set): the Schur complement of ``K'`` that
        eliminates the open pairs when they are the fewer (``O(n_open^3 + n_open n^2)``,
        nothing when every pair is closed), else the inverse of the closed pairs'
        block of the flexibility ``K'^{-1}``."""
        key = closed.tobytes()
        hit = self.__dict__.get("_closed")
        if hit is None or hit[0] != key:
            dim, K = self.problem.dim, self.problem.K
            flat = np.repeat(closed, dim)
            C, O = np.flatnonzero(flat), np.flatnonzero(~flat)
            n = np.arange(int(closed.sum())) * dim + dim - 1
            N = C[n]                                      # the closed normal rows of K'
            if len(O) <= len(C):
                S_nn = K[np.ix_(N, N)]
                if len(O):
                    L = sla.cho_factor(K[np.ix_(O, O)], lower=True, check_finite=False)
                    S_nn = S_nn - K[np.ix_(N, O)] @ sla.cho_solve(L, K[np.ix_(O, N)],
                                                                  check_finite=False)
            else:
                S_nn = np.linalg.inv(self.flexibility[np.ix_(C, C)])[np.ix_(n, n)]
            hit = (key, S_nn)
            self._closed = hit
        return hit[1]

    def shift_step(self, lam, s):
        r"""The shift after one Newton step on ``s - s(P(s)) = 0`` over the pairs in
        contact, their contact states held: ``dP/ds = -S_nn`` (the closed pairs' normal
        stiffness with the open ones free), so

        .. math:: (I + R' S_{nn})\,\Delta s = s(P) - s,\qquad R' = \mathrm{diag}\,
                  \frac{d s}{dP};

        zero at pairs without pressure."""
        P = lam[:, -1]
        closed = P > 0
        out = np.where(self.curved, 0.0, self.s_fixed)
        moving = (closed & self.curved)[closed]          # the curved ones of the closed
        if not moving.any():
            return out
        slope = (self.laws.normal_slope(P) - self.c[:, -1])[closed][moving]  # d s / dP
        J = slope[:, None] * self._closed_stiffness(closed)[np.ix_(moving, moving)]
        J[np.diag_indices_from(J)] += 1.0
        at = np.flatnonzero(closed)[moving]
        out[at] = s[at] + np.linalg.solve(J, (self.shift(P) - s)[at])
        return out


class Anderson:
    """Anderson acceleration of a fixed-point iteration ``x <- g(x)`` (depth ``m``): the
    next iterate combines the last ``m`` steps so that the combined residual
    ``g(x) - x`` is smallest in least squares (type II). Restarted when ``key``
    changes (for a contact problem: the pairs in contact, whose change makes another
    map)."""

    def __init__(self, m=5):
        self.m, self.X, self.F, self.key = m, [], [], None

    def __call__(self, x, g, key=None):
        f = g - x
        if key != self.key:
            self.X, self.F, self.key = [], [], key
        self.X.append(x)
        self.F.append(f)
        if len(self.X) > self.m + 1:
            self.X.pop(0)
            self.F.pop(0)
        if len(self.X) < 2:
            return g
        dX = np.diff(np.array(self.X), axis=0).T
        dF = np.diff(np.array(self.F), axis=0).T
        gamma = np.linalg.lstsq(dF, f, rcond=None)[0]
        return g - (dX + dF) @ gamma


def interface_springs(layer, closed):
    """Stiffness of the layer at each closed contact point, (n_pairs, dim) in the local
    frames: ``1/C`` where compliant, ``inf`` where rigid, 0 at open points; None for a
    rigid interface (its closed points are tied)."""
    if layer is None or not isinstance(layer, Layer) or layer.rigid:
        return None
    closed = np.asarray(closed, dtype=bool)[:, None]
    with np.errstate(divide="ignore"):
        k = np.where(layer.c > 0, 1.0 / np.where(layer.c > 0, layer.c, 1.0), np.inf)
    return np.where(closed, k, 0.0)


def solve_layered(layer, solve_once, lam_w, state, guess=None, tol=1e-10,
                  max_iterations=MAX_LAW_ITERATIONS):
    r"""Solve one level of a layered interface; returns the physical result.

    ``solve_once(lam_w, state, guess)`` solves the slider problem (``layer.problem``)
    for a welded force and a state and guess in slider coordinates (the caller's
    choice of method and zone). ``lam_w``: the slider's welded force ``W' a``;
    ``state``, ``guess``: physical states (``None``: the reference).

    Linear layer: one solve. Nonlinear: the shift ``s`` starts from the pressures of
    ``guess`` (else ``state``) and is updated by :meth:`Layer.shift_update` until the
    law's residual meets ``tol``; a shift enters the solve as a displacement of the
    normal components, ``d'' = d' + s``, whose welded force is ``lam_w - K' s``.
    """
    if not layer.nonlinear and not layer.frozen.any():
        res = solve_once(lam_w, layer.to_slider(state), layer.to_slider(guess))
        return layer.to_physical(res)
    start = guess if guess is not None else state
    s = layer.shift(np.zeros(layer.problem.n_pairs) if start is None else start.lam[:, -1])
    ref = state if state is not None else ContactState.reference(layer.physical)
    nit, res, law = 0, None, np.inf
    for it in range(max_iterations):
        shifted = lam_w - layer.shift_force(s).reshape(lam_w.shape) if s.any() else lam_w
        res = solve_once(shifted, layer.to_slider(ref, s),
                         layer.to_slider(guess, s) if guess is not None else None)
        nit += res.nit
        out = layer.to_physical(res, s)
        if not res.success:
            return _with(out, nit=nit)
        law = layer.law_residual(out, state)
        if law <= tol or not layer.nonlinear:
            return _with(out, nit=nit, residual=max(res.residual, law), law_residual=law)
        guess = out.state
        s = layer.shift_step(res.lam, s)
    return _with(out, nit=nit, success=False, outcome=Outcome.NOT_CONVERGED,
                 residual=max(res.residual, law), law_residual=law,
                 message=f"the interface law's pressure-overclosure iteration did not "
                         f"converge in {max_iterations} solves (law residual "
                         f"{law:.2e} > {tol:.1e})")


def _with(res, **changes):
    return replace(res, **changes)
