"""No behaviour change across the package's reorganisation (recording/ split into recording/,
offline/ and report/; input topics in one table; model/ below energetics_models): a bank run, an
offline log and a node log (a motion run conditioned as muscle_node conditions its inputs, and its
recompute) give the same bytes as the code before the change.

The DIGESTS below were computed by the code before the change (commit bb0d40a), by running this
file as a script against that commit's source:

    git worktree add ../vm_ros-bb0d40a bb0d40a
    cp config/muscles.yaml ../vm_ros-bb0d40a/config/   # the library the logs attach (below)
    PYTHONPATH=../vm_ros-bb0d40a:test .venv/bin/python test/test_layout_digests.py

The logs attach the shipped muscle library, so its bytes are in the digests: they were computed
with today's config/muscles.yaml in that commit's source (its entries are those of bb0d40a; the
file since gained comment lines), and change when the file does.

The model's constants are in the digests too: when the drive filter's constants became the fit's
output (config/model.yaml recruitment.lumped.relative_*, a new one among them, which the code of
bb0d40a and 8817190 cannot read), DIGESTS and SLOW_LEG_DIGESTS were recomputed by the same
procedure against the source of that change (commit cf33c05, a clean worktree, this file run
against it as above; SLOW_LEG_DIGESTS by ``slow_leg_digests``), and again when the drive filter's
fall came to follow the lumped unit's firing, against commit 1476522, and again when each fibre
type got its own filtered drive (state effective_drive (n, 2)), against commit 7fa3863, and when
the rise lost its power q (constants refit), against commit 2b9e843 (X86_V3 only, below).

A digest covers every message (channel topic and type, log time, publish time, raw CDR bytes),
every attachment and the metadata except the library versions and the paths of the files read
(``*_file``: the attachments hold their bytes). It depends on the numerical
libraries: the test is skipped when the installed versions are not those it was computed with.

It depends on the machine too: NumPy picks its transcendental functions' code by the CPU's SIMD
level, and their last bits differ between levels. The same code (commit 1476522, and main at
01d8dc3) gives other digests on a CPU without AVX-512 (NumPy's highest dispatch target X86_V3)
than on the AVX-512 machine (X86_V4) the digests were first computed on. So the digests are
kept per SIMD level (``simd_level``): X86_V4's computed as above up to commit 1476522 (on the
machines of 2026-11 and 2026-12-02), X86_V3's on 2026-12-03 by the same procedure against
commit 1476522's source on a 2-core AMD EPYC (Zen 3, AVX2, FMA; SLOW_LEG_DIGESTS' with
``slow_leg_digests`` in place of ``all_digests``). On a level with no digests the tests are
skipped, naming it; to add one, run the procedure above on such a machine.

When each fibre type got its own filtered drive (commit 7fa3863) the model's output changed on
every level. No X86_V4 machine was available to recompute that level's digests after this
model change, so its entries were dropped (the tests skip there, naming the level); X86_V3's were
recomputed by the procedure above against the model's latest commit, named where they are set
(a clean export of that commit's source, ``git archive``, in place of the worktree).
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import sys
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from vm_ros.cli import main
from vm_ros.model import MuscleBank

START_NS = 1_700_000_000_123_456_789
COMPUTED_WITH = {"numpy": "2.4.6", "scipy": "1.17.1", "mcap": "1.6.0"}
SIMD_LEVELS = ("X86_V3", "X86_V4")  # NumPy's dispatch targets the digests are kept for
DIGESTS = {
    # computed on 2026-12-03 on the 2-core AMD EPYC (Zen 3) against commit 2b9e843's source (the
    # relative_drive rise without q, its constants refit), by the procedure of the docstring
    "X86_V3": {
        "bank_numpy": "0d6f4d9225899a1b494bc3a04460c7b12471469e9abddd165b735330d9b3229b",
        "bank_auto": "213f38901960b84bdbd1d5e1c1e12dcb4e27235ac90c086835d10047fc4e00f2",
        "knee": "73553edfa22ff049cfbbea04be1688c0db60dcfeb8cfde177c2b5c4db6f38031",
        "leg": "b73cec23360aacadda86ccc09239b84c0f59b725b8994a365e973a7b52290942",
        "knee_recomputed": "4f7135b256f36d646aa55f1754322a883763eb0a590269f37d9950398b627108",
        "leg_recomputed": "7472d2f890db82dbe3b793b67f9b1383b7d1302994c843bdc130a2f67d026085",
    },
}


def _versions() -> dict:
    from importlib.metadata import version
    return {name: version(name) for name in COMPUTED_WITH}


def simd_level() -> str:
    """The highest of SIMD_LEVELS among the NumPy dispatch targets this CPU runs ("" for none)."""
    from numpy._core._multiarray_umath import __cpu_features__
    found = [level for level in SIMD_LEVELS if __cpu_features__.get(level)]
    return found[-1] if found else ""


def _skip_reason() -> str:
    """Why the digests cannot be compared here ("" when they can)."""
    if _versions() != COMPUTED_WITH:
        return f"digests computed with {COMPUTED_WITH}, installed {_versions()}"
    if simd_level() not in DIGESTS:
        return (f"digests kept for NumPy SIMD levels {sorted(DIGESTS)}, this CPU's is "
                f"{simd_level() or 'below ' + SIMD_LEVELS[0]} (module docstring: how to add it)")
    return ""


def bank_digest(backend: str) -> str:
    """1000 steps of 1 ms of vasti and rectus femoris with every published energetics model,
    under a drive and path lengths written here."""
    bank = MuscleBank.from_config(["vasti", "rectus_femoris"], recruitment="lumped",
                                  backend=backend, energetics_models=("all",))
    digest = hashlib.sha256()
    t = np.arange(1000) * 1e-3
    drive = np.stack([0.5 + 0.4 * np.sin(2 * np.pi * 3 * t), 0.3 + 0.2 * np.cos(2 * np.pi * t)], 1)
    length = np.stack([0.31 + 0.01 * np.sin(2 * np.pi * t), 0.52 + 0.005 * np.sin(4 * t)], 1)
    velocity = np.stack([0.02 * np.pi * np.cos(2 * np.pi * t), 0.02 * np.cos(4 * t)], 1)
    bank.reset(path_length=length[0])
    for k in range(len(t)):
        out = bank.step(1e-3, drive[k], length[k], velocity[k])
        for value in (out.force, out.fascicle_length, out.fascicle_velocity,
                      out.effective_activation, out.energy_rate_by_fibre.total,
                      out.energy_by_fibre.total, out.mechanical_work, out.energy_rate_models):
            digest.update(np.ascontiguousarray(value, dtype=np.float64).tobytes())
    return digest.hexdigest()


def log_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            digest.update(f"{channel.topic} {schema.name} {message.log_time} "
                          f"{message.publish_time} {message.sequence}".encode())
            digest.update(message.data)
        for attachment in reader.iter_attachments():
            digest.update(attachment.name.encode() + attachment.data)
        for metadata in reader.iter_metadata():
            values = {k: v for k, v in metadata.metadata.items()
                      if k != "versions" and not k.endswith("_file")}
            digest.update(metadata.name.encode() + json.dumps(values, sort_keys=True).encode())
    return digest.hexdigest()


def _run(args) -> None:
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(args) == 0


def log_digests(directory: Path) -> dict:
    """Digests of an offline scenario log, a motion log (the node's conditioning) and the
    recompute of each, written in ``directory`` under names relative to it."""
    from test_simulate_joint_space import leg_motion, write_geometry_file

    previous = Path.cwd()
    os.chdir(directory)
    try:
        start = ["--start-time", str(START_NS)]
        _run(["simulate", "--scenario", "knee_extension", "--duration", "0.3",
              "--energetics-models", "all", *start, "--out", "knee.mcap"])
        write_geometry_file(Path("."))
        leg_motion(Path("leg.mot"))
        _run(["simulate", "--motion", "leg.mot", "--geometry", "leg.yaml", "--excitation",
              "0.2", "--telemetry-rate", "50", *start, "--out", "leg.mcap"])
        _run(["recompute", "knee.mcap", "--out", "knee_recomputed.mcap"])
        _run(["recompute", "leg.mcap", "--out", "leg_recomputed.mcap"])
        return {name: log_digest(Path(f"{name}.mcap"))
                for name in ("knee", "leg", "knee_recomputed", "leg_recomputed")}
    finally:
        os.chdir(previous)


# A motion run with inputs slower than the model (path lengths extrapolated between
# joint_states), publish 200 Hz, telemetry 100 Hz and every published energetics model, and its
# recompute: computed by the code before the offline runs went by blocks for joint space and
# recompute read logs as arrays (commit 8817190), as above against that commit's source with
# today's config/muscles.yaml
SLOW_LEG_DIGESTS = {
    # as DIGESTS["X86_V3"], against commit 2b9e843, with slow_leg_digests
    "X86_V3": {
        "leg_slow": "bfe7dd0b7139cc29061942440592ec6b8e1c63ab5401f7815773be0e1315a30a",
        "leg_slow_recomputed": "72b42d9ffb749df8aa1a7be8fdac484b89ead00db391fae7709fb535443349c2",
    },
}


def slow_leg_digests(directory: Path) -> dict:
    from test_simulate_joint_space import leg_motion, write_geometry_file

    previous = Path.cwd()
    os.chdir(directory)
    try:
        write_geometry_file(Path("."))
        leg_motion(Path("leg.mot"))
        _run(["simulate", "--motion", "leg.mot", "--geometry", "leg.yaml", "--excitation", "0.3",
              "--input-rate", "250", "--publish-rate", "200", "--telemetry-rate", "100",
              "--energetics-models", "all", "--start-time", str(START_NS),
              "--out", "leg_slow.mcap"])
        _run(["recompute", "leg_slow.mcap", "--out", "leg_slow_recomputed.mcap"])
        return {name: log_digest(Path(f"{name}.mcap")) for name in ("leg_slow",
                                                                     "leg_slow_recomputed")}
    finally:
        os.chdir(previous)


def all_digests(directory: Path) -> dict:
    return {"bank_numpy": bank_digest("numpy"), "bank_auto": bank_digest("auto"),
            **log_digests(directory)}


@pytest.mark.skipif(bool(_skip_reason()), reason=_skip_reason())
def test_runs_and_logs_are_byte_identical_to_the_code_before_the_change(tmp_path):
    assert all_digests(tmp_path) == DIGESTS[simd_level()]


@pytest.mark.skipif(bool(_skip_reason()), reason=_skip_reason())
def test_a_motion_run_in_blocks_and_its_recompute_are_byte_identical_to_the_stepwise_code(
        tmp_path):
    assert slow_leg_digests(tmp_path) == SLOW_LEG_DIGESTS[simd_level()]


if __name__ == "__main__":
    import tempfile

    import vm_ros

    print(vm_ros.__file__, _versions(), simd_level())
    with tempfile.TemporaryDirectory() as folder:
        json.dump(all_digests(Path(folder)), sys.stdout, indent=1)
    print()
