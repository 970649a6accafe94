"""Physics against theory: circle radius, heading diffusion, straight-line speed."""

import numpy as np
import pytest

from kilobot_twin.core import kinematics, sim
from kilobot_twin.core.behaviors import Straight
from kilobot_twin.core.scenario import Scenario, StartSpec
from kilobot_twin.core.traits import SwarmTraits


def _fit_circle(x, y):
    """Algebraic (Kasa) least-squares circle fit; returns centre and radius."""
    A = np.column_stack([2 * x, 2 * y, np.ones_like(x)])
    b = x**2 + y**2
    cx, cy, c = np.linalg.lstsq(A, b, rcond=None)[0]
    return cx, cy, np.sqrt(c + cx**2 + cy**2)


@pytest.mark.parametrize("bias", [-0.04, -0.01, 0.005, 0.02, 0.04])
def test_noiseless_biased_robot_draws_circle_of_analytic_radius(bias):
    sc = Scenario(behavior=Straight(), dt_s=0.1, start=StartSpec(kind="origin", heading_rad=0.0))
    radius = kinematics.circle_radius_m(bias)
    v = sc.motors.forward_speed_m_s
    period_s = 2 * np.pi * radius / v
    sc = sc.replace(duration_s=period_s)
    traits = SwarmTraits.uniform(1).with_values(heading_bias=bias)
    res = sim.simulate(sc, traits, seed=1, record_every=10)
    x, y = res.traj["x"][0, 0], res.traj["y"][0, 0]
    cx, cy, r = _fit_circle(x, y)
    assert abs(r - radius) / radius < 0.005
    # Positive bias curves clockwise: starting along +x, the centre lies below (cy < 0).
    assert np.sign(cy) == -np.sign(bias)
    assert abs(cx) < 0.005 * radius


def test_straight_speed_is_kilobot_constant():
    sc = Scenario(behavior=Straight(), dt_s=0.1, duration_s=100.0)
    res = sim.simulate(sc, SwarmTraits.uniform(1), seed=0)
    # 48/255 of 6 cm/s for 100 s.
    assert res.summary["path_m"][0, 0] == pytest.approx(0.06 * 48 / 255 * 100, rel=1e-9)
    assert res.summary["x"][0, 0] == pytest.approx(0.06 * 48 / 255 * 100, rel=1e-9)


def test_heading_variance_grows_linearly_with_analytic_slope():
    """An unbiased robot with turn-rate noise sigma: Var(theta(t)) = sigma^2 t (Eq. 5).

    With M independent robots the sample variance s^2 of a normal quantity has relative
    standard error sqrt(2/(M-1)); we allow 4 of those (false-failure chance ~6e-5 per point).
    """
    sigma = 0.05
    M = 4000
    sc = Scenario(behavior=Straight(), dt_s=0.1, duration_s=100.0)
    traits = SwarmTraits.uniform(M).with_values(sigma_omega=sigma)
    res = sim.simulate(sc, traits, seed=7, record_every=100)
    th = res.traj["theta"][0]  # (M, T)
    var = th.var(axis=0, ddof=1)
    t = res.t_s
    tol = 4 * np.sqrt(2 / (M - 1))
    for ti, vi in zip(t[1:], var[1:]):
        assert abs(vi / (sigma**2 * ti) - 1) < tol
    # And the mean stays at zero (no bias): |mean| < 4 standard errors.
    assert np.all(np.abs(th[:, -1].mean()) < 4 * sigma * np.sqrt(t[-1] / M))


@pytest.mark.parametrize("tau", [0.5, 4.0])
def test_coloured_heading_noise_matches_the_ornstein_uhlenbeck_variance(tau):
    """Turn-rate noise with correlation time tau (an Ornstein-Uhlenbeck rate, long-run intensity
    sigma^2): Var(theta(t)) = sigma^2 (t - tau (1 - exp(-t / tau))) (the integrated OU process;
    e.g. Gardiner, Handbook of Stochastic Methods, 4.5.4). Short against tau the heading wanders
    less than white noise's sigma^2 t (ballistically, ~ sigma^2 t^2 / (2 tau)); long against it,
    it diffuses as white noise does. Tolerance as above: 4 relative standard errors of a variance
    over M robots (the discrete scheme is within 1.2 % of the continuous formula at t >= 0.5 s,
    dt 0.1 s, tau >= 0.5 s: a hand sum of the AR(1) autocovariances).
    """
    sigma = 0.05
    M = 4000
    sc = Scenario(behavior=Straight(), dt_s=0.1, duration_s=60.0)
    traits = SwarmTraits.uniform(M).with_values(sigma_omega=sigma, heading_noise_tau=tau)
    res = sim.simulate(sc, traits, seed=11, record_every=5)
    th = res.traj["theta"][0]
    th = th - th[:, :1]
    var = th.var(axis=0, ddof=1)
    t = res.t_s
    tol = 4 * np.sqrt(2 / (M - 1)) + 0.012
    for ti, vi in zip(t[1:], var[1:]):
        expected = sigma**2 * (ti - tau * (1 - np.exp(-ti / tau)))
        assert abs(vi / expected - 1) < tol, (ti, vi / expected)
    # At t = 1 s and tau = 4 s the heading has wandered 0.12 of white noise's variance.
    at = np.argmin(np.abs(t - 1.0))
    white = sigma**2 * t[at]
    assert var[at] / white == pytest.approx(1 - tau * (1 - np.exp(-t[at] / tau)) / t[at], rel=tol)


def test_turn_noise_correlation_decays_with_its_time():
    """Heading increments of one step, j steps apart, correlate as exp(-j dt / tau) (the OU
    rate's autocorrelation); white noise's do not correlate. Standard error of a correlation over
    M robots: about 1/sqrt(M)."""
    M = 4000
    sc = Scenario(behavior=Straight(), dt_s=0.1, duration_s=3.0)
    traits = SwarmTraits.uniform(M).with_values(sigma_omega=0.05,
                                                heading_noise_tau=np.where(np.arange(M) < M // 2, 1.0, 0.0))
    res = sim.simulate(sc, traits, seed=5, record_every=1)
    d = np.diff(res.traj["theta"][0], axis=1)
    for rows, tau in ((slice(0, M // 2), 1.0), (slice(M // 2, M), 0.0)):
        for j in (1, 5, 10):
            r = np.corrcoef(d[rows, 10], d[rows, 10 + j])[0, 1]
            expected = np.exp(-j * 0.1 / tau) if tau > 0 else 0.0
            assert abs(r - expected) < 4 / np.sqrt(M // 2), (tau, j, r)


def test_wheel_noise_heading_diffusion_matches_theory():
    """Uniform wheel factors U~U(-a,a): omega noise (v0/L)(U_R-U_L) each step, so
    Var(theta) grows by (v0 dt / L)^2 * 2 a^2/3 per step."""
    a = 0.5
    M = 4000
    sc = Scenario(behavior=Straight(), dt_s=0.1, duration_s=50.0)
    traits = SwarmTraits.uniform(M).with_values(wheel_noise=a)
    res = sim.simulate(sc, traits, seed=3)
    v0 = sc.motors.forward_speed_m_s
    per_step = (v0 * sc.dt_s / sc.motors.wheel_separation_m) ** 2 * 2 * a**2 / 3
    expected = per_step * sc.n_steps
    var = res.summary["theta"][0].var(ddof=1)
    assert abs(var / expected - 1) < 4 * np.sqrt(2 / (M - 1))


def test_speed_factor_scales_path_and_keeps_radius():
    sc = Scenario(behavior=Straight(), dt_s=0.1, duration_s=60.0)
    traits = SwarmTraits.uniform(2).with_values(speed_factor=[1.0, 1.3], heading_bias=0.02)
    res = sim.simulate(sc, traits, seed=0)
    p = res.summary["path_m"][0]
    assert p[1] / p[0] == pytest.approx(1.3, rel=1e-9)
    # Same radius: the heading turned is proportional to the path length.
    th = res.summary["theta"][0]
    assert th[1] / th[0] == pytest.approx(1.3, rel=1e-9)


def test_floor_tilt_makes_speed_depend_on_heading():
    sc = Scenario(behavior=Straight(), dt_s=0.1, duration_s=10.0, floor_tilt=0.2, floor_tilt_direction_rad=0.0)
    headings = np.array([0.0, np.pi / 2, np.pi])
    res = sim.simulate(sc, SwarmTraits.uniform(3), seed=0, poses=(0.0, 0.0, headings))
    v0 = sc.motors.forward_speed_m_s * 10
    np.testing.assert_allclose(res.summary["path_m"][0], v0 * (1 + 0.2 * np.cos(headings)), rtol=1e-9)
