"""What CalculiX 2.20 prints of a deck of :func:`qsma.deck.export_calculix` (its ``.dat``
file), read back as arrays: displacements per increment, contact stresses, eigenvalues;
and :func:`run_calculix`, which solves a deck with ``ccx``.

CalculiX prints 7 significant digits: values read here carry a relative round-off of
about 5e-7.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import shutil
import subprocess

import numpy as np

from ..errors import QSMAError

#: A printed block's title: ``displacements (vx,vy,vz) for set NALL and time  0.25E+00``.
_TITLE = re.compile(r"^\s*(\S.*?) for (?:set \S+|all contact elements) and time\s+(\S+)",
                    re.M)


class CalculixError(QSMAError):
    """``ccx`` is missing, stopped with an error, or printed less than the deck asks."""


def run_calculix(deck: Path, *, threads: int = 1, timeout: float | None = None) -> str:
    """Solve ``deck`` (an ``.inp`` file) with ``ccx`` in its folder; returns the text of
    its ``.dat`` file. Raises :class:`CalculixError` with the end of ccx's output when
    it stops with an error."""
    deck = Path(deck)
    if shutil.which("ccx") is None:
        raise CalculixError("ccx (CalculiX) is not on the PATH: install CalculiX 2.20 "
                            "(e.g. apt-get install calculix-ccx)")
    out = subprocess.run(["ccx", "-i", deck.stem], cwd=deck.parent, capture_output=True,
                         text=True, timeout=timeout,
                         env={**os.environ, "OMP_NUM_THREADS": str(threads)})
    dat = deck.with_suffix(".dat")
    errors = [ln.strip() for ln in out.stdout.splitlines() if "*ERROR" in ln]
    if out.returncode != 0 or errors or not dat.exists():
        raise CalculixError(f"ccx stopped on {deck.name} (exit {out.returncode}): "
                            f"{'; '.join(errors[:3]) or out.stdout[-1500:]}")
    return dat.read_text()


def _blocks(text: str, title: str):
    """``(time, rows)`` of every block whose title starts with ``title``; rows are the
    number lines below it (until the next title)."""
    heads = list(_TITLE.finditer(text))
    for k, m in enumerate(heads):
        if not m.group(1).lower().startswith(title):
            continue
        end = heads[k + 1].start() if k + 1 < len(heads) else len(text)
        rows = []
        for line in text[m.end():end].splitlines()[1:]:
            parts = line.split()
            if not parts:
                if rows:
                    break
                continue
            try:
                rows.append([float(v) for v in parts])
            except ValueError:
                break
        yield float(m.group(2)), rows


def displacements(text: str, n_nodes: int) -> list:
    """Every printed displacement block: ``[(time, u)]``, ``u`` of shape ``(n_nodes,
    3)`` with ``u[i]`` the displacement of node ``i + 1`` (0 for nodes not printed)."""
    out = []
    for time, rows in _blocks(text, "displacements"):
        u = np.zeros((n_nodes, 3))
        r = np.array(rows)
        keep = r[:, 0] <= n_nodes          # CalculiX's own nodes of expanded 2D elements
        u[r[keep, 0].astype(int) - 1] = r[keep, 1:4]
        out.append((time, u))
    return out


def contact_stresses(text: str) -> list:
    """Every printed contact stress block: ``[(time, rows)]``, rows ``(node, pressure,
    shear 1, shear 2)`` of the slave nodes of the contact elements (CalculiX's node
    numbers: for 2D elements those of its expanded 3D mesh)."""
    return [(t, np.array(rows).reshape(-1, 4)) for t, rows in _blocks(text, "contact stress")]


def eigenfrequencies(text: str) -> np.ndarray:
    """The frequencies (cycles per time unit) of the last eigenvalue table. CalculiX
    prints ``mode, eigenvalue, rad/time, cycles/time, imaginary`` for a symmetric
    stiffness and ``mode, rad/time, cycles/time, imaginary`` for a nonsymmetric one
    (friction in a perturbation step)."""
    parts = text.split("E I G E N V A L U E   O U T P U T")
    if len(parts) < 2:
        raise CalculixError("no eigenvalue table in CalculiX's output (no *FREQUENCY "
                            "step ran)")
    f = []
    for line in parts[-1].splitlines():
        cols = line.split()
        if not cols:
            if f:
                break
            continue
        if not cols[0].isdigit():
            if f:
                break
            continue
        f.append(float(cols[3] if len(cols) == 5 else cols[2]))
    return np.array(f)


def cycle_dissipations(deck, text: str) -> list:
    """The loops of the cyclic steps of ``deck`` (a :class:`qsma.deck.CalculixDeck`
    with ``amplitudes``) from CalculiX's output ``text``: per amplitude, per cycle
    (``deck.cycles`` of them), ``(alpha, q, D)``: the modal force and amplitude ``q =
    phi^T M (u - u_pre)`` at every printed increment from +A through -A back to +A,
    and ``D``, the closed integral of alpha dq (trapezoidal), the work done on the
    structure over the cycle: its dissipation.

    Step 1 (the preload) ends at total time 1; cyclic step ``j`` (0-based) runs from
    ``1 + j`` to ``2 + j``, its modal force linear in time between the step's ends."""
    blocks = displacements(text, deck.first_node[-1] - 1)     # the bodies' nodes
    ends = [x for A in deck.amplitudes for x in (A,) + (-A, A) * deck.cycles]
    if not ends:
        raise CalculixError("the deck has no cyclic steps (no amplitudes)")
    times = np.array([t for t, _ in blocks])
    pre = np.flatnonzero(times <= 1.0 + 1e-9)
    if pre.size == 0 or times[-1] < len(ends) + 1.0 - 1e-9:
        raise CalculixError(f"CalculiX printed displacements up to time "
                            f"{times[-1] if times.size else 0:g} of {len(ends) + 1}: "
                            f"a step stopped early (see its .sta file)")
    mphi = deck.mode["mphi"]
    u_pre = deck.per_body(blocks[pre[-1]][1])
    later = blocks[pre[-1] + 1:]
    t = times[pre[-1] + 1:]
    j = np.minimum(np.ceil(t - 1.0 - 1e-9).astype(int) - 1, len(ends) - 1)
    starts = np.array([0.0] + ends[:-1])
    alpha = starts[j] + (np.array(ends) - starts)[j] * (t - 1.0 - j)
    dim = mphi[0].shape[1]
    q = np.array([sum(np.sum(m * (u[:, :dim] - u0[:, :dim]))
                      for m, u, u0 in zip(mphi, deck.per_body(ub), u_pre))
                  for _, ub in later])
    out, per = [], 1 + 2 * deck.cycles
    for i in range(len(deck.amplitudes)):
        cycles = []
        for c in range(deck.cycles):
            top = int(np.flatnonzero(j == per * i + 2 * c)[-1])     # at +A, cycle starts
            end = int(np.flatnonzero(j == per * i + 2 * c + 2)[-1]) + 1
            a, qq = alpha[top:end], q[top:end]
            cycles.append((a, qq, float(np.trapezoid(a, qq))))
        out.append(cycles)
    return out
