"""Several modes of one model: one backbone per mode from one preparation, and the
tied mode shapes as VTU.

:func:`run_modes` prepares the model once (pairing, assembly, condensation:
:func:`qsma.analysis.prepare`), solves the preload once (cached by the preparation)
and runs the ramps of each mode (:func:`qsma.analysis.run_prepared`); each mode's
result equals a separate ``qsma run --mode k``. The folder it writes::

    OUT/mode-0/, OUT/mode-1/, ...   result folders as qsma run writes them
    OUT/modes.json                  per mode: f0, success, message, folder
    OUT/modes.vtu                   tied mode shapes after the preload (mode_00, ...)

OUT is one result folder (:class:`qsma.output.folders.RunFolder`, kind ``run-modes``): locked
and checked before anything is computed, written in a staging folder and swapped into
place as a whole, so a mode folder of an earlier run with other modes does not stay
behind; each ``mode-K`` has a manifest of its own.
"""
from __future__ import annotations

from dataclasses import dataclass
import json
from pathlib import Path

import numpy as np

from ..errors import InputError, QSMAError
from ..analysis.options import RunOptions

#: Name of the folder of mode ``k`` inside the output folder.
MODE_FOLDER = "mode-{k}"
MODES_JSON, MODES_VTU = "modes.json", "modes.vtu"


@dataclass(frozen=True, eq=False)
class ModesResult:
    """Outcome of :func:`run_modes`: ``results`` maps each mode that ran to its
    :class:`qsma.analysis.result.QSMAResult`; ``summary`` has one entry per mode asked for
    (``mode``, ``f0_hz``, ``success``, ``message``, ``folder``), as in modes.json."""

    success: bool
    results: dict
    summary: tuple
    paths: dict


def parse_modes(text) -> tuple:
    """``"0,1,2"`` -> (0, 1, 2): distinct mode indices >= 0."""
    try:
        modes = tuple(int(t) for t in str(text).split(",") if t.strip())
    except ValueError:
        raise InputError(f"--modes {text!r}: expected mode indices separated by commas, "
                         f"e.g. 0,1,2") from None
    if not modes or min(modes) < 0 or len(set(modes)) != len(modes):
        raise InputError(f"--modes {text!r}: give distinct mode indices >= 0, e.g. 0,1,2")
    return modes


def write_modes_vtu(model, modes, path):
    r"""Write mode shapes as point data ``mode_00``, ``mode_01``, ... of one VTU file
    holding both bodies (points as in fields.vtu).

    Parameters
    ----------
    model : :class:`qsma.model.Model`
    modes : :class:`qsma.modal.Modes` (mass-normalised shapes over the stacked DOFs)
    path : output file (the frequencies are in modes.json)
    """
    from ..output.files import vtu_grid, write_vtu_file
    dim = model.dim
    point_data = {"body": np.concatenate([np.full(b.mesh.n_nodes, k, np.int32)
                                          for k, b in enumerate(model.bodies)])}
    for k in range(modes.shapes.shape[1]):
        u = modes.shapes[:, k].reshape(-1, dim)
        point_data[f"mode_{k:02d}"] = np.column_stack([u, np.zeros(len(u))]) \
            if dim == 2 else u
    write_vtu_file(path, vtu_grid(model), point_data, model.units, dim)
    return Path(path)


def run_modes(model, modes, options: RunOptions | None = None, *, out=None, plots=True,
              vtu=True, progress=None) -> dict:
    """QSMA of several modes of ``model`` sharing one preparation.

    Parameters
    ----------
    model : :class:`qsma.model.Model`
    modes : sequence of int
        Mode indices (0 = lowest elastic mode of the tied structure).
    options : RunOptions, optional
        Options of every mode (its ``mode`` is replaced; ``n_modes`` defaults to
        ``max(6, max(modes) + 1)`` for all, as separate runs of each mode would take
        for the highest).
    out : path, optional
        Folder of the results (module docstring); nothing is written without it.
    plots, vtu : figures and fields.vtu in each mode's folder
    progress : callable, optional
        ``progress(k, n)`` after each mode.

    Returns
    -------
    ModesResult
        A mode that cannot be run (e.g. it does not move the tip) is recorded in the
        summary with its message; the others go on.
    """
    from ..output.folders import RunFolder
    modes = parse_modes(",".join(str(m) for m in modes))
    options = options or RunOptions()
    if options.n_modes is None:
        options = options.replace(n_modes=max(6, max(modes) + 1))
    if out is None:
        return _run_modes(model, modes, options, None, plots, vtu, progress)
    with RunFolder(out, kind="run-modes") as folder:     # taken before computing
        return _run_modes(model, modes, options, folder, plots, vtu, progress)


def _run_modes(model, modes, options, folder, plots, vtu, progress) -> ModesResult:
    """:func:`run_modes` into ``folder`` (an entered :class:`qsma.output.folders.RunFolder`, or
    None): every mode's folder and the tables are written into its staging folder and
    swapped into place together, so no mode folder of an earlier run stays behind."""
    from ..analysis import prepare, run_prepared
    from ..output.files import atomic_write, write_all
    prepared = prepare(model, options)
    results, summary, paths = {}, [], {}
    for i, m in enumerate(modes):
        try:
            res = run_prepared(prepared, options.replace(mode=m))
        except QSMAError as exc:     # e.g. a mode that does not move the tip: recorded
            summary.append(dict(mode=m, f0_hz=None, success=False, folder=None,
                                message=f"{type(exc).__name__}: {exc}"))
            continue
        results[m] = res
        entry = dict(mode=m, f0_hz=res.f0_hz, success=bool(res.success),
                     message=res.message, folder=MODE_FOLDER.format(k=m))
        summary.append(entry)
        if folder is not None:
            sub = folder.subfolder(entry["folder"])
            write_all(res, sub.path, plots=plots, vtu=vtu, folder=sub)
            paths[entry["folder"]] = sub.path
        if progress is not None:
            progress(i + 1, len(modes))
    if folder is not None and results:
        first = next(iter(results.values()))
        atomic_write(folder.staging / MODES_JSON, json.dumps(dict(
            model=first.model_info["name"], modes=summary,
            f_hz_tied=first.modes.f_hz.tolist()), indent=1) + "\n")
        write_modes_vtu(model, first.modes, folder.staging / MODES_VTU)
        paths["json"], paths["vtu"] = folder.path / MODES_JSON, folder.path / MODES_VTU
        folder.commit()             # none ran: nothing to write, the folder is kept
    return ModesResult(all(e["success"] for e in summary), results, tuple(summary), paths)


__all__ = ["run_modes", "ModesResult", "write_modes_vtu", "parse_modes", "MODE_FOLDER"]
