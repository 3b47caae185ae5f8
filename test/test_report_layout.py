"""`vm-ros report` with many muscles: every PNG within the size cap, per-muscle figures paged,
no legend over any plot's data area, and empty fibre-type panels saying so."""

from __future__ import annotations

import csv
import struct

import numpy as np
import pytest
from report_runs import write_muscle_run

from vm_ros.cli import main
from vm_ros.cli import report as report_verb
from vm_ros.recording.run_log import read_run
from vm_ros.report import plots as report_plots
from vm_ros.report import tables as report_tables

MAX_PX = (2400, 3400)  # the cap documented in vm_ros.report.plots
PAGE = 40  # muscles per page of a per-muscle figure
PER_MUSCLE = ("force", "kinematics", "drive", "energy_muscles")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """{muscles: log}: a gait-like run of 1, 18 and 80 muscles, 0.6 s."""
    folder = tmp_path_factory.mktemp("layout")
    logs = {}
    for n in (1, 18, 80):
        library, inputs = write_muscle_run(folder, n, 0.6)
        logs[n] = folder / f"run{n}.mcap"
        assert main(["simulate", "--inputs", str(inputs), "--library", str(library), "--out",
                     str(logs[n]), "--start-time", "0"]) == 0
    return logs


def _png_size(path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", path
    return struct.unpack(">II", data[16:24])  # IHDR: width, height


@pytest.mark.parametrize("muscles", [1, 18, 80])
def test_every_png_within_the_cap_and_pages_of_at_most_40_muscles(runs, muscles, tmp_path):
    out = tmp_path / "report"
    assert main(["report", str(runs[muscles]), "--out", str(out)]) == 0
    pngs = sorted(out.glob("*.png"))
    for path in pngs:
        width, height = _png_size(path)
        assert width <= MAX_PX[0] and height <= MAX_PX[1], (path.name, width, height)
    pages = -(-muscles // PAGE)
    names = {p.name for p in pngs}
    for stem in PER_MUSCLE:
        assert {f"{stem}.png"} | {f"{stem}-{k}.png" for k in range(2, pages + 1)} <= names
        assert f"{stem}-{pages + 1}.png" not in names
    muscle_files = {f"energy_{m}.png" for m in report_tables.muscle_names(read_run(
        runs[muscles]))}
    assert not muscle_files & names  # one figure for all muscles, not a file per muscle


def _figures(log, tmp_path):
    run = read_run(log)
    tables = {}
    for build in (report_tables.force_table, report_tables.energy_rate_table,
                  report_tables.totals_table, report_tables.telemetry_table):
        table = build(run)
        if table is not None:
            tables[table.name] = table
    plt = report_verb._pyplot()
    t = tables["forces"].column("time_s")
    bin_s, reason = report_plots.report_bin(run, t[-1] - t[0], float(np.median(np.diff(t))))
    return plt, report_plots.report_figures(plt, run, tables, tmp_path, bin_s, reason)


def _overlap_px(a, b) -> float:
    width = min(a.x1, b.x1) - max(a.x0, b.x0)
    height = min(a.y1, b.y1) - max(a.y0, b.y0)
    return max(width, 0.0) * max(height, 0.0)


@pytest.mark.parametrize("muscles", [1, 18, 80])
def test_no_legend_covers_a_plot(runs, muscles, tmp_path):
    plt, figures = _figures(runs[muscles], tmp_path)
    legends = 0
    for path, fig in figures:
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        boxes = [ax.get_window_extent(renderer) for ax in fig.axes if ax.axison]
        for legend in [*fig.legends, *(ax.get_legend() for ax in fig.axes)]:
            if legend is None:
                continue
            legends += 1
            box = legend.get_window_extent(renderer)
            assert box.x0 >= 0 and box.y0 >= 0 and box.x1 <= fig.bbox.x1 + 1 \
                and box.y1 <= fig.bbox.y1 + 1, f"{path.name}: legend outside the figure"
            for ax_box in boxes:
                assert _overlap_px(box, ax_box) < 1.0, f"{path.name}: a legend covers a plot"
        plt.close(fig)
    assert legends >= 5


def test_empty_fast_fibre_panels_say_not_recruited(runs, tmp_path):
    out = tmp_path / "report"
    assert main(["report", str(runs[18]), "--out", str(out), "--no-plots"]) == 0
    with open(out / "summary.csv", newline="") as handle:
        rows = list(csv.DictReader(handle))
    idle = {(r["muscle"], r["fibre"]) for r in rows
            if r["fibre"] in ("slow", "fast") and float(r["total_energy_J"]) == 0.0}
    assert any(fibre == "fast" for _, fibre in idle)  # the run has some: every third muscle
    plt, figures = _figures(runs[18], tmp_path)
    for path, fig in figures:
        if path.name == "energy_muscles.png":
            notes = [t for ax in fig.axes for t in ax.texts if t.get_text() == "not recruited"]
            assert len(notes) == len(idle)
        plt.close(fig)


def test_summary_names_the_top_muscles_and_groups_the_others(runs):
    run = read_run(runs[18])
    summary = report_tables.run_summary(run)
    named, others = report_plots.top_muscles(summary, report_tables.muscle_names(run))
    assert len(named) == 8 and len(others) == 10
    energy = {row.name: row.energy[-1, -1] for row in summary}
    assert min(energy[m] for m in named) >= max(energy[m] for m in others)
    assert report_plots.top_muscles(summary[:9], [r.name for r in summary[:9]])[1] == []


def _outside_px(box, fig) -> float:
    """How far (px) a text's box reaches beyond the figure on any side (0 when inside)."""
    return max(0.0, -box.x0, -box.y0, box.x1 - fig.bbox.x1, box.y1 - fig.bbox.y1)


def _cut_texts(fig) -> list[str]:
    """The titles (figure and axes) whose text reaches more than 1 px outside the figure."""
    fig.canvas.draw()
    renderer = fig.canvas.get_renderer()
    titles = [fig._suptitle] + [ax.title for ax in fig.axes]
    return [t.get_text() for t in titles
            if t is not None and t.get_text() and t.get_visible()
            and _outside_px(t.get_window_extent(renderer), fig) > 1.0]


@pytest.mark.parametrize("muscles", [18, 80])
def test_no_title_is_cut_off(runs, muscles, tmp_path):
    plt, figures = _figures(runs[muscles], tmp_path)
    for path, fig in figures:
        assert _cut_texts(fig) == [], path.name
        plt.close(fig)


@pytest.mark.parametrize("muscles", [1, 18, 80])
def test_energy_models_totals_keeps_its_title_and_legend_inside(muscles):
    """Tsianos 2012 and the eight published models over n muscles (energies made up: the layout,
    not the values, is checked): the title is not cut off and the legend covers no plot."""
    from vm_ros.model.energetics_models import MODEL_NAMES
    from vm_ros.report.summary import ModelTotals

    names = [f"muscle_with_a_long_name_{k}" for k in range(muscles)]
    tsianos = np.linspace(10.0, 50.0, muscles)
    rows = [ModelTotals(report_tables.TSIANOS, tsianos, tsianos)] + [
        ModelTotals(model, tsianos * (0.5 + 0.1 * j), tsianos)
        for j, model in enumerate(MODEL_NAMES)]
    plt = report_verb._pyplot()
    fig = report_plots.energy_models_totals_figure(plt, rows, names)
    assert _cut_texts(fig) == []
    renderer = fig.canvas.get_renderer()
    scale = report_plots.DPI / fig.dpi  # the PNG's pixels: saved at DPI
    assert round(fig.bbox.width * scale) <= MAX_PX[0]
    assert round(fig.bbox.height * scale) <= MAX_PX[1]
    legend = fig.legends[0].get_window_extent(renderer)
    assert _outside_px(legend, fig) <= 1.0
    for ax in fig.axes:
        assert _overlap_px(legend, ax.get_window_extent(renderer)) < 1.0
    plt.close(fig)


def test_a_wrapped_title_keeps_each_number_with_its_unit():
    text = "whole run: bins of 2.500 s each over 10 s, published at 100 Hz by 18 muscles"
    for width in range(20, 60):
        for line in report_plots.wrap_text(text, width).splitlines():
            assert not line.rstrip().endswith(("2.500", " 10", " 100", " 18")), line
    assert report_plots.wrap_text(text, 200).replace("\u00a0", " ") == text
