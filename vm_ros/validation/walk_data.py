"""The Gait10dof18musc walk of opensim-models: which files, from which commit, and where they are
kept. The files are not shipped with vm_ros: the model's credits grant CC BY 3.0 for the model,
but the repository has no licence for its data (motion, inverse dynamics, ground reactions,
CMC results), so ``scripts/fetch-gait-data`` downloads them at a pinned commit into a cache
directory outside the source tree, checking each file's SHA-256.

    python -m vm_ros.validation.walk_data [--source URL|DIR|GIT_DIR] [--into DIR]

``--source``: the raw-file URL base (default GitHub's raw host at COMMIT), a checkout of the
repository (a directory holding ``Pipelines/``; CRLF line ends of a Windows checkout are put
back to LF, as the repository stores them) or a bare clone (``git show COMMIT:path``).
``--into``: the cache directory (default ``data_dir()``: $VM_ROS_DATA/gait10dof18musc, else
$XDG_CACHE_HOME/vm_ros/gait10dof18musc, else ~/.cache/vm_ros/gait10dof18musc).
"""

from __future__ import annotations

import argparse
import hashlib
import os
import subprocess
import sys
import urllib.error
import urllib.request
from dataclasses import dataclass
from pathlib import Path

from vm_ros.errors import VmRosError
from vm_ros.resources import cache_home

REPOSITORY = "opensim-org/opensim-models"
COMMIT = "20a888b9655e73fb84963d6e03eee3752cf6074b"   # master, 2024-12-09
PREFIX = "Pipelines/Gait10dof18musc/OutputReference"
RAW_URL = f"https://raw.githubusercontent.com/{REPOSITORY}/{COMMIT}"
TIMEOUT_S = 60.0


@dataclass(frozen=True)
class WalkFile:
    path: str      # under PREFIX in the repository, and under the cache directory
    sha256: str
    what: str


FILES = {
    "model": WalkFile("subject01.osim", "e85ef0d31577f2d027b579a64f3455eb8b9887a024835ef6b9108b"
                      "f023ecc468", "scaled Gait10dof18musc model (CC BY 3.0, Seth, Anderson, "
                      "Delp et al.)"),
    "model_metabolics": WalkFile("CMC/subject01_metabolics.osim", "161281b19e69b7b5731ea370b8"
                                 "c45c434ee50047c9c27f3ed90bcc63c074298e",
                                 "the model with Umberger 2010 metabolic probes"),
    "motion": WalkFile("IK/subject01_walk_IK.mot", "10a3877abacf8c35049532d018b2bdfac7623234"
                       "c8f1ce9f7a68f007f2c7c976", "inverse kinematics, 151 frames at 60 Hz"),
    "inverse_dynamics": WalkFile("ID/Results/subject01_walk_ID.sto", "4cf120373352a471b6c67d"
                                 "e69c7c631ede488ab71a0bc595008e441add9019df",
                                 "inverse dynamics (coordinates low-pass filtered at 6 Hz)"),
    "id_setup": WalkFile("ID/walk_Setup_ID.xml", "2bf63ad86146fd2b569b704a452f0848d4d88b39b8"
                         "5c2fabf79b74869aaf5d31", "the inverse-dynamics setup"),
    "grf": WalkFile("ExperimentalData/subject01_walk_grf.mot", "c3b5b46c64e958832f402687c328"
                    "ca0f6fe132ebd8ccdf613600c5422d4a2a81", "ground reaction forces"),
    "grf_loads": WalkFile("ExperimentalData/subject01_walk_grf.xml", "307816039e06346094cb0b"
                          "0d0d6d176935761c02c9fef34a17cfbd57a7882d22",
                          "external loads (feet), data file subject01_walk_grf.mot"),
    "reserves": WalkFile("gait10dof_Reserve_Actuators.xml", "b6fd299d91361027b107aa2a30a0063"
                         "27bb57fe6d642291ff7aecbc916ed1e38", "pelvis residual and joint "
                         "reserve actuators of the CMC setup"),
    "cmc_controls": WalkFile("CMC/ResultsCMC/walk_subject_controls.sto", "f6e7b209a729819423"
                             "e480de37903fc63d19d2c45fdaf25471ab8e8a45f3dd76",
                             "CMC excitations"),
    "cmc_forces": WalkFile("CMC/ResultsCMC/walk_subject_Actuation_force.sto", "68b4bfec200d74"
                           "12ac7ee9e7d88ff1047f74ad8fe234e838fd555bbad770bbc1",
                           "CMC actuator (muscle and reserve) forces"),
    "cmc_probes": WalkFile("CMC/ResultsCMC_AnkleSpring/walk_subject_MetabolicsReporter_probes"
                           ".sto", "60b95da141e5d080a2a5d351d892ba2510154a91aaee23c9750711810d"
                           "5d1639", "Umberger 2010 probes over a CMC walk (ankle-spring "
                           "variant)"),
}


class WalkDataError(VmRosError):
    """The walk's files are missing, altered or cannot be fetched."""


def data_dir() -> Path:
    """The cache directory of the walk's files (module docstring)."""
    if os.environ.get("VM_ROS_DATA"):
        return Path(os.environ["VM_ROS_DATA"]) / "gait10dof18musc"
    return cache_home() / "gait10dof18musc"


def sha256(content: bytes) -> str:
    return hashlib.sha256(content).hexdigest()


def walk_files(directory=None) -> dict[str, Path]:
    """{name: path} of every file in FILES, present in ``directory`` (default ``data_dir()``)
    with its SHA-256; WalkDataError naming what is missing or altered otherwise."""
    root = Path(directory) if directory else data_dir()
    missing = [f.path for f in FILES.values() if not (root / f.path).is_file()]
    if missing:
        raise WalkDataError(f"the Gait10dof18musc walk is not in {root} ({len(missing)} of "
                            f"{len(FILES)} files missing, e.g. {missing[0]}): run "
                            "scripts/fetch-gait-data")
    altered = [f.path for f in FILES.values() if sha256((root / f.path).read_bytes()) != f.sha256]
    if altered:
        raise WalkDataError(f"{root}: {', '.join(altered)} differ from {REPOSITORY} at "
                            f"{COMMIT[:12]} (SHA-256): run scripts/fetch-gait-data again")
    return {name: root / f.path for name, f in FILES.items()}


def _from_url(base: str, path: str) -> bytes:
    url = f"{base.rstrip('/')}/{PREFIX}/{path}"
    try:
        with urllib.request.urlopen(url, timeout=TIMEOUT_S) as response:
            return response.read()
    except (urllib.error.URLError, OSError) as exc:
        reason = getattr(exc, "reason", exc)
        raise WalkDataError(f"cannot download {url} ({reason}); give a local copy of "
                            f"{REPOSITORY} with --source DIR") from exc


def _from_git(git_dir: Path, path: str) -> bytes:
    done = subprocess.run(["git", "--git-dir", str(git_dir), "show", f"{COMMIT}:{PREFIX}/{path}"],
                          capture_output=True, check=False)
    if done.returncode != 0:
        message = done.stderr.decode(errors="replace").strip().splitlines()
        raise WalkDataError(f"{git_dir}: no {PREFIX}/{path} at {COMMIT[:12]} "
                            f"({message[-1] if message else 'git failed'})")
    return done.stdout


def _from_checkout(root: Path, path: str) -> bytes:
    file = root / PREFIX / path
    if not file.is_file():
        raise WalkDataError(f"{root}: no {PREFIX}/{path} (not a checkout of {REPOSITORY}?)")
    return file.read_bytes()


def reader(source: str | None):
    """A function path -> bytes for a URL base, a checkout or a bare clone (module docstring)."""
    if source is None or "://" in source:
        base = source or RAW_URL
        return lambda path: _from_url(base, path)
    root = Path(source)
    if (root / "Pipelines").is_dir():
        return lambda path: _from_checkout(root, path)
    if (root / "HEAD").is_file() and (root / "objects").is_dir():
        return lambda path: _from_git(root, path)
    if (root / ".git").exists():
        return lambda path: _from_checkout(root, path)
    raise WalkDataError(f"--source {source}: neither a URL, a checkout of {REPOSITORY} (with "
                        "Pipelines/) nor a bare git repository")


def fetch(source: str | None = None, into=None, log=print) -> dict[str, Path]:
    """Copy every file in FILES from ``source`` into ``into`` (default ``data_dir()``), each
    checked against its SHA-256 (with CRLF line ends put back to LF where that matches); files
    already there with the right hash are kept. Returns ``walk_files(into)``."""
    root = Path(into) if into else data_dir()
    read = None
    for name, f in FILES.items():
        target = root / f.path
        if target.is_file() and sha256(target.read_bytes()) == f.sha256:
            log(f"  {name:17s} {f.path}: present")
            continue
        read = read or reader(source)
        content = read(f.path)
        if sha256(content) != f.sha256 and sha256(content.replace(b"\r\n", b"\n")) == f.sha256:
            content = content.replace(b"\r\n", b"\n")
        if sha256(content) != f.sha256:
            raise WalkDataError(f"{f.path}: SHA-256 {sha256(content)[:16]}... is not the pinned "
                                f"{f.sha256[:16]}... of {REPOSITORY} at {COMMIT[:12]}")
        target.parent.mkdir(parents=True, exist_ok=True)
        partial = target.with_name(target.name + ".part")
        partial.write_bytes(content)
        partial.replace(target)
        log(f"  {name:17s} {f.path}: {len(content)} bytes, SHA-256 checked")
    return walk_files(root)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog="fetch-gait-data", description=f"Fetch the Gait10dof18musc walk of {REPOSITORY} "
        f"at {COMMIT[:12]} into a cache directory (not redistributed with vm_ros: its data "
        "files carry no licence).")
    parser.add_argument("--source", help=f"URL base (default {RAW_URL}), a checkout or a bare "
                        "clone of the repository")
    parser.add_argument("--into", type=Path, help=f"cache directory (default {data_dir()})")
    args = parser.parse_args(argv)
    try:
        root = args.into or data_dir()
        print(f"Gait10dof18musc walk of {REPOSITORY} at {COMMIT[:12]} -> {root}")
        fetch(args.source, root)
    except WalkDataError as exc:
        print(f"fetch-gait-data: {exc}", file=sys.stderr)
        return 2
    return 0


__all__ = ["COMMIT", "FILES", "PREFIX", "REPOSITORY", "WalkDataError", "WalkFile", "data_dir",
           "fetch", "walk_files"]

if __name__ == "__main__":
    sys.exit(main())
