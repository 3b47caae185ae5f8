"""Print the model's parameters as loaded: each constant's value in SI (or in VM's normalised units
L0, L0T, F0, f0.5), the SI unit of that value, the unit written in the file, the confidence tag
(C certain, L likely, R reconstructed) and the source.

With no option: every constant of the shipped config/model.yaml (or of --params FILE), in file
order; a fibre-type constant shows its slow and fast values. With --muscle NAME: that muscle's
fields from the muscle library (config/muscles.yaml or --library FILE), each with the source given
for it (library fields carry their unit in their name and have no tag). --list-muscles lists the
library's muscles.

A model file may use the units that --units lists (the table of vm_ros.model.units); a unit that
is not in that table, or that measures another quantity than its parameter (ms for a length), is
an error (exit 2).
"""

from __future__ import annotations

import csv
import io
import sys
from pathlib import Path

import numpy as np

from vm_ros.model.params import (
    FIBRE_TYPES,
    load_model_params,
    load_muscle_library,
    model_rows,
    muscle_rows,
    resolve_muscles,
)
from vm_ros.model.units import UNITS

COLUMNS = ("parameter", "value", "SI unit", "unit in file", "tag", "source")


def add_arguments(parser) -> None:
    parser.add_argument("--params", type=Path, default=None, metavar="FILE",
                        help="model parameter YAML (default: the shipped config/model.yaml)")
    what = parser.add_mutually_exclusive_group()
    what.add_argument("--muscle", nargs="+", metavar="NAME",
                      help="print these muscles' parameters from the library instead")
    what.add_argument("--list-muscles", action="store_true",
                      help="list the muscles of the library (name and description)")
    what.add_argument("--units", action="store_true",
                      help="list the units a model file may use, with their quantity and SI factor")
    parser.add_argument("--library", type=Path, default=None, metavar="FILE",
                        help="muscle library YAML (default: the shipped config/muscles.yaml)")
    parser.add_argument("--format", choices=("text", "csv", "markdown"), default="text",
                        help="output format (default text: aligned columns)")


def format_value(value, full: bool = False) -> str:
    """A parameter value as text: 6 significant digits (all digits with ``full``); a fibre-type
    array as ``slow X; fast Y``."""
    def number(x) -> str:
        return repr(float(x)) if full else f"{float(x):.6g}"

    if isinstance(value, (bool, np.bool_)):
        return "true" if value else "false"
    if isinstance(value, str):
        return value
    if isinstance(value, np.ndarray):
        return "; ".join(f"{t} {number(x)}" for t, x in zip(FIBRE_TYPES, value, strict=True))
    if isinstance(value, tuple):
        return "[" + ", ".join(number(x) for x in value) + "]"
    return number(value)


def table(rows, fmt: str) -> list[list[str]]:
    return [[info.name, format_value(value, full=fmt == "csv"), info.si, info.unit,
             info.tag or "-", info.source] for info, value in rows]


def write(cells: list[list[str]], fmt: str, out) -> None:
    if fmt == "csv":
        writer = csv.writer(out, lineterminator="\n")
        writer.writerow(COLUMNS)
        writer.writerows(cells)
    elif fmt == "markdown":
        out.write("| " + " | ".join(COLUMNS) + " |\n")
        out.write("|" + "---|" * len(COLUMNS) + "\n")
        for row in cells:
            out.write("| " + " | ".join(c.replace("|", "\\|") for c in row) + " |\n")
    else:
        widths = [max(len(r[i]) for r in [list(COLUMNS), *cells]) for i in range(len(COLUMNS) - 1)]
        for row in [list(COLUMNS), *cells]:
            out.write("  ".join(c.ljust(w) for c, w in zip(row, widths, strict=False))
                      + "  " + row[-1] + "\n")


def run(args) -> int:
    params = load_model_params(args.params)
    out = io.StringIO()
    if args.list_muscles:
        for name, fields in load_muscle_library(args.library).items():
            description = fields.get("description", "") if isinstance(fields, dict) else ""
            out.write(f"{name}  {description}".rstrip() + "\n")
        return _print(out.getvalue())
    if args.units:
        out.write(f"{'unit':12}  {'SI':12}  {'factor':>12}  quantity\n")
        for unit in UNITS.values():
            out.write(f"{unit.symbol:12}  {unit.si:12}  {unit.factor:12.6g}  {unit.quantity}\n")
        return _print(out.getvalue())
    if args.muscle:
        specs = resolve_muscles(args.muscle, args.library, None, params.generic.ur_default)
        rows = [row for spec in specs for row in muscle_rows(spec)]
        title = f"muscle library {args.library or 'config/muscles.yaml (shipped)'}"
    else:
        rows = model_rows(params)
        title = f"model parameters from {params.path}"
    if args.format == "text":
        out.write(f"# {title}; values in SI or VM's normalised units (L0, L0T, F0, f0.5)\n")
    write(table(rows, args.format), args.format, out)
    return _print(out.getvalue())


def _print(text: str) -> int:
    """Write ``text`` to stdout (a closed pipe, ``| head``, ends quietly: vm_ros.cli.main)."""
    sys.stdout.write(text)
    sys.stdout.flush()
    return 0
