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
    (META + "camera_axis_m: [0.1]\n", "camera_axis_m"),
    (META + "camera_axis_m: [0.1, .nan]\n", "camera_axis_m"),
    (META + "camera_axis_m: 0.1\n", "camera_axis_m"),
    (META + "camera_axis_m: [0.1, 0.0]\ncamera_axis_sd_m: 0\n", "camera_axis_sd_m"),
    (META + "tracking_noise_m: -0.001\n", "tracking_noise_m"),
    (META + "tracking_noise_m: .inf\n", "tracking_noise_m"),
    (META + "tracking_noise_m: .nan\n", "tracking_noise_m"),
    (META.replace("nominal_speed_m_s: 0.0113", "nominal_speed_m_s: .inf"), "nominal_speed_m_s"),  # was taken
])
def test_bad_meta_names_the_key(tmp_path, meta, field):
    with pytest.raises(ConfigError) as e:
        measured.load(make(tmp_path, meta=meta))
    assert f"meta.yaml: {field}" in str(e.value)


def test_a_camera_axis_is_read_where_it_is_given(tmp_path):
    ds = measured.load(make(tmp_path, meta=META + "camera_axis_m: [0.1, -0.05]\ncamera_axis_sd_m: 0.01\n"))
    assert ds.meta["camera_axis_m"] == [0.1, -0.05] and ds.meta["camera_axis_sd_m"] == 0.01


def test_cli_gap_on_bad_dataset_exits_2_with_one_line(tmp_path):
    d = make(tmp_path, csv=CSV + "0,9,0.4,0,0\n")
    p = subprocess.run([sys.executable, "-m", "kilobot_twin", "gap", str(d), "--out", str(tmp_path / "o")],
                       capture_output=True, text=True)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert len(p.stderr.strip().splitlines()) == 1 and "robot_id" in p.stderr


def _rowwise(folder):
    """The dataset as the row-by-row (csv module) reader alone reads it."""
    fast = measured._plain_tracks
    measured._plain_tracks = lambda *a: None
    try:
        return measured.load(folder)
    finally:
        measured._plain_tracks = fast


def _plain_files():
    """Plain files a tracker or a table export writes: rows shuffled, columns in another order
    with one the format does not use, the optional heading, a byte-order mark, CRLF line ends,
    blank lines, numbers in exponent form, LED colours in any case."""
    rng = np.random.default_rng(5)
    rows = [(k, r, round(0.1 * j, 1), *rng.normal(0, 0.1, 3)) for k in range(2) for r in (3, 7, 11) for j in range(40)
            if rng.random() > 0.1]
    order = rng.permutation(len(rows))
    motion = "robot_id,x_m,note,t_s,theta_rad,trial,y_m\r\n" + "".join(
        f"{rows[i][1]},{rows[i][3]:.6e},n{i},{rows[i][2]},{float(rows[i][5])!r},{rows[i][0]},{rows[i][4]:.5f}\r\n"
        + ("\r\n" if i % 17 == 0 else "") for i in order)
    blink = "trial,robot_id,t_s,led\n" + "".join(
        f"{rows[i][0]},{rows[i][1]},{rows[i][2]},{('red', 'Blue', ' BLUE ')[i % 3]}\n" for i in order)
    meta = META.replace("robots: [0, 1]", "robots: [3, 7, 11]").replace("trials: 1", "trials: 2")
    blink_meta = meta.replace("kind: motion", "kind: blink").replace("behavior: straight\n", "") + \
        "half_period_ticks: 30\nnominal_tick_hz: 31\n"
    return [(meta, b"\xef\xbb\xbf" + motion.encode()), (blink_meta, blink.encode())]


@pytest.mark.parametrize("which", [0, 1])
def test_a_plain_file_read_in_one_pass_gives_the_row_by_row_readers_tracks(tmp_path, which):
    """Plain files are read by NumPy in one pass, 3-4x faster on large ones: the tracks must be
    those of the csv module's reader to the bit, in the same order, with the same columns."""
    meta, data = _plain_files()[which]
    d = make(tmp_path, meta=meta)
    (d / "observations.csv").write_bytes(data)
    header = data.decode("utf-8-sig").splitlines()[0].split(",")
    assert measured._plain_tracks(data.decode("utf-8-sig"), len(header), {c: header.index(c) for c in header if c != "note"},
                                  {"trials": 2, "robots": [3, 7, 11]}) is not None  # read in one pass
    ds, ref = measured.load(d), _rowwise(d)
    assert list(ds.tracks) == list(ref.tracks) and len(ds.tracks) == 6
    for key, tr in ref.tracks.items():
        got = ds.tracks[key]
        assert list(got.values) == list(tr.values) == (["x_m", "y_m", "theta_rad"] if which == 0 else ["led"])
        for a, b in [(got.t_s, tr.t_s)] + [(got.values[c], tr.values[c]) for c in tr.values]:
            assert a.dtype == b.dtype == np.float64 and np.array_equal(a, b)
        assert np.all(np.diff(got.t_s) > 0)


@pytest.mark.parametrize("extra", [
    '0,1,0.2,"1.5",0\n',      # quoted cell
    "0,1,0.2,nan,0\n",        # a lost sample written as a row
    "0,1,0.2,,0\n",           # the same, empty
    "0,1,0.2,0,0,9\n",        # a cell too many
    "0,1,0.2,0\n",            # a cell too few
    "0,1,0.0,5,5\n",          # a time twice
    "0,2,0.2,0,0\n",          # a robot not in meta.yaml
    "0,1.5,0.2,0,0\n",        # a robot id that is no integer
    "0,1,-0.1,0,0\n",         # a negative time
    "0,1,0.2,1_0,0\n",        # what float() reads but a CSV reader should not need to
])
def test_any_other_file_goes_to_the_row_by_row_reader(extra):
    """The one-pass reader takes plain files only; every other file is left to the row-by-row
    reader, which names the line of an error or reads a lost sample as a gap."""
    assert measured._plain_tracks(CSV + extra, 5, {c: j for j, c in enumerate(CSV.split("\n")[0].split(","))},
                                  {"trials": 1, "robots": [0, 1]}) is None
    assert measured._plain_tracks(CSV, 5,
                                  {c: j for j, c in enumerate(CSV.split("\n")[0].split(","))},
                                  {"trials": 1, "robots": [0, 1]}) is not None


def test_write_gives_the_rows_that_the_csv_module_reads_back_cell_for_cell(tmp_path):
    """``write`` against the standard library's csv reader and cells written out by hand: rows
    sorted by trial, robot and time whatever order the tracks come in, times to 4 decimals,
    values to 6 significant digits (small ones in exponent form), LED states as colours, and
    lines ending in CRLF, as the csv module writes them."""
    import csv

    motion = {(1, 0): measured.Track(np.array([0.0, 0.1]), {"x_m": np.array([1 / 3, -2.5e-7]),
                                                            "y_m": np.array([0.0113, 12345678.0]),
                                                            "theta_rad": np.array([-np.pi, 0.5])}),
              (0, 2): measured.Track(np.array([0.05]), {"x_m": np.array([1.0]), "y_m": np.array([-0.0]),
                                                        "theta_rad": np.array([2.0])})}
    meta = {"kind": "motion", "robots": [0, 2], "trials": 2, "dt_s": 0.05, "duration_s": 0.1,
            "behavior": "straight", "nominal_speed_m_s": 0.0113}
    d = measured.write(tmp_path / "m", meta, motion)
    raw = (d / "observations.csv").read_bytes()
    assert raw.count(b"\r\n") == 4 and raw.count(b"\n") == 4
    with open(d / "observations.csv", newline="") as f:
        rows = list(csv.reader(f))
    assert rows == [["trial", "robot_id", "t_s", "x_m", "y_m", "theta_rad"],
                    ["0", "2", "0.0500", "1", "-0", "2"],
                    ["1", "0", "0.0000", "0.333333", "0.0113", "-3.14159"],
                    ["1", "0", "0.1000", "-2.5e-07", "1.23457e+07", "0.5"]]
    blink = {(0, 0): measured.Track(np.array([0.0, 0.5, 1.0]), {"led": np.array([0.0, 1.0, 1.0])})}
    d = measured.write(tmp_path / "b", {"kind": "blink", "robots": [0], "trials": 1, "dt_s": 0.5,
                                        "duration_s": 1.0, "half_period_ticks": 32,
                                        "nominal_tick_hz": 31}, blink)
    with open(d / "observations.csv", newline="") as f:
        assert list(csv.reader(f)) == [["trial", "robot_id", "t_s", "led"], ["0", "0", "0.0000", "red"],
                                       ["0", "0", "0.5000", "blue"], ["0", "0", "1.0000", "blue"]]
    assert measured.load(d).track(0, 0).values["led"].tolist() == [0.0, 1.0, 1.0]
