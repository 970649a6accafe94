"""Aligning a bag's series on one time grid, from series written by hand (no bag, no decoder)."""

from pathlib import Path

import numpy as np

from kilobot_twin.recording.swarm_data import BagSeries, align

MS = 1_000_000


def test_align_puts_jittered_samples_in_their_slots_and_leaves_gaps():
    s = BagSeries("hand", Path("hand.mcap"))
    # Robot 3: poses every 100 ms with a few ms of jitter; the one at 300 ms is missing (a gap).
    s.pose[3] = [(t * MS + j * MS, 10_000 + t * MS, 0.01 * t, -0.02 * t, 0.1) for t, j in
                 ((0, 0), (100, 2), (200, -3), (400, 1), (500, 0))]
    # Its LED messages carry no stamp: each belongs to the first pose logged at or after it.
    s.led[3] = [(10_000 + 150 * MS, 1), (10_000 + 390 * MS, 0)]
    # Robot 5: light readings only, none at 400 ms. The grid step is the median stamp step (100 ms).
    s.light[5] = [(100 * MS, 700.0), (200 * MS, 710.0), (300 * MS, 720.0), (500 * MS, 650.0)]
    s.traits[3] = {"traits": {"heading_bias": -0.03}}
    rec = align(s)

    assert rec.robot_ids.tolist() == [3, 5]
    np.testing.assert_allclose(rec.t_s, [0.0, 0.1, 0.2, 0.3, 0.4, 0.5])
    nan = np.nan
    np.testing.assert_array_equal(rec.x[0], [0.0, 1.0, 2.0, nan, 4.0, 5.0])
    np.testing.assert_array_equal(rec.led[0], [nan, nan, 1.0, nan, 0.0, nan])
    np.testing.assert_array_equal(rec.reading[1], [nan, 700.0, 710.0, 720.0, nan, 650.0])
    assert np.isnan(rec.x[1]).all()
    np.testing.assert_array_equal(rec.heading_bias, [-0.03, nan])
    assert (rec.meta["t0_ns"], rec.meta["dt_ns"]) == (0, 100 * MS)
