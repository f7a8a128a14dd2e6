"""The study table: a row per case and load level, the case's parameters beside the
columns of a run's results.csv, read back from the case folders (so a resumed study
and a fresh one give the same table); written as CSV and, with pyarrow, Parquet."""
from __future__ import annotations

import csv
import io
import json
from pathlib import Path

from .cases import table_value

#: The table's files in the study folder (docs/studies.md).
TABLE_NAME, PARQUET_NAME = "study.csv", "study.parquet"


def table_columns(parameters) -> tuple:
    """Columns of the study table: case, parameters, status, message, then those of a
    run's results.csv (:func:`qsma.output.files.csv_columns`)."""
    from ..output.files import csv_columns
    return ("case",) + tuple(parameters) + ("status", "message") + csv_columns()


def study_table(cases, outcomes, out) -> dict:
    """Column name -> list, a row per case and level, read from the case folders
    (a case without levels has one row with empty level values)."""
    from ..output.files import csv_columns
    params = [n for n, _ in cases[0].params]
    cols = {c: [] for c in table_columns(params)}
    level_cols = csv_columns()
    for case, o in zip(cases, outcomes):
        path = out / case.name / "results.json"
        levels = json.loads(path.read_text())["levels"] if o.status != "failed" and \
            path.exists() else {}
        n = len(levels.get("alpha", []))
        for k in range(max(n, 1)):
            cols["case"].append(case.index)
            for name, v in case.params:
                cols[name].append(table_value(v))
            cols["status"].append(o.status)
            cols["message"].append(o.message)
            for c in level_cols:
                if n == 0:
                    cols[c].append(None)
                elif c == "level":
                    cols[c].append(k)
                else:
                    cols[c].append(levels[c][k])
    return cols


def write_table(table, out, units="SI", dim=3) -> dict:
    """Write the study table as CSV (always) and Parquet (when pyarrow is installed);
    the CSV header names the units of the level columns in the model's system
    (``tip [m]``, as results.csv)."""
    from ..output.files import atomic_path, atomic_write, csv_cell
    from ..analysis.result import level_units
    from ..units import column_label
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    names = list(table)
    unit = level_units(units, dim)
    w.writerow([column_label(c, unit.get(c)) for c in names])
    n = len(table[names[0]]) if names else 0
    for i in range(n):
        w.writerow([csv_cell(table[c][i]) for c in names])
    paths = {"table": Path(out) / TABLE_NAME}
    atomic_write(paths["table"], buf.getvalue())
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        return paths
    cols = {c: [";".join(v) if isinstance(v, list) else v for v in vals]
            for c, vals in table.items()}
    paths["parquet"] = Path(out) / PARQUET_NAME
    with atomic_path(paths["parquet"]) as tmp:
        pq.write_table(pa.table(cols), tmp)
    return paths


def read_table(path) -> dict:
    """The study CSV as column name (its unit left out: ``tip [m]`` -> ``tip``) -> list
    of strings (empty cells as '')."""
    from ..output.files import column_name
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return {column_name(name): [r[i] for r in rows[1:]] for i, name in enumerate(rows[0])}
