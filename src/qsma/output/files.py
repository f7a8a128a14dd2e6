"""Result files: results.json, results.csv and VTU fields, written as one run
into a result folder (:mod:`qsma.output.folders`)."""
from __future__ import annotations

import csv
from dataclasses import dataclass
import io
import json
import os
from pathlib import Path
import shutil
import tempfile

import numpy as np

from ..errors import AnalysisError
from ..fe import stress_at_nodes
from ..contact import STUCK
from ..model.pairing import MultiPairing, body_order, contact_sides
from ..analysis.result import (LEVEL_COLUMNS, LEVEL_FIELDS, load_factors, level_units,
                               units_block)
from ..units import column_label
from .folders import (TMP_PREFIX, RunFolder, atomic_path, atomic_write,  # noqa: F401
                     prepare_output_dir, write_error)

SCHEMA_VERSION = 1

def json_safe(x, where="results"):
    """JSON-safe value: numpy to Python; NaN/Inf are refused, never written."""
    if isinstance(x, dict):
        return {k: json_safe(v, f"{where}.{k}") for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [json_safe(v, where) for v in x]
    if isinstance(x, np.ndarray):
        return json_safe(x.tolist(), where)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        if not np.isfinite(x):
            raise AnalysisError(f"non-finite value in {where}: the analysis produced NaN or "
                                f"Inf; nothing was written for it")
        return float(x)
    return x


#: Per-level quantities that are NaN where they were not computed (a loop at a level
#: that used Masing, the -alpha ramp beyond a failure): written as null / empty
#: (``optional`` of :func:`qsma.analysis.result.column`).
OPTIONAL_FIELDS = tuple(k for k, c in LEVEL_COLUMNS.items() if c["optional"])


#: Flags of a level whose frequency and damping could not be computed (its loop did
#: not stabilise or failed, or a value came out non-finite): that level's NaN values of
#: :data:`LOOP_DERIVED` are written as null / empty beside the flag that says why, the
#: other levels kept.
NAN_FLAGS = ("not_finite", "loop_failed", "loop_not_stabilised")
#: The per-level columns that come from the frequency, the damping or the loop, and so
#: may be NaN at a level flagged with one of :data:`NAN_FLAGS` (``nan_when_flagged`` of
#: :func:`qsma.analysis.result.column`); the backbone (alpha, q, tip, residual) and the Masing
#: values never may.
LOOP_DERIVED = tuple(k for k, c in LEVEL_COLUMNS.items() if c["nan_when_flagged"])


def _level_columns(res) -> dict:
    """Per-level values by name, JSON-ready: optional NaN -> None, NaN of
    :data:`LOOP_DERIVED` at a level flagged with one of :data:`NAN_FLAGS` -> None,
    flags as lists. Any other NaN or Inf is kept (and refused by :func:`json_safe`)."""
    table = {}
    levels = res.levels_table()
    explained = [any(f in NAN_FLAGS for f in flags) for flags in levels["flags"]]
    for name, values in levels.items():
        if name == "flags":
            table[name] = [list(f) for f in values]
        elif name in OPTIONAL_FIELDS:
            table[name] = [None if not np.isfinite(v) else float(v) for v in values]
        elif name in LOOP_DERIVED:
            table[name] = [None if ok and np.isnan(v) else float(v)
                           for v, ok in zip(np.asarray(values, float), explained)]
        else:
            table[name] = np.asarray(values).tolist()
    return table


def results_dict(res) -> dict:
    """The content of results.json as plain, JSON-safe Python values.

    Parameters
    ----------
    res : :class:`qsma.analysis.result.QSMAResult`

    Returns
    -------
    dict
        ``schema_version``, ``success``, ``message``, ``failed_levels``, the
        ``units`` of every quantity (:func:`qsma.analysis.result.units_block`), the model
        summary, the analysed mode (``f0_hz = omega0 / 2 pi``), the preload solve, the
        per-level columns :data:`qsma.analysis.result.LEVEL_FIELDS` (NaN of optional fields as
        ``None``), timings, the solves, cycles and seconds per level
        (:class:`qsma.analysis.result.LevelCosts`), solver statistics and the options of the run. Every field,
        its unit and its meaning: docs/results.md.

    Raises
    ------
    AnalysisError
        a required value is NaN or infinite (nothing is written for it).
    """
    out = {
        "schema_version": SCHEMA_VERSION,
        "qsma_version": res.version,
        "success": bool(res.success),
        "message": res.message,
        "failed_levels": res.failed_levels,
        "units": units_block(res.units, res.model.dim),
        "model": {k: res.model_info[k] for k in ("name", "n_nodes", "n_dofs", "n_pairs",
                                                  "mu", "dim", "n_closed_after_preload",
                                                  "elements", "coupling")},
        "mode": {"index": res.mode_index, "f0_hz": res.f0_hz, "omega0": res.omega0,
                 "phi_tip": res.phi_tip,
                 "f_hz_tied": res.modes.f_hz.tolist(),
                 "rigid_modes": res.model_info.get("rigid_modes", 0),
                 "index_counts": "elastic modes (rigid-body modes skipped)",
                 "held_by_joint": res.model_info.get("held_by_joint", []),
                 "joint_spring_share_max": res.model_info.get("joint_spring_share_max", 0.0)},
        "preload": {"residual": res.preload.residual, "iterations": res.preload.nit,
                    "n_stuck": res.preload.n_stuck, "n_slip": res.preload.n_slipping,
                    "n_open": res.preload.n_open},
        "levels": _level_columns(res),
        "gross_slip_level": res.gross_slip_level,
        "timings_s": res.timings_s,
        "level_costs": None if res.level_costs is None else res.level_costs.as_dict(),
        "resources": res.resources or {},
        "warnings": list(res.warnings),
        "solver": res.solver,
        "options": res.options.as_dict(),
    }
    if res.direct_loop is not None:
        dl = res.direct_loop
        out["direct_loop"] = {"alpha": dl.alpha, "q": dl.q, "tip": dl.tip,
                              "dissipation": dl.dissipation,
                              "dissipation_masing": dl.dissipation_masing,
                              "success": dl.success, "message": dl.message}
    return json_safe(out)


def write_json(res, path):
    """Write :func:`results_dict` to ``path`` as indented JSON, atomically (a crash
    leaves the previous file or none, never half of one)."""
    atomic_write(path, json.dumps(results_dict(res), indent=1) + "\n")


def csv_columns() -> tuple[str, ...]:
    """Columns of results.csv: the level index, then :data:`qsma.analysis.result.LEVEL_FIELDS`."""
    return ("level",) + LEVEL_FIELDS


def csv_header(units="SI", dim=3) -> list[str]:
    """The header row of results.csv: each of :func:`csv_columns` with its unit in
    brackets (``tip [m]``, ``zeta [-]``), counts, names and flags bare."""
    unit = level_units(units, dim)
    return [column_label(c, unit.get(c)) for c in csv_columns()]


def column_name(heading: str) -> str:
    """The field name of a results.csv heading (``"tip [m]"`` -> ``"tip"``)."""
    return heading.split(" [", 1)[0]


def csv_cell(v):
    """A JSON-safe value as a CSV cell: null empty, flags joined by ``;``, true/false 1/0."""
    if v is None:
        return ""
    if isinstance(v, list):
        return ";".join(v)
    if isinstance(v, bool):
        return int(v)
    if isinstance(v, float):
        return f"{v:.10g}"
    return v


def write_csv(res, path):
    """Write the per-level table to ``path`` as CSV, atomically.

    One row per level, columns :func:`csv_columns` headed with their units
    (:func:`csv_header`); floats with 10 significant digits, optional values that were
    not computed as empty cells, flags joined by ``;``.
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    columns = csv_columns()
    w.writerow(csv_header(res.units, res.model.dim))
    table = json_safe(_level_columns(res), "levels")          # refuses NaN / Inf
    for k in range(res.n_levels):
        w.writerow([k] + [csv_cell(table[c][k]) for c in columns[1:]])
    atomic_write(path, buf.getvalue())


def write_vtu(res, path, levels=None):
    """Write one VTU file holding every body of the model, atomically.

    Point data: ``body`` (index, an integer), at the preload ``u_preload`` and
    ``von_mises_preload``, and for each level ``k`` of ``levels`` the total displacement
    ``u_levelKK``, the modal part ``u_modal_levelKK = u_levelKK - u_preload``, the von
    Mises stress and the interface pressure, shear and contact state (an integer,
    ``-1`` off the interface). Coordinates are the model's, in its units; the units of
    every array are the file's field data ``units`` (:func:`write_vtu_file`).

    Parameters
    ----------
    res : :class:`qsma.analysis.result.QSMAResult`
    path : file to write (``.vtu``)
    levels : level indices to write; default :func:`vtu_levels`.
    """
    fields = _Fields(res, levels)
    return write_vtu_file(path, fields.grid, fields.combined(), res.units, res.model.dim)


def vtu_levels(res) -> list:
    """The levels written to the VTU files by default: the first, middle and last."""
    return sorted({0, res.n_levels // 2, res.n_levels - 1}) if res.n_levels else []


#: Name of the ParaView time series of the levels (:func:`write_series`).
SERIES_NAME = "fields.pvd"


def series_file(k) -> str:
    """The VTU file of level ``k`` in the time series."""
    return f"fields_level{k:02d}.vtu"


def write_series(res, folder, levels=None, fields=None) -> dict:
    """Write the levels as a time series ParaView steps through: one VTU file per level
    (:func:`series_file`, the arrays of :func:`write_vtu` without the level suffix:
    ``u``, ``u_modal``, ``von_mises``, ``contact_pressure``, ``contact_shear``,
    ``contact_state``, with ``body``, ``u_preload`` and ``von_mises_preload``) and the
    collection :data:`SERIES_NAME` (ParaView's PVD format) listing them, the time of
    each being its level index.

    Returns
    -------
    dict
        name -> path written (``"series"`` the collection, ``"level_KK"`` the files).
    """
    folder = Path(folder)
    fields = _Fields(res, levels) if fields is None else fields
    paths = {}
    for k, arrays in fields.levels.items():
        paths[f"level_{k:02d}"] = write_vtu_file(
            folder / series_file(k), fields.grid, {**fields.common, **arrays}, res.units,
            res.model.dim)
    steps = "\n".join(f'<DataSet timestep="{k}" part="0" file="{series_file(k)}"/>'
                      for k in fields.levels)
    atomic_write(folder / SERIES_NAME,
                 '<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1">\n'
                 f'<Collection>\n{steps}\n</Collection>\n</VTKFile>\n')
    paths["series"] = folder / SERIES_NAME
    return paths


def write_fields(res, folder, levels=None) -> dict:
    """fields.vtu (:func:`write_vtu`) and the time series (:func:`write_series`) into
    ``folder``, each level's fields computed once; name -> path."""
    fields = _Fields(res, levels)
    path = write_vtu_file(Path(folder) / "fields.vtu", fields.grid, fields.combined(),
                          res.units, res.model.dim)
    return {"vtu": path, **write_series(res, folder, fields=fields)}


class _Fields:
    """The point arrays of a run's VTU files: ``common`` (``body`` and the preload's
    fields) and per level of ``levels`` its own (:func:`_level_point_data`)."""

    def __init__(self, res, levels=None):
        self.grid = vtu_grid(res.model)
        self.common = _preload_point_data(res)
        self.levels = {k: _level_point_data(res, k, self.grid, self.common["u_preload"])
                       for k in (vtu_levels(res) if levels is None else levels)}

    def combined(self) -> dict:
        """Every array in one file, the level's suffixed ``_levelKK``."""
        out = dict(self.common)
        for k, arrays in self.levels.items():
            out.update({f"{name}_level{k:02d}": v for name, v in arrays.items()})
        return out


@dataclass(frozen=True)
class VtuGrid:
    """Every body of a model as one unstructured grid: ``points`` ``(n, 3)`` (z = 0 in
    2D), cell ``blocks`` (``(meshio cell type, cells)`` per body and cell type) and the
    index of each body's first point ``offsets``."""

    points: np.ndarray
    blocks: list
    offsets: list


def vtu_grid(model) -> VtuGrid:
    """The :class:`VtuGrid` of ``model``'s bodies, in their order."""
    points, blocks, offsets = [], [], [0]
    for b in model.bodies:
        p = b.mesh.points
        points.append(np.column_stack([p, np.zeros(len(p))]) if model.dim == 2 else p)
        blocks += [(c.cell_type, c.cells + offsets[-1]) for c in b.mesh.cell_blocks]
        offsets.append(offsets[-1] + len(p))
    return VtuGrid(np.vstack(points).astype(float), blocks, offsets)


#: The quantity (:data:`qsma.units.QUANTITIES`) of each point array of the VTU files,
#: by name without the level suffix; the others (``body``, ``contact_state``) are
#: integers without a unit.
VTU_QUANTITIES = {"u": "length", "u_modal": "length", "u_preload": "length",
                  "von_mises": "stress", "von_mises_preload": "stress",
                  "contact_pressure": "stress", "contact_shear": "stress",
                  "mode": "mode_shape"}


def vtu_units(names, units="SI", dim=3) -> dict:
    """The ``units`` field data of a VTU file: the system, the unit of the points and
    of each array of ``names`` that has one."""
    from ..units import quantity_unit, unit_system
    import re
    out = {"system": unit_system(units).name, "Points": quantity_unit("length", units)}
    for name in names:
        base = re.sub(r"_(level)?\d+$", "", name)
        if base in VTU_QUANTITIES:
            out[name] = quantity_unit(VTU_QUANTITIES[base], units, dim)
    return out


def write_vtu_file(path, grid: VtuGrid, point_data, units="SI", dim=3):
    """Write ``grid`` with ``point_data`` (name -> ``(n,)`` or ``(n, k)`` array; float
    or integer) to the VTU file ``path``, atomically, through meshio (binary,
    zlib-compressed). The units of the arrays travel as the grid's field data
    ``units``: the UTF-8 bytes of a JSON object ``{"system": ..., "Points": ...,
    array name: unit}`` (:func:`vtu_units`), readable by ParaView, VTK and
    ``meshio.read`` alike (``json.loads(bytes(mesh.field_data["units"]))``). meshio
    reads VTU field data but does not write it, so the block is inserted into its
    output here."""
    import meshio
    mesh = meshio.Mesh(grid.points, [(t, np.asarray(c)) for t, c in grid.blocks],
                       point_data={k: np.ascontiguousarray(v) for k, v in point_data.items()})
    text = json.dumps(vtu_units(point_data, units, dim), separators=(",", ":"))
    with tempfile.TemporaryDirectory(prefix=TMP_PREFIX, dir=Path(path).parent) as tmp:
        plain = Path(tmp) / "plain.vtu"
        meshio.write(plain, mesh, file_format="vtu", binary=True, compression="zlib",
                     header_type="UInt64")
        with atomic_path(path) as out, open(plain, "rb") as src, open(out, "wb") as dst:
            _copy_with_field_data(src, dst, "units", text.encode())
            dst.flush()
            os.fsync(dst.fileno())
    return Path(path)


#: Bytes of meshio's VTU output read to find the start of the grid (its XML header
#: and a comment come first).
_HEAD_BYTES = 4096


def _copy_with_field_data(src, dst, name: str, data: bytes):
    """Copy the VTU file ``src`` to ``dst`` with a ``<FieldData>`` block holding
    ``data`` as a ``UInt8`` array ``name`` (ASCII format) at the start of its grid."""
    head = src.read(_HEAD_BYTES)
    tag = b"<UnstructuredGrid>"
    at = head.index(tag) + len(tag)
    values = " ".join(str(b) for b in data).encode()
    dst.write(head[:at] + b'<FieldData><DataArray type="UInt8" Name="' + name.encode()
              + b'" NumberOfTuples="' + str(len(data)).encode() + b'" format="ascii">'
              + values + b"</DataArray></FieldData>" + head[at:])
    shutil.copyfileobj(src, dst, 1 << 20)


def _preload_point_data(res) -> dict:
    """The arrays every VTU file of a run holds: ``body`` and the preload's fields."""
    u, vm = _stack_fields(res, None)
    body = np.concatenate([np.full(b.mesh.n_nodes, k, np.int32)
                           for k, b in enumerate(res.model.bodies)])
    return {"body": body, "u_preload": u, "von_mises_preload": vm}


def _level_point_data(res, k, grid, u_preload) -> dict:
    """The arrays of level ``k``: displacement, its modal part (from ``u_preload``), von
    Mises stress and the interface's pressure, shear and state."""
    u, vm = _stack_fields(res, k)
    out = {"u": u, "u_modal": u - u_preload, "von_mises": vm}
    out.update(_interface_point_data(res, k, grid.offsets, len(grid.points)))
    return out


def _stack_fields(res, k):
    dim = res.model.dim
    fields = res.fields(k)
    ordered = [None] * len(res.model.bodies)
    for i, u in zip(body_order(res.model, res.pairing), fields):
        ordered[i] = u
    us, vms = [], []
    for b, u in zip(res.model.bodies, ordered):
        U = u.reshape(-1, dim)
        us.append(np.column_stack([U, np.zeros(len(U))]) if dim == 2 else U)
        vms.append(stress_at_nodes(b, u)[1])
    return np.vstack(us), np.concatenate(vms)


def _interface_point_data(res, k, offsets, n):
    """Contact pressure and shear (force over tributary area, the model's stress
    unit), state (an integer)."""
    p = res.pairing
    lam = res.states.lam[k]
    area = p.area
    out = {"contact_pressure": np.zeros(n), "contact_shear": np.zeros(n),
           "contact_state": np.full(n, -1, np.int32)}
    # node-to-node: both sides; mortar: the slave nodes
    for i, nodes, rows in contact_sides(res.model, p):
        idx = offsets[i] + nodes
        out["contact_pressure"][idx] = lam[rows, -1] / area[rows]
        out["contact_shear"][idx] = np.linalg.norm(lam[rows, :-1], axis=1) / area[rows]
        out["contact_state"][idx] = res.states.status[k][rows]
    tied = getattr(p, "tied", ())
    if tied:                       # a tied point carries its force and is stuck
        lam_t = res.reduced.tied_forces(res.states.d[k], load_factors(res.reduced,
                                                                      res.alpha[k]))
        area_t = np.concatenate([c.pairing.area for c in tied])
        for i, nodes, rows in contact_sides(res.model, MultiPairing(tied, ())):
            idx = offsets[i] + nodes
            out["contact_pressure"][idx] = lam_t[rows, -1] / area_t[rows]
            out["contact_shear"][idx] = np.linalg.norm(lam_t[rows, :-1], axis=1) / area_t[rows]
            out["contact_state"][idx] = int(STUCK)
    return out


def write_all(res, out, plots=True, vtu=True, folder=None, report=None,
              plot_worker=None, amplitude=None):
    """Write every result file of a run as one run into folder ``out``.

    The files are written into a private staging folder, listed with their SHA-256 in
    ``manifest.json`` and swapped into place together (:class:`qsma.output.folders.RunFolder`):
    ``out`` holds either its previous contents or every file of this run.

    Parameters
    ----------
    res : :class:`qsma.analysis.result.QSMAResult`
    out : result folder (replaced as a whole)
    plots, vtu : also write the PNG figures / the VTU fields
    folder : a :class:`~qsma.output.folders.RunFolder` already entered for ``out`` (the CLI
        takes it before computing); ``None`` takes and releases one here
    report : also write report.html (:mod:`qsma.output.report`); ``None``: when ``plots``
    plot_worker : a started :class:`qsma.output.plotworker.PlotWorker` that draws the
        figures while the other files are written (``None``: drawn here). Its PNG
        bytes are written here; if it fails, the figures are drawn here instead (the
        same files). The caller closes it.
    amplitude : the amplitude measure the figures are drawn against (a key of
        :data:`qsma.output.plots.AMPLITUDES`; default the peak tip deflection)

    Returns
    -------
    dict
        name -> final path of each file (``"manifest"`` included).

    Raises
    ------
    OutputFolderBusy
        another run holds ``out``.
    OutputWriteError
        a file could not be written (e.g. the device is full); ``out`` is unchanged.
    """
    if folder is None:
        with RunFolder(out) as folder:
            return write_all(res, out, plots, vtu, folder, report, plot_worker, amplitude)
    stage = folder.staging
    paths = {"json": stage / "results.json", "csv": stage / "results.csv"}
    draw = plots and res.n_levels > 0
    if draw and plot_worker is not None:
        plot_worker.submit(res, amplitude)      # drawn while the files below are written
    try:
        write_csv(res, paths["csv"])
        if vtu and res.n_levels:
            paths.update(write_fields(res, stage))
        write_json(res, paths["json"])
        figures = None
        if draw:
            figures = _write_figures(res, stage, plot_worker, amplitude)
            paths.update(figures)
        if plots if report is None else report:
            from .report import REPORT_NAME, write_report
            paths["report"] = write_report(res, stage / REPORT_NAME, figures, amplitude)
    except OSError as exc:
        raise write_error(exc, folder.path) from exc
    folder.commit()
    paths["manifest"] = stage / "manifest.json"
    return {k: folder.path / Path(p).name for k, p in paths.items()}


def _write_figures(res, stage, plot_worker=None, amplitude=None) -> dict:
    """The figures of ``res`` written into ``stage``: the PNG bytes of ``plot_worker``
    (:mod:`qsma.output.plotworker`) if it delivers every figure, else drawn here
    (:func:`qsma.output.plots.write_plots`, the same files); name -> path."""
    from .plots import figure_files, write_plots
    files = figure_files(res.model.dim)
    if plot_worker is not None:
        from .plotworker import PlotWorkerFailed, log
        try:
            pngs = plot_worker.collect()
            if set(pngs) != set(files):
                raise PlotWorkerFailed(f"the figure process drew {sorted(pngs)}, not "
                                       f"{sorted(files)}")
        except PlotWorkerFailed as exc:
            log.warning("figures drawn in the qsma process instead: %s", exc)
        else:
            paths = {name: stage / file for name, (file, _) in files.items()}
            for name, path in paths.items():
                atomic_write(path, pngs[name], "wb")
            return paths
    return write_plots(res, stage, amplitude)
