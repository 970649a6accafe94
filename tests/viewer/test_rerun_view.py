"""Bag / results -> .rrd: read back with Rerun's own reader (rerun.chunk.RrdReader) and `rerun rrd verify`."""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from kilobot_twin.core.constants import LED_BLUE, LED_RED
from kilobot_twin.recording.swarm_data import SwarmRecording, field_raster

rr_chunk = pytest.importorskip("rerun.chunk")

from kilobot_twin.viewer.rerun_view import bias_colours, write_rrd  # noqa: E402

RERUN = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))


def small_recording() -> SwarmRecording:
    from kilobot_twin.core.scenario import Scenario

    n, T = 3, 50
    t = np.arange(T) * 0.1
    x = np.stack([0.01 * t + 0.1 * i for i in range(n)])
    y = np.stack([0.02 * t - 0.1 * i for i in range(n)])
    theta = np.full((n, T), 0.5)
    led = np.full((n, T), float(LED_RED))
    led[1] = LED_BLUE
    reading = np.stack([100.0 + i + t for i in range(n)])
    x[2, 10:20] = y[2, 10:20] = reading[2, 10:20] = np.nan  # a tracking gap of robot 2
    fld, ext = field_raster(Scenario())
    return SwarmRecording("small", np.array([4, 7, 9]), t, x, y, theta, led, reading,
                          heading_bias=np.array([-0.02, 0.0, 0.03]), traits={4: {"traits": {"heading_bias": -0.02}}},
                          light_center=(0.0, 0.0), light_field=fld, field_extent=ext)


def chunks_by_entity(path):
    store = rr_chunk.RrdReader(str(path)).store()
    out = {}
    for ch in store.stream().to_chunks():
        out.setdefault(ch.entity_path, []).append(ch)
    return out


def column(chunks, name):
    vals = []
    for ch in chunks:
        rb = ch.to_record_batch()
        if name in rb.schema.names:
            vals += rb.column(name).to_pylist()
    return vals


def test_rrd_holds_every_entity_with_the_right_rows_and_values(tmp_path):
    rec = small_recording()
    out = write_rrd(rec, tmp_path / "small.rrd")["path"]
    assert subprocess.run([RERUN, "rrd", "verify", str(out)], capture_output=True).returncode == 0
    ents = chunks_by_entity(out)
    for e in ("/arena/light_field", "/arena/light_center", "/arena/trajectories", "/arena/robots", "/arena/headings",
              "/light/kilobot_4", "/light/kilobot_7", "/light/kilobot_9", "/metrics/led_red_fraction",
              "/metrics/led_blue_fraction", "/metrics/mean_distance_to_light_m", "/traits"):
        assert e in ents, (e, sorted(ents))
    # One row per step; robot 2 is missing in the 10 gap steps.
    positions = column(ents["/arena/robots"], "Points3D:positions")
    assert len(positions) == 50
    assert [len(p) for p in positions[10:20]] == [2] * 10 and len(positions[0]) == 3
    # The arena in metres: x, y as recorded (float32 in the file), robots just above the floor.
    np.testing.assert_allclose(positions[5][1][:2], [rec.x[1, 5], rec.y[1, 5]], rtol=1e-6)
    # The light field covers its extent in metres, row 0 of the image at +y.
    corners = np.array(column(ents["/arena/light_field"], "Mesh3D:vertex_positions")[0])
    assert corners[:, 0].min() == rec.field_extent[0] and corners[:, 1].max() == rec.field_extent[3]
    # LED colours per robot: red, blue.
    colours = column(ents["/arena/robots"], "Points3D:colors")
    assert colours[0][0] == 0xE61414FF and colours[0][1] == 0x143CF0FF
    # Readings: gaps are left out, values kept.
    r9 = [v[0] for v in column(ents["/light/kilobot_9"], "Scalars:scalars")]
    assert len(r9) == 40 and r9[0] == pytest.approx(102.0)
    # Trajectories: robot 2 is split at its gap -> 4 strips; colours follow the bias map.
    strips = column(ents["/arena/trajectories"], "LineStrips3D:strips")[0]
    assert [len(s) for s in strips] == [50, 50, 10, 30]
    strip_cols = column(ents["/arena/trajectories"], "LineStrips3D:colors")[0]
    r, g, b = bias_colours(rec.heading_bias)[0]
    assert strip_cols[0] == (int(r) << 24) | (int(g) << 16) | (int(b) << 8) | 255
    assert r > b  # negative bias (left) is red
    red = [v[0] for v in column(ents["/metrics/led_red_fraction"], "Scalars:scalars")]
    assert red[0] == pytest.approx(2 / 3) and len(red) == 50
    text = column(ents["/traits"], "TextDocument:text")[0][0]
    assert "| 4 | -0.0200" in text and "heading_bias b (wheel imbalance)" in text
    # The blueprint travels with the recording.
    assert len(rr_chunk.RrdReader(str(out)).blueprints()) == 1


def test_bias_colours_follow_the_paper_map():
    c = bias_colours(np.array([-1.0, 0.0, 1.0, np.nan]))
    assert tuple(c[0]) == (255, 0, 0) and tuple(c[1]) == (128, 0, 128) and tuple(c[2]) == (0, 89, 255)
    assert tuple(c[3]) == (128, 128, 128)


def test_view_of_batch_results_npz(tmp_path, capsys):
    from kilobot_twin.cli import main

    cfg = tmp_path / "c.yaml"
    cfg.write_text("scenario: {preset: paper, behavior: {kind: phototaxis, p_right: 0.5}, duration_s: 5}\n"
                   "swarm: {population: {n: 4, heading_bias: {dist: uniform, low: -0.04, high: 0.04}}}\n"
                   "seed: 3\nruns: 2\nrecord_every: 1\n")
    assert main(["simulate", str(cfg), "--out", str(tmp_path / "r.npz"), "--workers", "1", "--no-progress"]) == 0
    assert main(["view", str(tmp_path / "r.npz"), "--run", "1"]) == 0
    ents = chunks_by_entity(tmp_path / "r.rrd")
    assert len(column(ents["/arena/robots"], "Points3D:positions")) == 51
    assert sum(1 for e in ents if e.startswith("/light/kilobot_")) == 4
    # A point or run outside the results: one line naming the option (a point past the grid, or a
    # negative one, was reported as trajectories never recorded).
    capsys.readouterr()
    for args, option in ((["--point", "1"], "--point"), (["--point", "-1"], "--point"), (["--run", "2"], "--run")):
        assert main(["view", str(tmp_path / "r.npz"), *args, "--out", str(tmp_path / "x.rrd")]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].split(": error: ")[1].startswith(option + ":"), err
        assert not (tmp_path / "x.rrd").exists()


def test_view_refuses_a_missing_source_with_one_line(tmp_path, capsys):
    from kilobot_twin.cli import main

    assert main(["view", str(tmp_path / "nothing")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "nothing" in err[0]
