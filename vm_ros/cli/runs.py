"""Options and helpers shared by the verbs that run the model offline (simulate, recompute)."""

from __future__ import annotations

import argparse
import math
import signal
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

from vm_ros.errors import VmRosError
from vm_ros.model import SCHEMES
from vm_ros.model.params import DRIVE_LAWS, RECOVERY_MODES
from vm_ros.model.run_config import RunConfig, parse_overrides
from vm_ros.recording.writer import FLUSH_INTERVAL_S


@dataclass(frozen=True)
class RunOutcome:
    """What a finished offline run computed (simulate, recompute), handed to the caller of the
    verb's ``run(args, on_outcome)`` (vm_ros.study): the numbers its summary printed.

    | field | meaning |
    | --- | --- |
    | muscles | per muscle: force statistics, energy per fibre type and component, work
      (vm_ros.report.summary.MuscleSummary) |
    | model_totals | per published energetics model, energy per muscle (ModelTotals; Tsianos
      2012 first; [] without energetics models) |
    | duration_s | model time simulated (s) |
    """

    muscles: list
    model_totals: list
    duration_s: float


def add_model_options(parser, defaults_from: str) -> None:
    """--recruitment, --recovery-mode, --drive-law, --override, --params, --library,
    --units-per-type."""
    group = parser.add_argument_group(f"model (default: {defaults_from})")
    group.add_argument("--recruitment", choices=SCHEMES, help="recruitment scheme")
    group.add_argument("--recovery-mode", choices=RECOVERY_MODES,
                       help="recovery energy: static ratio or dynamic (filtered)")
    group.add_argument("--drive-law", choices=DRIVE_LAWS,
                       help="drive filter of lumped units: relative_drive (follows natural "
                            "units) or tsianos2012 (the paper's, as reconstructed)")
    group.add_argument("--override", action="append", default=[], metavar="MUSCLE.FIELD=VALUE",
                       help="change one muscle-library field, e.g. vasti.fpcsa_slow=0.5 "
                            "(repeatable)")
    group.add_argument("--params", type=Path, metavar="MODEL.yaml",
                       help="model-parameter file instead")
    group.add_argument("--library", type=Path, metavar="MUSCLES.yaml",
                       help="muscle-library file instead")
    group.add_argument("--units-per-type", type=int, metavar="N",
                       help="motor units per fibre type (natural recruitment)")


def flush_interval_s(text: str) -> float:
    """argparse type of --flush-interval: a finite number of seconds > 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds, got {text!r}") from None
    if not (0 < value < math.inf):
        raise argparse.ArgumentTypeError(f"must be a finite number of seconds > 0, got {text!r}")
    return value


# --log-writer: whether the log's McapRecorder writes from a background thread
LOG_WRITERS = {"thread": True, "caller": False}


def add_output_options(parser, default_out: str) -> None:
    """--out, --publish-rate, --telemetry-rate, --chunk-size, --flush-interval, --log-writer,
    --max-bag-size, --max-bag-duration, --progress."""
    group = parser.add_argument_group("output")
    group.add_argument("--out", type=Path, metavar="FILE.mcap|NAME",
                       help=f"log file ({default_out}); a path without .mcap is a rosbag2 bag "
                            f"directory NAME/ (NAME_0.mcap and metadata.yaml), as `ros2 bag "
                            f"record -o NAME` makes")
    group.add_argument("--publish-rate", type=float, metavar="HZ",
                       help="rate of the output channels (default 100 Hz)")
    group.add_argument("--telemetry-rate", type=float, metavar="HZ",
                       help="rate of muscle_telemetry records, 0 for none (default 100 Hz)")
    group.add_argument("--chunk-size", type=int, default=1 << 20, metavar="BYTES",
                       help="MCAP chunk size before compression (default 1 MiB); a crash loses "
                            "at most the open chunk, smaller chunks compress less")
    group.add_argument("--flush-interval", type=flush_interval_s, default=FLUSH_INTERVAL_S,
                       metavar="S",
                       help=f"longest wall time (s) a message waits before its chunk is written "
                            f"to the file: what a crash can lose (default {FLUSH_INTERVAL_S:g})")
    group.add_argument("--log-writer", choices=LOG_WRITERS, default="thread",
                       help="who compresses and writes the log: a background thread while the "
                            "run goes on (thread, the default: the shorter wall time), or the "
                            "run's own thread (caller: less CPU in all, one core per run, as "
                            "a study's workers write theirs)")
    group.add_argument("--max-bag-size", type=int, default=0, metavar="BYTES",
                       help="with a bag directory --out NAME: start a new file NAME_<k>.mcap once "
                            "the current one holds this many bytes (default 0: one file)")
    group.add_argument("--max-bag-duration", type=float, default=0.0, metavar="S",
                       help="with a bag directory: start a new file once the current one spans "
                            "this much log time (default 0: one file)")
    group.add_argument("--progress", action="store_true",
                       help="show progress on stderr even when it is not a terminal")


def recorder_options(args) -> dict:
    """McapRecorder options of the output options:
    ``open_run_log(path, info, bank, **recorder_options(args))``."""
    return {"chunk_size": args.chunk_size, "flush_interval_s": args.flush_interval,
            "background": LOG_WRITERS[args.log_writer],
            "max_file_size": args.max_bag_size, "max_file_duration_s": args.max_bag_duration}


def apply_model_options(config: RunConfig, args) -> RunConfig:
    """``config`` with the command line's model options applied on top."""
    changes = {key: getattr(args, key) for key in
               ("recruitment", "recovery_mode", "drive_law", "params", "library",
                "units_per_type")
               if getattr(args, key) is not None}
    return config.replace(**changes).with_overrides(parse_overrides(args.override))


def default_log_path(stem: str, directory=Path("out")) -> Path:
    """``directory/<stem>-<date>-<time>.mcap`` (local time): ``out/`` for a run with no input
    log (simulate), the input log's folder for a run made from one (recompute)."""
    return Path(directory) / f"{stem}-{time.strftime('%Y%m%d-%H%M%S')}.mcap"


def beside(log_path) -> tuple[Path, str]:
    """(folder, name stem) of an input log, file or bag directory, for the files written
    beside it: ``runs/knee.mcap`` and ``runs/knee`` (a bag directory) -> (runs, knee)."""
    path = Path(log_path)
    if not path.name:  # ".", "/": name the folder itself
        path = path.resolve()
    return path.parent, path.stem


class InputWarnings:
    """Inputs a user may mean but that change the result (an excitation file that covers only
    part of the run, motion frames outside the geometry's box, ...): each is printed on stderr
    when found and repeated at the end of the summary (``closing_lines``); with ``strict``
    (--strict) the first one is an error instead (VmRosError, exit 2)."""

    def __init__(self, verb: str, strict: bool):
        self.verb = verb
        self.strict = strict
        self.items: list[str] = []

    def extend(self, texts) -> None:
        for text in texts:
            if self.strict:
                raise VmRosError(f"{text} (an error with --strict)")
            self.items.append(text)
            print(f"vm-ros {self.verb}: warning: {text}", file=sys.stderr)

    def closing_lines(self) -> list[str]:
        if not self.items:
            return []
        return [f"{len(self.items)} input warning(s), the numbers above depend on them "
                "(--strict makes them errors):", *(f"  {text}" for text in self.items)]


def add_strict_option(parser) -> None:
    parser.add_argument("--strict", action="store_true",
                        help="make every input warning (inputs that cover only part of the run, "
                             "values clamped to the geometry's box, ...) an error, exit 2")


class StopOnSignal:
    """While active, SIGINT and SIGTERM only set ``signum``, so a run can stop between two steps
    and finish its log cleanly: ``with StopOnSignal() as stop: ... if stop.signum: break``.
    Outside the main thread (a run on a Dask worker: vm_ros.study.task) nothing is installed,
    since Python delivers signals to the main thread only; the process's owner stops it."""

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self):
        self.signum: int | None = None
        self._previous = {}

    def _handle(self, signum, frame) -> None:
        self.signum = signum

    def __call__(self) -> bool:
        return self.signum is not None

    def __enter__(self) -> StopOnSignal:
        if threading.current_thread() is not threading.main_thread():
            return self
        for sig in self.SIGNALS:
            self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def __exit__(self, *exc) -> None:
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)

    @property
    def exit_code(self) -> int:
        return 128 + int(self.signum) if self.signum else 0
