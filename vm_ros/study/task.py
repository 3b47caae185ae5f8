"""One study run on a worker: the run's verb (``vm-ros simulate`` or ``recompute``) with its own
options, runner and log writer.

The run's rows are the numbers its summary printed (vm_ros.cli.runs.RunOutcome). The log is
written under a temporary name beside its final one and renamed when the run has
finished, so ``runs/<run id>.mcap`` is always a complete log, whichever worker wrote it and
however often the run was started. What the verb prints goes to ``runs/<run id>.txt``, with
the log's final name.

A run that fails for a reason of its own (a VmRosError: an unreadable input, a model file that
does not build; or a log that could not be written: disk full) returns a record with status
``failed`` and the one-line error, as does a run that computed no step (dt longer than the
run), which has no rows; any other exception propagates, so that Dask retries the run
(the study's ``retries``) and the client records it if it still fails.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import threading
import time
import uuid
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vm_ros import telemetry as tm
from vm_ros.errors import VmRosError, plain_value

STATUS_OK, STATUS_FAILED = "ok", "failed"
# A chunk of a study run's log is closed by its size alone (not after a wall time), so that a run
# with a fixed start time writes the same bytes on any worker; a run cut short is rerun whole.
FLUSH_INTERVAL_S = 3600.0
# A worker process has one core (one worker per core, one thread each): the run writes its own
# log rather than a second thread competing for the other workers' cores (docs/studies.md).
LOG_WRITER = "caller"
# one run at a time per worker process: a run's output is captured by redirecting sys.stdout
_RUN_LOCK = threading.Lock()


@dataclass(frozen=True)
class Verb:
    """An offline verb as the study runs it: its name, ``add_arguments(parser)`` and
    ``run(args, on_outcome) -> exit status`` (vm_ros.cli.simulate, vm_ros.cli.recompute; the
    command line hands them in, and Dask sends them to the workers by reference)."""

    name: str
    add_arguments: Callable
    run: Callable


@dataclass(frozen=True)
class RunTask:
    """What a worker needs for one run (picklable): the run's id, its verb and arguments, its
    log path (``runs/<run id>.mcap`` of the study folder, which the workers must see) and the
    log time of model time 0 (None: the wall clock at the start, as the verbs do)."""

    run_id: str
    verb: Verb
    argv: tuple
    log_path: str
    start_time_ns: int | None = None


class _Parser(argparse.ArgumentParser):
    """The verb's parser, raising instead of exiting."""

    def error(self, message):
        raise VmRosError(f"arguments: {message}")


def _last_error(text: str, verb: str) -> str:
    """The verb's last ``error:`` line on stderr, without its prefix."""
    prefix = f"vm-ros {verb}: error: "
    lines = [line for line in text.splitlines() if line.startswith(prefix)]
    return lines[-1][len(prefix):] if lines else ""


def one_line(error: BaseException) -> str:
    """An exception as one line: its type (unless a VmRosError) and the first line of its
    text (:func:`error_text`)."""
    text = (error_text(error).splitlines() or [""])[0]
    return text if isinstance(error, VmRosError) else f"{type(error).__name__}: {text}"


def error_text(error: BaseException) -> str:
    """The exception's text; when it has none, that of the same exception made again from its
    args, else its repr (cut). An exception that Dask carried back from a worker (pickled with
    tblib) can lose the text its class builds from its fields: a UnicodeDecodeError arrived
    with an empty text and its args intact."""
    text = str(error).strip()
    if not text and error.args:
        with contextlib.suppress(Exception):
            text = str(type(error)(*error.args)).strip()
    return text or plain_value(error)


def execute(task: RunTask) -> dict:
    """Run ``task``: the record {run_id, status, error, rows, wall_s, worker}."""
    final = Path(task.log_path)
    partial = _partial_log(final, uuid.uuid4().hex[:8])
    argv = [*task.argv, "--out", str(partial), "--flush-interval", repr(FLUSH_INTERVAL_S),
            "--log-writer", LOG_WRITER]
    if task.start_time_ns is not None and task.verb.name != "recompute":  # keeps its log's
        argv += ["--start-time", str(task.start_time_ns)]
    record = {"run_id": task.run_id, "status": STATUS_FAILED, "error": "", "rows": [],
              "worker": f"{os.uname().nodename}:{os.getpid()}"}
    start = time.perf_counter()
    out, err = io.StringIO(), io.StringIO()
    try:
        parser = _Parser(prog=f"vm-ros {task.verb.name}")
        task.verb.add_arguments(parser)
        args = parser.parse_args(argv)
        outcomes = []
        with _RUN_LOCK, contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            code = int(task.verb.run(args, on_outcome=outcomes.append) or 0)
        if code == 0 and outcomes and not outcomes[0].muscles:
            record["error"] = no_step_error(outcomes[0], args)
        elif code == 0 and outcomes:
            os.replace(partial, final)
            record.update(status=STATUS_OK, rows=outcome_rows(outcomes[0]))
        else:
            record["error"] = (_last_error(err.getvalue(), task.verb.name)
                               or f"exit status {code}")
    except (VmRosError, OSError) as error:
        record["error"] = one_line(error)
    finally:
        record["wall_s"] = time.perf_counter() - start
        with contextlib.suppress(OSError):
            partial.unlink(missing_ok=True)
        printed = out.getvalue() + err.getvalue()
        if record["status"] == STATUS_OK:  # the verb printed the log's temporary name
            printed = printed.replace(str(partial), str(final))
        with contextlib.suppress(OSError):  # best effort: the record carries the error
            final.with_suffix(".txt").write_text(printed)
    return record


def no_step_error(outcome, args) -> str:
    """The one-line error of a run that finished without a step (no muscle summary, so no
    rows): its time step is longer than the run."""
    given = ", ".join(f"--{name} {value:g}" for name in ("dt", "duration")
                      if (value := getattr(args, name, None)) is not None)
    return (f"the run computed no step ({outcome.duration_s:g} s of model time, {given}): "
            "dt is longer than the run")


def partial_logs(task: RunTask) -> list[Path]:
    """The run's logs still under a temporary name: left by a worker that died mid-run (SIGKILL,
    out of memory), whose run Dask started again elsewhere."""
    final = Path(task.log_path)
    return sorted(final.parent.glob(_partial_log(final, "*").name))


def _partial_log(final: Path, tag: str) -> Path:
    """A log being written: ``.<run id>-<tag>.mcap`` beside its final name."""
    return final.with_name(f".{final.stem}-{tag}.mcap")


def outcome_rows(outcome) -> list[dict]:
    """One dict per muscle of a finished run (vm_ros.cli.runs.RunOutcome): model time
    simulated, force statistics, mechanical work, energy per fibre type and component (J), each
    published model's energy (J)."""
    from vm_ros.report.tables import TSIANOS

    models = [m for m in outcome.model_totals if m.model != TSIANOS]
    rows = []
    for i, summary in enumerate(outcome.muscles):
        row = {"muscle": summary.name, "duration_s": outcome.duration_s,
               "peak_force_N": summary.peak_force, "mean_force_N": summary.mean_force,
               "mechanical_work_J": summary.mechanical_work}
        for j, fibre in enumerate(tm.FIBRE_LABELS):
            for k, component in enumerate(tm.COMPONENT_LABELS):
                row[energy_column(fibre, component)] = summary.energy[j, k]
        for model in models:
            row[model_column(model.model)] = model.energy[i]
        rows.append({key: (float(value) if isinstance(value, (float, np.floating)) else value)
                     for key, value in row.items()})
    return rows


def energy_column(fibre: str, component: str) -> str:
    return f"{fibre}.{component}_energy_J"


def model_column(model: str) -> str:
    return f"{model}.energy_J"
