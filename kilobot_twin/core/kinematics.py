"""Differential-drive kinematics of a Kilobot with individual wheel imbalance and noise.

Paper Eqs. 1-3 (unicycle), 5 (noisy velocities) and 7 (wheel off-balance). All functions take
arrays of any common shape, typically (runs, robots), or 0-d arrays for a single robot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import constants as C
from . import libm, rng


@dataclass(frozen=True)
class MotorConfig:
    """Motor calibration values and the wheel geometry.

    A turn drives one wheel only, as the Kilobot library does: turning left runs the right
    wheel at ``turn_right``; turning right runs the left wheel at ``turn_left``.
    """

    straight_left: int = C.KILO_STRAIGHT_LEFT
    straight_right: int = C.KILO_STRAIGHT_RIGHT
    turn_left: int = C.KILO_TURN_LEFT
    turn_right: int = C.KILO_TURN_RIGHT
    wheel_speed_max_m_s: float = C.WHEEL_SPEED_MAX_M_S
    wheel_separation_m: float = C.WHEEL_SEPARATION_M

    def wheel_table_m_s(self) -> np.ndarray:
        """Nominal (left, right) wheel speeds for STOP, FORWARD, TURN_LEFT, TURN_RIGHT; shape (4, 2)."""
        k = self.wheel_speed_max_m_s / 255.0
        return k * np.array(
            [
                [0.0, 0.0],
                [self.straight_left, self.straight_right],
                [0.0, self.turn_right],
                [self.turn_left, 0.0],
            ]
        )

    @property
    def forward_speed_m_s(self) -> float:
        return self.wheel_speed_max_m_s * (self.straight_left + self.straight_right) / 2 / 255.0


def wheel_speeds(motion, heading_bias, speed_factor, wheel_noise, wheel_keys, step: int, motors: MotorConfig,
                 table: np.ndarray | None = None):
    """Actual (left, right) wheel speeds in m/s for each robot this step.

    ``left = nominal_left * speed_factor * (1 + b/2 + U_L)``,
    ``right = nominal_right * speed_factor * (1 - b/2 + U_R)``, with U uniform on
    [-wheel_noise, wheel_noise] drawn per wheel per step (the authors' simulator's noise).
    Positive ``b`` makes the left wheel faster: the robot curves clockwise (right).
    """
    table = motors.wheel_table_m_s() if table is None else table
    nominal = table[motion]  # (..., 2)
    half_b = 0.5 * heading_bias
    f_left = speed_factor * (1.0 + half_b)
    f_right = speed_factor * (1.0 - half_b)
    if np.any(wheel_noise > 0):
        a = wheel_noise * speed_factor
        f_left = f_left + a * (2.0 * rng.uniform(wheel_keys, 2 * step) - 1.0)
        f_right = f_right + a * (2.0 * rng.uniform(wheel_keys, 2 * step + 1) - 1.0)
    return nominal[..., 0] * f_left, nominal[..., 1] * f_right


def turn_noise_coefficients(sigma_omega, tau_s, dt_s: float):
    """The per-step coefficients ``(a, c, g)`` of the turn-rate noise, each shaped as the traits.

    The noise is a unit-variance AR(1) sequence ``zeta_k = a zeta_(k-1) + c z_k`` (z_k the
    step's standard normal, ``a = exp(-dt / tau)``, ``c = sqrt(1 - a^2)``): the exact sampling
    of an Ornstein-Uhlenbeck process with correlation time tau at the step times. The heading
    turns by ``g zeta_k`` per step, ``g = sigma_omega sqrt(dt (1 - a) / (1 + a))``, so that over
    n steps the heading's variance grows by ``n g^2 (1 + a) / (1 - a) = sigma_omega^2 n dt`` at
    long times whatever tau (``sum_j a^|j| = (1 + a) / (1 - a)``); over times short against tau
    it grows more slowly (as ``t^2`` rather than ``t``). ``tau = 0`` gives ``a = 0``, ``c = 1``,
    ``g = sigma_omega sqrt(dt)``: white noise, bit for bit the same as without the trait.
    """
    sigma = np.asarray(sigma_omega, dtype=np.float64)
    tau = np.broadcast_to(np.asarray(tau_s, dtype=np.float64), sigma.shape)
    coloured = tau > 0
    root_dt = np.sqrt(dt_s)
    if not np.any(coloured):
        return np.zeros(sigma.shape), np.ones(sigma.shape), sigma * root_dt
    a = np.where(coloured, libm.exp(-dt_s / np.where(coloured, tau, 1.0)), 0.0)
    c = np.sqrt(1.0 - a * a)
    g = np.where(coloured, sigma * root_dt * np.sqrt((1.0 - a) / (1.0 + a)), sigma * root_dt)
    return a, c, g


def integrate(x, y, theta, v_left, v_right, sigma_v, sigma_omega, motion_keys, step: int, dt_s: float,
              wheel_separation_m: float = C.WHEEL_SEPARATION_M, tau_s=0.0, turn_noise=None):
    """Advance poses by one step of ``dt_s`` (paper Eqs. 1, 3 and 5).

    ``v = (v_left + v_right) / 2``, ``omega = (v_right - v_left) / L``; while a wheel is driven,
    white noise of intensity ``sigma_v`` (m/sqrt(s)) is added to path length and noise of
    intensity ``sigma_omega`` (rad/sqrt(s)) to heading, white or with correlation time ``tau_s``
    (:func:`turn_noise_coefficients`; ``turn_noise`` holds its state zeta, which runs on while
    the robot stands). Positions move along the chord at the mid-step heading, which is exact
    for the arc's direction and errs on its length by (omega dt)^2/24 relative.

    Returns
    -------
    x, y, theta : ndarray
        New pose; theta is not wrapped (so that heading diffusion can be measured directly).
    turn_noise : ndarray
        The noise state after this step (``turn_noise`` as given when there is no motion noise).
    """
    ds = 0.5 * (v_left + v_right) * dt_s
    dth = (v_right - v_left) * (dt_s / wheel_separation_m)
    if turn_noise is None:
        turn_noise = np.zeros(np.shape(x))
    if np.any(sigma_v > 0) or np.any(sigma_omega > 0):
        active = (v_left != 0) | (v_right != 0)
        z_v, z_w = rng.normal_pair(motion_keys, step)
        root_dt = np.sqrt(dt_s)
        a, c, g = turn_noise_coefficients(sigma_omega, tau_s, dt_s)
        turn_noise = a * turn_noise + c * z_w
        ds = ds + np.where(active, sigma_v * root_dt * z_v, 0.0)
        dth = dth + np.where(active, g * turn_noise, 0.0)
    mid = theta + 0.5 * dth
    return x + ds * np.cos(mid), y + ds * np.sin(mid), theta + dth, turn_noise


def circle_radius_m(heading_bias: float, wheel_separation_m: float = C.WHEEL_SEPARATION_M) -> float:
    """Analytic radius of the circle a noiseless robot driving 'straight' draws: ``L / |b|``.

    From ``v = v0`` and ``omega = -b v0 / L``: ``r = v / |omega| = L / |b|`` (independent of speed).
    """
    return wheel_separation_m / abs(heading_bias)


def heading_bias_from_turn_rate(turn_rate_rad_s, speed_m_s, wheel_separation_m: float = C.WHEEL_SEPARATION_M):
    """Heading bias (wheel imbalance, + = clockwise) a robot turning at ``turn_rate_rad_s`` while
    moving at ``speed_m_s`` has: ``b = -omega L / v`` (paper Eq. 7 solved for b)."""
    return -np.asarray(turn_rate_rad_s) * wheel_separation_m / np.asarray(speed_m_s)
