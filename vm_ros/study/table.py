"""Where a study's results live: one record file per finished run, and the table made from them.

    DIR/rows/<run id>.json     the record of a finished run (ok or failed), written by the
                               client as the run's future completes: written to a temporary
                               file, flushed to disk, then renamed (a crash leaves the old record
                               or the new one, never half of one); one file per run id, so a run
                               that ran twice is still one record
    DIR/results.parquet, .csv  the table: one row per run and muscle, runs in study order,
                               remade from the records (also after Ctrl-C), written the same way
    DIR/runs.csv               per run: id, input, status, error, wall time (s), worker; wall
                               times differ from one execution to the next, so they are kept out
                               of the results table, which is the same bit for bit whatever the
                               number of workers

Floats are stored in the records as Python's shortest round-trip text (json), so the table holds
the exact values the worker computed. The records live on the client's disk: a lost worker takes
no finished row with it.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from pathlib import Path

from vm_ros import telemetry as tm
from vm_ros.study.study_file import Study
from vm_ros.study.task import STATUS_FAILED, STATUS_OK, energy_column

ROWS_DIR, RUNS_DIR, PARAMS_DIR = "rows", "runs", "params"
RESULTS_PARQUET, RESULTS_CSV, RUNS_CSV = "results.parquet", "results.csv", "runs.csv"
FIXED_COLUMNS = ("run_id", "input")
RESULT_COLUMNS = ("muscle", "status", "error", "duration_s", "peak_force_N", "mean_force_N",
                  "mechanical_work_J",
                  *(energy_column(f, c) for f in tm.FIBRE_LABELS for c in tm.COMPONENT_LABELS))
STRING_COLUMNS = ("run_id", "input", "muscle", "status", "error")
RUNS_COLUMNS = ("run_id", "input", "status", "error", "wall_s", "worker")


def write_atomically(path: Path, data: bytes) -> None:
    """``data`` to ``path`` through a temporary file in the same folder, flushed to disk and
    renamed over ``path``."""
    partial = path.with_name(f".{path.name}.{os.getpid()}.partial")
    try:
        with open(partial, "wb") as handle:
            handle.write(data)
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(partial, path)
    finally:
        if partial.exists():
            partial.unlink()


class RecordStore:
    """The records of a study's finished runs under ``DIR/rows/``."""

    def __init__(self, out_dir: Path):
        self.folder = Path(out_dir) / ROWS_DIR

    def path(self, run_id: str) -> Path:
        return self.folder / f"{run_id}.json"

    def write(self, record: dict) -> None:
        self.folder.mkdir(parents=True, exist_ok=True)
        write_atomically(self.path(record["run_id"]), json.dumps(record).encode())

    def read(self, run_id: str) -> dict | None:
        """The run's record, or None when there is none (or it does not parse: rerun)."""
        try:
            return json.loads(self.path(run_id).read_text())
        except (OSError, ValueError):
            return None

    def finished(self, study: Study) -> dict:
        """{run id: record} of the study's runs that have a record with status ok."""
        found = {}
        for spec in study.runs:
            record = self.read(spec.run_id)
            if record is not None and record.get("status") == STATUS_OK:
                found[spec.run_id] = record
        return found


def _parameter_type(values) -> str:
    """'double' when every value is a number (bools excepted), else 'string'."""
    numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
    return "double" if numbers and values else "string"


def _text(value) -> str:
    return value if isinstance(value, str) else json.dumps(value)


def table_rows(study: Study, store: RecordStore) -> tuple[list[str], dict, list[dict]]:
    """(columns, {column: 'double' | 'string'}, rows) of the study's recorded runs in study
    order: one row per muscle of a finished run, one row (no muscle) for a failed one. A column
    for every parameter the study changes (Study.parameter_columns: varied, then settings),
    empty in the runs of a change set that does not set it."""
    records = [(spec, store.read(spec.run_id)) for spec in study.runs]
    records = [(spec, record) for spec, record in records if record is not None]
    models = list(dict.fromkeys(key for _, record in records for row in record["rows"]
                                for key in row if key.endswith(".energy_J")
                                and key not in RESULT_COLUMNS))
    parameters = study.parameter_columns
    columns = [*FIXED_COLUMNS, *parameters, *RESULT_COLUMNS, *models]
    types = {column: "string" if column in STRING_COLUMNS else "double" for column in columns}
    for key in parameters:
        types[key] = _parameter_type([value for spec in study.runs
                                      if (value := study.value(spec, key)) is not None])
    rows = []
    for spec, record in records:
        base = {"run_id": spec.run_id, "input": spec.input, "status": record["status"],
                "error": record.get("error", "")}
        for key in parameters:
            value = study.value(spec, key)  # None: not set in this run's change set
            base[key] = (None if value is None else float(value) if types[key] == "double"
                         else _text(value))
        for row in record["rows"] or [{}]:
            rows.append({**{c: None for c in columns}, **base, **row})
    return columns, types, rows


def _csv_cell(value) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return repr(value) if isinstance(value, float) else str(value)


def write_table(study: Study, out_dir: Path) -> int:
    """Write results.parquet, results.csv and runs.csv of the study's recorded runs; the
    number of rows."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    out_dir = Path(out_dir)
    store = RecordStore(out_dir)
    columns, types, rows = table_rows(study, store)
    schema = pa.schema([(c, pa.string() if types[c] == "string" else pa.float64())
                        for c in columns])
    table = pa.Table.from_pylist(rows, schema=schema)
    buffer = pa.BufferOutputStream()
    pq.write_table(table, buffer)
    write_atomically(out_dir / RESULTS_PARQUET, buffer.getvalue().to_pybytes())
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(columns)
    writer.writerows([_csv_cell(row[c]) for c in columns] for row in rows)
    write_atomically(out_dir / RESULTS_CSV, text.getvalue().encode())
    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(RUNS_COLUMNS)
    for spec in study.runs:
        record = store.read(spec.run_id)
        if record is not None:
            writer.writerow([spec.run_id, spec.input, record["status"], record.get("error", ""),
                             _csv_cell(record.get("wall_s")), record.get("worker", "")])
    write_atomically(out_dir / RUNS_CSV, text.getvalue().encode())
    return len(rows)


def failed_record(run_id: str, error: str) -> dict:
    """The record of a run whose task raised (after Dask's retries) or whose worker was lost
    too often."""
    return {"run_id": run_id, "status": STATUS_FAILED, "error": error, "rows": [],
            "worker": ""}
