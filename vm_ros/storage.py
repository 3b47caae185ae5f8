"""OpenSim storage files (.sto, .mot) as text tables, read without OpenSim.

Layout: header lines (``name=value`` pairs such as ``inDegrees=yes``), a line ``endheader``, a
line of column labels (tab- or space-separated, the first ``time``), then one row of numbers per
sample. The motion reader (vm_ros.importers.motion) and the excitation reader
(vm_ros.offline.excitations) both start here.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from vm_ros.errors import VmRosError


@dataclass(frozen=True)
class StorageTable:
    """header: ``{lower-case key: value}``; labels: column labels (``time`` first); rows: the data
    rows as strings, one list per row."""

    header: dict
    labels: list
    rows: list


def parse_storage(path, text: str, what: str) -> StorageTable:
    """Split a storage file's text; VmRosError ``"<what> <path>: ..."`` when it is not one."""
    path = Path(path)
    lines = text.splitlines()
    end = next((i for i, line in enumerate(lines) if line.strip().lower() == "endheader"), None)
    if end is None:
        raise VmRosError(f"{what} {path}: no 'endheader' line: not an OpenSim .mot/.sto file")
    header = {}
    for line in lines[:end]:
        key, sep, value = line.partition("=")
        if sep:
            header[key.strip().lower()] = value.strip()
    body = [line for line in lines[end + 1:] if line.strip()]
    if not body:
        raise VmRosError(f"{what} {path}: no column labels after 'endheader'")
    labels = [label.strip() for label in (body[0].split("\t") if "\t" in body[0]
                                          else body[0].split())]
    if not labels or labels[0].lower() != "time":
        raise VmRosError(f"{what} {path}: the first column must be 'time', got "
                         f"{labels[0] if labels else None!r}")
    return StorageTable(header, labels, [row.split() for row in body[1:]])


def read_storage(path, what: str) -> StorageTable:
    """Read and split a storage file; VmRosError ``"<what> <path>: ..."`` when it cannot be
    read or is not one."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError as exc:
        raise VmRosError(f"{what} {path}: cannot read ({exc.strerror or exc})") from exc
    return parse_storage(path, text, what)


def numeric_rows(path, labels, rows, what: str):
    """The data rows as a finite float array (n_rows, len(labels)); VmRosError otherwise."""
    import numpy as np

    try:
        data = np.array([[float(v) for v in row] for row in rows], dtype=float)
    except ValueError as exc:
        raise VmRosError(f"{what} {path}: a data row is not numbers ({exc})") from None
    if data.ndim != 2 or data.shape[0] == 0 or data.shape[1] != len(labels):
        raise VmRosError(f"{what} {path}: need rows of {len(labels)} numbers (one per column), "
                         f"got {data.shape}")
    if not np.all(np.isfinite(data)):
        raise VmRosError(f"{what} {path}: non-finite values")
    return data


def check_increasing(path, time, what: str) -> None:
    """VmRosError naming the first data row (1-based) whose time does not increase."""
    import numpy as np

    back = np.diff(time) <= 0
    if np.any(back):
        raise VmRosError(f"{what} {path}: times must increase strictly (row "
                         f"{int(np.argmax(back)) + 2} does not)")


def read_columns(path, what: str):
    """(time (n,), {label: column (n,)}, labels in file order) of a numeric storage file
    whose times increase strictly; VmRosError ``"<what> <path>: ..."`` otherwise (a label given
    twice included)."""
    table = read_storage(path, what)
    data = numeric_rows(path, table.labels, table.rows, what)
    check_increasing(path, data[:, 0], what)
    labels = table.labels[1:]
    if len(set(labels)) != len(labels):
        twice = sorted({label for label in labels if labels.count(label) > 1})
        raise VmRosError(f"{what} {path}: column(s) {', '.join(twice)} appear twice")
    return data[:, 0], {label: data[:, i + 1] for i, label in enumerate(labels)}, labels


__all__ = ["StorageTable", "check_increasing", "numeric_rows", "parse_storage", "read_columns",
           "read_storage"]
