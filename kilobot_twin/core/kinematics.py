"""Differential-drive kinematics of a Kilobot with individual wheel imbalance and noise.

Paper Eqs. 1-3 (unicycle), 5 (noisy velocities) and 7 (wheel off-balance). All functions take
arrays of any common shape, typically (runs, robots), or 0-d arrays for a single robot.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from . import constants as C
from . import rng


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


def integrate(x, y, theta, v_left, v_right, sigma_v, sigma_omega, motion_keys, step: int, dt_s: float,
              wheel_separation_m: float = C.WHEEL_SEPARATION_M):
    """Advance poses by one step of ``dt_s`` (paper Eqs. 1, 3 and 5).

    ``v = (v_left + v_right) / 2``, ``omega = (v_right - v_left) / L``; while a wheel is driven,
    white noise of intensity ``sigma_v`` (m/sqrt(s)) and ``sigma_omega`` (rad/sqrt(s)) is added
    to path length and heading. Positions move along the chord at the mid-step heading, which
    is exact for the arc's direction and errs on its length by (omega dt)^2/24 relative.

    Returns
    -------
    x, y, theta : ndarray
        New pose; theta is not wrapped (so that heading diffusion can be measured directly).
    """
    ds = 0.5 * (v_left + v_right) * dt_s
    dth = (v_right - v_left) * (dt_s / wheel_separation_m)
    if np.any(sigma_v > 0) or np.any(sigma_omega > 0):
        active = (v_left != 0) | (v_right != 0)
        z_v, z_w = rng.normal_pair(motion_keys, step)
        root_dt = np.sqrt(dt_s)
        ds = ds + np.where(active, sigma_v * root_dt * z_v, 0.0)
        dth = dth + np.where(active, sigma_omega * root_dt * z_w, 0.0)
    mid = theta + 0.5 * dth
    return x + ds * np.cos(mid), y + ds * np.sin(mid), theta + dth


def circle_radius_m(heading_bias: float, wheel_separation_m: float = C.WHEEL_SEPARATION_M) -> float:
    """Analytic radius of the circle a noiseless robot driving 'straight' draws: ``L / |b|``.

    From ``v = v0`` and ``omega = -b v0 / L``: ``r = v / |omega| = L / |b|`` (independent of speed).
    """
    return wheel_separation_m / abs(heading_bias)


def heading_bias_from_turn_rate(turn_rate_rad_s, speed_m_s, wheel_separation_m: float = C.WHEEL_SEPARATION_M):
    """Heading bias (wheel imbalance, + = clockwise) a robot turning at ``turn_rate_rad_s`` while
    moving at ``speed_m_s`` has: ``b = -omega L / v`` (paper Eq. 7 solved for b)."""
    return -np.asarray(turn_rate_rad_s) * wheel_separation_m / np.asarray(speed_m_s)
