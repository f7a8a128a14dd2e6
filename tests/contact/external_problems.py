r"""Third-party frictional contact problems: Siconos ``.dat`` local problems, for the
tests and the corpus benchmark (not part of the package: qsma solves the problems of its
own models).

The Siconos project ships its frictional-contact test problems as text files
(``numerics/src/FrictionContact/test/data/*.dat``, Apache-2.0). A *local*
problem is the Delassus form

.. math:: u = W r + q, \qquad r \in K_\mu, \quad
          \hat u = u + \mu \lVert u_t \rVert e_n \in K_\mu^*, \quad r \perp \hat u ,

with per contact the normal component first, ``r = (r_n, r_t)``. De Saxce's
complementarity has the three branches of the qsma law (open: ``r = 0,
u_n >= 0``; stuck: ``u = 0``; slipping: ``u_n = 0``, ``r_t = -mu r_n
u_t/|u_t|``), so with ``lam = r`` (pressure ``P = r_n``, shear ``Q = r_t``),
``d = u`` (opening ``w = u_n``, slip increment ``dv = u_t`` from the reference
``d_prev = 0``) the problem is exactly ``lam = K d + lam_w`` with

.. math:: K = W^{-1}, \qquad \lambda_w = -K q ,

after reordering each contact's components to the qsma order ``(t, n)`` /
``(t1, t2, n)``. This needs ``W`` symmetric positive definite (up to the
round-off of the file); the problems whose ``W`` is only positive
semi-definite or not symmetric have no stiffness form here.

FCLIB global problems (``.hdf5``, group ``fclib_global``: ``M v = H r + f``,
``u = H^T v + w``, the Siconos convention) become the same local form with
``W = H^T M^-1 H``, ``q = H^T M^-1 f + w`` (:func:`read_fclib_global`; needs
``h5py``, which qsma does not depend on: only the corpus benchmark reads
these files, and only a diagonal ``M`` is supported).

Only the reader of the format is here (written from the layout of the files,
no Siconos code): dense (storage ``0``), sparse block (``1``) and
CSparse-printed sparse (``2``) matrices. The sparse print has 6 significant digits, so those files
define a nearby problem, not Siconos' own to full precision.
"""
from __future__ import annotations

import re
from pathlib import Path
from typing import NamedTuple

import numpy as np

from qsma.contact import ContactProblem
from qsma.errors import InputError


class DelassusProblem(NamedTuple):
    """A Siconos local problem ``u = W r + q`` (normal component first per contact)."""

    W: np.ndarray
    q: np.ndarray
    mu: np.ndarray
    dim: int


def read_siconos_dat(path):
    """Read a Siconos ``FrictionContactProblem`` text file.

    Layout: ``dim``, ``n_contacts``, the matrix (``storage``, ``size0``,
    ``size1``, then for ``storage = 0`` ``size0 size1`` and the values in
    column-major order, for ``storage = 1`` a sparse block structure, for
    ``storage = 2`` a CSparse print), then ``q``
    (``dim * n_contacts`` values) and ``mu`` (``n_contacts`` values).

    Returns
    -------
    DelassusProblem

    Raises
    ------
    InputError
        Unsupported storage or a truncated file.
    """
    text = Path(path).read_text()
    head = text.split(None, 5)
    dim, nc, storage, n = int(head[0]), int(head[1]), int(head[2]), int(head[3])
    if storage == 0:
        tokens = text.split()
        values = np.array(tokens[7:7 + n * n], dtype=float)
        W = values.reshape(n, n, order="F")
        rest = tokens[7 + n * n:]
    elif storage == 1:
        W, rest = _read_sparse_block(text.split()[5:], n)
    elif storage == 2:
        W, rest = _read_csparse(text, n)
    else:
        raise InputError(f"{path}: matrix storage {storage} is not supported "
                         "(expected 0 dense, 1 sparse block or 2 CSparse)")
    if len(rest) < n + nc:
        raise InputError(f"{path}: expected {n} values of q and {nc} of mu after the matrix, "
                         f"got {len(rest)} values")
    q = np.array(rest[:n], dtype=float)
    mu = np.array(rest[n:n + nc], dtype=float)
    return DelassusProblem(W, q, mu, dim)


def read_fclib_global(path):
    r"""Read an FCLIB global problem (``.hdf5``) and condense it to the local form.

    The file holds ``M`` (``n x n``), ``H`` (``n x d n_c``), ``f``, ``w``, ``mu``
    of ``M v = H r + f``, ``u = H^T v + w`` (CSparse triplet or compressed-column
    storage, normal component first per contact). With ``M`` diagonal,

    .. math:: u = W r + q, \qquad W = H^T M^{-1} H, \quad q = H^T M^{-1} f + w .

    Returns
    -------
    DelassusProblem

    Raises
    ------
    InputError
        ``h5py`` not installed, no ``fclib_global`` group, or ``M`` not diagonal.
    """
    try:
        import h5py
    except ImportError:
        raise InputError("reading FCLIB .hdf5 files needs h5py: pip install h5py") from None
    with h5py.File(path, "r") as f:
        if "fclib_global" not in f:
            raise InputError(f"{path}: no 'fclib_global' group (only global FCLIB problems "
                             "are read)")
        g = f["fclib_global"]
        M, H = _fclib_matrix(g["M"]), _fclib_matrix(g["H"])
        force, w = g["vectors/f"][()], g["vectors/w"][()]
        mu, dim = g["vectors/mu"][()], int(g["spacedim"][0])
    if (M - np.diag(np.diag(M))).any():
        raise InputError(f"{path}: M is not diagonal; only diagonal mass matrices are read")
    HM = H.T / np.diag(M)
    return DelassusProblem(HM @ H, HM @ force + w, np.asarray(mu, float), dim)


def _fclib_matrix(group):
    """Dense matrix of an FCLIB sparse matrix (``nz >= 0`` triplet, ``nz = -1``
    compressed columns)."""
    m, n, nz = int(group["m"][0]), int(group["n"][0]), int(group["nz"][0])
    i, p, x = group["i"][()], group["p"][()], group["x"][()]
    out = np.zeros((m, n))
    if nz >= 0:
        np.add.at(out, (i[:nz], p[:nz]), x[:nz])
    elif nz == -1:
        cols = np.repeat(np.arange(n), np.diff(p[:n + 1]))
        np.add.at(out, (i[:len(cols)], cols), x[:len(cols)])
    else:
        raise InputError(f"FCLIB matrix storage nz={nz} (compressed rows) is not supported")
    return out


def _read_sparse_block(tokens, n):
    """Matrix of a sparse block print: block counts, cumulative block sizes, the
    compressed-row block index, then each block (its number, values column-major)."""
    bn0, bn1 = int(tokens[1]), int(tokens[2])
    k = 3
    rows = np.r_[0, np.array(tokens[k:k + bn0], dtype=int)]
    k += bn0
    cols = np.r_[0, np.array(tokens[k:k + bn1], dtype=int)]
    k += bn1
    filled1, filled2 = int(tokens[k]), int(tokens[k + 1])
    k += 2
    index1 = np.array(tokens[k:k + filled1], dtype=int)
    k += filled1
    index2 = np.array(tokens[k:k + filled2], dtype=int)
    k += filled2
    W = np.zeros((n, n))
    for row in range(filled1 - 1):
        for block in range(index1[row], index1[row + 1]):
            col = index2[block]
            nr, ncol = rows[row + 1] - rows[row], cols[col + 1] - cols[col]
            values = np.array(tokens[k + 1:k + 1 + nr * ncol], dtype=float)
            W[rows[row]:rows[row + 1], cols[col]:cols[col + 1]] = values.reshape(
                nr, ncol, order="F")
            k += 1 + nr * ncol
    return W, tokens[k:]


def _read_csparse(text, n):
    """Matrix of a CSparse ``cs_print`` (``col j : ...`` then ``i : value`` lines)."""
    W = np.zeros((n, n))
    lines = text.splitlines()
    col, k = 0, 0
    entry = re.compile(r"^\s*(\d+)\s*:\s*(\S+)\s*$")
    for k, line in enumerate(lines[8:], start=8):
        stripped = line.strip()
        if stripped.startswith("col"):
            col = int(stripped.split()[1])
            continue
        match = entry.match(line)
        if match is None:
            break
        W[int(match.group(1)), col] = float(match.group(2))
    return W, " ".join(lines[k:]).split()


#: Default accepted asymmetry of ``W``, ``max|W - W^T| <= ... max|W|``: the
#: symmetry test of :class:`ContactProblem` (round-off only).
W_SYMMETRY_RTOL = 1e-8


def stiffness_form(delassus, max_asymmetry=W_SYMMETRY_RTOL):
    """The qsma problem of a Delassus problem: ``K = W^-1``, ``lam_w = -K q``.

    Components are reordered from Siconos' ``(n, t...)`` to qsma's
    ``(t..., n)`` per contact; ``W`` is symmetrised (its asymmetry must be
    round-off, see :class:`ContactProblem`). The Siconos "Rover" problems carry
    an asymmetry of 1e-5 to 3e-5 of ``max|W|``; with ``max_asymmetry=1e-4``
    they are read as the nearby symmetric problem ``(W + W^T)/2``, which is
    then a different problem from Siconos' own (say so wherever it is used).

    Returns
    -------
    problem : ContactProblem
    lam_w : (n_contacts, dim)

    Raises
    ------
    InputError
        ``W`` not symmetric or not positive definite.
    """
    W, q, mu, dim = delassus
    nc = len(mu)
    order = (np.arange(nc)[:, None] * dim + np.r_[1:dim, 0]).ravel()
    W = W[np.ix_(order, order)]
    scale = np.max(np.abs(W))
    asymmetry = np.max(np.abs(W - W.T)) / scale
    if asymmetry > max_asymmetry:
        raise InputError(f"W is not symmetric: max|W - W^T| = {asymmetry:.1e} max|W| > "
                         f"{max_asymmetry:g} max|W|; no stiffness form")
    W = 0.5 * (W + W.T)
    try:
        np.linalg.cholesky(W)
    except np.linalg.LinAlgError:
        raise InputError("W is not positive definite: no stiffness form") from None
    K = np.linalg.inv(W)
    K = 0.5 * (K + K.T)
    lam_w = -(K @ q[order]).reshape(nc, dim)
    return ContactProblem(K, mu, dim=dim), lam_w

