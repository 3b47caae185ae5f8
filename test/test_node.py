"""muscle_node in-process: outputs equal the model run offline, layouts, bad inputs and time,
parameters, the MCAP log. Plain rclpy: a node, a probe node and one executor spun in short slices
until a predicate holds (test/conftest.py)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import set_clock, stamp_ns

from vm_ros import telemetry as tm
from vm_ros.errors import ConfigError, VmRosError
from vm_ros.model import MuscleBank
from vm_ros.node.health import ISSUE_KINDS
from vm_ros.node.inputs import physical_path_length_range

pytestmark = pytest.mark.ros

MUSCLES = ["vasti", "rectus_femoris"]
MS = 1_000_000
SIM_T0 = 1_000 * MS


@pytest.fixture(scope="module")
def lengths():
    lo, hi = physical_path_length_range(MuscleBank.from_config(MUSCLES), 0.0)
    return 0.5 * (lo + hi)


def connected(ros, node, probe) -> None:
    """Wait until the probe and the node see each other on every topic used here."""
    assert ros.spin_until(lambda: all(p.get_subscription_count() > 0 for p in (
        probe.excitation, probe.excitation_array, probe.kinematics))
        and all(p.get_subscription_count() > 0
                for p in node._publishers_by_topic.values()), timeout_s=10)


def sim_node(ros, lengths, **params):
    """A node under /clock; a tick per step unless ``batch_steps`` is given (the tests step the
    clock 1 ms at a time)."""
    params.setdefault("batch_steps", 1)
    node = ros.muscle_node(use_sim_time=True, muscles=MUSCLES, stale_input_policy="hold",
                           input_timeout_s=1000.0, **params)
    probe = ros.probe()
    connected(ros, node, probe)
    set_clock(ros, probe, node, SIM_T0)
    probe.send_kinematics(MUSCLES, lengths)
    assert ros.spin_until(lambda: node.inputs.ready, timeout_s=5)
    return node, probe


# --- outputs -------------------------------------------------------------------------------------


def test_outputs_equal_the_bank_run_offline_under_sim_time(ros, lengths, tmp_path):
    """/clock drives the model: every published force, energy rate and total equals an offline
    MuscleBank run on the same inputs, step for step; the MCAP log replays to the same forces."""
    path = tmp_path / "run.mcap"
    node, probe = sim_node(ros, lengths, mcap__enabled=True, mcap__path=str(path))
    u1, u2 = np.array([0.6, 0.2]), np.array([0.1, 0.9])
    probe.send_excitation_array(u1)
    assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, u1))
    start = SIM_T0 + MS
    set_clock(ros, probe, node, start)
    assert node.scheduler.started and node.scheduler.anchor_ns == start
    for k in range(1, 31):  # 300 steps in jumps of 10 steps
        if k == 16:
            probe.send_excitation(MUSCLES[::-1], u2[::-1])  # by name, in another order
            assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, u2))
        set_clock(ros, probe, node, start + k * 10 * MS)
    assert ros.spin_until(lambda: len(probe.energy_totals) >= 31 and len(probe.forces) >= 31)

    bank = MuscleBank.from_config(MUSCLES)
    offline = [bank.reset(path_length=lengths)]
    offline += [bank.step(1e-3, u1 if i < 150 else u2, lengths) for i in range(300)]
    assert len(probe.forces) == 31
    for msg, rate, rate_total, total in zip(probe.forces, probe.energy_rates,
                                            probe.energy_rate_totals, probe.energy_totals,
                                            strict=True):
        steps, rest = divmod(stamp_ns(msg) - start, MS)
        assert rest == 0 and steps % 10 == 0
        out = offline[steps]
        assert list(msg.name) == MUSCLES
        np.testing.assert_allclose(msg.effort, out.force, rtol=1e-12)
        np.testing.assert_allclose(msg.position, out.fascicle_length, rtol=1e-12)
        np.testing.assert_allclose(msg.velocity, out.fascicle_velocity, rtol=1e-12, atol=1e-15)
        np.testing.assert_allclose(rate.data, tm.energy_rate_array(out).ravel(), rtol=1e-12)
        assert rate_total.data == pytest.approx(out.total_energy_rate, rel=1e-12)
        assert total.data == pytest.approx(out.total_energy, rel=1e-12)
    assert probe.forces[-1].effort[1] > probe.forces[15].effort[1]  # the new drive took effect

    node.close_run_log()
    assert_log_replays(path, lengths, [np.array(m.effort) for m in probe.forces])


def test_batched_ticks_equal_the_bank_run_offline(ros, lengths, tmp_path):
    """The default: a tick every publish period (10 steps) runs the steps due in MuscleBank.run
    batches split at publish steps. Under /clock jumps of 10, 25, 30 and 40 ms (catch-up
    across publish steps, batches that start between two), every published output equals
    offline steps on the same inputs, and the log replays to the same forces."""
    path = tmp_path / "run.mcap"
    node, probe = sim_node(ros, lengths, batch_steps=0, mcap__enabled=True,
                           mcap__path=str(path))
    assert node.config.steps_per_tick == 10
    u1, u2 = np.array([0.6, 0.2]), np.array([0.1, 0.9])
    probe.send_excitation_array(u1)
    assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, u1))
    start = SIM_T0 + 10 * MS  # the timer fires every 10 ms of ROS time
    set_clock(ros, probe, node, start)
    assert node.scheduler.started and node.scheduler.anchor_ns == start
    jumps_ms = [10] * 5 + [25, 10, 30, 10, 40, 5 + 10, 10] + [10] * 5
    now, switched = start, None
    for k, jump in enumerate(jumps_ms):
        if k == 9:
            probe.send_excitation(MUSCLES[::-1], u2[::-1])
            assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, u2))
            switched = (now - start) // MS
        now += jump * MS
        set_clock(ros, probe, node, now)
    steps = (now - start) // MS
    assert node.scheduler.total_steps == steps
    assert ros.spin_until(lambda: len(probe.energy_totals) == steps // 10 + 1
                          and len(probe.forces) == steps // 10 + 1)

    bank = MuscleBank.from_config(MUSCLES)
    offline = [bank.reset(path_length=lengths)]
    offline += [bank.step(1e-3, u1 if i < switched else u2, lengths) for i in range(steps)]
    for msg, rate, total in zip(probe.forces, probe.energy_rates, probe.energy_totals,
                                strict=True):
        published, rest = divmod(stamp_ns(msg) - start, MS)
        assert rest == 0 and published % 10 == 0
        out = offline[published]
        np.testing.assert_allclose(msg.effort, out.force, rtol=1e-12)
        np.testing.assert_allclose(msg.position, out.fascicle_length, rtol=1e-12)
        np.testing.assert_allclose(rate.data, tm.energy_rate_array(out).ravel(), rtol=1e-12)
        assert total.data == pytest.approx(out.total_energy, rel=1e-12)
    assert [stamp_ns(m) for m in probe.forces] == [start + 10 * MS * i
                                                  for i in range(steps // 10 + 1)]
    node.close_run_log()
    assert_log_replays(path, lengths, [np.array(m.effort) for m in probe.forces])


def test_real_time_ticks_fall_after_whole_periods_and_run_one_batch(ros, lengths):
    """ROS time from the system clock, the default tick of one publish period (10 steps): the
    timer restarts at the model's start, so that its next call falls a whole number of periods
    after it (left in its own phase, that gap is short of a whole period by the start tick's
    wake-up delay, and every tick woken sooner in its period than the start tick ran 9 steps
    and split the next tick's 11 into two calls). In 1 s of running, about one MuscleBank call
    per publish period (a tick woken a whole period late, on a busy machine, runs two periods in
    two calls, each ending at its publish step; one woken a few steps late holds the steps past
    its publish step for the next tick instead of a second call)."""
    node = ros.muscle_node(muscles=MUSCLES, stale_input_policy="hold", input_timeout_s=1000.0)
    probe = ros.probe()
    connected(ros, node, probe)
    probe.send_excitation_array(np.array([0.4, 0.3]))
    probe.send_kinematics(MUSCLES, lengths)
    assert ros.spin_until(lambda: node.scheduler.started, timeout_s=5)
    period_ns = node.scheduler.step_ns * node.scheduler.steps_per_tick
    next_call_ns = node.get_clock().now().nanoseconds + node._model_timer.time_until_next_call()
    phase_ns = (next_call_ns - node.scheduler.anchor_ns) % period_ns
    assert phase_ns < 0.05 * period_ns, phase_ns  # the reset comes microseconds after the start

    calls = []
    for name in ("run", "step"):
        method = getattr(node.bank, name)
        setattr(node.bank, name, lambda *a, _m=method, **k: calls.append(1) or _m(*a, **k))
    ticks, steps = node.ticks, node.scheduler.total_steps
    ros.spin_for(1.0)
    ticks, periods = node.ticks - ticks, (node.scheduler.total_steps - steps) // 10
    assert ticks >= 10 and periods >= 10
    assert len(calls) <= 1.2 * periods, (len(calls), ticks, periods)


@pytest.mark.parametrize("batch_steps", [0, 1])
def test_a_non_finite_step_resets_the_model_at_that_step(ros, lengths, batch_steps):
    """A state that gives a NaN (here planted): the model is reset to equilibrium at that step
    (one model_reset issue), then runs on, also when the step is inside a batch."""
    node, probe = sim_node(ros, lengths, batch_steps=batch_steps)
    probe.send_excitation_array([0.6, 0.2])
    assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, [0.6, 0.2]))
    start = SIM_T0 + 10 * MS
    set_clock(ros, probe, node, start)
    for k in range(1, 3):
        set_clock(ros, probe, node, start + k * 10 * MS)
    state = node.bank.state
    state.fascicle_velocity_m_per_s[:] = np.nan  # as if a step had gone wrong
    node.bank.set_state(state)
    before = node.issues.counts.get("model_reset", 0)
    energy = probe.energy_totals[-1].data
    for k in range(3, 6):
        set_clock(ros, probe, node, start + k * 10 * MS)
    assert node.scheduler.total_steps == 50
    assert node.issues.counts.get("model_reset", 0) == before + 1
    assert ros.spin_until(lambda: len(probe.forces) == 6)
    assert all(np.all(np.isfinite(m.effort)) for m in probe.forces)
    assert probe.energy_totals[-1].data > energy  # the energy before the reset is kept


def test_a_periods_samples_each_drive_their_own_steps(ros, lengths, tmp_path):
    """The node runs a publish period of steps at each tick, after that period's samples came.
    Ten kinematics and drive samples stamped 1 ms apart, all received before the tick: each
    step uses the sample stamped at or before its start, as the offline run of the same
    samples does (before, every step of the period took the last one: the path length stepped
    once per period and the tendon turned that into force spikes). The log replays exactly."""
    path = tmp_path / "run.mcap"
    node, probe = sim_node(ros, lengths, batch_steps=0, mcap__enabled=True,
                           mcap__path=str(path))
    probe.send_excitation(MUSCLES, [0.3, 0.3])
    assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, [0.3, 0.3]))
    start = SIM_T0 + 10 * MS
    set_clock(ros, probe, node, start)
    assert node.scheduler.started and node.scheduler.anchor_ns == start
    periods = 4
    t = np.arange(periods * 10) * 1e-3
    swing = np.array([0.004, -0.003])  # m: the path lengths move 4 and 3 mm over a period
    length = lengths + swing * np.sin(2 * np.pi * 25 * t)[:, None]
    velocity = swing * 2 * np.pi * 25 * np.cos(2 * np.pi * 25 * t)[:, None]
    drive = 0.3 + 0.5 * (np.arange(periods * 10) % 7 == 3)[:, None] * np.array([1.0, 0.4])
    for k in range(periods):
        period_ns = start + 10 * k * MS
        set_clock(ros, probe, node, period_ns + 9 * MS, tick=False)  # no tick is due before 10
        for j in range(10):
            i = 10 * k + j
            probe.send_kinematics(MUSCLES, length[i], velocity[i], stamp_ns=period_ns + j * MS)
            probe.send_excitation(MUSCLES, drive[i], stamp_ns=period_ns + j * MS)
        last_ns = period_ns + 9 * MS  # every sample in, each at its stamp
        assert ros.spin_until(lambda: node.inputs.length_time_ns.min() == last_ns  # noqa: B023
                              and node.inputs.drive_time_ns.min() == last_ns)  # noqa: B023
        assert node.scheduler.model_time_ns == period_ns  # the samples came before the steps
        set_clock(ros, probe, node, period_ns + 10 * MS)
    assert ros.spin_until(lambda: len(probe.forces) == periods + 1)

    bank = MuscleBank.from_config(MUSCLES)
    offline = [bank.reset(path_length=lengths)]
    offline += [bank.step(1e-3, drive[i], length[i], velocity[i]) for i in range(periods * 10)]
    forces = [np.array(m.effort) for m in probe.forces]
    for k, force in enumerate(forces):
        np.testing.assert_allclose(force, offline[10 * k].force, rtol=1e-9)
    node.close_run_log()
    assert_log_replays(path, lengths, forces)


def assert_log_replays(path, lengths, forces):
    """The log holds what recomputing needs: inputs at the time the node applied them,
    conditioned as the node did (vm_ros.node.replay), from the recorded start give the
    same forces (one every 10 steps)."""
    from vm_ros.node.replay import NodeReplayInputs
    from vm_ros.recording import read_run

    run = read_run(path, raw=[tm.TOPIC_EXCITATION, tm.TOPIC_EXCITATION_ARRAY,
                              tm.TOPIC_KINEMATICS])
    assert run.complete and run.info.source == "muscle_node"
    bank = run.info.config.make_bank()
    inputs = NodeReplayInputs(run, bank)
    start, dt_ns = run.info.timing.start_time_ns, run.info.timing.dt_ns
    replayed = [bank.reset(path_length=inputs.advance_to(start)[1]).force]
    for k in range(10 * (len(forces) - 1)):
        out = bank.step(dt_ns * 1e-9, *inputs.advance_to(start + k * dt_ns))
        if (k + 1) % 10 == 0:
            replayed.append(out.force)
    np.testing.assert_allclose(np.array(replayed), np.array(forces), rtol=1e-12)
    logged = run.get(tm.TOPIC_FORCE)
    np.testing.assert_allclose(logged.fields["effort"], np.array(forces), rtol=0)
    assert np.array_equal(logged.time_ns, logged.fields["stamp_ns"])  # outputs at model time
    assert_recompute_reproduces(path, len(forces))


def assert_recompute_reproduces(path, count: int):
    """`vm-ros recompute` of the node log gives the logged outputs, by node conditioning."""
    import contextlib
    import io

    from vm_ros.cli import main
    from vm_ros.recording import read_run

    out = path.with_name(path.stem + "-recomputed.mcap")
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        assert main(["recompute", str(path), "--out", str(out)]) == 0
    assert "inputs: muscle_node conditioning" in text.getvalue()
    assert "approximate" not in text.getvalue()
    original, again = read_run(path), read_run(out)
    assert again.info.source == "recompute"
    for topic, key in ((tm.TOPIC_FORCE, "effort"), (tm.TOPIC_ENERGY_RATE, "data")):
        logged, recomputed = original.get(topic), again.get(topic)
        assert len(logged) == count
        np.testing.assert_array_equal(recomputed.time_ns, logged.time_ns)
        np.testing.assert_allclose(recomputed.fields[key], logged.fields[key], rtol=1e-9,
                                   atol=0, err_msg=topic)
    for topic in (tm.TOPIC_ENERGY_RATE_TOTAL, tm.TOPIC_ENERGY_TOTAL):
        np.testing.assert_allclose(again.get(topic).fields["data"],
                                   original.get(topic).fields["data"], rtol=1e-9, atol=0)


def test_energy_rate_layout_is_as_documented(ros, lengths):
    node = ros.muscle_node(muscles=MUSCLES, initial_path_length_m=list(lengths))
    probe = ros.probe()
    connected(ros, node, probe)
    probe.send_excitation_array([0.8, 0.4])
    assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, [0.8, 0.4]))
    n = len(probe.energy_rates)
    assert ros.spin_until(lambda: len(probe.energy_rates) >= n + 20
                          and len(probe.energy_rates) == len(probe.energy_rate_totals))
    msg = probe.energy_rates[-1]
    assert [(d.label, d.size, d.stride) for d in msg.layout.dim] == [
        ("muscle", 2, 24), ("fibre", 3, 12), ("component", 4, 4)]
    assert msg.layout.data_offset == 0
    assert tm.FIBRE_LABELS == ("slow", "fast", "all")
    assert tm.COMPONENT_LABELS == ("activation", "cross_bridge", "recovery", "total")
    data = np.array(msg.data).reshape(2, 3, 4)  # data[i*12 + j*4 + k]
    assert np.all(data >= 0) and data[0, 2, 3] > 0
    np.testing.assert_allclose(data[:, 0] + data[:, 1], data[:, 2], rtol=1e-12)  # slow + fast
    np.testing.assert_allclose(data[..., :3].sum(axis=-1), data[..., 3], rtol=1e-12)
    index = len(probe.energy_rates) - 1
    assert probe.energy_rate_totals[index].data == pytest.approx(data[:, 2, 3].sum(), rel=1e-12)
    force = probe.forces[-1]
    assert list(force.name) == MUSCLES and np.all(np.array(force.effort) > 0)


# --- bad inputs ----------------------------------------------------------------------------------


def hostile_cases(lengths):
    far = list(lengths * 1000)  # mm sent as m
    return [
        ("excitation", (["vasti"], [float("nan")]), "non_finite", 1),
        ("excitation", (["vasti", "nobody", "biceps"], [0.3, 0.2, 0.9]), "unknown_name", 2),
        ("excitation", (["vasti"], [0.1, 0.2]), "wrong_size", 1),
        ("excitation", ([], [0.1, 0.2, 0.3]), "wrong_size", 1),
        ("excitation", (["vasti"], [1e300]), "drive_clipped", 1),
        ("excitation", (["vasti", "vasti"], [0.1, 0.2]), "duplicate_name", 1),
        ("excitation_array", ([0.1],), "wrong_size", 1),
        ("excitation_array", ([float("-inf"), 0.1],), "non_finite", 1),
        ("kinematics", (MUSCLES, far), "non_physical_length", 1),
        ("kinematics", (MUSCLES, list(lengths), [1e3, 0.0]), "non_physical_velocity", 1),
        ("kinematics", (MUSCLES, [float("nan"), lengths[1]]), "non_finite", 1),
        ("kinematics", (MUSCLES, list(lengths), [0.0]), "wrong_size", 1),
        ("raw", (b"\x00\x01\x00\x00" + b"\xff" * 12,), "undecodable", 1),
    ]


def send(probe, topic, args):
    if topic == "excitation":
        probe.send_excitation(*args)
    elif topic == "excitation_array":
        probe.send_excitation_array(*args)
    elif topic == "kinematics":
        probe.send_kinematics(*args)
    else:
        probe.excitation.publish(args[0])  # bytes: published as an already serialised message


def test_each_bad_input_is_counted_and_reported_in_diagnostics(ros, lengths):
    node = ros.muscle_node(muscles=MUSCLES, initial_path_length_m=list(lengths),
                           diagnostics_period_s=0.1, input_timeout_s=1000.0)
    probe = ros.probe()
    connected(ros, node, probe)
    probe.send_excitation_array([0.3, 0.3])
    assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, [0.3, 0.3]))
    cases = hostile_cases(lengths)
    for topic, args, kind, count in cases:
        before = node.issues.counts[kind]
        send(probe, topic, args)
        assert ros.spin_until(lambda k=kind, b=before, c=count: node.issues.counts[k] == b + c,
                              timeout_s=3), (topic, args, kind)
        drive = [1.0, 0.3] if kind == "drive_clipped" else [0.3, 0.3]
        assert np.array_equal(node.inputs.drive, drive), kind
        assert np.array_equal(node.inputs.length_m, lengths), kind  # bad lengths never stored
        if kind == "drive_clipped":
            probe.send_excitation_array([0.3, 0.3])
            assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, [0.3, 0.3]))

    counts = {kind: node.issues.counts[kind] for _, _, kind, _ in cases}  # timing kinds vary
    labels = {kind: label for kind, (label, _) in ISSUE_KINDS.items()}

    def reported():
        diag = probe.last_diagnostics()
        return bool(diag) and all(diag.get(labels[k]) == str(v) for k, v in counts.items())
    assert ros.spin_until(reported, timeout_s=3)
    diag = probe.last_diagnostics()
    assert diag[labels["non_finite"]] == "3" and diag[labels["wrong_size"]] == "4"
    assert diag["_level"] == 1 or diag["state"] == "running"  # WARN while issues are recent
    assert {"step time p99 (ms)", "tick rate (Hz)", "excitation age (s)", "kinematics age (s)",
            "overruns (ticks longer than their period)", "mcap"} <= set(diag)
    n = len(probe.forces)
    assert ros.spin_until(lambda: len(probe.forces) > n + 3)  # still running
    assert np.all(np.isfinite(probe.forces[-1].effort))


def test_bursts_of_hostile_messages_leave_the_node_running(ros, lengths):
    node = ros.muscle_node(muscles=MUSCLES, initial_path_length_m=list(lengths), qos_depth=50)
    probe = ros.probe()
    connected(ros, node, probe)
    cases = hostile_cases(lengths)
    rng = np.random.default_rng(1)
    for i in range(3000):
        topic, args, _, _ = cases[rng.integers(len(cases))]
        send(probe, topic, args)
        if i % 100 == 0:
            ros.spin_for(0.002)
    n = len(probe.forces)
    assert ros.spin_until(lambda: len(probe.forces) > n + 20, timeout_s=10)
    assert 0 < node.issues.total() <= 3000 * 2
    for msg in probe.forces[-20:]:
        assert np.all(np.isfinite(msg.effort)) and np.all(np.isfinite(msg.position))
    assert all(np.isfinite(m.data) for m in probe.energy_totals[-20:])
    assert np.array_equal(node.inputs.length_m, lengths)


# --- time ----------------------------------------------------------------------------------------


def test_time_jumps_and_stalls(ros, lengths):
    node, probe = sim_node(ros, lengths, max_catch_up_steps=20, diagnostics_period_s=0.1)
    start = SIM_T0 + MS
    set_clock(ros, probe, node, start)
    set_clock(ros, probe, node, start + 10 * MS)
    assert node.scheduler.total_steps == 10
    # backwards (a simulator reset): model state kept, time base restarts
    steps = node.scheduler.total_steps
    set_clock(ros, probe, node, 500 * MS, tick=False)
    set_clock(ros, probe, node, 501 * MS)
    assert node.issues.counts["time_backwards"] == 1
    set_clock(ros, probe, node, 520 * MS)
    assert node.scheduler.total_steps == steps + 19
    assert ros.spin_until(lambda: 501 * MS < stamp_ns(probe.forces[-1]) <= 520 * MS)
    # forward by 10 s: max_catch_up_steps run, the rest is skipped and counted
    set_clock(ros, probe, node, 10_510 * MS)
    assert node.issues.counts["skipped_time"] >= 1
    assert node.scheduler.skipped_ns >= 9_900 * MS
    assert ros.spin_until(
        lambda: float(probe.last_diagnostics().get("skipped model time (s)", "0")) >= 9.9,
        timeout_s=3)
    assert probe.last_diagnostics()["time jumps backwards"] == "1"
    assert np.all(np.isfinite(probe.forces[-1].effort))


def test_pause_policy_stops_model_time_while_inputs_are_stale(ros, lengths):
    from rclpy.parameter import Parameter

    node, probe = sim_node(ros, lengths, diagnostics_period_s=0.1)
    node.set_parameters([Parameter("stale_input_policy", value="pause"),
                         Parameter("input_timeout_s", value=0.05)])
    assert node.config.stale_input_policy == "pause" and node.inputs.limits.timeout_ns == 50 * MS
    probe.send_excitation_array([0.5, 0.5])
    assert ros.spin_until(lambda: node.inputs.drive_seen.all())
    start = SIM_T0 + MS
    set_clock(ros, probe, node, start)
    for k in range(1, 21):
        set_clock(ros, probe, node, start + k * 10 * MS)
    # inputs arrived at SIM_T0, stale after SIM_T0 + 50 ms: the tick at start + 50 ms (and every
    # later one) finds them stale and pauses the whole interval since the last tick
    assert node.scheduler.total_steps == 40
    assert node.scheduler.paused_ns == 160 * MS
    assert node.issues.counts["stale_excitation"] == 1
    assert ros.spin_until(lambda: probe.last_diagnostics().get("state", "").startswith("paused"),
                          timeout_s=3)
    probe.send_excitation_array([0.5, 0.5])
    probe.send_kinematics(MUSCLES, lengths)
    assert ros.spin_until(lambda: node.inputs.length_time_ns.min() > SIM_T0)
    steps = node.scheduler.total_steps
    set_clock(ros, probe, node, start + 210 * MS)
    assert node.scheduler.total_steps == steps + 10  # resumed, no catch-up of the paused time


# --- parameters ----------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("params", "field"),
    [
        ({"muscles": ["vasti", "no_such_muscle"]}, "muscles"),
        ({"model_rate_hz": -5.0}, "model_rate_hz"),
        ({"model_rate_hz": "fast"}, "model_rate_hz"),
        ({"publish_rate_hz": 5000.0}, "publish_rate_hz"),
        ({"stale_input_policy": "whatever"}, "stale_input_policy"),
        ({"recruitment": 3}, "recruitment"),
        ({"qos_depth": 0}, "qos_depth"),
        ({"overrides": "{vasti: {no_field: 1}}"}, "overrides"),
        ({"initial_path_length_m": [0.3]}, "initial_path_length_m"),
        ({"initial_path_length_m": [5.0, 5.0]}, "initial_path_length_m"),
        ({"model_rate": 500.0}, "model_rate"),
        ({"qos_overrides./no_topic.publisher.depth": 5}, "qos_overrides./no_topic.publisher.depth"),
    ],
)
def test_bad_parameters_stop_the_node_naming_the_field(ros, params, field):
    with pytest.raises(ConfigError) as info:
        ros.muscle_node(**params)
    assert info.value.field == field
    assert field in str(info.value)


def test_unwritable_mcap_path_stops_the_node(ros, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    with pytest.raises(VmRosError, match=str(blocker)):
        ros.muscle_node(mcap__enabled=True, mcap__path=str(blocker / "x.mcap"))


def test_runtime_parameters(ros):
    from rclpy.parameter import Parameter

    node = ros.muscle_node(model_rate_hz=500)  # an integer for a double is fine
    assert node.config.step_ns == 2 * MS
    ok = node.set_parameters([Parameter("input_timeout_s", value=2.0)])[0]
    assert ok.successful and node.inputs.limits.timeout_ns == 2_000 * MS
    bad = node.set_parameters([Parameter("stale_input_policy", value="bogus")])[0]
    assert not bad.successful and node.config.stale_input_policy == "zero_drive"
    read_only = node.set_parameters([Parameter("model_rate_hz", value=100.0)])[0]
    assert not read_only.successful and node.config.model_rate_hz == 500.0
    descriptor = node.describe_parameter("model_rate_hz")
    assert descriptor.read_only and "[Hz]" in descriptor.description
    assert descriptor.floating_point_range[0].to_value == 20000.0


def test_qos_overrides_let_best_effort_publishers_in(ros, lengths):
    from rclpy.qos import qos_profile_sensor_data
    from std_msgs.msg import Float64MultiArray

    node = ros.muscle_node(muscles=MUSCLES, initial_path_length_m=list(lengths), **{
        "qos_overrides./excitation_array.subscription.reliability": "best_effort"})
    probe = ros.probe()
    sensor = probe.node.create_publisher(Float64MultiArray, "excitation_array",
                                         qos_profile_sensor_data)
    assert ros.spin_until(lambda: sensor.get_subscription_count() == 1, timeout_s=10)
    assert ros.spin_until(lambda: (sensor.publish(Float64MultiArray(data=[0.4, 0.6]))
                                   or np.array_equal(node.inputs.drive, [0.4, 0.6])))
    assert node._subscriptions_by_topic["excitation"].qos_profile.reliability.name == "RELIABLE"


def test_bad_qos_override_is_a_config_error(ros):
    with pytest.raises(ConfigError, match="qos_overrides"):
        ros.muscle_node(**{"qos_overrides./muscle_force.publisher.reliability": "sometimes"})


def test_energetics_models_are_published_and_logged(ros, lengths, tmp_path):
    """energetics_models: energy_rate_models carries every model's rates on the node's state,
    equal to an offline bank with the same models step for step; the log holds the channel and
    recompute reproduces it. A bad name is a one-line parameter error."""
    import contextlib
    import io

    from vm_ros.cli import main
    from vm_ros.node.params import NodeConfig
    from vm_ros.recording import read_run

    models = ["umberger2010", "bhargava2004", "minetti1997"]
    path = tmp_path / "run.mcap"
    node, probe = sim_node(ros, lengths, batch_steps=0, energetics_models=models,
                           mcap__enabled=True, mcap__path=str(path))
    received = probe.energy_rate_models
    probe.send_excitation_array([0.7, 0.3])
    assert ros.spin_until(lambda: np.array_equal(node.inputs.drive, [0.7, 0.3]))
    start = SIM_T0 + 10 * MS
    set_clock(ros, probe, node, start)
    for k in range(1, 6):
        set_clock(ros, probe, node, start + k * 10 * MS)
    assert ros.spin_until(lambda: len(received) == 6)
    bank = MuscleBank.from_config(MUSCLES, energetics_models=models)
    offline = [bank.reset(path_length=lengths)]
    offline += [bank.step(1e-3, [0.7, 0.3], lengths) for _ in range(50)]
    for i, msg in enumerate(received):
        assert [tm.split_dim_label(d.label) for d in msg.layout.dim] == [
            ("muscle", tuple(MUSCLES)), ("model", tuple(models)),
            ("component", tm.MODEL_COMPONENT_LABELS)]
        np.testing.assert_allclose(np.array(msg.data).reshape(2, 3, 5),
                                   offline[10 * i].energy_rate_models, rtol=1e-9, atol=1e-12)
    node.close_run_log()
    logged = read_run(path).get(tm.TOPIC_ENERGY_RATE_MODELS)
    assert logged is not None and len(logged) == 6
    out = tmp_path / "again.mcap"
    with contextlib.redirect_stdout(io.StringIO()):
        assert main(["recompute", str(path), "--out", str(out)]) == 0
    again = read_run(out).get(tm.TOPIC_ENERGY_RATE_MODELS)
    np.testing.assert_array_equal(again.time_ns, logged.time_ns)
    np.testing.assert_allclose(again.fields["data"], logged.fields["data"], rtol=1e-9, atol=0)
    with pytest.raises(ConfigError, match="energetics_models.*unknown"):
        NodeConfig.from_values({"energetics_models": ["umberger2099"]})
