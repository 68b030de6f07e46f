"""A simulated drive, frame by frame, and the recording it writes.

``SimulatedDrive`` streams :class:`SimStep` objects (image, CAN frames and PTU
samples since the previous frame, truth); ``simulate`` writes them as a drive
recording with ``truth.json``. The demo and the benchmarks use the stream.

Recording clock: the first frame is at ``T0 = 1000.0`` s; CAN and PTU start
0.1 s earlier. ``collision_t`` and every time in the truth are on this clock.
"""

from __future__ import annotations

import dataclasses
import zlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import numpy as np
from numpy.typing import NDArray

from appliance import __version__
from appliance.config import Config, load_config, resource_path
from appliance.errors import UsageError
from appliance.recording import CanDecoding, RecordingMeta
from appliance.sim import sensors
from appliance.sim.collision import (
    Vehicle,
    collision_time,
    footprint_corners,
    gap,
    relative_pose,
    relative_velocity,
)
from appliance.sim.effects import EffectsPipeline
from appliance.sim.ego import BodyBounce, EgoPath, world_from_vehicle
from appliance.sim.look import Look
from appliance.sim.materials import TextureBank
from appliance.sim.movers import SIZES, Trajectory
from appliance.sim.render import Renderer
from appliance.sim.scenarios import SCENARIOS, Plan
from appliance.sim.street import Centreline, KeepClear, StreetBuilder
from appliance.sim.truth import boxes_near_image, project_box, truth_record
from appliance.sim.world import Body, StaticObject, box_faces
from appliance.vision.geometry import (
    PinholeCamera,
    relative_motion,
    rotational_flow,
    vehicle_from_camera,
)

T0 = 1000.0  # s, recording-clock time of the first frame
SENSOR_LEAD_S = 0.1  # s, CAN and PTU start this long before the first frame
MAX_DURATION_S = 600.0
VIDEO_FORMATS = ("mkv", "avi", "png")


@dataclass(frozen=True)
class SimStep:
    """One frame of a simulated drive.

    image: (H, W) uint8 gray or (H, W, 3) BGR (a colour look); can_messages: frames with
    timestamps in (previous frame, t] (the first step also gets those before it); ptu_samples: (t, pan_rad, tilt_rad) likewise;
    truth_frame: {"camera_pose": 4x4 world-from-camera, "objects": {id: {bbox, visible,
    pos_vehicle, vel_vehicle}}}; ids: (H, W) uint16 object id of every pixel (0 = road/sky).
    """

    index: int
    t: float
    image: NDArray[np.uint8]
    can_messages: list[can.Message]
    ptu_samples: list[tuple[float, float, float]]
    truth_frame: dict[str, Any]
    ids: NDArray[np.uint16]


@dataclass(frozen=True)
class Mover:
    body: Body
    trajectory: Trajectory


def _r(x: float, nd: int) -> float:
    return float(round(float(x), nd))


def _streams(scenario: str, seed: int) -> list[np.random.Generator]:
    """The drive's independent random streams: 0 timeline, 1 street layout, 3 body bounce,
    5 sensor noise, 6 CAN and PTU, 7 look (2 and 4 unused)."""
    seq = np.random.SeedSequence([seed, zlib.crc32(scenario.encode())])
    return [np.random.default_rng(s) for s in seq.spawn(8)]


def drive_look(scenario: str, seed: int, cfg: Config | None = None) -> Look:
    """The look (camera, mount, materials, bounce, sensor) the drive of ``scenario`` and
    ``seed`` is seen with, for the image size of ``cfg`` (default ``load_config()``)."""
    c = (cfg if cfg is not None else load_config()).camera
    return Look.draw(_streams(scenario, seed)[7], c.width, c.height)


class SimulatedDrive:
    """The frames of one scenario (see :mod:`appliance.sim.scenarios`), deterministic per seed.

    :param duration: seconds of drive ending at the scenario's end (the collision for
        collision scenarios); default the scenario's own.
    :param cfg: image size, lens distortion, the camera's position on the vehicle and the
        vehicle outline (default: ``load_config()``); the focal length, principal point,
        mount height and pitch come from the look.
    :param look: how the drive is seen (see :mod:`appliance.sim.look`); default drawn from the
        scenario and seed (:func:`drive_look`).
    :raises UsageError: unknown scenario, negative seed, bad duration.
    """

    def __init__(
        self,
        scenario: str,
        seed: int,
        duration: float | None = None,
        cfg: Config | None = None,
        *,
        look: Look | None = None,
    ) -> None:
        if scenario not in SCENARIOS:
            raise UsageError(f"unknown scenario {scenario!r} (known: {', '.join(SCENARIOS)})")
        if seed < 0:
            raise UsageError(f"--seed must be >= 0, got {seed}")
        if duration is not None and not 0.0 < duration <= MAX_DURATION_S:
            raise UsageError(
                f"--duration must be > 0 and <= {MAX_DURATION_S:g} s, got {duration:g}"
            )
        self.cfg = cfg if cfg is not None else load_config()
        self.name, self.seed = scenario, seed
        c = self.cfg.camera
        rng = _streams(scenario, seed)
        self.look = look if look is not None else Look.draw(rng[7], c.width, c.height)
        lk = self.look
        self.camera = PinholeCamera(c.width, c.height, lk.fx, lk.fy, lk.cx, lk.cy,
                                    tuple(c.distortion))
        self.mount = dataclasses.replace(
            self.cfg.mount, z_m=lk.mount_height_m, pitch_rad=lk.mount_pitch_rad
        )
        m = self.mount
        self.vehicle = Vehicle(m.vehicle_front_m, m.vehicle_rear_m, m.vehicle_width_m, m.x_m, m.y_m)
        self.plan: Plan = SCENARIOS[scenario].make(self.vehicle)
        self._timeline(duration, rng[0])
        self._world(rng[1])
        self.bounce = BodyBounce.random(
            rng[3], self.tau_start - 1.0, self.tau_end + 1.0,
            lk.bounce_pitch_scale, lk.bounce_roll_scale,
        )
        self.effects = lk.effects
        self._effects_seed = int(rng[5].integers(2**63))  # every iteration replays the same noise
        self._sensors(rng[6])
        self.meta = RecordingMeta(
            camera=self.camera,
            mount=m,
            can=CanDecoding(
                str(resource_path("vehicle.dbc")),
                "VEHICLE_SPEED.SPEED",
                "km/h",
                "YAW_RATE.YAW_RATE",
                "deg/s",
                1,
            ),
            extra={
                "simulator": {
                    "scenario": scenario,
                    "seed": seed,
                    "duration_s": _r(self.duration, 6),
                    "version": __version__,
                    **lk.table(),
                }
            },
        )
        self.truth_header: dict[str, Any] = {
            "scenario": scenario,
            "collision": self.collision_tau is not None,
            "collision_t": None if self.collision_tau is None else self.clock(self.collision_tau),
            "collision_object": self.collision_object,
            "objects": [
                {"id": o.body.obj, "class": o.body.kind, "moving": o.trajectory.moves()}
                for o in self.movers
            ]
            + [{"id": s.body.obj, "class": s.body.kind, "moving": False} for s in self.parked],
        }

    # ------------------------------------------------------------ set-up

    def _timeline(self, duration: float | None, rng: np.random.Generator) -> None:
        plan = self.plan
        probe = EgoPath(plan.ego, -5.0, 80.0)
        hits = [
            (collision_time(probe, mv.trajectory, SIZES[mv.kind], self.vehicle, -5.0, 75.0), k)
            for k, mv in enumerate(plan.movers)
        ]
        found = sorted((t, k) for t, k in hits if t is not None)
        if plan.end_s is None:
            if not found:
                raise RuntimeError(f"scenario {self.name} ends at a collision but none occurs")
            self.tau_end = found[0][0]
        else:
            self.tau_end = plan.end_s
        self.duration = float(duration if duration is not None else plan.duration_s)
        self.tau_start = self.tau_end - self.duration
        n = int(np.ceil(self.duration * sensors.FPS - 1e-9)) + 1
        self.frame_offsets = sensors.frame_times(rng, n)
        self.frame_offsets[-1] = max(self.frame_offsets[-1], (n - 1) / sensors.FPS)
        self.path = EgoPath(plan.ego, self.tau_start - 2.0, self.tau_end + 12.0)
        hits = [
            (
                collision_time(
                    self.path,
                    mv.trajectory,
                    SIZES[mv.kind],
                    self.vehicle,
                    self.tau_start,
                    self.tau_end + 10.0,
                ),
                k,
            )
            for k, mv in enumerate(plan.movers)
        ]
        found = sorted((t, k) for t, k in hits if t is not None)
        self.collision_tau = found[0][0] if found else None
        self.collision_object = found[0][1] + 1 if found else None

    def _world(self, rng_layout: np.random.Generator) -> None:
        self.bank = TextureBank.for_seed(self.seed, self.look.texture_contrast)
        self.movers = []
        keep = []
        for k, mv in enumerate(self.plan.movers):
            size = SIZES[mv.kind]
            body = Body(
                k + 1,
                mv.kind,
                size,
                box_faces(
                    *size,
                    self.bank.skin(mv.kind, k, self.look.plain_movers),
                    self.bank.textures,
                    k + 1,
                ),
            )
            self.movers.append(Mover(body, mv.trajectory))
            taus = np.arange(self.tau_start - 1.0, self.tau_end + 5.0, 0.05)
            keep.append(
                KeepClear(
                    mv.trajectory.position(taus), 0.5 * float(np.hypot(size[0], size[1])) + 0.4
                )
            )
        s_lo = float(self.path.arc_length(self.tau_start)) - 60.0
        s_hi = float(self.path.arc_length(self.tau_end)) + 200.0
        builder = StreetBuilder(
            self.plan.street, Centreline(self.path), self.bank, rng_layout, keep
        )
        self.static_faces, statics = builder.build(s_lo, s_hi)
        self.statics: list[StaticObject] = statics
        self.parked: list[StaticObject] = [s for s in statics if s.body.kind == "car"]
        self._parked_corners = np.array(
            [s.body.corners(s.x, s.y, s.yaw) for s in self.parked]
        ).reshape(-1, 8, 3)

    def _sensors(self, rng: np.random.Generator) -> None:
        t_first, t_last = T0 - SENSOR_LEAD_S, T0 + float(self.frame_offsets[-1])
        vcan = sensors.VehicleCan(resource_path("vehicle.dbc"), sensors.CanErrors.random(rng), rng)
        self.can_errors = vcan.errors
        ts = vcan.schedule(t_first, t_last)
        ty = ts + 0.01
        ty = ty[ty <= t_last]
        tau_s, tau_y = self.tau(ts), self.tau(ty)
        self._can = vcan.messages(
            ts,
            self.plan.ego.speed_at(tau_s),
            self.plan.ego.yaw_rate_at(tau_s),
            ty,
            self.plan.ego.yaw_rate_at(tau_y),
        )
        tp = sensors.ptu_samples(rng, t_first, t_last)
        pan, tilt = self.plan.ptu.at(self.tau(tp))
        self._ptu = list(
            zip(
                tp.tolist(), sensors.quantise_ptu(pan).tolist(), sensors.quantise_ptu(tilt).tolist()
            )
        )

    # ------------------------------------------------------------ time

    def clock(self, tau: float) -> float:
        """Recording-clock time (s) of scenario time ``tau``."""
        return T0 + float(tau) - self.tau_start

    def tau(self, t: NDArray[np.float64] | float) -> NDArray[np.float64]:
        return np.asarray(t, float) - T0 + self.tau_start

    @property
    def n_frames(self) -> int:
        return int(len(self.frame_offsets))

    def __len__(self) -> int:
        return self.n_frames

    def frame_time(self, k: int) -> float:
        return T0 + float(self.frame_offsets[k])

    @property
    def can_messages(self) -> list[can.Message]:
        """Every CAN frame of the drive (sorted by time; the steps hand them out frame by frame)."""
        return list(self._can)

    @property
    def ptu_samples(self) -> list[tuple[float, float, float]]:
        """Every PTU sample (t, pan_rad, tilt_rad) of the drive."""
        return list(self._ptu)

    # ------------------------------------------------------------ geometry

    def camera_pose(self, tau: float) -> NDArray[np.float64]:
        """4x4 world-from-camera at ``tau``: vehicle pose with bounce, then the PTU on its mount."""
        x, y, psi = self.path.pose(tau)
        pitch, roll, heave = self.bounce.at(tau)
        pan, tilt = self.plan.ptu.at(tau)
        m = self.mount
        T_wv = world_from_vehicle(
            float(x), float(y), float(psi), float(pitch), float(roll), float(heave)
        )
        return T_wv @ vehicle_from_camera(
            (m.x_m, m.y_m, m.z_m), m.pitch_rad, float(pan), float(tilt)
        )

    def _object_truth(
        self, tau: float, T_cw: NDArray[np.float64], ids: NDArray[np.uint16]
    ) -> dict[str, Any]:
        """Truth of every mover and parked car whose box projects into the image."""
        out: dict[str, Any] = {}
        tau_a = np.array([tau])
        for mv in self.movers:
            p = mv.trajectory.position(tau)
            corners = mv.body.corners(float(p[0]), float(p[1]), float(mv.trajectory.heading(tau)))
            view = project_box(self.camera, T_cw, corners)
            if view is None:
                continue
            centre, heading = relative_pose(self.path, mv.trajectory, tau_a)
            vel = relative_velocity(self.path, mv.trajectory, tau_a)
            length, width = mv.body.size[0], mv.body.size[1]
            g = gap(footprint_corners(centre, heading, length, width), self.vehicle)
            out[str(mv.body.obj)] = truth_record(
                view, ids, mv.body.obj, centre[0], vel[0], gap_m=float(g[0])
            )
        if not self.parked:
            return out
        # parked cars: a quick vectorised test first, the exact projection only for candidates
        cam = self.camera
        inside = boxes_near_image(cam, T_cw, self._parked_corners)
        x, y, psi = (float(a) for a in self.path.pose(tau))
        vx, vy = (float(a) for a in self.path.velocity(tau))
        w = float(self.plan.ego.yaw_rate_at(tau))
        c, sn = np.cos(psi), np.sin(psi)
        for k in np.flatnonzero(inside):
            obj = self.parked[k]
            view = project_box(cam, T_cw, self._parked_corners[k])
            if view is None:
                continue
            dx, dy = obj.x - x, obj.y - y
            px, py = c * dx + sn * dy, -sn * dx + c * dy
            rvx, rvy = -(c * vx + sn * vy), -(-sn * vx + c * vy)
            out[str(obj.body.obj)] = truth_record(
                view, ids, obj.body.obj, np.array([px, py]), np.array([rvx + w * py, rvy - w * px])
            )
        return out

    # ------------------------------------------------------------ the stream

    def _renderer(self) -> Renderer:
        return Renderer(self.camera, self.bank.textures, self.bank["asphalt"])

    def _render(
        self, renderer: Renderer, k: int
    ) -> tuple[float, NDArray[np.float64], NDArray[np.uint8], NDArray[np.uint16], dict[str, Any]]:
        """(t, world-from-camera, clean image, ids, truth) of frame k."""
        t = self.frame_time(k)
        tau = float(self.tau(t))
        T_wc = self.camera_pose(tau)
        T_cw = np.asarray(np.linalg.inv(T_wc), np.float64)
        movers = []
        for mv in self.movers:
            p = mv.trajectory.position(tau)
            movers.append(
                mv.body.placed(float(p[0]), float(p[1]), float(mv.trajectory.heading(tau)))
            )
        image, ids = renderer.render(T_cw, [self.static_faces], movers)
        pose = [[round(float(v), 10) for v in row] for row in T_wc]
        truth = {"camera_pose": pose, "objects": self._object_truth(tau, T_cw, ids)}
        return t, T_wc, image, ids, truth

    def snapshot(self, k: int) -> SimStep:
        """Frame k on its own (random access, for tests and tools): no camera effects and no
        sensor samples."""
        if not 0 <= k < self.n_frames:
            raise IndexError(f"frame {k} out of range 0..{self.n_frames - 1}")
        t, _, image, ids, truth = self._render(self._renderer(), k)
        return SimStep(k, t, image, [], [], truth, ids)

    def __iter__(self) -> Iterator[SimStep]:
        renderer = self._renderer()
        fx = EffectsPipeline(self.effects, np.random.default_rng(self._effects_seed))
        can_i = ptu_i = 0
        prev_pose: NDArray[np.float64] | None = None
        centre = np.array([[self.camera.cx, self.camera.cy]])
        for k in range(self.n_frames):
            t, T_wc, image, ids, truth = self._render(renderer, k)
            motion = (0.0, 0.0)
            if prev_pose is not None:  # rotational image motion over one frame, for motion blur
                R, _ = relative_motion(prev_pose, T_wc)
                f = rotational_flow(self.camera, centre, R)[0]
                motion = (float(f[0]), float(f[1]))
            image = fx.apply(image, t, motion, ids)
            prev_pose = T_wc
            can_j = can_i
            while can_j < len(self._can) and self._can[can_j].timestamp <= t:
                can_j += 1
            ptu_j = ptu_i
            while ptu_j < len(self._ptu) and self._ptu[ptu_j][0] <= t:
                ptu_j += 1
            yield SimStep(k, t, image, self._can[can_i:can_j], self._ptu[ptu_i:ptu_j], truth, ids)
            can_i, ptu_i = can_j, ptu_j


def simulate(
    scenario: str,
    out_dir: str | Path,
    seed: int = 0,
    duration: float | None = None,
    video: str = "mkv",
    cfg: Config | None = None,
    *,
    look: Look | None = None,
    progress: bool = False,
) -> Path:
    """Write the drive as a recording (spec: "Drive recording") with ``truth.json``.

    Returns the recording's path.

    :raises UsageError: bad arguments or a non-empty output directory.
    """
    out = Path(out_dir)
    if video not in VIDEO_FORMATS:
        raise UsageError(f"--video must be one of {', '.join(VIDEO_FORMATS)}, got {video!r}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise UsageError(f"{out}: output directory exists and is not empty")
    drive = SimulatedDrive(scenario, seed, duration, cfg, look=look)
    from appliance.sim.recorder import write_recording  # (recorder imports this module)

    return write_recording(drive, out, video, progress)
