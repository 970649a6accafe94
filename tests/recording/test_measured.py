"""measured-v1: validation with file, line and column; gaps stay gaps."""

import subprocess
import sys

import numpy as np
import pytest

from kilobot_twin.recording import measured
from kilobot_twin.errors import ConfigError

META = """format: kilobot-twin/measured-v1
kind: motion
robots: [0, 1]
trials: 1
dt_s: 0.1
duration_s: 0.3
behavior: straight
nominal_speed_m_s: 0.0113
"""
CSV = "trial,robot_id,t_s,x_m,y_m\n0,0,0.0,0,0\n0,1,0.0,1,0\n0,0,0.1,0.001,0\n0,0,0.3,0.003,0\n"


def make(tmp_path, meta=META, csv=CSV):
    d = tmp_path / "ds"
    d.mkdir(exist_ok=True)
    (d / "meta.yaml").write_text(meta)
    (d / "observations.csv").write_text(csv)
    return d


def test_load_keeps_gaps_and_interleaving(tmp_path):
    ds = measured.load(make(tmp_path))
    tr = ds.track(0, 0)
    assert tr.t_s.tolist() == [0.0, 0.1, 0.3]  # the missing 0.2 stays missing
    _, x = ds.grid("x_m")
    assert x.shape == (1, 2, 4) and np.isnan(x[0, 0, 2]) and x[0, 0, 3] == 0.003
    assert np.isnan(x[0, 1, 1:]).all()


def test_a_lost_sample_written_as_a_row_with_an_empty_or_nan_cell_is_a_missing_row(tmp_path):
    """measured-v1 writes a lost sample as no row; a table exported with its gaps (pandas writes
    NaN) writes the row with an empty or NaN value. Both load as the file without those rows (by
    hand: robot 0 at 0.0, 0.1, 0.3), for positions and for LED colours alike."""
    ds = measured.load(make(tmp_path, csv=CSV + "0,0,0.2,nan,NaN\n0,1,0.1,,\n0,1,0.2,NA,0.5\n"))
    assert ds.track(0, 0).t_s.tolist() == [0.0, 0.1, 0.3] and ds.track(0, 1).t_s.tolist() == [0.0]
    blink = META.replace("kind: motion", "kind: blink").replace("behavior: straight\n", "") + \
        "half_period_ticks: 30\nnominal_tick_hz: 31\n"
    ds = measured.load(make(tmp_path, meta=blink, csv="trial,robot_id,t_s,led\n0,0,0.0,red\n0,0,0.1,\n0,0,0.2,blue\n"))
    assert ds.track(0, 0).t_s.tolist() == [0.0, 0.2] and ds.track(0, 0).values["led"].tolist() == [0.0, 1.0]


def test_a_byte_order_mark_before_the_header_is_no_column_name(tmp_path):
    """A spreadsheet's UTF-8 export leads with a byte-order mark (EF BB BF), which a plain UTF-8
    read makes part of the first column's name ("missing column 'trial'"): it loads as without."""
    d = make(tmp_path)
    (d / "observations.csv").write_bytes(b"\xef\xbb\xbf" + CSV.encode())
    ds = measured.load(d)
    assert ds.track(0, 0).t_s.tolist() == [0.0, 0.1, 0.3] and ds.track(0, 1).values["x_m"].tolist() == [1.0]


def test_a_trial_longer_than_duration_keeps_every_sample(tmp_path):
    """meta.yaml gives one duration_s; a trial that ran longer (uneven trials, or a jittered last
    stamp) keeps its late samples on the grid, each in its own slot (by hand: robot 0's samples at
    0.0, 0.1, 0.3, 0.5 and 0.6 s go to slots 0, 1, 3, 5, 6 of a 7-slot grid); a grid cut at
    duration_s had piled the three late ones onto its last slot, keeping one."""
    ds = measured.load(make(tmp_path, csv=CSV + "0,0,0.5,0.005,0\n0,0,0.6,0.006,0\n"))
    assert ds.duration_s == 0.3 and ds.span_s == 0.6
    t, x = ds.grid("x_m")
    assert x.shape == (1, 2, 7) and np.allclose(t, np.arange(7) * 0.1)
    np.testing.assert_array_equal(x[0, 0], [0.0, 0.001, np.nan, 0.003, np.nan, 0.005, 0.006])
    assert measured.load(make(tmp_path)).span_s == 0.3  # no sample past duration_s: the grid as before


def test_rows_and_columns_in_any_order(tmp_path):
    """measured-v1 allows rows in any order (and names columns by the header): the same samples
    with the columns permuted and the rows reversed load as the file in time order does, each
    (trial, robot) sorted by time (here by hand: robot 0 at 0.0, 0.1, 0.2, 0.3)."""
    rows = CSV.splitlines()[1:] + ["0,0,0.2,0.002,0.5"]
    shuffled = "y_m,robot_id,x_m,trial,t_s\n" + "".join(
        f"{y},{r},{x},{k},{t}\n" for k, r, t, x, y in (line.split(",") for line in reversed(rows)))
    ds = measured.load(make(tmp_path, csv=shuffled))
    tr = ds.track(0, 0)
    assert tr.t_s.tolist() == [0.0, 0.1, 0.2, 0.3]
    assert tr.values["x_m"].tolist() == [0.0, 0.001, 0.002, 0.003]
    assert tr.values["y_m"].tolist() == [0.0, 0.0, 0.5, 0.0]
    assert ds.track(0, 1).values["x_m"].tolist() == [1.0]


@pytest.mark.parametrize("csv, where", [
    ("trial,robot_id,t_s,x_m\n0,0,0,0\n", "observations.csv:1"),                     # missing column y_m
    (CSV + "0,0,0.4,abc,0\n", "observations.csv:6: column x_m"),                    # non-numeric
    (CSV + "0,7,0.4,0,0\n", "observations.csv:6: column robot_id"),                 # robot not in robots
    (CSV + "0,0,0.3,0,0\n", "observations.csv:6: column t_s"),                      # duplicated sample
    ("trial,robot_id,t_s,x_m,y_m\n0,0,0.3,0,0\n0,0,0.1,0,0\n0,0,0.3,1,0\n", "observations.csv:4: column t_s"),  # apart
    (CSV + "0,0,0.4,inf,0\n", "observations.csv:6: column x_m"),                    # not finite
    (CSV + "0,0,nan,0,0\n", "observations.csv:6: column t_s"),                      # a key cannot be lost
    (CSV + "1,0,0.4,0,0\n", "observations.csv:6: column trial"),                    # trial out of range
])
def test_bad_rows_name_file_line_column(tmp_path, csv, where):
    with pytest.raises(ConfigError) as e:
        measured.load(make(tmp_path, csv=csv))
    assert where in str(e.value) and "\n" not in str(e.value)


@pytest.mark.parametrize("meta, field", [
    (META.replace("kind: motion", "kind: video"), "kind"),
    (META.replace("trials: 1", "trials: zero"), "trials"),
    (META.replace("behavior: straight\n", ""), "behavior"),
    (META.replace("measured-v1", "measured-v9"), "format"),
])
def test_bad_meta_names_the_key(tmp_path, meta, field):
    with pytest.raises(ConfigError) as e:
        measured.load(make(tmp_path, meta=meta))
    assert f"meta.yaml: {field}" in str(e.value)


def test_cli_gap_on_bad_dataset_exits_2_with_one_line(tmp_path):
    d = make(tmp_path, csv=CSV + "0,9,0.4,0,0\n")
    p = subprocess.run([sys.executable, "-m", "kilobot_twin", "gap", str(d), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "robot_id" in p.stderr
