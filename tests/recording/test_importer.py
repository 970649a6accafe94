"""`import`: measured datasets -> twin bags (gaps kept, trials in sequence, heading from motion)."""

import json

import numpy as np
import pytest

from kilobot_twin.cli import main as cli_main
from kilobot_twin.recording.importer import heading_from_motion, import_dataset, trial_period_s
from kilobot_twin.recording.measured import Track, load, write
from kilobot_twin.recording.bag import BagReader
from kilobot_twin.recording.swarm_data import from_bag

from ..ros.test_bag import assert_foxglove_reads_what_rosbags_reads, rerun_check, rosbags_messages

V = 0.0113  # m/s
L = 0.025   # wheel separation


def circle(bias, T=101, dt=0.5):
    """A robot with heading bias b turning at -b v / L (clockwise for b > 0)."""
    t = np.arange(T) * dt
    th = 0.3 - bias * V / L * t
    x = np.cumsum(np.concatenate([[0], V * dt * np.cos(th[:-1])]))
    y = np.cumsum(np.concatenate([[0], V * dt * np.sin(th[:-1])]))
    return t, x, y, th


def motion_dataset(folder, with_theta=False):
    tracks = {}
    for trial in range(2):
        for robot, b in ((3, 0.03), (5, -0.02)):
            t, x, y, th = circle(b)
            keep = np.ones(len(t), bool)
            if robot == 3 and trial == 1:
                keep[40:50] = False  # tracking loss
            vals = {"x_m": x[keep], "y_m": y[keep]}
            if with_theta:
                vals["theta_rad"] = th[keep]
            tracks[(trial, robot)] = Track(t[keep], vals)
    return write(folder, {"kind": "motion", "robots": [3, 5], "trials": 2, "dt_s": 0.5, "duration_s": 50.0,
                          "behavior": "straight", "nominal_speed_m_s": V}, tracks)


def test_motion_import_keeps_values_gaps_and_trial_boundaries(tmp_path):
    ds = motion_dataset(tmp_path / "ds")
    res = import_dataset(ds, tmp_path / "bags" / "m")
    bag = res["path"]
    assert rerun_check(bag / "m_0.mcap").returncode == 0
    counts = BagReader(bag).counts()
    assert counts["/kilobot_3/pose"] == 2 * 101 - 10 and counts["/kilobot_5/pose"] == 202
    assert counts["/world/trial"] == 2
    assert assert_foxglove_reads_what_rosbags_reads(bag) == sum(counts.values())  # from the bag's own schemas
    meta = BagReader(bag).metadata()["kilobot_twin.import"]
    trials = json.loads(meta["trials"])
    period = trial_period_s(load(ds))
    assert [t["start_ns"] for t in trials] == [0, int(period * 1e9)]
    assert meta["heading"] == "estimated from motion"
    # Independent reader: positions as measured, stamps = t + trial offset, heading along the path.
    msgs = [m for t, m in rosbags_messages(bag) if t == "/kilobot_5/pose"]
    t, _x, _y, th = circle(-0.02)
    x = load(ds).tracks[(0, 5)].values["x_m"]  # as written (6 significant digits)
    got_x = np.array([m.pose.position.x for m in msgs])
    np.testing.assert_allclose(got_x[:101], x, atol=1e-12)
    np.testing.assert_allclose(got_x[101:], x, atol=1e-12)
    stamps = np.array([m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for m in msgs])
    np.testing.assert_allclose(stamps[101:] - stamps[:101], period, atol=1e-9)
    yaw = np.array([2 * np.arctan2(m.pose.orientation.z, m.pose.orientation.w) for m in msgs[:101]])
    # Central-difference heading of a circle lies half a step behind/ahead: within one step's turn.
    err = np.angle(np.exp(1j * (yaw[1:-1] - 0.5 * (th[1:-1] + th[:-2]) - 0.5 * (th[1:-1] - th[:-2]))))
    assert np.max(np.abs(err)) < abs(0.02 * V / L * 0.5) + 1e-3
    # Traits carry the estimated bias with its sign (b > 0 = clockwise = right).
    docs = {t: json.loads(m.data) for t, m in rosbags_messages(bag) if t.endswith("/traits")}
    assert docs["/kilobot_3/traits"]["traits"]["heading_bias"] == pytest.approx(0.03, rel=0.05)
    assert docs["/kilobot_5/traits"]["traits"]["heading_bias"] == pytest.approx(-0.02, rel=0.05)
    # The viewer's arrays: gaps and the pause between trials are NaN, not interpolated.
    rec = from_bag(bag)
    i3 = list(rec.robot_ids).index(3)
    k1 = int(round(period / 0.5))
    assert np.isnan(rec.x[i3, k1 + 40:k1 + 50]).all() and np.isfinite(rec.x[i3, k1 + 39])
    assert np.isnan(rec.x[:, 101:k1]).all()
    assert np.isfinite(rec.x).sum() == 2 * 202 - 10


def test_a_trial_longer_than_duration_stays_before_the_next(tmp_path):
    """duration_s is 50 s but trial 0 of robot 3 runs to 60 s: its trial window (meta) covers its
    last sample, which lies before trial 1 starts, so no trial's samples run into the next one's."""
    tracks = {}
    for trial in range(2):
        t, x, y, _ = circle(0.01, T=121 if trial == 0 else 101)
        tracks[(trial, 3)] = Track(t, {"x_m": x, "y_m": y})
    ds = write(tmp_path / "ds", {"kind": "motion", "robots": [3], "trials": 2, "dt_s": 0.5, "duration_s": 50.0,
                                 "behavior": "straight", "nominal_speed_m_s": V}, tracks)
    bag = import_dataset(ds, tmp_path / "bags" / "m")["path"]
    trials = json.loads(BagReader(bag).metadata()["kilobot_twin.import"]["trials"])
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for t, m in rosbags_messages(bag)
              if t == "/kilobot_3/pose"]  # read by rosbags, not by the project
    assert len(stamps) == 222 and stamps[120] == pytest.approx(60.0)
    assert trials[0]["end_ns"] == pytest.approx(60e9) and stamps[120] < trials[1]["start_ns"] * 1e-9
    assert stamps[121] == pytest.approx(trials[1]["start_ns"] * 1e-9)  # trial 1's first sample, at its start


def test_measured_theta_is_used_when_present(tmp_path):
    res = import_dataset(motion_dataset(tmp_path / "ds", with_theta=True), tmp_path / "m")
    msgs = [m for t, m in rosbags_messages(res["path"]) if t == "/kilobot_3/pose"]
    yaw = np.array([2 * np.arctan2(m.pose.orientation.z, m.pose.orientation.w) for m in msgs[:101]])
    th = load(tmp_path / "ds").tracks[(0, 3)].values["theta_rad"]
    np.testing.assert_allclose(np.angle(np.exp(1j * (yaw - th))), 0, atol=1e-12)


def test_light_sweep_and_blink_imports(tmp_path):
    t = np.arange(11) * 1.0
    write(tmp_path / "ls", {"kind": "light_sweep", "robots": [1], "trials": 1, "dt_s": 1.0, "duration_s": 10.0},
          {(0, 1): Track(t, {"stimulus": t / 10, "reading": 100 + 50 * t})})
    res = import_dataset(tmp_path / "ls", tmp_path / "b1")
    assert res["counts"]["/kilobot_1/light"] == 11 and res["counts"]["/kilobot_1/stimulus"] == 11
    rec = from_bag(res["path"])
    np.testing.assert_allclose(rec.reading[0], 100 + 50 * t)
    write(tmp_path / "bl", {"kind": "blink", "robots": [2, 4], "trials": 1, "dt_s": 0.5, "duration_s": 5.0,
                            "half_period_ticks": 31, "nominal_tick_hz": 31.0},
          {(0, r): Track(np.arange(11) * 0.5, {"led": (np.arange(11) // 2 % 2).astype(float)}) for r in (2, 4)})
    res = import_dataset(tmp_path / "bl", tmp_path / "b2")
    assert res["counts"]["/kilobot_2/led"] == 11
    rec = from_bag(res["path"])
    np.testing.assert_array_equal(rec.led[1], np.arange(11) // 2 % 2)
    # Foxglove reads what rosbags reads, from the schemas each bag carries (the motion import's
    # topics in the first test's bag below)
    for bag in (tmp_path / "b1", tmp_path / "b2"):
        assert assert_foxglove_reads_what_rosbags_reads(bag) == sum(BagReader(bag).counts().values())


def test_heading_from_motion_holds_the_last_direction_when_standing():
    x = np.array([0.0, 0.01, 0.01, 0.01, 0.02])
    y = np.zeros(5)
    th = heading_from_motion(x, y)
    np.testing.assert_allclose(th, 0.0)
    assert np.isnan(heading_from_motion(np.zeros(3), np.zeros(3))).all()


@pytest.mark.parametrize("edit,where", [
    (lambda p: p.write_text(p.read_text().replace("y_m", "why")), "observations.csv:1"),
    (lambda p: p.write_text(p.read_text().replace("\n0,3,0.5000,", "\n0,3,abc,", 1)), "column t_s"),
    (lambda p: p.write_text(p.read_text().replace("\n0,5,", "\n0,6,", 1)), "column robot_id"),
])
def test_bad_input_is_one_line_with_file_line_and_column(tmp_path, capsys, edit, where):
    ds = motion_dataset(tmp_path / "ds")
    edit(ds / "observations.csv")
    assert cli_main(["import", str(ds), "--out", str(tmp_path / "x")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and where in err[0] and "observations.csv" in err[0], err
    assert not (tmp_path / "x").exists()


def test_unknown_kind_is_refused(tmp_path, capsys):
    ds = motion_dataset(tmp_path / "ds")
    (ds / "meta.yaml").write_text((ds / "meta.yaml").read_text().replace("kind: motion", "kind: dance"))
    assert cli_main(["import", str(ds), "--out", str(tmp_path / "x")]) == 2
    assert "kind" in capsys.readouterr().err
