"""benchmarks/blink_trial_levels.py: the trial-to-trial scatter of a null blink against its own
world's, and one clear line for what it cannot read."""

from . import benchmark

btl = benchmark.load("blink_trial_levels")
iw = benchmark.load("indep_world")


def test_a_common_shift_of_one_trial_is_far_beyond_the_world_s_scatter(tmp_path, capsys):
    """An independent-world null blink (no clock jitter, no phase diffusion), and the same with
    every time of trial 0 scaled by 1 / 1.01 (its robots toggle 1 % faster): robots' rates
    within a trial scatter by about the rounding to frames, well below 1e-3, so the trial means
    vary hundreds of times what that allows. The unshifted dataset lies among its world's."""
    nz = {"clock_trial_sd": 0.0, "tick_diffusion": 0.0}
    iw.generate("blink", "none", tmp_path / "d", seed=5, nuisance=nz)
    assert btl.main([str(tmp_path / "d"), "--runs", "8"]) == 0
    out = capsys.readouterr().out.splitlines()
    data, runs = float(out[0].split("x ")[0].split()[-1]), out[1]
    assert data <= float(runs.split("max ")[1].split(";")[0]) * 3  # not far beyond its own world

    (tmp_path / "s").mkdir()
    (tmp_path / "s" / "meta.yaml").write_text((tmp_path / "d" / "meta.yaml").read_text())
    lines = (tmp_path / "d" / "observations.csv").read_text().splitlines()
    head, rows = lines[0], [r.split(",") for r in lines[1:]]
    t = head.split(",").index("t_s")
    for r in rows:
        if r[0] == "0":
            r[t] = f"{float(r[t]) / 1.01:.6f}"
    (tmp_path / "s" / "observations.csv").write_text("\n".join([head] + [",".join(r) for r in rows]) + "\n")
    assert btl.level_ratio(tmp_path / "s") > 100 * max(btl.level_ratio(tmp_path / "d"), 1.0)


def test_what_it_cannot_read_is_one_line_and_exit_2(tmp_path, capsys):
    assert btl.main([str(tmp_path / "none")]) == 2
    iw.generate("blink", "clock_drift", tmp_path / "c", seed=5)
    assert btl.main([str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 2 and all(e.startswith("error: ") for e in err)
