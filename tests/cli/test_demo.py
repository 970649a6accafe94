"""`make demo` works every time: each run gets its own folder, `latest` points at the newest,
an earlier run (its bag above all) is never touched."""

import hashlib
import os
from pathlib import Path


from kilobot_twin import cli, demo


def _digest(folder: Path) -> dict:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def test_new_run_dir_is_fresh_and_latest_follows(tmp_path):
    a = demo.new_run_dir(tmp_path / "d")
    b = demo.new_run_dir(tmp_path / "d")  # same second: a suffix, never the same folder
    assert a != b and a.is_dir() and b.is_dir()
    demo.point_latest(a)
    assert (tmp_path / "d" / "latest").resolve() == a.resolve()
    demo.point_latest(b)
    assert (tmp_path / "d" / "latest").resolve() == b.resolve()
    assert os.readlink(tmp_path / "d" / "latest") == b.name  # relative: the folder can move


def test_latest_that_is_a_real_folder_is_left_alone(tmp_path):
    (tmp_path / "d" / "latest").mkdir(parents=True)
    (tmp_path / "d" / "latest" / "mine.txt").write_text("user data")
    demo.point_latest(demo.new_run_dir(tmp_path / "d"))
    assert (tmp_path / "d" / "latest" / "mine.txt").read_text() == "user data"


def test_demo_twice_into_the_same_out(tmp_path, monkeypatch, capsys):
    monkeypatch.setattr(demo, "QUICK_TWIN_S", 2.0)
    monkeypatch.setitem(demo.DEMO_CONFIG["scenario"], "duration_s", 30.0)  # a short campaign: this is about files
    out = tmp_path / "demo"
    assert cli.main(["demo", "--quick", "--out", str(out), "--no-progress", "--workers", "1"]) == 0
    first = (out / "latest").resolve()
    before = _digest(first)
    assert (first / "bags" / "twin" / "metadata.yaml").is_file() and (first / "twin.rrd").is_file()
    assert cli.main(["demo", "--quick", "--out", str(out), "--no-progress", "--workers", "1"]) == 0
    second = (out / "latest").resolve()
    assert second != first
    for run in (first, second):
        assert (run / "bags" / "twin" / "metadata.yaml").is_file()
        assert (run / "twin.rrd").is_file() and (run / "summary.md").is_file() and (run / "phototaxis.png").is_file()
    assert _digest(first) == before  # the first run, its bag included, untouched
    printed = capsys.readouterr().out
    assert "make view" in printed and str(second) in printed
    # The summary says which bias scale its numbers are on and defines its terms.
    import json

    doc = json.loads((second / "summary.json").read_text())
    assert doc["bias_scale"] == {"axis": "paper", "wheel_imbalance_per_axis_unit": 10.0}
    md = (second / "summary.md").read_text()
    for term in ("**P_R**", "**cost**", "**R_acc**", "**N_acc**", "paper axis"):
        assert term in md, term
