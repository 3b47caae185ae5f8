"""The walk's reference readers and comparison (vm_ros.validation.walk_reference) on hand-written
files with known answers; OpenSim's StaticOptimization on the fetched walk when it is there."""

from __future__ import annotations

import numpy as np
import pytest

from vm_ros.validation import walk_reference as wr


def _sto(path, labels, rows):
    lines = ["probe", "version=1", "inDegrees=no", "endheader", "\t".join(labels)]
    lines += ["\t".join(f"{v:.10g}" for v in row) for row in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


MODEL = """<?xml version="1.0" encoding="UTF-8" ?>
<OpenSimDocument Version="40000"><Model name="m">
  <BodySet><objects><Body name="a"><mass>2.5</mass></Body><Body name="b"><mass>1.25</mass></Body>
  </objects></BodySet>
  <ForceSet><objects><Thelen2003Muscle name="soleus_r"/><CoordinateActuator name="reserve"/>
  <Millard2012EquilibriumMuscle name="vasti_r"/></objects></ForceSet>
</Model></OpenSimDocument>
"""


def test_model_muscles_and_mass_from_the_xml(tmp_path):
    (tmp_path / "m.osim").write_text(MODEL)
    assert wr.model_muscles(tmp_path / "m.osim") == ("soleus_r", "vasti_r")
    assert wr.body_mass_kg(tmp_path / "m.osim") == pytest.approx(3.75)


def test_umberger_probe_is_the_time_average_per_kg(tmp_path):
    """TOTAL rises linearly from 100 to 300 W over 2 s: 200 W on average, over 3.75 kg."""
    (tmp_path / "m.osim").write_text(MODEL)
    t = np.linspace(1.0, 3.0, 21)
    probes = _sto(tmp_path / "p.sto", ["time", "metabolics_TOTAL", "metabolics_BASAL",
                                       "metabolics_soleus_r"],
                  np.column_stack([t, 100 + 100 * (t - 1), 0 * t, 50 + 0 * t]))
    rate = wr.umberger_probe({"cmc_probes": probes, "model_metabolics": tmp_path / "m.osim"})
    assert rate["total_w"] == pytest.approx(200.0)
    assert rate["per_kg"] == pytest.approx(200.0 / 3.75)
    assert rate["muscles_w"] == {"soleus_r": pytest.approx(50.0)}
    assert rate["span_s"] == (1.0, 3.0)


def test_gait_events_and_cycle_percent(tmp_path):
    """A right foot loaded from 0.5 to 1.1 s and from 1.7 s on: strikes 0.5 and 1.7 s, toe-off
    1.1 s; 1.1 s is 50 % of the 1.2 s cycle."""
    t = np.round(np.arange(0, 2.001, 0.1), 6)
    right = np.where(((t >= 0.5) & (t < 1.1)) | (t >= 1.7), 700.0, 0.0)
    grf = _sto(tmp_path / "grf.mot", ["time", "ground_force_vy", "1_ground_force_vy"],
               np.column_stack([t, right, 700.0 - right]))
    events = wr.gait_events({"grf": grf}, threshold_n=20.0)
    assert events["r"] == {"strike": [0.5, 1.7], "off": [1.1]}
    assert events["l"] == {"strike": [1.1], "off": [0.5, 1.7]}
    inside, percent = wr.cycle_percent(np.array([0.4, 1.1, 1.7, 1.8]), events["r"]["strike"])
    assert inside.tolist() == [False, True, True, False]
    assert percent[1] == pytest.approx(50.0)


def test_compare_correlation_and_rms_against_known_signals():
    """Ours = 2 x reference + 1 on half the frames: r = 1; ours = reference + 3: RMS 3."""
    t = np.linspace(0.0, 1.0, 101)
    ref = wr.MuscleSeries("ref", t, ("a", "b"), np.column_stack([np.sin(6 * t), t]), "N")
    ours = wr.MuscleSeries("ours", t[:51], ("b", "a"),
                           np.column_stack([t[:51] + 3, 2 * np.sin(6 * t[:51]) + 1]), "N")
    out = wr.compare(ours, ref)
    assert out["a"]["r"] == pytest.approx(1.0)
    assert out["b"]["rms"] == pytest.approx(3.0)
    assert out["b"]["rms_of_peak"] == pytest.approx(3.0 / 0.5)


def test_static_optimization_of_the_walk_agrees_with_cmc_in_shape():
    """OpenSim's SO on the fetched walk: every muscle's force correlates with CMC's (r > 0.5;
    the two solve different problems) and the joint reserves stay below 1 N m."""
    from vm_ros.errors import VmRosError
    from vm_ros.importers.osim import load_opensim
    from vm_ros.validation.walk_data import WalkDataError, walk_files

    try:
        files = walk_files()
        load_opensim()
    except (WalkDataError, VmRosError) as exc:
        pytest.skip(str(exc))
    so = wr.static_optimization(files)
    assert so["force"].values.shape == (151, 18)
    correlation = [v["r"] for v in wr.compare(so["force"], wr.cmc_forces(files)).values()]
    assert min(correlation) > 0.5
    joints = [n for n in so["reserve"].muscles if n.endswith("_reserve") and "lumbar" not in n]
    assert np.abs(np.column_stack([so["reserve"].column(n) for n in joints])).max() < 1.0
