"""Input conditioning for muscle_node: message arrays in, the drive and path length each model
step uses out (no rclpy here; vm_ros.node unpacks the messages).

Every message is checked before anything is stored, so a bad message never reaches the model:
it is dropped whole (or, for unknown names, those entries are) and reported as an
:class:`~vm_ros.node.health.Issue`. Times are integer ns on the ROS clock: a sample's header stamp
when that is on the node's clock, else its receipt time (:func:`input_time_ns`).

Kinematics between samples: the path length is extrapolated with the sample's velocity for at most
``extrapolation_max_s`` (and never past ``input_timeout_s``), then held with velocity 0; the result
is clamped to the physical range.

Physical path-length range per muscle: [lo - m L0, hi + m L0] with lo = library
``path_length_min_m`` (else 0.97 L0T + 0.6 L0, the library's slack convention), hi = library
``path_length_max_m`` (else L0T + Lmax L0), m = ``path_length_margin_l0``; for a joint-driven
muscle widened to its geometry's range over the box (allow_path_range); lo never below
``vm_ros.geometry.checks.MIN_PATH_LENGTH_M`` (1 mm).

So whatever :meth:`NodeInputs.sample_many` hands a model step passes the model's input checks
(MuscleBank.check_inputs: drive, path length and velocity finite, path length > 0 m): drive is
checked finite and clipped to [0, 1], lengths and velocities are checked against these bounds
before they are stored, and extrapolated lengths are clamped into them.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from vm_ros import topics as tp
from vm_ros.geometry.checks import MIN_PATH_LENGTH_M
from vm_ros.model.jit import HAVE_NUMBA, model_cache_directory, numba
from vm_ros.node.health import Issue
from vm_ros.node.params import NodeConfig
from vm_ros.recording.run_log import stamp_on_clock


def input_time_ns(stamp_ns: int, placed_ns: int, timeout_ns: int) -> int:
    """The time of an input sample placed at model time ``placed_ns`` (its arrival, or the model
    time it arrived after: vm_ros.node.input_timeline): its header stamp when the stamp is on the
    node's clock (not zero, not after the placement, at most ``timeout_ns`` before it), else the
    placement. Kinematics are extrapolated and inputs age from this time, so a sample that came a
    few ms late continues the motion from where it was measured instead of stepping it back."""
    return int(stamp_ns) if stamp_on_clock(stamp_ns, placed_ns, timeout_ns) else int(placed_ns)


@dataclass(frozen=True)
class InputLimits:
    """Per-muscle physical ranges and the input-handling parameters (SI; times in ns)."""

    path_length_min_m: np.ndarray
    path_length_max_m: np.ndarray
    path_speed_max_m_per_s: float
    timeout_ns: int
    extrapolation_max_ns: int
    stale_policy: str

    @classmethod
    def for_bank(cls, bank, config: NodeConfig) -> InputLimits:
        lo, hi = physical_path_length_range(bank, config.path_length_margin_l0)
        timeout_ns = int(round(config.input_timeout_s * 1e9))
        return cls(
            path_length_min_m=lo,
            path_length_max_m=hi,
            path_speed_max_m_per_s=config.path_speed_max_m_per_s,
            timeout_ns=timeout_ns,
            extrapolation_max_ns=min(int(round(config.extrapolation_max_s * 1e9)), timeout_ns),
            stale_policy=config.stale_input_policy,
        )


def physical_path_length_range(bank, margin_l0: float) -> tuple[np.ndarray, np.ndarray]:
    """(lo, hi) path length (m) per muscle accepted from muscle_kinematics (module docstring)."""
    l0, l0t = bank.l0_m, bank.l0t_m
    lo = np.array([s.path_length_min_m if s.path_length_min_m is not None
                   else 0.97 * s.l0t_m + 0.6 * s.l0_m for s in bank.specs])
    hi = np.array([s.path_length_max_m if s.path_length_max_m is not None
                   else s.l0t_m + lmax * s.l0_m
                   for s, lmax in zip(bank.specs, bank.lmax, strict=True)])
    lo = np.maximum(lo - margin_l0 * l0, 0.1 * l0t)  # never down to 0: the bank needs > 0
    return lo, hi + margin_l0 * l0


def stale_behaviour(stream: str, policy: str) -> str:
    """What a stale ``stream`` ('excitation' or 'kinematics') does under ``policy``."""
    if policy == "pause":
        return "model paused until it is fresh (stale_input_policy pause)"
    if stream == "kinematics":
        return f"length held, velocity 0 (stale_input_policy {policy})"
    if policy == "zero_drive":
        return "drive 0 while stale (stale_input_policy zero_drive)"
    return "last drive held (stale_input_policy hold)"


class HeldInputs(NamedTuple):
    """The inputs a NodeInputs holds, each (rows, n): one row (held now) or a row per message or
    step (NodeInputs.hold_rows)."""

    drive: np.ndarray
    drive_seen: np.ndarray
    drive_time_ns: np.ndarray
    length_m: np.ndarray
    velocity_m_per_s: np.ndarray
    length_seen: np.ndarray
    length_time_ns: np.ndarray


def latest_rows(updated: np.ndarray) -> np.ndarray | None:
    """(k, n): for row i and column j, 1 + the last row at or before i where ``updated`` (k, n)
    is set, 0 where none is (carried's ``latest``); None when every entry is set (then row i's
    own, i + 1, in every column)."""
    if updated.all():
        return None
    k = len(updated)
    return np.maximum.accumulate(np.where(updated, np.arange(1, k + 1)[:, None], 0), axis=0)


def carried(held: np.ndarray, new: np.ndarray, latest: np.ndarray | None,
            applied: np.ndarray) -> np.ndarray:
    """(m, n): for each of ``applied`` (m,), a count of rows of ``new`` (k, n), the latest of
    those rows where it was updated (``latest``: latest_rows of the updated mask), per column,
    else ``held`` (n,) (a value stored by some messages and kept through the others): values
    picked, never computed, so the same bits as row-by-row storing."""
    rows = np.concatenate([held[None, :], np.asarray(new, dtype=held.dtype)])
    if latest is None:  # every row updated: row applied[i] as it is
        return rows[applied]
    latest = np.concatenate([np.zeros((1, latest.shape[1]), dtype=latest.dtype), latest])
    return np.take_along_axis(rows, latest[applied], axis=0)


class NodeInputs:
    """Latest valid drive and kinematics per muscle, and what a model step at time t uses.

    ``joint_driven``: names of muscles whose path kinematics come from joint_states through a
    geometry (vm_ros.joint_space, via :meth:`set_path_kinematics`): muscle_kinematics entries for
    them are ignored and counted, and their ``initial_path_length`` entries are not used.
    """

    def __init__(self, names: Sequence[str], limits: InputLimits, initial_path_length=None,
                 joint_driven: Sequence[str] = ()):
        self.names = tuple(names)
        self.n = len(self.names)
        self._index = {name: i for i, name in enumerate(self.names)}
        # every muscle in order: a message that names them so (or none, positional) is stored
        # by slices instead of index arrays (the usual message, in fewer NumPy operations)
        self._order = np.arange(self.n)
        self._order.flags.writeable = False
        unknown = [m for m in joint_driven if m not in self._index]
        if unknown:
            raise ValueError(f"joint-driven muscles {unknown} are not among {self.names}")
        self.joint_driven = np.isin(self.names, list(joint_driven))
        self._any_joint_driven = bool(self.joint_driven.any())
        # path-length ranges accepted beyond the library's (allow_path_range)
        self._allowed_lo = np.full(self.n, np.inf)
        self._allowed_hi = np.full(self.n, -np.inf)
        self.limits = limits
        self.drive = np.zeros(self.n)
        self.drive_seen = np.zeros(self.n, dtype=bool)
        self.drive_time_ns = np.zeros(self.n, dtype=np.int64)
        self.length_m = np.full(self.n, np.nan)
        if initial_path_length is not None and len(initial_path_length):
            self.length_m[:] = np.where(self.joint_driven, np.nan, initial_path_length)
        # a muscle given an initial length is not stale before its first kinematics: the
        # initial length holds (documented behaviour of initial_path_length_m)
        self.length_initial = np.isfinite(self.length_m)
        self.velocity_m_per_s = np.zeros(self.n)
        self.length_seen = np.zeros(self.n, dtype=bool)
        self.length_time_ns = np.zeros(self.n, dtype=np.int64)
        self.last_excitation_ns: int | None = None
        self.last_kinematics_ns: int | None = None
        self.drive_stale = np.ones(self.n, dtype=bool)
        # muscles whose drive does not come from the excitation topics (live coordination):
        # never stale for excitation (exempt_drive)
        self.drive_exempt = np.zeros(self.n, dtype=bool)
        self.length_stale = np.ones(self.n, dtype=bool)
        self._was_stale = {"excitation": True, "kinematics": True}
        # per topic: (names object, size) and what _select made of them, for a publisher that
        # sends the same names every time (vm_ros.recording.cdr.JointStateDecoder reuses them)
        self._selections: dict = {}

    @property
    def limits(self) -> InputLimits:
        return self._limits

    @limits.setter
    def limits(self, limits: InputLimits) -> None:
        """New limits (runtime parameters); the accepted path lengths follow."""
        self._limits = limits
        self._bounds = self._path_bounds()

    # --- messages ---------------------------------------------------------------------------

    def _where(self, muscles: np.ndarray):
        """The index that stores values of ``muscles``: a slice for every muscle in order."""
        return slice(None) if muscles is self._order else muscles

    def _select(self, topic: str, names,
                size: int) -> tuple[list, np.ndarray | None, np.ndarray]:
        """Indices into the message and into the muscles for ``names`` (or positional when
        there are no names); returns (issues, muscle index or None when rejected, message index).
        The same names tuple (the same object) and size as the topic's last message give the
        same answer without looking the names up again. Every muscle in order and nothing else:
        both indices are ``self._order``."""
        last = self._selections.get(topic)
        if last is not None and last[0] is names and last[1] == size:
            issues, muscles, entries = last[2]
            return list(issues), muscles, entries
        issues, muscles, entries = self._selection(topic, names, size)
        entries = np.asarray(entries, dtype=int)
        if (muscles is not None and size == self.n and np.array_equal(muscles, self._order)
                and np.array_equal(entries, self._order)):
            muscles = entries = self._order
        selection = issues, muscles, entries
        if isinstance(names, tuple):
            self._selections[topic] = (names, size, selection)
        issues, muscles, entries = selection
        return list(issues), muscles, entries

    def _selection(self, topic: str, names, size: int) -> tuple[list, np.ndarray | None, list]:
        if len(names) == 0:
            if size != self.n:
                text = (f"{topic}: {size} values without names, expected {self.n} (one per "
                        "muscle, in the muscles parameter order)")
                return [Issue("wrong_size", text)], None, []
            return [], np.arange(self.n), list(range(self.n))
        if len(names) != size:
            return [Issue("wrong_size", f"{topic}: {len(names)} names but {size} values")], None, []
        issues, muscles, entries = [], [], []
        unknown = [name for name in names if name not in self._index]
        if unknown:
            shown = ", ".join(repr(str(u)[:40]) for u in unknown[:3])
            issues.append(Issue("unknown_name", f"{topic}: unknown muscle name(s) {shown}",
                                count=len(unknown)))
        for entry, name in enumerate(names):
            if name in self._index:
                muscles.append(self._index[name])
                entries.append(entry)
        repeated = [self.names[i] for i, k in Counter(muscles).items() if k > 1]
        if repeated:
            issues.append(Issue("duplicate_name", f"{topic}: {repeated[0]!r} named twice"))
            return issues, None, []
        return issues, np.array(muscles, dtype=int), entries

    def _set_drive(self, topic: str, muscles, values: np.ndarray, now_ns: int) -> list[Issue]:
        # array methods and np.minimum/np.maximum: NumPy's np.all, np.any and np.clip add a
        # Python-level call each, for every input message (docs/performance.md)
        if not np.isfinite(values).all():
            return [Issue("non_finite", f"{topic}: drive is not finite ({values.tolist()[:4]})")]
        issues = []
        clipped = np.minimum(np.maximum(values, 0.0), 1.0)
        if (clipped != values).any():
            issues.append(Issue("drive_clipped", f"{topic}: drive outside [0, 1] "
                                f"({values.min():.3g} .. {values.max():.3g})"))
        where = self._where(muscles)
        self.drive[where] = clipped
        self.drive_seen[where] = True
        self.drive_time_ns[where] = now_ns
        self.last_excitation_ns = now_ns
        return issues

    def on_drive(self, topic: str, names, drive, now_ns: int) -> list[Issue]:
        """A DRIVE input (vm_ros.topics): ``names`` the muscles (empty: all, in order), or None
        for one drive per muscle in the muscles-parameter order."""
        drive = np.asarray(drive, dtype=float).ravel()
        if names is None:
            if drive.size != self.n:
                return [Issue("wrong_size", f"{topic}: {drive.size} values, expected "
                              f"{self.n} (one per muscle)")]
            return self._set_drive(topic, self._order, drive, now_ns)
        issues, muscles, entries = self._select(topic, names, drive.size)
        if muscles is None:
            return issues
        if muscles.size == 0:
            return issues
        values = drive if entries is self._order else drive[entries]
        return issues + self._set_drive(topic, muscles, values, now_ns)

    def on_excitation(self, names: Sequence[str], drive, now_ns: int) -> list[Issue]:
        """JointState on excitation: name[] muscles (or empty: all, in order), position[] drive."""
        return self.on_drive("excitation", names, drive, now_ns)

    def on_excitation_array(self, drive, now_ns: int) -> list[Issue]:
        """Float64MultiArray on excitation_array: one drive per muscle, muscles-parameter order."""
        return self.on_drive("excitation_array", None, drive, now_ns)

    @property
    def joint_driven_names(self) -> tuple[str, ...]:
        return tuple(n for n, d in zip(self.names, self.joint_driven, strict=True) if d)

    def on_kinematics(self, names: Sequence[str], length, velocity, now_ns: int) -> list[Issue]:
        """JointState on muscle_kinematics: position[] path length (m), velocity[] (m/s, or
        empty for 0). Entries for joint-driven muscles are ignored and counted."""
        return self.on_path("muscle_kinematics", names, length, velocity, now_ns)

    def on_path(self, topic: str, names, length, velocity, now_ns: int) -> list[Issue]:
        """A PATH input (vm_ros.topics): path lengths (m) and velocities (m/s, or empty for 0) of
        ``names`` (empty or None: all, in order), as on_kinematics."""
        names = () if names is None else names
        length = np.asarray(length, dtype=float).ravel()
        velocity = np.asarray(velocity, dtype=float).ravel()
        if velocity.size not in (0, length.size):
            return [Issue("wrong_size", f"{topic}: {velocity.size} velocities for "
                          f"{length.size} positions (give none or one per position)")]
        issues, muscles, entries = self._select(topic, names, length.size)
        if muscles is None or muscles.size == 0:
            return issues
        if self._any_joint_driven:
            driven = self.joint_driven[muscles]
            if driven.any():
                shown = ", ".join(self.names[i] for i in muscles[driven][:3])
                issues.append(Issue("joint_driven_kinematics", f"{topic}: {shown} driven from "
                                    "joint_states", count=int(driven.sum())))
                muscles, entries = muscles[~driven], entries[~driven]
                if muscles.size == 0:
                    return issues
        if entries is not self._order:  # (every muscle in order: the message's arrays as is)
            length = length[entries]
            velocity = velocity[entries] if velocity.size else velocity
        if not velocity.size:
            velocity = np.zeros(length.size)
        more, accepted = self.set_path_kinematics(topic, muscles, length, velocity, now_ns)
        if accepted:
            self.last_kinematics_ns = now_ns
        return issues + more

    def allow_path_range(self, muscles: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> None:
        """Also accept path lengths in [lo, hi] (m) for ``muscles`` (indices): the range a
        joint-driven muscle's geometry gives over its box, which can reach beyond the library's
        range (an importer clips Lmax into VM's 1.1-1.4 and shortens the library's maximum)."""
        self._allowed_lo[muscles] = lo
        self._allowed_hi[muscles] = hi
        self._bounds = self._path_bounds()

    def path_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) path length (m) accepted per muscle: the limits, widened by
        allow_path_range."""
        return self._bounds

    def _path_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        # never below MIN_PATH_LENGTH_M: the model needs L > 0 (MuscleBank.check_inputs), and a
        # geometry's widened range (allow_path_range) can reach 0
        lo = np.maximum(np.minimum(self.limits.path_length_min_m, self._allowed_lo),
                        MIN_PATH_LENGTH_M)
        hi = np.maximum(self.limits.path_length_max_m, self._allowed_hi)
        lo.flags.writeable = hi.flags.writeable = False
        return lo, hi

    def set_path_kinematics(self, topic: str, muscles: np.ndarray, lp: np.ndarray,
                            vp: np.ndarray, now_ns: int) -> tuple[list[Issue], bool]:
        """Store path lengths ``lp`` (m) and velocities ``vp`` (m/s) of ``muscles`` (indices)
        received at ``now_ns``, if all are finite and physical; (issues, stored). Used by
        on_kinematics and by vm_ros.joint_space for the joint-driven muscles."""
        where = self._where(muscles)
        lo, hi = (bound[where] for bound in self._bounds)
        # one test for the usual message (a NaN or an infinity fails a comparison), the
        # checks one by one only to say what is wrong
        if not (((lp >= lo) & (lp <= hi)).all()
                and (np.abs(vp) <= self.limits.path_speed_max_m_per_s).all()):
            return self._rejected(topic, muscles, lp, vp, lo, hi), False
        self.length_m[where] = lp
        self.velocity_m_per_s[where] = vp
        self.length_seen[where] = True
        self.length_time_ns[where] = now_ns
        return [], True

    def set_path_rows(self, topic: str, muscles: np.ndarray, lengths: np.ndarray,
                      velocities: np.ndarray, rows: np.ndarray,
                      now_ns: int) -> tuple[list[Issue], bool]:
        """set_path_kinematics(topic, muscles, lengths[rows], velocities[rows], now_ns): the
        checks and stores in one compiled call where Numba is available (the same comparisons
        and values); a path it would refuse goes through set_path_kinematics, which says why."""
        store = _compiled_store()
        if store is not None and store(
                lengths, velocities, rows, muscles, *self._bounds,
                float(self.limits.path_speed_max_m_per_s), self.length_m, self.velocity_m_per_s,
                self.length_seen, self.length_time_ns, int(now_ns)):
            return [], True
        return self.set_path_kinematics(topic, muscles, lengths[rows], velocities[rows], now_ns)

    def _rejected(self, topic: str, muscles, lp, vp, lo, hi) -> list[Issue]:
        """What set_path_kinematics found wrong with path kinematics it did not store."""
        if not (np.all(np.isfinite(lp)) and np.all(np.isfinite(vp))):
            return [Issue("non_finite", f"{topic}: length or velocity is not finite")]
        bad = (lp < lo) | (lp > hi)
        if np.any(bad):
            i = int(np.argmax(bad))
            return [Issue("non_physical_length", f"{topic}: {self.names[muscles[i]]} "
                          f"path length {lp[i]:.6g} m outside [{lo[i]:.4g}, "
                          f"{hi[i]:.4g}] m")]
        i = int(np.argmax(np.abs(vp) > self.limits.path_speed_max_m_per_s))
        return [Issue("non_physical_velocity", f"{topic}: {self.names[muscles[i]]} "
                      f"path velocity {vp[i]:.6g} m/s beyond "
                      f"{self.limits.path_speed_max_m_per_s:g} m/s")]

    # --- time -------------------------------------------------------------------------------

    @property
    def ready(self) -> bool:
        """Every muscle has a path length (from kinematics or initial_path_length_m)."""
        return bool(np.all(np.isfinite(self.length_m)))

    def update_staleness(self, now_ns: int) -> list[Issue]:
        """Which muscles' inputs are stale at ``now_ns`` (for the pause policy, diagnostics and
        the fresh -> stale reports; sample() judges staleness at its own time)."""
        timeout = self.limits.timeout_ns
        if (not (self._was_stale["excitation"] or self._was_stale["kinematics"])
                and now_ns - self.drive_time_ns.min() <= timeout
                and now_ns - self.length_time_ns.min() <= timeout
                and self.drive_seen.all() and self.length_seen.all()):
            return []  # fresh as at the last call: drive_stale and length_stale stay all False
        self.drive_stale = (~self.drive_seen | (now_ns - self.drive_time_ns > timeout)) \
            & ~self.drive_exempt
        self.length_stale = np.where(self.length_seen, now_ns - self.length_time_ns > timeout,
                                     ~self.length_initial)
        issues = []
        for name, stale in (("excitation", self.drive_stale), ("kinematics", self.length_stale)):
            now_stale = bool(np.any(stale))
            if now_stale and not self._was_stale[name]:
                muscles = ", ".join(n for n, s in zip(self.names, stale, strict=True) if s)
                policy = self.limits.stale_policy
                issues.append(Issue(f"stale_{name}", f"{name} stale for {muscles} (older than "
                                    f"{timeout * 1e-9:g} s)",
                                    behaviour=stale_behaviour(name, policy)))
            self._was_stale[name] = now_stale
        return issues

    def exempt_drive(self, muscles) -> None:
        """The drive of ``muscles`` (indices) comes from elsewhere (live coordination): their
        excitation is never stale (the caller replaces their drive in what sample_many gives)."""
        self.drive_exempt = self.drive_exempt.copy()
        self.drive_exempt[np.asarray(muscles, dtype=int)] = True
        self.drive_seen = self.drive_seen | self.drive_exempt
        self.drive_time_ns[self.drive_exempt] = np.iinfo(np.int64).max // 2  # never older

    @property
    def any_stale(self) -> bool:
        return bool(np.any(self.drive_stale) or np.any(self.length_stale))

    def rebase(self, now_ns: int) -> None:
        """After the clock went backwards: count the latest samples as received at ``now_ns``."""
        self.drive_time_ns[self.drive_seen] = now_ns
        self.length_time_ns[self.length_seen] = now_ns
        if self.last_excitation_ns is not None:
            self.last_excitation_ns = now_ns
        if self.last_kinematics_ns is not None:
            self.last_kinematics_ns = now_ns

    def sample(self, t_ns: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(drive, path length m, path velocity m/s) for a model step starting at ``t_ns``.

        Staleness is judged at ``t_ns`` itself, so a replay of the same messages at the same
        times gives the same inputs step by step.
        """
        return tuple(array[0] for array in self.sample_many([t_ns]))

    def sample_many(self, times_ns) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`sample` at each of ``times_ns`` (model step starts, ns) from the inputs held
        now: (drive, path length, path velocity), (k, n) each, the same values element by
        element as k calls (a batch of steps between two input messages)."""
        return self.sample_held(times_ns, self.held())

    def held(self) -> HeldInputs:
        """The inputs held now, each (1, n)."""
        return HeldInputs(*(array[None, :] for array in (
            self.drive, self.drive_seen, self.drive_time_ns, self.length_m,
            self.velocity_m_per_s, self.length_seen, self.length_time_ns)))

    def sample_held(self, times_ns, held: HeldInputs) -> tuple[np.ndarray, np.ndarray,
                                                               np.ndarray]:
        """:meth:`sample` at each of ``times_ns`` (k,) from the inputs ``held`` then, (1, n)
        (held now: sample_many) or (k, n) (a row per step: what a block of messages left
        before each step, hold_rows): (drive, path length, path velocity), (k, n) each; the
        same operations element by element whatever the shapes, so the same bits."""
        t_ns = np.asarray(times_ns, dtype=np.int64)[:, None]
        timeout = self.limits.timeout_ns
        u = np.repeat(held.drive, len(t_ns), axis=0) if len(held.drive) == 1 else \
            held.drive.copy()  # a new (k, n) array
        if self.limits.stale_policy == "zero_drive":
            drive_stale = ~held.drive_seen | (t_ns - held.drive_time_ns > timeout)
            if drive_stale.any():
                u[drive_stale] = 0.0
        since_ns = np.maximum(t_ns - held.length_time_ns, 0)
        horizon_ns = self.limits.extrapolation_max_ns  # <= timeout
        moving = held.length_seen & (since_ns < horizon_ns)
        lp = held.length_m + held.velocity_m_per_s * (np.minimum(since_ns, horizon_ns) * 1e-9
                                                      * held.length_seen)
        lo, hi = self._bounds
        clamped = np.minimum(np.maximum(lp, lo), hi)  # np.clip, faster on small arrays
        vp = np.where(moving & (clamped == lp), held.velocity_m_per_s, 0.0)
        return u, clamped, vp

    def drive_many(self, topic: str, names, drives, times_ns):
        """:meth:`on_drive` of k messages naming ``names`` (rows of ``drives`` (k, m), at
        ``times_ns``) as arrays, when each would be stored whole with no issue: (muscle index,
        the drives (k, index size)); None when one of them would not (a name unknown or
        repeated, a drive not finite or clipped): the caller hands them over one by one."""
        drives = np.asarray(drives, dtype=float)
        issues, muscles, entries = self._select(topic, names, drives.shape[1])
        if issues or muscles is None or muscles.size == 0:
            return None
        values = drives if entries is self._order else drives[:, entries]
        if not (np.isfinite(values).all() and ((values >= 0.0) & (values <= 1.0)).all()):
            return None
        return np.asarray(muscles), np.minimum(np.maximum(values, 0.0), 1.0)  # as _set_drive

    def hold_rows(self, times_ns, drive_update, path_update, applied) -> HeldInputs:
        """What k messages at ``times_ns`` leave held after the first ``applied`` (m,) of them
        (0: before the first): HeldInputs of (m, n). ``drive_update`` (muscle index, drives
        (k, m)) as drive_many gives them, ``path_update`` (updated (k, n) bool per message and
        muscle, lengths and velocities (k, n)): the path kinematics each message stored."""
        k = len(times_ns)
        applied = np.asarray(applied, dtype=int)
        times = np.asarray(times_ns, dtype=np.int64)[:, None]
        muscles, drives = drive_update
        new_drive = np.zeros((k, self.n))
        new_drive[:, muscles] = drives
        drive_set = np.zeros((k, self.n), dtype=bool)
        drive_set[:, muscles] = True
        updated, lengths, velocities = path_update
        every = np.broadcast_to(times, (k, self.n))
        seen = np.ones((k, self.n), dtype=bool)
        drive_latest, path_latest = latest_rows(drive_set), latest_rows(updated)
        return HeldInputs(
            carried(self.drive, new_drive, drive_latest, applied),
            carried(self.drive_seen, seen, drive_latest, applied),
            carried(self.drive_time_ns, every, drive_latest, applied),
            carried(self.length_m, lengths, path_latest, applied),
            carried(self.velocity_m_per_s, velocities, path_latest, applied),
            carried(self.length_seen, seen, path_latest, applied),
            carried(self.length_time_ns, every, path_latest, applied))

    def keep(self, held: HeldInputs, last_excitation_ns: int) -> None:
        """Hold the last row of ``held`` (hold_rows after every message of a block)."""
        (self.drive, self.drive_seen, self.drive_time_ns, self.length_m, self.velocity_m_per_s,
         self.length_seen, self.length_time_ns) = (array[-1].copy() for array in held)
        self.last_excitation_ns = int(last_excitation_ns)

    def ages_s(self, now_ns: int) -> dict:
        """Age (s) of the newest excitation and kinematics message; None if never received."""
        def age(t):
            return None if t is None else max(now_ns - t, 0) * 1e-9

        return {"excitation": age(self.last_excitation_ns),
                "kinematics": age(self.last_kinematics_ns)}

    def stale_names(self) -> dict:
        def names(mask):
            return [n for n, s in zip(self.names, mask, strict=True) if s]

        return {"excitation": names(self.drive_stale), "kinematics": names(self.length_stale)}


_store = None


def _compiled_store():
    """The compiled checks and stores of NodeInputs.set_path_rows (None without Numba):
    store(lengths, velocities, rows, muscles, lo, hi, speed_max, length_m, velocity_m_per_s,
    length_seen, length_time_ns, now_ns) -> stored: nothing is stored unless every muscle's
    path length lengths[rows[i]] lies in [lo, hi] of muscles[i] and |velocities[rows[i]]| <=
    speed_max (a NaN fails both, as in set_path_kinematics)."""
    global _store
    if _store is None and HAVE_NUMBA:
        with model_cache_directory():

            @numba.njit(cache=True, fastmath=False, error_model="numpy")
            def store(lengths, velocities, rows, muscles, lo, hi, speed_max, length_m,
                      velocity_m_per_s, length_seen, length_time_ns, now_ns):
                for i in range(rows.shape[0]):
                    lp, vp, m = lengths[rows[i]], velocities[rows[i]], muscles[i]
                    if not (lp >= lo[m] and lp <= hi[m] and abs(vp) <= speed_max):
                        return False
                for i in range(rows.shape[0]):
                    m = muscles[i]
                    length_m[m] = lengths[rows[i]]
                    velocity_m_per_s[m] = velocities[rows[i]]
                    length_seen[m] = True
                    length_time_ns[m] = now_ns
                return True

        _store = store
    return _store


def node_receivers(inputs: NodeInputs, on_joint_states) -> dict:
    """muscle_node's receiver of each input role (vm_ros.topics.apply_input): the drive and path
    inputs of ``inputs`` (looked up at each message), and ``on_joint_states(names, position,
    velocity, time_ns)`` for the joint inputs. The node and its replay (vm_ros.node.replay)
    both dispatch through this one map."""
    return {tp.DRIVE: lambda *values: inputs.on_drive(*values),
            tp.PATH: lambda *values: inputs.on_path(*values),
            tp.JOINTS: lambda topic, names, position, velocity, time_ns:
                on_joint_states(names, position, velocity, time_ns)}


__all__ = ["HeldInputs", "InputLimits", "NodeInputs", "carried", "input_time_ns", "latest_rows",
           "node_receivers", "physical_path_length_range"]
