"""Joint-space benchmarks (no ROS; extra ``mujoco`` with myo-sim): the geometry of the myo-sim
leg evaluated three ways, and the closed loop in one process. ``vm-ros bench --only joint`` adds
muscle_node from joint_states (vm_ros_bench.node_bench.run_joint_node_benchmark).

- Geometry (``bench_geometry``): one ``evaluate(q, qdot)`` call (path lengths, lengthening
  velocities and moment arms of every muscle, with the box checks and clamping a caller gets) of
  the myolegs polynomial geometry with the compiled (Numba) and the NumPy evaluator, and of
  ``MujocoGeometry`` (MuJoCo's exact tendons: mj_kinematics, mj_comPos, mj_tendon and the dense
  tendon Jacobian), at poses drawn uniformly inside the boxes with velocities uniform in
  +-``QDOT_MAX`` per second; and the torque product ``generalized_forces(r, F)``. The polynomial
  against MuJoCo at those poses is reported beside (largest length and moment-arm differences).
- Closed loop (``bench_closed_loop``): ``ClosedLoop.run`` (vm_ros.closed_loop) wall time per
  simulated second at 1 ms steps, from the middle of every box, with the alternating pulses about
  the first coordinate that ``vm-ros closed-loop`` uses by default. myolegs twice: with its root
  free joint removed from the model (the pelvis welded where the model places it: closed_loop.py
  has no option for this, the bench edits the MjSpec before compiling), and as shipped (the body
  falls onto the floor; the root height at the start and end of the last repeat is reported).

- Motion (``bench_motion``): `vm-ros simulate --motion` in this process over MOTION_S of
  myolegs motion (every coordinate a sinusoid inside its box, frames at 100 Hz, drive 0.2 for
  every muscle of the imported library; model 1 kHz, inputs 1 kHz, publish 100 Hz, log written),
  against the model alone (MuscleBank.run of the same muscles over as many steps, fixed inputs)
  measured right before it in each repeat: wall time (target < 1 s), the process's CPU time
  over the run (``simulate_cpu_s``: the log's writer thread included; less inflated than the
  wall time on a busy machine) and the paired ratio.

The myolegs geometry and muscle library come from ``vm-ros import-mjcf``'s Python API
(``import_myolegs``), imported once into a cache folder and reused while the model, the import
options and the MuJoCo, myo-sim and vm_ros versions are the same. The quick variant imports
with degree 3 over 100 poses (much faster, docs/performance.md; fewer polynomial terms, so its
geometry timings are smaller than the full import's and not comparable).

Timings are wall-clock medians over repeats (``time.perf_counter``), with min and max.
"""

from __future__ import annotations

import hashlib
import importlib.util
import io
import json
import statistics
import time
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np

import vm_ros

MODEL = "myolegs"
DT_S = 1e-3
QDOT_MAX = 2.0                  # rad/s (m/s): joint velocities drawn in +-QDOT_MAX
FORCE_MAX_N = 1000.0            # tensions drawn in [0, FORCE_MAX_N] for generalized_forces
POSES = 1000                    # random poses cycled through by the geometry timings
ACCURACY_POSES = 200            # of them, compared against MuJoCo
IMPORTS = {"full": {"degree": 6, "samples": 1000},      # vm-ros import-mjcf's defaults
           "quick": {"degree": 3, "samples": 100}}
STAMP = "bench_import.json"
MOTION_S = 10.0                 # seconds of motion of bench_motion
MOTION_FRAME_S = 0.01           # its frame interval
MOTION_TARGET_S = 1.0           # issue 33: 10 s of myolegs motion in < 1 s in process
IMPORTER_MODULES = ("importers/mjcf.py", "importers/common.py", "geometry/fit.py",
                    "geometry/file.py", "geometry/mujoco_backend.py")


def missing_extra() -> str | None:
    """Why the joint benchmarks cannot run here (None: they can)."""
    for module, extra in (("mujoco", "mujoco"), ("myo_sim", "mujoco")):
        if importlib.util.find_spec(module) is None:
            return (f"needs the {extra} extra ({module} is not installed): "
                    f"pip install 'vm_ros[{extra}]'")
    return None


def _versions() -> dict:
    """MuJoCo's, myo-sim's and vm_ros's versions, and a digest of the importer's code (a changed
    importer or fit invalidates a cached import even at the same vm_ros version)."""
    import mujoco
    import myo_sim

    from vm_ros.recording.versions import VM_ROS_VERSION

    root = Path(vm_ros.__file__).parent
    digest = hashlib.sha256()
    for module in IMPORTER_MODULES:
        digest.update((root / module).read_bytes())
    return {"mujoco": mujoco.__version__, "myo_sim": myo_sim.__version__,
            "vm_ros": VM_ROS_VERSION, "importer_sha256": digest.hexdigest()[:16]}


def import_myolegs(folder, quick: bool = False, progress=None) -> dict:
    """geometry.yaml and muscles.yaml of ``vm-ros import-mjcf myolegs`` in ``folder``, imported
    unless a previous import with the same options and versions is there (its record:
    ``bench_import.json``). Returns the record: paths, options, versions, seconds, reused."""
    from vm_ros.importers.mjcf import MjcfOptions, import_mjcf

    folder = Path(folder)
    options = IMPORTS["quick" if quick else "full"]
    wanted = {"model": MODEL, "options": options, "versions": _versions()}
    stamp = folder / STAMP
    geometry, library = folder / "geometry.yaml", folder / "muscles.yaml"
    try:
        record = json.loads(stamp.read_text())
    except (OSError, ValueError):
        record = None
    if (record and geometry.is_file() and library.is_file()
            and all(record.get(k) == v for k, v in wanted.items())):
        return {**record, "reused": True}
    if progress:
        progress(f"importing {MODEL} (degree {options['degree']}, {options['samples']} poses) "
                 f"into {folder} ...")
    folder.mkdir(parents=True, exist_ok=True)
    stamp.unlink(missing_ok=True)
    log = io.StringIO()
    started = time.perf_counter()
    result = import_mjcf(MODEL, folder, MjcfOptions(**options), file=log)
    record = {**wanted, "geometry": str(geometry), "library": str(library),
              "import_s": time.perf_counter() - started,
              "library_muscles": len(result.library.entries),
              "left_out": list(result.library.excluded)}
    (folder / "import.log").write_text(log.getvalue())
    stamp.write_text(json.dumps(record, indent=2) + "\n")
    return {**record, "reused": False}


def time_calls(call: Callable, arguments: list, repeats: int = 7,
               min_seconds: float = 0.2) -> dict:
    """Wall time (s) per ``call(*arguments[k])``, cycling through ``arguments``: median, min and
    max over ``repeats`` blocks of calls, each block about ``min_seconds`` long; and the median
    of the thread's CPU time per call (``cpu_median_s``: on a busy machine the wall time also
    holds the time other processes had the core)."""
    for args in arguments[:20]:  # warm-up (compilation, caches)
        call(*args)
    count = len(arguments)
    start, probe = time.perf_counter(), 0
    while time.perf_counter() - start < 0.05 and probe < 2000:
        call(*arguments[probe % count])
        probe += 1
    block = int(min(20000, max(5, min_seconds * probe / (time.perf_counter() - start))))
    samples, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.thread_time()
        for k in range(block):
            call(*arguments[k % count])
        samples.append((time.perf_counter() - t0) / block)
        cpu.append((time.thread_time() - c0) / block)
    return {"median_s": statistics.median(samples), "min_s": min(samples),
            "max_s": max(samples), "cpu_median_s": statistics.median(cpu),
            "calls_per_repeat": block, "repeats": repeats}


def _timing_us(timing: dict) -> dict:
    return {"call_us": 1e6 * timing["median_s"], "call_us_min": 1e6 * timing["min_s"],
            "call_us_max": 1e6 * timing["max_s"], "call_cpu_us": 1e6 * timing["cpu_median_s"],
            "calls_per_repeat": timing["calls_per_repeat"],
            "repeats": timing["repeats"]}


def bench_geometry(geometry_path, repeats: int = 7, min_seconds: float = 0.2, seed: int = 0,
                   progress=None) -> dict:
    """Per-call cost of evaluate(q, qdot) (compiled, NumPy, MuJoCo exact) and of
    generalized_forces at random poses inside the boxes (module docstring)."""
    from vm_ros.geometry import generalized_forces, load_geometry
    from vm_ros.geometry import kernel as geometry_kernel
    from vm_ros.geometry.mujoco_backend import MujocoGeometry

    numpy_geometry = load_geometry(geometry_path, backend="numpy")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # myo-sim's composed models warn about empty prefixes
        exact = MujocoGeometry(MODEL, muscles=numpy_geometry.muscle_names)
    rng = np.random.default_rng(seed)
    n_q = len(numpy_geometry.coordinates)
    q = numpy_geometry.lower + (numpy_geometry.upper - numpy_geometry.lower) * rng.random(
        (POSES, n_q))
    qdot = QDOT_MAX * (2 * rng.random((POSES, n_q)) - 1)
    # the same poses in MuJoCo's coordinate order (coordinates no fitted path crosses: middle)
    q_exact = np.tile((exact.lower + exact.upper) / 2, (POSES, 1))
    qdot_exact = np.zeros_like(q_exact)
    columns = [exact.coordinate_index(c) for c in numpy_geometry.coordinate_names]
    q_exact[:, columns], qdot_exact[:, columns] = q, qdot
    packed = numpy_geometry.packed
    out = {"model": MODEL, "geometry_file": str(geometry_path),
           "muscles": len(numpy_geometry.muscle_names), "coordinates": n_q,
           "polynomial_terms": int(len(packed.term_coefficient)),
           "largest_degree": packed.max_degree, "mujoco_coordinates": len(exact.coordinates),
           "poses": POSES, "qdot_max_per_s": QDOT_MAX, "rows": []}
    backends = [("compiled", None), ("numpy", numpy_geometry), ("mujoco", exact)]
    for backend, geometry in backends:
        if backend == "compiled":
            if not geometry_kernel.available():
                out["rows"].append({"backend": backend, "call": "evaluate",
                                    "skipped": "numba not importable"})
                continue
            geometry = load_geometry(geometry_path, backend="compiled")
        poses = (list(zip(q_exact, qdot_exact, strict=True)) if backend == "mujoco"
                 else list(zip(q, qdot, strict=True)))
        timing = time_calls(geometry.evaluate, poses, repeats, min_seconds)
        out["rows"].append({"backend": backend, "call": "evaluate", **_timing_us(timing)})
        if progress:
            progress(f"geometry evaluate {backend}: {out['rows'][-1]['call_us']:.1f} us "
                     f"(thread CPU {out['rows'][-1]['call_cpu_us']:.1f} us)")
    moment_arm = numpy_geometry.evaluate(q[0], qdot[0]).moment_arm
    forces = [(moment_arm, f) for f in FORCE_MAX_N * rng.random((POSES, len(moment_arm)))]
    out["rows"].append({"backend": "numpy", "call": "generalized_forces",
                        **_timing_us(time_calls(generalized_forces, forces, repeats,
                                                min_seconds))})
    out.update(_against_mujoco(numpy_geometry, exact, q[:ACCURACY_POSES],
                               q_exact[:ACCURACY_POSES]))
    return out


def _against_mujoco(polynomial, exact, q, q_exact) -> dict:
    """Largest |L| and |r| differences (mm) of the polynomial against MuJoCo at the poses, over
    every muscle and the coordinates of the polynomial."""
    columns = [exact.coordinate_index(c) for c in polynomial.coordinate_names]
    length, arm = 0.0, 0.0
    for pose, pose_exact in zip(q, q_exact, strict=True):
        a, b = polynomial.evaluate(pose), exact.evaluate(pose_exact)
        length = max(length, float(np.abs(a.length_m - b.length_m).max()))
        arm = max(arm, float(np.abs(a.moment_arm - b.moment_arm[:, columns]).max()))
    return {"length_max_diff_vs_mujoco_mm": 1e3 * length,
            "moment_arm_max_diff_vs_mujoco_mm": 1e3 * arm, "compared_poses": len(q)}


# ---------------------------------------------------------------------------- closed loop


def fixed_root_model(name: str):
    """The myo-sim model ``name`` compiled with its free joints removed (those bodies welded
    where the model places them)."""
    import mujoco
    import myo_sim

    from vm_ros.geometry.mujoco_backend import quiet_mujoco

    with quiet_mujoco():
        spec = myo_sim.load_spec(name)
        free = [j for j in spec.joints if j.type == mujoco.mjtJoint.mjJNT_FREE]
        for joint in free:
            spec.delete(joint)
        return spec.compile(), [j.name for j in free]


def derived_library(geometry, path) -> Path:
    """A muscle library derived the MuJoCo way, as ``vm-ros closed-loop`` does without
    --library, written to ``path``."""
    from vm_ros.importers import common, mjcf

    choices = common.ImportChoices(common.specific_tension_option("rajagopal"))
    library = mjcf.derive_library(geometry, choices, *mjcf.path_extremes(geometry))
    return common.write_library(path, library.entries,
                                f"Derived the MuJoCo way from {geometry.source['model']} "
                                "(vm-ros bench)")


def closed_loop_cases(myolegs_library, cache) -> list[dict]:
    """The benchmark's cases: myoelbow (derived library in ``cache``), myolegs with its root
    fixed and free (``myolegs_library``: the imported library)."""
    cases = [{"model": "myoelbow", "fix_root": False, "root": "fixed base", "library": None}]
    if myolegs_library is not None:
        cases += [{"model": MODEL, "fix_root": True, "root": "pelvis fixed",
                   "library": myolegs_library},
                  {"model": MODEL, "fix_root": False, "root": "pelvis free",
                   "library": myolegs_library}]
    for case in cases:
        case["cache"] = Path(cache)
    return cases


def bench_closed_loop(cases: list[dict], duration_s: float = 2.0, repeats: int = 7,
                      progress=None) -> list[dict]:
    """Wall time per simulated second of ClosedLoop.run for each case (module docstring)."""
    from vm_ros.closed_loop import ClosedLoop, pulse_excitation
    from vm_ros.geometry.mujoco_backend import MujocoGeometry
    from vm_ros.model import MuscleBank, load_muscle_library

    rows = []
    for case in cases:
        removed = []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if case["fix_root"]:
                model, removed = fixed_root_model(case["model"])
                geometry = MujocoGeometry(model)
            else:
                geometry = MujocoGeometry(case["model"])
        library = case["library"] or derived_library(
            geometry, case["cache"] / case["model"] / "muscles.yaml")
        known = load_muscle_library(library)
        names = [m for m in geometry.muscle_names if m in known]
        bank = MuscleBank.from_config(names, library=library)
        q0 = (geometry.lower + geometry.upper) / 2
        excitation = pulse_excitation(geometry.evaluate(q0).moment_arm[:, 0],
                                      geometry.coordinate_names[0])
        loop = ClosedLoop(geometry, bank, DT_S)
        walls, result, root = [], None, None
        for k in range(repeats + 1):  # the first: warm-up (compilation, caches), not counted
            loop.reset(q0, excitation(0.0)[loop.rows])
            height0 = float(loop.data.qpos[2]) if case["root"] == "pelvis free" else None
            result = loop.run(duration_s if k else 10 * DT_S, excitation)
            if k:
                walls.append(result.wall_per_sim_s)
            if height0 is not None:
                root = (height0, float(loop.data.qpos[2]))
        steps = len(result.force)
        rows.append({
            "model": case["model"], "root": case["root"], "muscles": bank.n,
            "model_muscles": len(geometry.muscle_names), "coordinates": len(geometry.coordinates),
            "dt_s": DT_S, "simulated_s": steps * DT_S, "repeats": repeats,
            "backend": bank.backend, "excitation": excitation.description,
            "wall_per_sim_s": statistics.median(walls), "wall_per_sim_s_min": min(walls),
            "wall_per_sim_s_max": max(walls),
            "step_us": 1e6 * statistics.median(walls) * DT_S,
            "joint_limit_steps": result.limit_steps, "contacts_at_end": int(loop.data.ncon),
            **({"free_joints_removed": removed} if removed else {}),
            **({"root_height_start_m": root[0], "root_height_end_m": root[1]} if root else {})})
        if progress:
            progress(f"closed loop {case['model']} ({case['root']}): "
                     f"{rows[-1]['wall_per_sim_s']:.3f} s per simulated s")
    return rows


def write_mot(path, times_s, names, columns_deg, title: str = "bench motion") -> Path:
    """An OpenSim .mot in degrees: ``columns_deg`` (one array per name) at ``times_s``."""
    lines = [title, "version=1", f"nRows={len(times_s)}", f"nColumns={len(columns_deg) + 1}",
             "inDegrees=yes", "endheader", "\t".join(["time", *names])]
    lines += ["\t".join(repr(float(v)) for v in (times_s[i], *(c[i] for c in columns_deg)))
              for i in range(len(times_s))]
    Path(path).write_text("\n".join(lines) + "\n")
    return Path(path)


def write_motion(geometry_path, path, duration_s: float = MOTION_S) -> Path:
    """An OpenSim .mot (degrees) of every coordinate of the geometry: coordinate j at
    mid + 0.4 (upper - lower) sin(2 pi (0.3 + 0.1 j) t), frames every MOTION_FRAME_S."""
    from vm_ros.geometry import load_geometry

    geometry = load_geometry(geometry_path)
    t = np.arange(0.0, duration_s + MOTION_FRAME_S / 2, MOTION_FRAME_S)
    columns = [np.degrees((c.lower + c.upper) / 2 + 0.4 * (c.upper - c.lower)
                          * np.sin(2 * np.pi * (0.3 + 0.1 * j) * t))
               for j, c in enumerate(geometry.coordinates)]
    return write_mot(path, t, geometry.coordinate_names, columns)


def bench_motion(imported: dict, repeats: int = 7, duration_s: float = MOTION_S,
                 progress=None) -> dict:
    """`vm-ros simulate --motion` of ``write_motion`` through the imported myolegs geometry and
    library, in this process, against the model alone (module docstring)."""
    import contextlib
    import tempfile

    from vm_ros.cli import main
    from vm_ros.model import MuscleBank, load_muscle_library

    geometry, library = imported["geometry"], imported["library"]
    known = load_muscle_library(library)
    with tempfile.TemporaryDirectory(prefix="vm_ros-bench-motion-") as tmp:
        motion = write_motion(geometry, Path(tmp) / "motion.mot", duration_s)
        arguments = ["simulate", "--motion", str(motion), "--geometry", str(geometry),
                     "--library", str(library), "--excitation", "0.2", "--out",
                     str(Path(tmp) / "motion.mcap")]
        names = None
        walls, cpus, models, text = [], [], [], ""
        for k in range(repeats + 1):  # the first: warm-up (compilation, caches), not counted
            buffer = io.StringIO()
            if names is not None:
                bank = MuscleBank.from_config(names, library=library)
                steps = int(round(duration_s / DT_S))
                lp = np.tile(bank.l0t_m + bank.l0_m, (steps, 1))
                bank.reset(lp[0])
                start = time.perf_counter()
                bank.run(DT_S, np.full_like(lp, 0.2), lp, np.zeros_like(lp))
                model_s = time.perf_counter() - start
            start, cpu_start = time.perf_counter(), time.process_time()
            with contextlib.redirect_stdout(buffer):
                code = main(arguments)
            wall, cpu = time.perf_counter() - start, time.process_time() - cpu_start
            if code != 0:
                raise RuntimeError(f"vm-ros simulate --motion exited with {code}")
            text = buffer.getvalue()
            if names is None:
                from vm_ros.geometry import load_geometry

                names = [m for m in load_geometry(geometry).muscle_names if m in known]
            if k:
                walls.append(wall)
                cpus.append(cpu)
                models.append(model_s)
    result = {"model": MODEL, "muscles": len(names), "motion_s": duration_s,
              "repeats": repeats, "simulate_s": statistics.median(walls),
              "simulate_s_min": min(walls), "simulate_s_max": max(walls),
              "simulate_cpu_s": statistics.median(cpus),
              "model_s": statistics.median(models),
              "simulate_over_model_paired": statistics.median(
                  w / m for w, m in zip(walls, models, strict=True)),
              "target_s": MOTION_TARGET_S, "log": text.strip().splitlines()[-1]}
    if progress:
        progress(f"simulate --motion {MODEL} {duration_s:g} s: {result['simulate_s']:.2f} s "
                 f"(model alone {result['model_s']:.2f} s)")
    return result


__all__ = ["IMPORTS", "bench_closed_loop", "bench_geometry", "bench_motion", "closed_loop_cases",
           "derived_library", "fixed_root_model", "import_myolegs", "missing_extra",
           "time_calls", "write_mot", "write_motion"]
