"""Result files: results.json, results.csv and VTU fields, written as one run
into a result folder (:mod:`qsma.rundir`)."""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

import numpy as np

from .errors import AnalysisError
from .fe import stress_at_nodes
from .multibody import body_order, contact_sides
from .result import LEVEL_FIELDS
from .rundir import (RunFolder, atomic_path, atomic_write,  # noqa: F401 (re-exported)
                     prepare_output_dir, write_error)

SCHEMA_VERSION = 1

def _clean(x, where="results"):
    """JSON-safe value: numpy to Python; NaN/Inf are refused, never written."""
    if isinstance(x, dict):
        return {k: _clean(v, f"{where}.{k}") for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_clean(v, where) for v in x]
    if isinstance(x, np.ndarray):
        return _clean(x.tolist(), where)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, (float, np.floating)):
        if not np.isfinite(x):
            raise AnalysisError(f"non-finite value in {where}: the analysis produced NaN or "
                                f"Inf; nothing was written for it")
        return float(x)
    return x


#: Per-level quantities that are NaN where they were not computed (a loop at a level
#: that used Masing, the -alpha ramp beyond a failure): written as null / empty.
OPTIONAL_FIELDS = ("q_neg", "asymmetry", "f_hz_loop", "zeta_loop", "dissipation_loop",
                   "dissipation_first_cycle", "dissipation_error")


#: Flags of a level whose frequency and damping could not be computed (its loop did
#: not stabilise or failed, or a value came out non-finite): that level's NaN values of
#: :data:`LOOP_DERIVED` are written as null / empty beside the flag that says why, the
#: other levels kept.
NAN_FLAGS = ("not_finite", "loop_failed", "loop_not_stabilised")
#: The per-level columns that come from the frequency, the damping or the loop, and so
#: may be NaN at a level flagged with one of :data:`NAN_FLAGS`; the backbone (alpha,
#: q, tip, residual) and the Masing values never may.
LOOP_DERIVED = ("f_hz", "zeta", "zeta_structure", "zeta_total", "dissipation",
                "tip_velocity")


def _level_columns(res) -> dict:
    """Per-level values by name, JSON-ready: optional NaN -> None, NaN of
    :data:`LOOP_DERIVED` at a level flagged with one of :data:`NAN_FLAGS` -> None,
    flags as lists. Any other NaN or Inf is kept (and refused by :func:`_clean`)."""
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
    res : :class:`qsma.result.QSMAResult`

    Returns
    -------
    dict
        ``schema_version``, ``success``, ``message``, ``failed_levels``, the model
        summary, the analysed mode (``f0_hz = omega0 / 2 pi``), the preload solve, the
        per-level columns :data:`qsma.result.LEVEL_FIELDS` (NaN of optional fields as
        ``None``), timings, solver statistics and the options of the run. Every field,
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
    return _clean(out)


def write_json(res, path):
    """Write :func:`results_dict` to ``path`` as indented JSON, atomically (a crash
    leaves the previous file or none, never half of one)."""
    atomic_write(path, json.dumps(results_dict(res), indent=1) + "\n")


def csv_columns() -> tuple[str, ...]:
    """Columns of results.csv: the level index, then :data:`qsma.result.LEVEL_FIELDS`."""
    return ("level",) + LEVEL_FIELDS


def _csv_cell(v):
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

    One row per level, columns :func:`csv_columns`; floats with 10 significant digits,
    optional values that were not computed as empty cells, flags joined by ``;``.
    """
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    columns = csv_columns()
    w.writerow(columns)
    table = _clean(_level_columns(res), "levels")          # refuses NaN / Inf
    for k in range(res.n_levels):
        w.writerow([k] + [_csv_cell(table[c][k]) for c in columns[1:]])
    atomic_write(path, buf.getvalue())


def write_vtu(res, path, levels=None):
    """Write one VTU file holding every body of the model, atomically.

    Point data: ``body`` (index), at the preload ``u_preload`` and
    ``von_mises_preload``, and for each level ``k`` of ``levels`` the total displacement
    ``u_levelKK``, the modal part ``u_modal_levelKK = u_levelKK - u_preload``, the von
    Mises stress and the interface pressure, shear and contact state (``-1`` off the
    interface). Coordinates are the model's, in its units.

    Parameters
    ----------
    res : :class:`qsma.result.QSMAResult`
    path : file to write (``.vtu``)
    levels : level indices to write; default the first, middle and last level.
    """
    model = res.model
    if levels is None:
        levels = sorted({0, res.n_levels // 2, res.n_levels - 1}) if res.n_levels else []
    dim = model.dim
    points, cells, offsets = [], [], [0]
    for b in model.bodies:
        p = b.mesh.points
        points.append(np.column_stack([p, np.zeros(len(p))]) if dim == 2 else p)
        cells.append([(c.cell_type, c.cells + offsets[-1]) for c in b.mesh.cell_blocks])
        offsets.append(offsets[-1] + len(p))
    pts = np.vstack(points)
    point_data = {"body": np.concatenate([np.full(b.mesh.n_nodes, k, float)
                                          for k, b in enumerate(model.bodies)])}
    pre = _stack_fields(res, None)
    point_data["u_preload"], point_data["von_mises_preload"] = pre
    for k in levels:
        u, vm = _stack_fields(res, k)
        point_data[f"u_level{k:02d}"] = u
        point_data[f"u_modal_level{k:02d}"] = u - pre[0]
        point_data[f"von_mises_level{k:02d}"] = vm
        for name, v in _interface_point_data(res, k, offsets, len(pts)).items():
            point_data[f"{name}_level{k:02d}"] = v
    blocks = [block for body in cells for block in body]  # per body, per cell type
    with atomic_path(path) as tmp:
        Path(tmp).write_text(vtu_text(pts, blocks, point_data), encoding="ascii")


#: VTK cell type numbers of the meshio cell types (the node order of both is VTK's).
VTK_CELL_TYPES = {"triangle": 5, "quad": 9, "tetra": 10, "hexahedron": 12, "triangle6": 22,
                  "quad8": 23, "tetra10": 24, "hexahedron20": 25, "quad9": 28,
                  "hexahedron27": 29}


def _vtu_array(values, name=None, components=None) -> str:
    """One ``<DataArray>`` of a VTU file: little-endian values, zlib-compressed as one
    block, base64-encoded after the VTK header ``[blocks = 1, block size, last block
    size, compressed size]`` (``UInt64``)."""
    import base64
    import zlib
    kind = {"f": "Float", "i": "Int", "u": "UInt"}[values.dtype.kind]
    raw = np.ascontiguousarray(values, dtype=values.dtype.newbyteorder("<")).tobytes()
    packed = zlib.compress(raw, 1)
    header = np.array([1, len(raw), len(raw), len(packed)], dtype="<u8").tobytes()
    attrs = f' type="{kind}{8 * values.dtype.itemsize}"'
    attrs += f' Name="{name}"' if name else ""
    attrs += f' NumberOfComponents="{components}"' if components else ""
    data = base64.b64encode(header).decode() + base64.b64encode(packed).decode()
    return f'<DataArray{attrs} format="binary">{data}</DataArray>'


def vtu_text(points, blocks, point_data) -> str:
    """A VTK XML unstructured grid (``.vtu``) of ``points`` ``(n, 3)``, cell ``blocks``
    (``(meshio cell type, cells)``, written in that order) and ``point_data`` (name ->
    ``(n,)`` or ``(n, k)`` array): binary, zlib-compressed, readable by ParaView and
    ``meshio.read``."""
    connectivity = np.concatenate([c.ravel() for _, c in blocks]).astype(np.int64)
    sizes = np.concatenate([np.full(len(c), c.shape[1]) for _, c in blocks])
    types = np.concatenate([np.full(len(c), VTK_CELL_TYPES[t]) for t, c in blocks])
    fields = "\n".join(_vtu_array(np.asarray(v, dtype=float), name,
                                   None if np.ndim(v) == 1 else np.shape(v)[1])
                       for name, v in point_data.items())
    return (
        '<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="1.0" '
        'byte_order="LittleEndian" header_type="UInt64" '
        'compressor="vtkZLibDataCompressor">\n<UnstructuredGrid>\n'
        f'<Piece NumberOfPoints="{len(points)}" NumberOfCells="{len(sizes)}">\n'
        f'<Points>\n{_vtu_array(np.asarray(points, dtype=float), components=3)}\n'
        '</Points>\n<Cells>\n'
        f'{_vtu_array(connectivity, "connectivity")}\n'
        f'{_vtu_array(np.cumsum(sizes).astype(np.int64), "offsets")}\n'
        f'{_vtu_array(types.astype(np.uint8), "types")}\n</Cells>\n'
        f'<PointData>\n{fields}\n</PointData>\n</Piece>\n</UnstructuredGrid>\n'
        '</VTKFile>\n')


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
    """Contact pressure [Pa] and shear [Pa] (force over tributary area), state."""
    p = res.pairing
    lam = res.states.lam[k]
    area = p.area
    out = {"contact_pressure": np.zeros(n), "contact_shear": np.zeros(n),
           "contact_state": np.full(n, -1.0)}
    # node-to-node: both sides; mortar: the slave nodes
    for i, nodes, rows in contact_sides(res.model, p):
        idx = offsets[i] + nodes
        out["contact_pressure"][idx] = lam[rows, -1] / area[rows]
        out["contact_shear"][idx] = np.linalg.norm(lam[rows, :-1], axis=1) / area[rows]
        out["contact_state"][idx] = res.states.status[k][rows]
    return out


def write_all(res, out, plots=True, vtu=True, folder=None, report=None,
              plot_worker=None):
    """Write every result file of a run as one run into folder ``out``.

    The files are written into a private staging folder, listed with their SHA-256 in
    ``manifest.json`` and swapped into place together (:class:`qsma.rundir.RunFolder`):
    ``out`` holds either its previous contents or every file of this run.

    Parameters
    ----------
    res : :class:`qsma.result.QSMAResult`
    out : result folder (replaced as a whole)
    plots, vtu : also write the PNG figures / the VTU fields
    folder : a :class:`~qsma.rundir.RunFolder` already entered for ``out`` (the CLI
        takes it before computing); ``None`` takes and releases one here
    report : also write report.html (:mod:`qsma.report`); ``None``: when ``plots``
    plot_worker : a started :class:`qsma._plotworker.PlotWorker` that draws the
        figures while the other files are written (``None``: drawn here). Its PNG
        bytes are written here; if it fails, the figures are drawn here instead (the
        same files). The caller closes it.

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
            return write_all(res, out, plots, vtu, folder, report, plot_worker)
    stage = folder.staging
    paths = {"json": stage / "results.json", "csv": stage / "results.csv"}
    draw = plots and res.n_levels > 0
    if draw and plot_worker is not None:
        plot_worker.submit(res)                 # drawn while the files below are written
    try:
        write_csv(res, paths["csv"])
        if vtu and res.n_levels:
            paths["vtu"] = stage / "fields.vtu"
            write_vtu(res, paths["vtu"])
        write_json(res, paths["json"])
        figures = None
        if draw:
            figures = _write_figures(res, stage, plot_worker)
            paths.update(figures)
        if plots if report is None else report:
            from .report import REPORT_NAME, write_report
            paths["report"] = write_report(res, stage / REPORT_NAME, figures)
    except OSError as exc:
        raise write_error(exc, folder.path) from exc
    folder.commit()
    paths["manifest"] = stage / "manifest.json"
    return {k: folder.path / Path(p).name for k, p in paths.items()}


def _write_figures(res, stage, plot_worker=None) -> dict:
    """The figures of ``res`` written into ``stage``: the PNG bytes of ``plot_worker``
    (:mod:`qsma._plotworker`) if it delivers every figure, else drawn here
    (:func:`qsma.plots.write_plots`, the same files); name -> path."""
    from .plots import figure_files, write_plots
    files = figure_files(res.model.dim)
    if plot_worker is not None:
        from ._plotworker import PlotWorkerFailed, log
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
    return write_plots(res, stage)
