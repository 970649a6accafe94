"""A tilted floor, as an effect of your own for ``kilobot-twin gap --effects``.

The gap library has no floor tilt on purpose: on a tilted floor the workflow flags
``speed:heading_dependence`` (a robot's speed follows the heading it drove in) and ends
``unexplained``, since no effect of the library accounts for it. The twin's core does model a
tilted floor (every robot's speed times ``1 + floor_tilt cos(heading - floor_tilt_direction_rad)``,
fields of a scenario file), so this effect only has to fit those two numbers; the workflow
simulates, scores and names it as it does the library's, and reports the gap it removed:

    kilobot-twin gap DATA --effects docs/examples/floor_tilt.py --out out/tilt

Fit: each track's speed relative to its robot's mean, regressed on the cosine and sine of the
track's mean heading (per robot centred, pooled over robots), gives A cos phi and A sin phi of
speed = v (1 + A cos(heading - phi)). A track's summaries blur that (tracking noise lengthens
chords by the same amount whatever the speed; a robot's heading wanders within a trial), so one
simulation of the fitted floor is regressed the same way and the amplitude scaled, and the
direction turned, by what it lost; and the population's speed level matched again (the base
matched it without a floor, so it holds what the tilt added on average over the headings the
trials happened to take: a per cent, at 12 robots, that every held-out trial then missed by).

The noise levels, again: the base model, fitted without a tilt, took the speed changes the tilt
makes from trial to trial for trial-to-trial speed jitter (a nuisance it fits from the data).
With that jitter kept, the tilted twin's trial speeds vary far more than the data's and the flag
stays. So the effect fits the noise levels again (``refits_noise``; the library's own
``fit_noise_levels``) on speeds with the tilt taken out: the data's by their own regression, and
every simulated replicate's by its own. (Fitted on speeds with the tilt left in, the jitter read
whatever a few per cent of error in the amplitude leaves, which at a tilt of 0.15 is a jitter of
0.03.) Any effect whose signal the base had read as noise must do the same.

What the data can see: ``at_size`` puts a floor of a given slope into a model (downhill in a
direction drawn from the ``rng`` it is handed), so the report states the smallest slope these data
flag with 80 % power (``workflow.simulated_detection``: the twin simulated on such floors under the
data's conditions), and "nothing named" reads "no tilt larger than that".
"""

import numpy as np

from kilobot_twin.gap.effects import Effect, Summaries, fit_noise_levels


def tilt_coefficients(speed, heading):
    """(a, b) of the regression of relative speed on (cos, sin) of the heading, each robot's trials
    centred on its own means, pooled over robots: summaries (..., K, N) -> (..., 2), one
    regression per leading index (a simulated replicate)."""
    speed, heading = np.asarray(speed, float), np.asarray(heading, float)
    ok = np.isfinite(speed) & np.isfinite(heading)
    cols = []
    with np.errstate(all="ignore"):
        rel = speed / np.nanmean(np.where(ok, speed, np.nan), axis=-2, keepdims=True)
        for a in (rel, np.cos(heading), np.sin(heading)):
            a = np.where(ok, a, np.nan)
            cols.append(np.nan_to_num(a - np.nanmean(a, axis=-2, keepdims=True)))
    y, c, s = cols

    def S(u, v):
        return (u * v).sum((-2, -1))

    A = np.stack([np.stack([S(c, c), S(c, s)], -1), np.stack([S(c, s), S(s, s)], -1)], -2)
    return np.linalg.solve(A, np.stack([S(c, y), S(s, y)], -1)[..., None])[..., 0]


def untilted(summaries):
    """The summaries with each track's speed divided by the tilt its own regression finds."""
    out = dict(summaries)
    ab = tilt_coefficients(summaries["speed"], summaries["heading"])[..., None, None, :]
    h = np.asarray(summaries["heading"], float)
    out["speed"] = summaries["speed"] / (1 + ab[..., 0] * np.cos(h) + ab[..., 1] * np.sin(h))
    return Summaries(out, summaries.trials) if isinstance(summaries, Summaries) else out


class FloorTilt(Effect):
    """A floor that slopes one way for the whole swarm: speed x (1 + A cos(heading - phi))."""

    name, kind = "floor_tilt", "motion"
    predicts = {"speed": "pop"}  # two numbers for the whole swarm, from all robots' trials
    refits_noise = True  # the trial-to-trial speed jitter the base had read off the tilt
    # For the report's "what this dataset can see": the floor at a size (at_size), the sizes to
    # search and what a size is.
    size_unit = "floor slope A: speed x (1 + A cos(heading - downhill))"
    size_range = (0.005, 0.5)

    def explains(self, signal):
        return signal == "speed:heading_dependence"

    def at_size(self, model, size, rng):
        """The model on a floor of slope ``size``, downhill in a direction drawn from ``rng``."""
        return model.with_traits(scenario={"floor_tilt": size, "floor_tilt_direction_rad": float(rng.uniform(-np.pi, np.pi))})

    def fit(self, model, meas, ref, resim=None, noise=None):
        a, b = tilt_coefficients(meas["speed"], meas["heading"])
        amp, phi = float(np.hypot(a, b)), float(np.arctan2(b, a))
        m = model.with_traits(scenario={"floor_tilt": min(amp, 0.9), "floor_tilt_direction_rad": phi})
        if resim is None:
            return m
        if noise is not None:  # a fold: the noise levels of the fit on all trials
            sw = noise.swarm
            m = m.with_traits(speed_trial_sd=noise.speed_trial_sd, sigma_omega=sw.sigma_omega,
                              sigma_v=sw.sigma_v, bias_trial_sd=sw.bias_trial_sd)
        else:  # first, so that the step below simulates the tilt under the data's own noise
            m = fit_noise_levels(m, untilted(meas), lambda mm: untilted(resim(mm)))
        sim = resim(m)
        if amp > 0:  # one step: what the summaries keep of the fitted floor
            a1, b1 = tilt_coefficients(sim["speed"], sim["heading"]).mean(0)
            if np.hypot(a1, b1) > 0:
                amp, phi = amp * amp / np.hypot(a1, b1), phi + phi - float(np.arctan2(b1, a1))
                m = m.with_traits(scenario={"floor_tilt": float(min(amp, 0.9)),
                                            "floor_tilt_direction_rad": float(np.angle(np.exp(1j * phi)))})
        # The speed level again: the base matched it to these trials without a floor, so it holds
        # what the tilt added on average over the headings they happened to take.
        ok = np.isfinite(meas["speed"])
        level = np.nanmean(meas["speed"]) / np.nanmean(np.where(ok, sim["speed"], np.nan))
        return m.with_traits(speed_factor=m.swarm.speed_factor * level)
