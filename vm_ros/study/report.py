"""A study's table, printed, and its main effects plotted: for each varied parameter, the mean
energy over the runs at each of its values (the other parameters averaged over), per muscle and
for all muscles (the sum over muscles of each run); parameters varied together (equal in every
run, as both muscles' fibre mix) share a panel; with ``by``, one line per value of that
parameter (an interaction plot).
"""

from __future__ import annotations

import math
from pathlib import Path

from vm_ros.errors import VmRosError
from vm_ros.study.table import FIXED_COLUMNS, RESULT_COLUMNS, RESULTS_PARQUET
from vm_ros.study.task import STATUS_OK, energy_column

DEFAULT_ENERGY = energy_column("all", "total")
PLOT_FILE = "main_effects.png"
ALL_MUSCLES = "all muscles"
SHOWN = ("duration_s", "peak_force_N", "mean_force_N", DEFAULT_ENERGY)


def read_table(out_dir: Path) -> tuple[list[str], list[dict]]:
    """(columns, rows) of a study folder's results.parquet."""
    import pyarrow.parquet as pq

    path = Path(out_dir) / RESULTS_PARQUET
    if not path.is_file():
        raise VmRosError(f"{out_dir}: no {RESULTS_PARQUET} (not a study folder, or `vm-ros study "
                         "run` has not finished a run there)")
    table = pq.read_table(path)
    return table.column_names, table.to_pylist()


def varied_columns(columns: list[str]) -> list[str]:
    """The parameter columns: between the fixed columns and the results."""
    return columns[len(FIXED_COLUMNS):columns.index(RESULT_COLUMNS[0])]


def _cell(value) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return ""
    return f"{value:.6g}" if isinstance(value, float) else str(value)


def table_text(columns: list[str], rows: list[dict]) -> str:
    models = columns[len(FIXED_COLUMNS) + len(varied_columns(columns)) + len(RESULT_COLUMNS):]
    shown = ["run_id", "input", *varied_columns(columns), "muscle", "status", *SHOWN, *models,
             "error"]
    cells = [[_cell(row[c]) for c in shown] for row in rows]
    widths = [max([len(c), *(len(r[i]) for r in cells)]) for i, c in enumerate(shown)]
    lines = ["  ".join(c.ljust(w) for c, w in zip(shown, widths, strict=True))]
    lines += ["  ".join(v.ljust(w) for v, w in zip(r, widths, strict=True)).rstrip()
              for r in cells]
    return "\n".join(lines)


def main_effects(rows: list[dict], parameter: str, energy: str, by: str | None = None) -> dict:
    """{(muscle or ALL_MUSCLES, by value or None): ([parameter values], [mean energy])} over the
    finished runs; parameter values in order of first appearance."""
    ok = [r for r in rows if r["status"] == STATUS_OK]
    per_run: dict = {}
    for row in ok:  # the sum over muscles of each run
        key = row["run_id"]
        base = per_run.setdefault(key, {**row, "muscle": ALL_MUSCLES, energy: 0.0})
        base[energy] += row[energy]
    values = list(dict.fromkeys(r[parameter] for r in ok))
    effects = {}
    for row in [*ok, *per_run.values()]:
        key = (row["muscle"], row[by] if by else None)
        sums = effects.setdefault(key, {v: [] for v in values})
        sums[row[parameter]].append(row[energy])
    return {key: ([v for v in values if sums[v]], [sum(sums[v]) / len(sums[v])
                                                   for v in values if sums[v]])
            for key, sums in effects.items()}


def together(parameters: list[str], rows: list[dict]) -> list[list[str]]:
    """The parameters grouped into panels: those with equal values in every row (varied
    together, as both muscles' fibre mix) share one."""
    panels: dict = {}
    for name in parameters:
        panels.setdefault(tuple(r[name] for r in rows), []).append(name)
    return list(panels.values())


def plot(columns: list[str], rows: list[dict], path: Path, energy: str, by: str | None) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = together([p for p in varied_columns(columns)  # a setting has one value: no panel
                       if p != by and len({r[p] for r in rows}) > 1], rows)
    fig, axes = plt.subplots(1, max(len(panels), 1), figsize=(5.5 * max(len(panels), 1), 4.2),
                             squeeze=False)
    styles = ["-", "--", ":", "-."]
    for ax, names in zip(axes[0], panels, strict=False):
        parameter = names[0]
        effects = main_effects(rows, parameter, energy, by)
        muscles = list(dict.fromkeys(m for m, _ in effects))
        splits = list(dict.fromkeys(b for _, b in effects))
        for (muscle, split), (xs, ys) in effects.items():
            numeric = all(isinstance(x, float) for x in xs)
            label = muscle if split is None else f"{muscle}, {split}"
            ax.plot(xs if numeric else [str(x) for x in xs], [y / 1e3 for y in ys], marker="o",
                    color=f"C{muscles.index(muscle)}",
                    ls=styles[splits.index(split) % len(styles)], label=label)
        ax.set_xlabel("\n= ".join(names))
        ax.set_ylabel(f"{energy} (kJ)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("main effects" + (f" by {by}" if by else "") + "\n(means over the other "
                 "parameters)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def report(out_dir: Path, plots: bool = True, energy: str = DEFAULT_ENERGY,
           by: str | None = None) -> int:
    """Print the table of a study folder and write main_effects.png there."""
    columns, rows = read_table(out_dir)
    for name, what in ((energy, "--energy"), (by, "--by")):
        if name is not None and name not in columns:
            raise VmRosError(f"{what} {name}: not a column of {out_dir / RESULTS_PARQUET} "
                             f"(varied: {', '.join(varied_columns(columns)) or 'none'})")
    print(table_text(columns, rows))
    failed = len({r["run_id"] for r in rows if r["status"] != STATUS_OK})
    print(f"{len({r['run_id'] for r in rows})} runs ({failed} failed), {len(rows)} rows")
    if plots and varied_columns(columns):
        path = Path(out_dir) / PLOT_FILE
        plot(columns, rows, path, energy, by)
        print(f"plot: {path}")
    return 0
