"""No behaviour change across the package's reorganisation (recording/ split into recording/,
offline/ and report/; input topics in one table; model/ below energetics_models): a bank run, an
offline log and a node log (a motion run conditioned as muscle_node conditions its inputs, and its
recompute) give the same bytes as the code before the change.

The DIGESTS below were computed by the code before the change (commit bb0d40a), by running this
file as a script against that commit's source:

    git worktree add ../vm_ros-bb0d40a bb0d40a
    PYTHONPATH=../vm_ros-bb0d40a:test .venv/bin/python test/test_layout_digests.py

A digest covers every message (channel topic and type, log time, publish time, raw CDR bytes),
every attachment (a YAML attachment by its parsed content) and the metadata except the library
versions and the paths of the files read (``*_file``: the attachments hold their bytes). It
depends on the numerical libraries: the test is skipped when the installed versions are not those
it was computed with.
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
import yaml
from mcap.reader import make_reader

from vm_ros.cli import main
from vm_ros.model import MuscleBank

START_NS = 1_700_000_000_123_456_789
COMPUTED_WITH = {"numpy": "2.4.6", "scipy": "1.17.1", "mcap": "1.6.0"}
DIGESTS = {
    "bank_numpy": "66233637afe147b291f732637155f9100f30887739b8ec7a56d9a1e7a265f906",
    "bank_auto": "eef3c545b6724a49b9becc3b1b55cc74c47067dd959d4630bcb3b471b9c1d0ba",
    "knee": "81dbcac2c03ab66f0f3d341c491d4121dbe767841475ea0daa178f0ade4685d0",
    "leg": "5a0a54b773745841caf27fd614381e90cb3db6fcb933a8ded5f89f34415cb640",
    "knee_recomputed": "9bf14e905362efe4b93f78bf4ce90865017c691fc8e390ea28926905d314c1a3",
    "leg_recomputed": "9d64c76a312831977f9ce8b67a99db25b2831d8c097f0784fca50f3fa50c0f6c",
}


def _versions() -> dict:
    from importlib.metadata import version
    return {name: version(name) for name in COMPUTED_WITH}


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


def _attachment_content(attachment) -> bytes:
    """An attached YAML file by what it says (comments and layout do not count: a comment added
    to config/muscles.yaml is not a change of behaviour); any other attachment by its bytes."""
    if attachment.name.endswith((".yaml", ".yml")):
        return json.dumps(yaml.safe_load(attachment.data), sort_keys=True).encode()
    return attachment.data


def log_digest(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as stream:
        reader = make_reader(stream)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            digest.update(f"{channel.topic} {schema.name} {message.log_time} "
                          f"{message.publish_time} {message.sequence}".encode())
            digest.update(message.data)
        for attachment in reader.iter_attachments():
            digest.update(attachment.name.encode() + _attachment_content(attachment))
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


def all_digests(directory: Path) -> dict:
    return {"bank_numpy": bank_digest("numpy"), "bank_auto": bank_digest("auto"),
            **log_digests(directory)}


@pytest.mark.skipif(_versions() != COMPUTED_WITH,
                    reason=f"digests computed with {COMPUTED_WITH}, installed {_versions()}")
def test_runs_and_logs_are_byte_identical_to_the_code_before_the_change(tmp_path):
    assert all_digests(tmp_path) == DIGESTS


if __name__ == "__main__":
    import tempfile

    import vm_ros

    print(vm_ros.__file__, _versions())
    with tempfile.TemporaryDirectory() as folder:
        json.dump(all_digests(Path(folder)), sys.stdout, indent=1)
    print()
