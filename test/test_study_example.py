"""The example studies of config/studies/: each passes `vm-ros study check`, and the Fig. 7
example's runs and grid, shortened, show the trend Tsianos 2012 Fig. 7 states, on a Dask
LocalCluster of 2 workers bound to 127.0.0.1 (the embedded cluster of `vm-ros study run`; run
inside scripts/netns-run).

The physics checked, not the code's numbers: slow fibres cost less energy than fast ones (lower
activation and cross-bridge rates), so the total energy falls as both muscles' slow-fibre
fraction rises, with either recovery kernel; and the recovery kernel shapes the recovery
(oxidative) energy alone, so activation and cross-bridge energies are the same under both
kernels at the same fraction, and recovery energies differ.
"""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
import yaml
from conftest import require_module

from vm_ros.cli import main

ROOT = Path(__file__).resolve().parents[1]
STUDIES = sorted((ROOT / "config" / "studies").glob("*.yaml"))
FIG7 = ROOT / "config" / "studies" / "fig7_slow_fraction.yaml"
DURATION_S = 5.0  # five of the example's 180 knee-extension cycles
KERNEL = "model.energetics.recovery_kernel"
MUSCLES = ("rectus_femoris", "vasti")


def test_there_are_example_studies():
    assert FIG7 in STUDIES


@pytest.mark.parametrize("study", STUDIES, ids=[p.name for p in STUDIES])
def test_every_example_study_passes_check(study, capsys):
    assert main(["study", "check", str(study)]) == 0, capsys.readouterr().err


def _shortened_fig7(folder: Path) -> Path:
    """The example's own runs and grid, DURATION_S of model time each instead of 180 s."""
    study = yaml.safe_load(FIG7.read_text())
    study["settings"] = {**study.get("settings", {}), "duration": DURATION_S}
    path = folder / "fig7_short.yaml"
    path.write_text(yaml.safe_dump(study, sort_keys=False))
    return path


@pytest.mark.slow
def test_fig7_example_total_energy_falls_with_slow_fibres_and_kernels_differ_in_recovery(
        tmp_path, capsys):
    require_module("distributed", "study")
    out = tmp_path / "out"
    code = main(["study", "run", str(_shortened_fig7(tmp_path)), "--out", str(out),
                 "--workers", "2"])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert "tcp://127.0.0.1:" in printed.out  # the embedded cluster, on loopback
    with (out / "results.csv").open(newline="") as f:
        rows = list(csv.DictReader(f))
    example = yaml.safe_load(FIG7.read_text())
    kernels = example["grid"][KERNEL]
    fractions = sorted(change["library.vasti.fpcsa_slow"] for change in example["runs"])
    assert all(change[f"library.{m}.fpcsa_slow"] == change["library.vasti.fpcsa_slow"]
               for change in example["runs"] for m in MUSCLES)  # both muscles get one fraction
    assert len(fractions) >= 2 and len(rows) == len(fractions) * len(kernels) * len(MUSCLES)
    assert {r["status"] for r in rows} == {"ok"}
    energy = {(float(r["library.vasti.fpcsa_slow"]), r[KERNEL], r["muscle"]):
              {part: float(r[f"all.{part}_energy_J"])
               for part in ("activation", "cross_bridge", "recovery", "total")} for r in rows}

    for kernel in kernels:
        for muscle in MUSCLES:  # each muscle, and both together, fall with every step
            totals = [energy[f, kernel, muscle]["total"] for f in fractions]
            assert np.all(np.diff(totals) < 0), (kernel, muscle, totals)
        both = [sum(energy[f, kernel, m]["total"] for m in MUSCLES) for f in fractions]
        assert np.all(np.diff(both) < 0), (kernel, both)

    first, second = kernels
    for fraction in fractions:
        for muscle in MUSCLES:
            a, b = energy[fraction, first, muscle], energy[fraction, second, muscle]
            assert a["activation"] == b["activation"] and a["cross_bridge"] == b["cross_bridge"]
            assert a["recovery"] != b["recovery"]
