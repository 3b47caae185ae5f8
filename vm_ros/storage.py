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


__all__ = ["StorageTable", "numeric_rows", "parse_storage"]
