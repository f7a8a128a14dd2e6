"""The modes of the tied assembly (:func:`linear_modes`), through the condensed bodies
where they cover the case, else through the factorised tied stiffness."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from ..errors import InputError
from ..fe.assembly import stiffness_matrix
from ..fe.bolts import bolt_stiffness
from ..model.spring import spring_matrix
from ..reduction.rigid import assembly_free_motions
from .substructured import _substructured_modes, substructured_inverse
from .tied import (Modes, _check_free_rigid, _check_rigid, _checked_springs, _factor,
                   _lanczos, _spring_stiffness, check_n_modes, free_shift, partly_tied, stacked,
                   tie_transform)

def linear_modes(model, assembled, pairing, tied=None, n_modes=6, reduced=None,
                 springs=None) -> Modes:
    """First ``n_modes`` modes with the pairs in mask ``tied`` tied (default: all).

    Solves ``(T^T K T - w^2 T^T M T) phi_r = 0`` by shift-invert Lanczos about 0;
    shapes are mass-normalised (``phi^T M phi = 1``). An assembly that no clamp holds
    (free-free, :func:`qsma.reduction.rigid.assembly_free_motions` motions free) has its rigid
    modes first (``Modes.n_rigid``) and ``n_modes`` elastic modes follow them.

    ``reduced``: the condensed two-body model of the run (:mod:`qsma.reduction.two_bodies`, bolts
    locked or not). Where given and it covers the case (:func:`substructured_inverse`),
    ``(T^T K T)^-1`` is applied through its per-body ``K_EE`` factors and the dense
    interface matrices, and a free-free assembly's rigid motions are projected out of
    the operator (:class:`SubstructuredInverse`); otherwise, and without it, the tied
    stiffness is factorised (:func:`_factor`), a free-free one shifted to ``-s``
    (:data:`FREE_SHIFT_RTOL`). Both give the same modes to round-off.

    ``springs``, optional: (n_pairs, dim) stiffness of a compliant interface layer at
    each tied contact point, per component of its local frame
    (:func:`qsma.contact.layer.interface_springs`): ``inf`` ties the component, a finite
    value joins the two sides by a spring, 0 leaves it free. Contact points tied in every
    component are tied as without springs.
    """
    tied, springs, held, T, M, inverse = tied_operators(model, assembled, pairing, tied,
                                                        n_modes, reduced, springs)
    n_free = assembly_free_motions(model, assembled)
    if inverse is not None:
        return check_hourglass(
            _substructured_modes(inverse, M, T, tied, n_modes, model, assembled), assembled)
    if springs is not None:
        T = partly_tied(T, model, pairing, springs, held)
        M = (T.T @ stacked([a.M for a in assembled]) @ T).tocsc()
    K = stacked([a.K for a in assembled])
    if getattr(model, "bolts", ()):
        K = K + bolt_stiffness(model)                  # the bolts locked after preload
    if springs is not None:
        K = K + _spring_stiffness(model, pairing, springs, held)
    K = (T.T @ K @ T).tocsc()
    k = min(n_modes + n_free, T.shape[1] - 2)
    shift = free_shift(K, M) if n_free else 0.0
    solve = _factor((K + shift * M).tocsc() if n_free else K, model, assembled, T)
    lam, vec = _lanczos(K, k, M, -shift, solve, solve)
    if n_free:
        _check_free_rigid(lam, model, assembled, T, vec, n_free)
    else:
        _check_rigid(lam, model, assembled, T, vec)
    vec /= np.sqrt(np.einsum("ik,ik->k", vec, M @ vec))
    omega = np.sqrt(np.maximum(lam, 0.0))
    omega[:n_free] = 0.0
    return check_hourglass(Modes(omega, T @ vec, tied.copy(), n_free), assembled)



def tied_operators(model, assembled, pairing, tied, n_modes, reduced, springs):
    """What :func:`linear_modes` checks and builds before its eigen solve: ``(tied,
    springs, held, T, M, inverse)``, ``held`` the contact points tied in every
    component, ``T`` their tie transform, ``M`` the tied mass matrix and ``inverse`` the
    :class:`SubstructuredInverse` (None where the condensed bodies do not cover the
    case)."""
    if tied is None:
        tied = np.ones(pairing.n_pairs, dtype=bool)
    tied = np.asarray(tied, dtype=bool)
    if tied.shape != (pairing.n_pairs,):
        raise InputError(f"tied mask must have {pairing.n_pairs} entries, got {tied.shape}")
    springs = _checked_springs(springs, pairing.n_pairs, model.dim)
    held = tied if springs is None else tied & np.all(np.isinf(springs), axis=1)
    T = tie_transform(model, assembled, pairing, held)
    check_n_modes(n_modes, T.shape[1])
    M = (T.T @ stacked([a.M for a in assembled]) @ T).tocsc()
    inverse = None if reduced is None else substructured_inverse(
        model, assembled, pairing, tied, reduced, T, M, springs)
    return tied, springs, held, T, M, inverse

#: A mode whose strain energy in a body on the full rule exceeds this many times its
#: energy on the reduced rule of that body's elements is a zero-energy (hourglass) mode
#: of reduced integration (for a physical mode the ratio is about 1: the reduced rule
#: only softens the element slightly).
HOURGLASS_RATIO = 10.0


def check_hourglass(modes, assembled):
    """Refuse modes that are zero-energy modes of reduced integration (C3D20R, CPE8R):
    their deformation carries almost no strain energy on the reduced rule and a normal
    amount on the full one. Such modes spread through meshes one element thick; in
    thicker meshes they cannot, and every mode passes."""
    offsets = np.cumsum([0] + [a.n_dofs for a in assembled])
    for j, a in enumerate(assembled):
        form = a.element
        if not getattr(form, "reduced", False):
            continue
        # the body's own K (its grounded springs included) against the same body on
        # the full rule, springs added: only the cells' rule differs between the two
        K_full = stiffness_matrix(a.body, replace(form, reduced=False))
        if a.body.springs:
            K_full = K_full + spring_matrix(a.body)
        phi = modes.shapes[offsets[j]:offsets[j + 1], modes.n_rigid:]
        e_red = np.einsum("ik,ik->k", phi, a.K @ phi)
        e_full = np.einsum("ik,ik->k", phi, K_full @ phi)
        scale = max(e_full.max(initial=0.0), np.finfo(float).tiny)
        bad = np.flatnonzero(e_full > HOURGLASS_RATIO * np.maximum(e_red, 0.0)
                             + 1e-9 * scale)
        if bad.size:
            k = int(bad[0])
            raise InputError(
                f"body {a.body.name!r} ({form.name}): mode {k} (f = "
                f"{modes.f_hz[modes.n_rigid + k]:.4g} Hz) is a zero-energy (hourglass) mode "
                f"of reduced integration: its strain energy on the full rule is "
                f"{e_full[k] / max(e_red[k], np.finfo(float).tiny):.3g} times that on the "
                f"reduced one. It spreads through a mesh one element thick: use the fully "
                f"integrated {form.name[:-1]} or mesh at least two elements through every "
                f"section")
    return modes
