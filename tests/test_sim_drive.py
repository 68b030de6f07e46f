"""Simulated drives as recordings: determinism, read-back, CAN and camera poses, collision truth."""

from __future__ import annotations

import json
from pathlib import Path

import can
import cantools
import numpy as np
import pytest

from appliance.config import resource_path
from appliance.errors import UsageError
from appliance.recording import Recording
from appliance.sim.drive import T0, SimulatedDrive, simulate
from appliance.sim.movers import SIZES
from appliance.vision.geometry import relative_motion

VEHICLE_DBC = cantools.database.can.Database()
VEHICLE_DBC.add_dbc_file(str(resource_path("vehicle.dbc")))


def _files(path: Path) -> dict[str, bytes]:
    return {
        n: (path / n).read_bytes()
        for n in ("frames.csv", "can.log", "ptu.csv", "truth.json", "meta.toml")
    }


def _frames(path: Path) -> list[np.ndarray]:
    return [f.image for f in Recording(path).frames()]


def test_same_seed_gives_an_identical_recording_and_another_seed_a_different_one(
    tmp_path: Path,
) -> None:
    a = simulate("pedestrian_crossing_nearside", tmp_path / "a", seed=5, duration=0.3)
    b = simulate("pedestrian_crossing_nearside", tmp_path / "b", seed=5, duration=0.3)
    c = simulate("pedestrian_crossing_nearside", tmp_path / "c", seed=6, duration=0.3)
    assert _files(a) == _files(b)
    fa, fb, fc = _frames(a), _frames(b), _frames(c)
    assert len(fa) == len(fb) == 10
    assert all(np.array_equal(x, y) for x, y in zip(fa, fb))
    assert not any(np.array_equal(x, y) for x, y in zip(fa, fc))
    assert _files(a)["can.log"] != _files(c)["can.log"]
    assert _files(a)["frames.csv"] != _files(c)["frames.csv"]  # capture jitter differs too


def test_recording_reads_back_with_the_truth_of_the_spec(tmp_path: Path) -> None:
    drive = SimulatedDrive("car_crossing_intersection", seed=2, duration=0.4)
    steps = list(drive)
    out = simulate("car_crossing_intersection", tmp_path / "rec", seed=2, duration=0.4, video="avi")
    rec = Recording(out)
    assert rec.n_frames == len(steps) == 13
    for step, frame in zip(steps, rec.frames()):
        assert frame.index == step.index and frame.t == step.t
        np.testing.assert_array_equal(frame.image, step.image)  # FFV1 is lossless
    msgs = list(rec.can_messages())
    assert [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in msgs] == [
        (m.timestamp, m.arbitration_id, bytes(m.data)) for s in steps for m in s.can_messages
    ]
    assert all(not m.is_extended_id and m.channel == "can0" for m in msgs)
    ptu = rec.ptu()
    assert ptu is not None and len(ptu.t) == sum(len(s.ptu_samples) for s in steps)
    np.testing.assert_allclose(ptu.pan, [p[1] for s in steps for p in s.ptu_samples])
    assert rec.meta.extra["simulator"]["scenario"] == "car_crossing_intersection"

    truth = json.loads((out / "truth.json").read_text())
    assert set(truth) >= {"scenario", "collision", "collision_t", "objects", "camera_poses"}
    assert truth["scenario"] == "car_crossing_intersection" and truth["collision"] is True
    assert truth["collision_t"] == pytest.approx(
        T0 + 0.4, abs=1e-6
    )  # the drive ends at the collision
    assert rec.frame_times[-1] >= truth["collision_t"] > rec.frame_times[-2]
    assert sorted(map(int, truth["camera_poses"])) == list(range(rec.n_frames))
    for k, step in enumerate(steps):
        np.testing.assert_allclose(
            truth["camera_poses"][str(k)], drive.camera_pose(float(drive.tau(step.t))), atol=1e-9
        )
    mover = next(o for o in truth["objects"] if o["id"] == truth["collision_object"])
    assert mover["class"] == "car" and mover["moving"] is True
    assert len(mover["frames"]) == rec.n_frames
    for rec_k in mover["frames"].values():
        assert set(rec_k) == {"bbox", "visible", "pos_vehicle", "vel_vehicle", "gap_m"}
        u0, v0, u1, v1 = rec_k["bbox"]
        assert 0 <= u0 <= u1 <= 639 and 0 <= v0 <= v1 <= 479
        assert 0.0 <= rec_k["visible"] <= 1.0
    parked = [o for o in truth["objects"] if not o["moving"]]
    assert parked and all(o["class"] == "car" for o in parked)


def _decode(
    msgs: list[can.Message], name: str, signal: str
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    m = VEHICLE_DBC.get_message_by_name(name)
    rows = [
        (x.timestamp, dict(m.decode(bytes(x.data))))
        for x in msgs
        if x.arbitration_id == m.frame_id
    ]
    return (
        np.array([t for t, _ in rows]),
        np.array([d[signal] for _, d in rows], float),
        np.array([d["COUNTER"] for _, d in rows]),
    )


def test_can_frames_decode_to_the_speed_and_yaw_profile_within_noise_and_bias() -> None:
    drive = SimulatedDrive("bend_static", seed=4, duration=9.0)  # covers the yaw ramps
    msgs = drive.can_messages
    e = drive.can_errors
    ts, kmh, cs = _decode(msgs, "VEHICLE_SPEED", "SPEED")
    ty, dps, cy = _decode(msgs, "YAW_RATE", "YAW_RATE")
    for t, c in ((ts, cs), (ty, cy)):
        assert np.all(np.abs(np.diff(t) - 0.02) < 0.001)  # 50 Hz
        assert np.all((np.diff(c) % 16) == 1)  # rolling 4-bit counter
    assert ts[0] == pytest.approx(T0 - 0.1, abs=0.001) and ts[-1] <= drive.frame_time(
        drive.n_frames - 1
    )
    true_kmh = 3.6 * drive.plan.ego.speed_at(drive.tau(ts))
    true_dps = np.degrees(drive.plan.ego.yaw_rate_at(drive.tau(ty)))
    assert abs(e.speed_scale) <= 0.01 and abs(e.yaw_bias_deg_s) <= 0.2  # a small bias
    ds = kmh - true_kmh * (1 + e.speed_scale)
    dy = dps - true_dps - e.yaw_bias_deg_s
    assert (
        np.abs(ds).max() < 5 * e.speed_noise_kmh + 0.01
        and np.abs(dy).max() < 5 * e.yaw_noise_deg_s + 0.01
    )
    assert np.std(ds) == pytest.approx(e.speed_noise_kmh, rel=0.2)
    assert np.std(dy) == pytest.approx(e.yaw_noise_deg_s, rel=0.2)
    assert true_dps.max() > 7.0  # the bend is in the window


def test_camera_motion_agrees_with_can_but_has_pitch_can_does_not_see() -> None:
    drive = SimulatedDrive("bend_static", seed=4, duration=9.0)
    ts, kmh, _ = _decode(drive.can_messages, "VEHICLE_SPEED", "SPEED")
    ty, dps, _ = _decode(drive.can_messages, "YAW_RATE", "YAW_RATE")
    e = drive.can_errors
    t = np.array([drive.frame_time(k) for k in range(drive.n_frames)])
    poses = [drive.camera_pose(float(drive.tau(x))) for x in t]
    dt = np.diff(t)
    speed = (
        np.array([np.linalg.norm(relative_motion(a, b)[1]) for a, b in zip(poses, poses[1:])]) / dt
    )
    axis = np.array([p[:3, 2] for p in poses])  # optical axis in the world
    heading = np.unwrap(np.arctan2(axis[:, 1], axis[:, 0]))
    yaw_rate = np.diff(heading) / dt
    tm = 0.5 * (t[1:] + t[:-1])
    can_speed = np.interp(tm, ts, kmh) / 3.6 / (1 + e.speed_scale)
    can_yaw = np.radians(np.interp(tm, ty, dps) - e.yaw_bias_deg_s)
    # translation per frame matches CAN speed to a few percent (the bounce moves the camera too)
    assert np.median(np.abs(speed / can_speed - 1)) < 0.02
    # heading change per frame matches the CAN yaw rate minus its bias
    assert np.median(np.abs(yaw_rate - can_yaw)) < np.radians(0.5)
    # the camera pitches with the body: CAN carries no pitch at all
    pitch = np.degrees(np.arcsin(-axis[:, 2]))
    assert 0.05 < np.std(pitch) < 1.0 and np.ptp(pitch) < 2.5


def _gaps(
    pos: np.ndarray,
    vel: np.ndarray,
    heading: float,
    size: tuple[float, float, float],
    front: float,
    rear: float,
    width: float,
    dts: np.ndarray,
) -> np.ndarray:
    """Footprint extrapolated at constant relative velocity: its distance (m) to the ego outline
    at each time offset in ``dts`` (dense boundary samples; independent of the simulator's SAT)."""
    a = np.linspace(-0.5, 0.5, 60)
    edge = (
        np.concatenate(
            [np.stack([a, np.full_like(a, s)], 1) for s in (-0.5, 0.5)]
            + [np.stack([np.full_like(a, s), a], 1) for s in (-0.5, 0.5)]
        )
        * size[:2]
    )
    c, s = np.cos(heading), np.sin(heading)
    local = edge @ np.array([[c, s], [-s, c]])
    p = local[None] + pos + vel * dts[:, None, None]  # (T, N, 2)
    inside = (p[..., 0] >= -rear) & (p[..., 0] <= front) & (np.abs(p[..., 1]) <= width / 2)
    dx = np.maximum(np.maximum(-rear - p[..., 0], p[..., 0] - front), 0.0)
    dy = np.maximum(np.abs(p[..., 1]) - width / 2, 0.0)
    return np.where(inside.any(1), 0.0, np.hypot(dx, dy).min(1))


@pytest.mark.parametrize(
    "scenario",
    ["pedestrian_crossing_nearside", "car_crossing_intersection", "cyclist_crossing_intersection"],
)
def test_collision_t_is_where_pos_and_vel_lead(scenario: str) -> None:
    drive = SimulatedDrive(scenario, seed=0)
    m = drive.cfg.mount
    ct = drive.truth_header["collision_t"]
    oid = drive.truth_header["collision_object"]
    mover = drive.movers[oid - 1]
    # the recording ends at (just after) the collision
    assert ct is not None and drive.frame_time(drive.n_frames - 1) >= ct > drive.frame_time(
        drive.n_frames - 2
    )
    ego_speed = float(drive.plan.ego.speed_at(0.0))
    for before_s in (2.5, 1.0):
        step = drive.snapshot(drive.n_frames - 1 - int(round(before_s * 30)))
        rec = step.truth_frame["objects"][str(oid)]
        pos, vel = np.array(rec["pos_vehicle"]), np.array(rec["vel_vehicle"])
        heading = float(
            np.arctan2(vel[1], vel[0] + ego_speed)
        )  # movers head where they go (straight ego)
        dts = np.arange(0.0, before_s + 1.0, 0.001)
        g = _gaps(
            pos,
            vel,
            heading,
            SIZES[mover.body.kind],
            m.vehicle_front_m,
            m.vehicle_rear_m,
            m.vehicle_width_m,
            dts,
        )
        assert g[0] > 0.5 and np.any(g == 0.0)
        assert step.t + dts[np.argmax(g == 0.0)] == pytest.approx(ct, abs=0.005)
        # gap_m is that footprint's distance to the outline, the near side's, not the centre's
        assert rec["gap_m"] == pytest.approx(g[0], abs=0.01)


@pytest.mark.parametrize("scenario", ["pedestrian_passes_front", "pedestrian_passes_behind"])
def test_near_misses_pass_one_metre_from_the_outline(scenario: str) -> None:
    drive = SimulatedDrive(scenario, seed=0)
    assert drive.truth_header["collision"] is False and drive.truth_header["collision_t"] is None
    m = drive.cfg.mount
    step = drive.snapshot(drive.n_frames - 1 - 60)  # 1.5 s before the closest approach
    rec = step.truth_frame["objects"]["1"]
    g = _gaps(
        np.array(rec["pos_vehicle"]),
        np.array(rec["vel_vehicle"]),
        np.pi / 2,
        SIZES["pedestrian"],
        m.vehicle_front_m,
        m.vehicle_rear_m,
        m.vehicle_width_m,
        np.arange(0.0, 4.0, 0.002),
    )
    assert g.min() == pytest.approx(1.0, abs=0.03)
    assert 1.0 < np.argmin(g) * 0.002 < 2.0


def test_bad_arguments_are_usage_errors(tmp_path: Path) -> None:
    with pytest.raises(UsageError, match="unknown scenario"):
        SimulatedDrive("nope", 0)
    with pytest.raises(UsageError, match="seed"):
        SimulatedDrive("bend_static", -1)
    with pytest.raises(UsageError, match="duration"):
        SimulatedDrive("bend_static", 0, duration=0.0)
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "x").write_text("x")
    with pytest.raises(UsageError, match="not empty"):
        simulate("bend_static", tmp_path / "full", duration=0.1)
    assert (tmp_path / "full" / "x").read_text() == "x"  # nothing lost
