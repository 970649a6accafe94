"""How often do the base's 90 % nuisance intervals hold another world's truth?

The gap report gives each noise level the base fits with a 90 % interval (``nuisance_ci90``,
``effects.noise_intervals``: a bootstrap over robots, the fit's simulated map resampled alongside).
This fits the base, as ``kilobot-twin gap`` does, to null datasets of the independent world
(``indep_world.py``: its own integrator, noise and tracker; every nuisance drawn per dataset as in
the evaluations), and counts how often each interval holds the level the world was drawn with.

- motion: ``sigma_omega`` against the world's heading noise, which is drawn white here
  (``heading_noise_tau_s`` 0) so that its intensity is what the twin's ``sigma_omega`` means;
  ``sigma_v`` against its speed noise, ``speed_trial_sd`` against its relative trial-to-trial
  speed jitter, ``bias_trial_sd`` against its turn-rate jitter read as a heading bias
  (b = -omega L / v at the population's speed).
- light_sweep: the reading noise per reading and the offset's trial-to-trial spread, in counts.
  A reading noise of 0 counts as held where the interval reaches the twin's rounding floor (a
  dithered twin goes no lower), and a sensor fitted without noise states no interval for it.
- blink: the clocks' relative trial-to-trial jitter. The world's tick phase also diffuses
  (``tick_diffusion``), which the twin has no term for and reads as jitter where robots start
  with the frames: ``--no-tick-diffusion`` draws worlds without it.

    python benchmarks/nuisance_ci.py --kind motion --first-seed 6902 --seeds 80 [--workers 2]
    python benchmarks/nuisance_ci.py --kind light_sweep --first-seed 6903 --seeds 40
    python benchmarks/nuisance_ci.py --kind blink --first-seed 6903 --seeds 40 [--no-tick-diffusion]
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from kilobot_twin.gap import effects as E
from kilobot_twin.gap import workflow as W
from kilobot_twin.gap.model import measured_summaries
from kilobot_twin.recording import measured

#: the twin's reading noise can go no lower than the ADC's rounding dithered (per sample), over
#: the samples a reading averages
READING_FLOOR = np.sqrt(E.ADC_ROUNDING_VAR / 10)


def _indep_world():
    spec = importlib.util.spec_from_file_location("indep_world", Path(__file__).parent / "indep_world.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def one(kind: str, seed: int, tick_diffusion: bool = True) -> dict:
    """The base's intervals and the world's truth for one null dataset."""
    iw = _indep_world()
    with tempfile.TemporaryDirectory() as d:
        over = {"heading_noise_tau_s": 0.0} if kind == "motion" else None
        if kind == "blink" and not tick_diffusion:
            over = {"tick_diffusion": 0.0}
        truth = iw.generate(kind, [], Path(d) / "ds", seed=seed, program="random", nuisance=over)
        cond, meas = measured_summaries(measured.load(Path(d) / "ds"))
    meas = E.Summaries(meas, np.arange(cond.trials))
    gs = W.GapSettings(seed=seed)
    fitter = W._Fitter(cond, meas, E.nominal_model(kind, cond.robot_ids, cond.forward_speed_m_s), gs, True)
    fitter.fit((), list(range(cond.trials)))
    ci = W._nuisance_intervals(fitter, meas, cond, gs)
    nz = truth["nuisance"]
    if kind == "motion":
        v = truth["population"]["speed_m_s"]
        true = {"sigma_omega_rad_sqrt_s": nz["heading_noise"], "sigma_v_m_sqrt_s": nz["speed_noise"],
                "speed_trial_sd": nz["speed_trial_sd"], "bias_trial_sd": nz["turn_trial_sd"] * iw.AXLE_M / v}
    elif kind == "light_sweep":
        true = {"reading_noise_counts": max(nz["sensor_noise"], READING_FLOOR),
                "sensor_offset_trial_sd_counts": nz["sensor_offset_trial_sd"]}
    else:
        true = {"clock_trial_sd": nz["clock_trial_sd"]}
    return {"seed": seed, "robots": len(cond.robot_ids), "trials": cond.trials, "truth": true, "ci": ci,
            "tracking_m": [nz["tracking_noise_m"], nz["tracking_correlated_m"]] if kind == "motion" else None}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--kind", choices=("motion", "light_sweep", "blink"), default="motion")
    ap.add_argument("--no-tick-diffusion", action="store_true", help="blink: worlds whose tick phase does not diffuse")
    ap.add_argument("--first-seed", type=int, default=6902)
    ap.add_argument("--seeds", type=int, default=40)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", default=None, help="write every dataset's intervals and truth here (JSON lines)")
    a = ap.parse_args(argv)
    from tqdm import tqdm

    rows = []
    with ProcessPoolExecutor(a.workers) as pool:
        jobs = [pool.submit(one, a.kind, s, not a.no_tick_diffusion) for s in range(a.first_seed, a.first_seed + a.seeds)]
        for j in tqdm(jobs, desc="datasets", unit="dataset"):
            rows.append(j.result())
    if a.out:
        Path(a.out).write_text("".join(json.dumps(r) + "\n" for r in rows))
    print(f"{a.kind}, independent world, seeds {a.first_seed}-{a.first_seed + a.seeds - 1}: "
          f"90 % intervals holding the truth")
    for k in rows[0]["truth"]:
        held = [r["ci"][k][0] <= r["truth"][k] <= r["ci"][k][1] for r in rows if k in r["ci"]]
        print(f"  {k:32s} {sum(held)}/{len(held)} ({100 * np.mean(held):.0f} %)")


if __name__ == "__main__":
    main()
