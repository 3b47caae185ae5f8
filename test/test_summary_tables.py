"""The printed summary tables keep whole names: muscle and joint names of real models (OpenSim's
`flexor_digitorum_longus_r`, 25 characters) were cut at 12 characters or ran into the numbers."""

from __future__ import annotations

import numpy as np

from vm_ros.report.summary import (
    JointSummary,
    ModelTotals,
    MuscleSummary,
    joint_summary_table,
    model_totals_table,
    summary_table,
)

LONG = "flexor_digitorum_longus_r"
SHORT = "vasti"


def _columns_line_up(text: str, name: str, second: str, second_header: str) -> None:
    """The row of ``name`` starts with the whole name, and its next cell ``second`` sits under
    the header's ``second_header``."""
    lines = text.splitlines()
    row = next(line for line in lines if line.startswith(name))
    assert row.split()[0] == name
    assert row.index(second, len(name)) == lines[0].index(second_header), (row, lines[0])


def test_muscle_table_keeps_long_names():
    energy = np.arange(12.0).reshape(3, 4)
    rows = [MuscleSummary(name, 100.0, 50.0, energy, 1.0) for name in (LONG, SHORT)]
    text = summary_table(rows)
    _columns_line_up(text, LONG, "slow", "fibre")
    _columns_line_up(text, SHORT, "slow", "fibre")


def test_joint_table_keeps_long_names():
    name = "subtalar_angle_r_with_a_long_suffix"
    text = joint_summary_table([JointSummary(name, "rad", 1.0, 0.5, -2.0, 0)])
    lines = text.splitlines()
    row = next(line for line in lines if line.startswith(name))
    assert len(row) == len(lines[0]) and row.split()[0] == name


def test_model_totals_table_keeps_long_muscle_names():
    rows = [ModelTotals("umberger2010", np.array([1.0, 2.0]), np.array([1.0, 2.0]))]
    header = model_totals_table(rows, [LONG, SHORT]).splitlines()[0]
    assert LONG in header and SHORT in header
    row = model_totals_table(rows, [LONG, SHORT]).splitlines()[3]
    assert len(row) == len(header)
