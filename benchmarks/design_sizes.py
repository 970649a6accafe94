"""Does a report's detection size for more robots or trials hold on data of that design?

Each report scales its detection sizes to other designs (``at_other_designs``: a trial or two
more, twice the trials, twice the robots) by the exact F test's size at both, from the size it
emulates on the data at hand (``workflow.other_designs``). This checks that on the independent
world (``indep_world.py``, another code base): per seed, a null dataset of the fixed shape (12
robots x 4 trials at 10 Hz, or 16 x 4 blinks at 30 Hz; every nuisance at ``--nuisance-scale`` x
nominal) gives the report's size at ``--design`` (robots x trials); the same world at that design
is then written with the effect at exactly that size (its spread over the robots; the world's noise
drawn afresh), and the workflow is run on it. With ``--design`` the fixed shape itself, the size is
the report's own detection size, which the others are scaled from. Counted: the datasets in which the detection step
flags the effect's signal in round 0 (should be 80 % +- the binomial spread), and those that name it.

    python benchmarks/design_sizes.py --effect bias_drift --design 12x6 --first-seed 7000 --seeds 40
    python benchmarks/design_sizes.py --effect heading_bias --design 24x4 --seeds 40
    python benchmarks/design_sizes.py --effect bias_drift --design 12x5 --seeds 20 --stated 0.0045

``--stated SIZE`` writes null data of the design itself and prints the sizes their reports state,
named and detected, and in how many each is below SIZE (the issue's drift: 0.0045 rad/s per trial).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))

from eval_gap import realised_sizes, scale_to_size  # noqa: E402  (the effects' sizes as the evaluations set them)

#: effect -> (kind, the signal whose flag is its detection)
EFFECTS = {"heading_bias": ("motion", "turn_rate:between_robots"), "bias_drift": ("motion", "turn_rate:trial_trend"),
           "speed_heterogeneity": ("motion", "speed:between_robots"), "sensor_gain": ("light_sweep", "gain:between_robots"),
           "clock_drift": ("blink", "toggle_rate:between_robots")}


def _gap(ds: Path, out: Path, seed: int) -> dict:
    from kilobot_twin.gap.workflow import GapSettings, run_gap

    return run_gap([str(ds)], out, gs=GapSettings(seed=seed), log=lambda *a: None)


def one(effect: str, design: tuple, seed: int, nuisance_scale: float) -> dict:
    """The size stated for ``design`` on the fixed shape's null data, and the workflow on that design
    with the effect at that size."""
    import indep_world as iw

    kind, signal = EFFECTS[effect]
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        shape = iw.generate(kind, [], d / "null", seed=seed, nuisance_scale=nuisance_scale, fixed_shape=True)["shape"]
        mde = _gap(d / "null", d / "null_gap", seed)["datasets"][0]["minimum_detectable"][effect]
        own = [{"robots": shape["robots"], "trials": shape["trials"], "detection_size": mde["detection_size"]}]
        stated = next((x for x in own + mde.get("at_other_designs", []) if (x["robots"], x["trials"]) == design), None)
        if stated is None:
            return {"seed": seed, "skipped": f"no size stated for {design[0]} x {design[1]}"}
        def write(scale):
            return iw.generate(kind, [effect], d / "ds", seed=seed, nuisance_scale=nuisance_scale, effect_scale=scale,
                               fixed_shape=True, design=design)

        truth = write(scale_to_size(write, effect, stated["detection_size"]))  # its spread over the robots: the size stated
        rep = _gap(d / "ds", d / "gap", seed)
    flagged = {x["signal"] for x in rep["disagreements"] if x["round"] == 0}
    return {"seed": seed, "here": mde["detection_size"], "stated": stated["detection_size"], "size": realised_sizes(truth)[effect],
            "flagged": signal in flagged, "named": effect in rep["named_effects"], "named_effects": rep["named_effects"]}


def stated_at(effect: str, design: tuple, seed: int, nuisance_scale: float) -> dict:
    """What a null report of the design itself states (``--stated``): the size named and detected."""
    import indep_world as iw

    kind, _ = EFFECTS[effect]
    with tempfile.TemporaryDirectory() as d:
        d = Path(d)
        iw.generate(kind, [], d / "null", seed=seed, nuisance_scale=nuisance_scale, fixed_shape=True, design=design)
        mde = _gap(d / "null", d / "null_gap", seed)["datasets"][0]["minimum_detectable"][effect]
    return {"seed": seed, "size": mde["size"], "detection_size": mde["detection_size"]}


def _design(text: str) -> tuple:
    try:
        n, k = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: write robots x trials, e.g. 12x6") from None
    return n, k


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--effect", choices=sorted(EFFECTS), default="bias_drift")
    ap.add_argument("--design", type=_design, default=(12, 6), help="robots x trials, one of the report's designs")
    ap.add_argument("--nuisance-scale", type=float, default=2.0)
    ap.add_argument("--first-seed", type=int, default=7000)
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=None, help="write each dataset's row here (JSON lines)")
    ap.add_argument("--stated", type=float, default=None, metavar="SIZE",
                    help="instead: the sizes that null reports of the design itself state, against SIZE")
    a = ap.parse_args(argv)
    from tqdm import tqdm

    rows = []
    with ProcessPoolExecutor(a.workers) as pool:
        fn = one if a.stated is None else stated_at
        jobs = [pool.submit(fn, a.effect, a.design, s, a.nuisance_scale) for s in range(a.first_seed, a.first_seed + a.seeds)]
        for j in tqdm(jobs, desc="datasets", unit="dataset"):
            rows.append(j.result())
    if a.out:
        Path(a.out).write_text("".join(json.dumps(r) + "\n" for r in rows))
    if a.stated is not None:
        print(f"{a.effect}: null reports of {a.design[0]} robots x {a.design[1]} trials (independent world, nuisances "
              f"{a.nuisance_scale}x, seeds {a.first_seed}-{a.first_seed + a.seeds - 1})")
        for key, what in (("size", "named"), ("detection_size", "detected")):
            x = np.array([np.inf if r[key] is None else r[key] for r in rows])
            print(f"  {what}: median {np.median(x):.3g}, below {a.stated:g} in {(x < a.stated).sum()}/{len(x)}")
        return
    done = [r for r in rows if "skipped" not in r]
    n, flagged, named = len(done), sum(r["flagged"] for r in done), sum(r["named"] for r in done)
    sd = np.sqrt(0.8 * 0.2 / max(n, 1))
    print(f"{a.effect} on {a.design[0]} robots x {a.design[1]} trials (independent world, nuisances {a.nuisance_scale}x, "
          f"seeds {a.first_seed}-{a.first_seed + a.seeds - 1}), at the detection size each null report of the fixed shape states for it:")
    print(f"  flagged {flagged}/{n} ({100 * flagged / max(n, 1):.0f} %; 80 % +- {200 * sd:.0f} at 2 binomial sd), "
          f"named {named}/{n}; skipped {len(rows) - n}")
    if done:
        ratio = np.array([r["stated"] / r["here"] for r in done])
        print(f"  size stated there / size at the fixed shape: median {np.median(ratio):.3f}; "
              f"size stated: median {np.median([r['stated'] for r in done]):.3g}")


if __name__ == "__main__":
    main()
