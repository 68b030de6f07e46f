"""Ego vehicle motion: speed and yaw-rate profiles, body bounce, and the PTU.

Scenario time ``tau`` (s) is 0 at the start of the scenario's default drive;
the world frame is the road-level vehicle frame at ``tau = 0`` (x forward,
y left, z up, origin on the road below the rear axle).

* :class:`EgoPlan` gives speed (m/s) and yaw rate (rad/s, CCW +) as piecewise
  linear profiles, held constant outside their breakpoints. The road-level
  pose (x, y, heading) is their integral.
* :class:`BodyBounce` adds pitch, roll (rad) and heave (m) from road bumps.
  The vehicle's CAN signals do not contain them: this is the paper's reason
  for refining the camera motion from images. ISO 8855: pitch positive is
  nose down, roll positive is left side up.
* :class:`PtuPlan` turns the camera: smooth moves of pan (left +) and tilt (up +).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from appliance.vision.geometry import euler_to_matrix

FloatArray = NDArray[np.float64]

_DT = 0.001  # s, integration step of the road-level path


def _profile(breaks: tuple[tuple[float, float], ...], tau: FloatArray) -> FloatArray:
    t = np.array([b[0] for b in breaks], float)
    v = np.array([b[1] for b in breaks], float)
    out: FloatArray = np.interp(tau, t, v)
    return out


@dataclass(frozen=True)
class EgoPlan:
    """Speed and yaw-rate breakpoints ``((tau_s, value), ...)``, linear in between.

    ``speed``: m/s (forward); ``yaw_rate``: rad/s, counter-clockwise positive.
    """

    speed: tuple[tuple[float, float], ...]
    yaw_rate: tuple[tuple[float, float], ...] = ((0.0, 0.0),)

    def speed_at(self, tau: FloatArray | float) -> FloatArray:
        return _profile(self.speed, np.asarray(tau, float))

    def yaw_rate_at(self, tau: FloatArray | float) -> FloatArray:
        return _profile(self.yaw_rate, np.asarray(tau, float))


class EgoPath:
    """The integrated road-level pose of an :class:`EgoPlan` over [tau_lo, tau_hi].

    Pose (0, 0, 0) at ``tau = 0``. Integration by the trapezoid rule on a 1 ms
    grid, which is exact for a constant speed on a straight road (the collision
    courses).
    """

    def __init__(self, plan: EgoPlan, tau_lo: float, tau_hi: float) -> None:
        lo = min(tau_lo, 0.0) - 1.0
        hi = max(tau_hi, 0.0) + 1.0
        n = int(np.ceil((hi - lo) / _DT)) + 1
        self.tau: FloatArray = lo + _DT * np.arange(n, dtype=np.float64)
        i0 = int(round(-lo / _DT))
        self.tau[i0] = 0.0
        v = plan.speed_at(self.tau)
        w = plan.yaw_rate_at(self.tau)
        dt = np.diff(self.tau)
        psi = np.concatenate([[0.0], np.cumsum(0.5 * (w[1:] + w[:-1]) * dt)])
        psi -= psi[i0]
        vx, vy = v * np.cos(psi), v * np.sin(psi)
        x = np.concatenate([[0.0], np.cumsum(0.5 * (vx[1:] + vx[:-1]) * dt)])
        y = np.concatenate([[0.0], np.cumsum(0.5 * (vy[1:] + vy[:-1]) * dt)])
        s = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
        self.x, self.y, self.psi = x - x[i0], y - y[i0], psi
        self.s = s - s[i0]
        self.v, self.w = v, w
        self.plan = plan

    def pose(self, tau: FloatArray | float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Road-level (x, y, heading) at ``tau`` (world frame, m and rad)."""
        tau = np.asarray(tau, float)
        return (
            np.interp(tau, self.tau, self.x),
            np.interp(tau, self.tau, self.y),
            np.interp(tau, self.tau, self.psi),
        )

    def velocity(self, tau: FloatArray | float) -> tuple[FloatArray, FloatArray]:
        """World velocity (vx, vy), m/s."""
        _, _, psi = self.pose(tau)
        v = self.plan.speed_at(tau)
        return v * np.cos(psi), v * np.sin(psi)

    def arc_length(self, tau: FloatArray | float) -> FloatArray:
        out: FloatArray = np.interp(np.asarray(tau, float), self.tau, self.s)
        return out


@dataclass(frozen=True)
class Oscillation:
    """``amplitude * sin(2 pi f (tau - start) + phase)``,
    damped by ``exp(-zeta 2 pi f (tau - start))``
    after ``start`` (``zeta = 0``: a steady oscillation for all tau)."""

    amplitude: float
    freq_hz: float
    phase: float = 0.0
    start: float = -np.inf
    zeta: float = 0.0

    def __call__(self, tau: FloatArray) -> FloatArray:
        if self.zeta == 0.0:
            return self.amplitude * np.sin(2 * np.pi * self.freq_hz * tau + self.phase)
        dt = tau - self.start
        on = dt >= 0
        dtp = np.where(on, dt, 0.0)
        w = 2 * np.pi * self.freq_hz
        return np.where(on, self.amplitude * np.exp(-self.zeta * w * dtp) * np.sin(w * dtp), 0.0)


@dataclass(frozen=True)
class BodyBounce:
    """Pitch, roll (rad) and heave (m) of the body over the road, sums of oscillations."""

    pitch: tuple[Oscillation, ...] = ()
    roll: tuple[Oscillation, ...] = ()
    heave: tuple[Oscillation, ...] = ()

    @staticmethod
    def random(
        rng: np.random.Generator,
        tau_lo: float,
        tau_hi: float,
        pitch_scale: float = 1.0,
        roll_scale: float = 1.0,
    ) -> BodyBounce:
        """Road-induced bounce: steady 1-3 Hz pitching of a few tenths of a degree,
        plus bumps (damped 1.2-2 Hz responses) of up to about one degree; every pitch and
        roll amplitude times ``pitch_scale`` and ``roll_scale`` (a stiffer or softer car, a
        smoother or rougher road). The scales change no random draw."""
        bounce = BodyBounce._random(rng, tau_lo, tau_hi)
        return BodyBounce(
            tuple(dataclasses.replace(o, amplitude=pitch_scale * o.amplitude) for o in bounce.pitch),
            tuple(dataclasses.replace(o, amplitude=roll_scale * o.amplitude) for o in bounce.roll),
            bounce.heave,
        )

    @staticmethod
    def _random(rng: np.random.Generator, tau_lo: float, tau_hi: float) -> BodyBounce:
        deg = np.pi / 180.0
        pitch = [
            Oscillation(
                float(rng.uniform(0.08, 0.25)) * deg,
                float(rng.uniform(1.0, 1.6)),
                float(rng.uniform(0, 2 * np.pi)),
            ),
            Oscillation(
                float(rng.uniform(0.04, 0.12)) * deg,
                float(rng.uniform(2.0, 3.0)),
                float(rng.uniform(0, 2 * np.pi)),
            ),
        ]
        roll = [
            Oscillation(
                float(rng.uniform(0.05, 0.15)) * deg,
                float(rng.uniform(1.0, 2.0)),
                float(rng.uniform(0, 2 * np.pi)),
            )
        ]
        heave = [
            Oscillation(
                float(rng.uniform(0.004, 0.012)),
                float(rng.uniform(1.2, 2.0)),
                float(rng.uniform(0, 2 * np.pi)),
            )
        ]
        n_bumps = int(rng.poisson(0.3 * (tau_hi - tau_lo)))
        for start in np.sort(rng.uniform(tau_lo, tau_hi, n_bumps)):
            f = float(rng.uniform(1.2, 2.0))
            a = float(rng.uniform(0.3, 0.9)) * deg * float(rng.choice([-1.0, 1.0]))
            pitch.append(Oscillation(a, f, 0.0, float(start), 0.3))
            roll.append(Oscillation(0.4 * a * float(rng.uniform(-1, 1)), f, 0.0, float(start), 0.3))
            heave.append(Oscillation(0.02 * float(rng.uniform(-1, 1)), f, 0.0, float(start), 0.3))
        return BodyBounce(tuple(pitch), tuple(roll), tuple(heave))

    def at(self, tau: FloatArray | float) -> tuple[FloatArray, FloatArray, FloatArray]:
        """(pitch, roll, heave) at ``tau``."""
        tau = np.asarray(tau, float)
        zero = np.zeros_like(tau)
        return (
            sum((o(tau) for o in self.pitch), zero),
            sum((o(tau) for o in self.roll), zero),
            sum((o(tau) for o in self.heave), zero),
        )


def world_from_vehicle(
    x: float, y: float, psi: float, pitch: float = 0.0, roll: float = 0.0, heave: float = 0.0
) -> FloatArray:
    """4x4 world-from-vehicle transform: ``T(x, y, heave) Rz(psi) Ry(pitch) Rx(roll)``."""
    T = np.eye(4)
    T[:3, :3] = euler_to_matrix(np.array([roll, pitch, psi]))
    T[:3, 3] = (x, y, heave)
    return T


@dataclass(frozen=True)
class PtuMove:
    """Move to (pan, tilt) rad from ``start`` s, taking ``duration`` s (smooth cosine ramp)."""

    start: float
    duration: float
    pan: float
    tilt: float = 0.0


@dataclass(frozen=True)
class PtuPlan:
    """The PTU starts at (pan0, tilt0) and executes ``moves`` in order."""

    pan0: float = 0.0
    tilt0: float = 0.0
    moves: tuple[PtuMove, ...] = field(default_factory=tuple)

    def at(self, tau: FloatArray | float) -> tuple[FloatArray, FloatArray]:
        """True (pan, tilt) rad at ``tau``."""
        tau = np.asarray(tau, float)
        pan = np.full_like(tau, self.pan0)
        tilt = np.full_like(tau, self.tilt0)
        for m in self.moves:
            k = np.clip((tau - m.start) / max(m.duration, 1e-9), 0.0, 1.0)
            w = 0.5 - 0.5 * np.cos(np.pi * k)
            pan = np.where(tau >= m.start, pan + w * (m.pan - pan), pan)
            tilt = np.where(tau >= m.start, tilt + w * (m.tilt - tilt), tilt)
        return pan, tilt
