"""3-D state per track: back-projection, refined pitch, ego-motion removal, path and scale TTC."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable

import numpy as np
import pytest

from appliance.config import Config, MountConfig
from appliance.decision.ground_state import (
    PITCH_DECAY_S,
    GroundModel,
    CameraPose,
    GroundContact,
    GroundTrack,
    back_project,
    bearing_innovation,
    bearing_update,
    camera_pose,
    foot_halo_shift,
    ground_contact,
    ground_init,
    ground_predict,
    ground_update,
    range_rate_update,
    update_body_pitch,
)
from appliance.decision.hidden import BEARING_GATE_SIGMAS, BEARING_STD_PX
from appliance.decision.scale_ttc import (
    independent_windows,
    measure_expansion,
    scale_predict,
    scale_ttc,
    scale_update,
)
from appliance.decision.threat import (
    bumper_ttc,
    fuse,
    near_side_gap,
    outline_gap,
    path_expansion,
    predict_path,
    significant_acceleration,
    significant_speed,
    significant_velocity,
)
from appliance.decision.assess import ACCELERATION_SIGNIFICANCE
from appliance.decision.frame import speed_slope
from appliance.messages import EgoMotion, SensorSample
from appliance.vision.geometry import (
    PinholeCamera,
    euler_to_matrix,
    matrix_to_euler,
    relative_motion,
    rotational_flow,
    vehicle_from_camera,
    vehicle_from_camera_rotation,
)

CAM = PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5)
CAM_DIST = PinholeCamera(640, 480, 700.0, 700.0, 319.5, 239.5, (-0.12, 0.03, 0.001, -0.001, 0.0))


def project(camera: PinholeCamera, pose: CameraPose, P: np.ndarray) -> np.ndarray:
    Rvc = vehicle_from_camera_rotation(pose.pitch, pose.pan, pose.tilt)
    return camera.project((np.atleast_2d(P) - np.asarray(pose.position)) @ Rvc)


@pytest.mark.parametrize("camera", [CAM, CAM_DIST])
def test_back_projection_recovers_a_known_road_point(camera: PinholeCamera) -> None:
    pose = CameraPose((1.9, 0.1, 1.3), pitch=0.05, pan=0.2, tilt=-0.03)
    P = np.array([[15.0, 4.0, 0.0], [6.0, 1.0, 0.0], [30.0, 6.5, 0.0]])
    uv = project(camera, pose, P)
    assert np.all(np.isfinite(uv))
    xy = back_project(camera, uv, pose)
    np.testing.assert_allclose(xy, P[:, :2], atol=1e-4 if camera is CAM else 2e-2)


def test_back_projection_above_the_horizon_is_nan() -> None:
    pose = CameraPose((1.9, 0.0, 1.3), pitch=0.0, pan=0.0, tilt=0.0)
    xy = back_project(CAM, np.array([[320.0, 100.0], [320.0, 239.5], [320.0, 400.0]]), pose)
    assert np.all(np.isnan(xy[:2])) and np.all(np.isfinite(xy[2]))


def test_the_foot_halo_is_there_only_where_the_road_below_flows_too_little_to_tell() -> None:
    """foot_halo_shift: the road's own flow below a foot at range Z is f h d / Z^2 px; the
    halo below the feet is half the window where that is short against sigma_p, none where
    it is long, so the foot moves down by 0 far away and by the whole halo near."""
    f, h, d, halo, sigma = 700.0, 1.3, 10.0 / 30.0, 4.5, 0.5
    z_at_sigma = math.sqrt(f * h * d / sigma)     # the range where L = sigma (24.6 m)
    assert foot_halo_shift(z_at_sigma, d, f, h, halo, sigma) == pytest.approx(
        halo * (1.0 - math.exp(-0.5)))
    shifts = [foot_halo_shift(z, d, f, h, halo, sigma) for z in (8.0, 15.0, 25.0, 40.0, 60.0)]
    assert shifts[0] == pytest.approx(halo, abs=1e-3) and shifts[-1] < 0.1
    assert all(a > b for a, b in itertools.pairwise(shifts))
    assert foot_halo_shift(20.0, 0.0, f, h, halo, sigma) == 0.0   # standstill: no road flow


def test_ground_contact_covariance_grows_with_range(default_config: Config) -> None:
    pose = CameraPose((1.9, 0.0, 1.3), 0.0, 0.0, 0.0)
    near = ground_contact(CAM, tuple(project(CAM, pose, np.array([8.0, 0.0, 0.0]))[0]), pose,
                          GroundModel())
    far = ground_contact(CAM, tuple(project(CAM, pose, np.array([40.0, 0.0, 0.0]))[0]), pose,
                         GroundModel())
    assert near is not None and far is not None
    assert near.z == pytest.approx([8.0, 0.0], abs=1e-6)
    assert math.sqrt(far.R[0, 0]) > 10 * math.sqrt(near.R[0, 0])
    # beyond max_range_m: unusable (scale cue only)
    assert ground_contact(CAM, tuple(project(CAM, pose, np.array([40.0, 0.0, 0.0]))[0]), pose,
                          GroundModel(max_range_m=30.0)) is None


@pytest.mark.parametrize("pan", [0.0, 0.4])
def test_body_pitch_from_refined_minus_prior_rotation(default_config: Config, pan: float) -> None:
    """A nose-down body pitch of 0.01 rad that CAN cannot see is recovered from the rotation."""
    pos = (1.9, 0.0, 1.3)
    before = vehicle_from_camera(pos, 0.02, pan, 0.0)
    after = vehicle_from_camera(pos, 0.03, pan, 0.0)
    R, _ = relative_motion(before, after)
    r = matrix_to_euler(R)
    ego = EgoMotion(r, np.zeros(3), None, np.zeros(3), np.zeros(3), None, 50, True)
    pose = CameraPose(pos, 0.02, pan, 0.0)
    b = update_body_pitch(0.0, ego, pose, 0.0)
    assert b == pytest.approx(0.01, rel=0.02)
    # the prior (CAN + PTU) explains it all: no body pitch
    explained = EgoMotion(r, np.zeros(3), None, r, np.zeros(3), None, 50, True)
    assert update_body_pitch(0.0, explained, pose, 0.0) == pytest.approx(0.0)
    # not confident: only decays
    lost = EgoMotion(r, np.zeros(3), None, np.zeros(3), np.zeros(3), None, 3, False)
    decayed = update_body_pitch(0.01, lost, pose, 1.0)
    assert decayed == pytest.approx(0.01 * math.exp(-1.0 / PITCH_DECAY_S))


def world_to_vehicle(P: np.ndarray, ego_xy: np.ndarray, psi: float) -> np.ndarray:
    c, s = math.cos(psi), math.sin(psi)
    d = P - ego_xy
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]])


@pytest.mark.parametrize("obj_vel", [(0.0, 0.0), (-3.0, 1.5)])
def test_ground_filter_removes_ego_motion(default_config: Config, obj_vel: tuple[float, float]
                                          ) -> None:
    """Ego on an arc at 12 m/s, 0.15 rad/s: the filter finds the object's velocity over ground."""
    cfg = GroundModel()
    rng = np.random.default_rng(0)
    speed, yaw, dt = 12.0, 0.15, 1.0 / 30.0
    obj = np.array([30.0, 3.0])
    ego = np.zeros(2)
    psi = 0.0
    g = None
    R = np.diag([0.3, 0.1]) ** 2
    for k in range(90):
        t = k * dt
        if k:
            # exact arc motion of the ego vehicle over dt, object at constant velocity
            ego = ego + speed * dt * np.array([math.cos(psi + 0.5 * yaw * dt),
                                               math.sin(psi + 0.5 * yaw * dt)])
            psi += yaw * dt
            obj = obj + np.asarray(obj_vel) * dt
        z = world_to_vehicle(obj, ego, psi) + rng.normal(0, [0.3, 0.1])
        contact = GroundContact(z=z, R=R)
        sensors = SensorSample(t, speed, yaw)
        g = ground_init(contact, t, cfg) if g is None else ground_update(
            ground_predict(g, dt, sensors, cfg), contact, t)
    assert g is not None
    # the velocity over ground, expressed in the current vehicle frame
    c, s = math.cos(psi), math.sin(psi)
    v_true = np.array([c * obj_vel[0] + s * obj_vel[1], -s * obj_vel[0] + c * obj_vel[1]])
    np.testing.assert_allclose(g.velocity, v_true, atol=0.6)
    np.testing.assert_allclose(g.position, world_to_vehicle(obj, ego, psi), atol=0.3)


def test_path_prediction_collision_and_near_miss(default_config: Config) -> None:
    mount = default_config.mount  # front 3.9 m, width 1.8 m
    # crossing at 2.5 m/s from the right into the middle of the bumper at 10 m/s
    hit = predict_path(np.array([23.9, -5.0]), np.array([0.0, 2.5]), 10.0, 0.0, mount,
                       margin=0.3, radius=0.2, horizon_s=6.0)
    assert hit.ttc == pytest.approx((23.9 - 4.1) / 10.0, abs=0.05) and hit.closest == 0.0
    # 2 s later it would have crossed: passes 1.5 m in front of the car... after it
    miss = predict_path(np.array([23.9, -5.0]), np.array([0.0, 5.0]), 10.0, 0.0, mount,
                        margin=0.3, radius=0.2, horizon_s=6.0)
    assert miss.ttc is None and miss.closest > 1.0 and not miss.ahead   # it passes beside
    # lead car driving away: no contact; its gap is kept ahead in the lane, the one it has now
    away = predict_path(np.array([20.0, 0.0]), np.array([15.0, 0.0]), 10.0, 0.0, mount,
                        0.3, 1.0, 6.0)
    assert away.ttc is None and away.ahead
    assert away.closest == pytest.approx(20.0 - 1.0 - mount.vehicle_front_m)
    # in a left bend the ego arc reaches an object on the left that a straight path misses
    # (the front bumper's circle about the turn centre (0, 50 m) passes through (20, 4))
    bend = predict_path(np.array([20.0, 4.0]), np.zeros(2), 10.0, 0.2, mount, 0.3, 0.3, 6.0)
    straight = predict_path(np.array([20.0, 4.0]), np.zeros(2), 10.0, 0.0, mount, 0.3, 0.3, 6.0)
    assert bend.ttc is not None and straight.ttc is None


def test_a_braking_ego_comes_to_a_stop_in_its_stopping_distance(default_config: Config) -> None:
    mount = default_config.mount  # front 3.9 m
    standing = np.array([3.9 + 15.0, 0.0])   # 15 m ahead of the bumper, not moving
    # at 10 m/s: contact after 1.5 s at constant speed; braking at 4 m/s^2 it stops after
    # 12.5 m, 2.5 m short; at 2 m/s^2 it needs 25 m and meets it (10 t - t^2 = 15: t = 1.84 s)
    assert predict_path(standing, np.zeros(2), 10.0, 0.0, mount, 0.3, 0.0, 6.0).ttc \
        == pytest.approx(1.5, abs=0.03)
    stops = predict_path(standing, np.zeros(2), 10.0, 0.0, mount, 0.3, 0.0, 6.0, ego_accel=-4.0)
    assert stops.ttc is None and stops.closest == pytest.approx(2.5, abs=0.05)
    late = predict_path(standing, np.zeros(2), 10.0, 0.0, mount, 0.3, 0.0, 6.0, ego_accel=-2.0)
    assert late.ttc == pytest.approx(5.0 - math.sqrt(10.0), abs=0.03)
    # braking in a bend: along the same arc (radius 50 m), 12.5 m of it
    bend = predict_path(np.array([3.9 + 12.0, 1.45]), np.zeros(2), 10.0, 0.2, mount, 0.3, 0.0,
                        6.0, ego_accel=-4.0)
    assert bend.ttc is not None   # the object stands on the arc 12 m ahead: reached
    # the slope of the CAN speed: a car braking at 4 m/s^2 reads so within a second; a car
    # at constant speed does not brake; an unknown speed knows no braking, and the first
    # speed after it has no slope yet
    a, v = 0.0, 10.0
    for _ in range(30):
        a = speed_slope(a, v, v - 4.0 / 30, 1 / 30)
        v -= 4.0 / 30
    assert a == pytest.approx(-4.0, abs=0.2)
    assert speed_slope(a, None, 5.0, 1 / 30) == a
    assert speed_slope(a, 5.0, None, 1 / 30) == 0.0
    steady = 0.0
    for _ in range(30):
        steady = speed_slope(steady, 10.0, 10.0, 1 / 30)
    assert steady == 0.0


def test_distance_is_the_gap_of_the_near_side_across_the_optical_axis(
        default_config: Config) -> None:
    """The near side: the segment through the ground contact along its image row (across the
    optical axis), as wide as the box. Checked against the simulator's exact footprint gap
    (collision.gap) of that segment (a footprint of width 0)."""
    from appliance.sim.collision import Vehicle, footprint_corners, gap

    mount = default_config.mount
    ego = Vehicle(mount.vehicle_front_m, mount.vehicle_rear_m, mount.vehicle_width_m)
    # a car straight ahead: its whole near side is as far as its centre (3.9 m front bumper)
    assert near_side_gap(np.array([16.0, 0.3]), 0.9, mount) == pytest.approx(12.1, abs=1e-9)
    # one crossing from the right 8 m beside the path: its near end, 2 m nearer the path
    assert near_side_gap(np.array([16.0, -8.0]), 2.0, mount) == pytest.approx(
        math.hypot(12.1, 8.0 - 2.0 - 0.9), abs=1e-9)
    rng = np.random.default_rng(3)
    closer = 0
    for _ in range(200):
        pos = np.array([rng.uniform(5.0, 40.0), rng.uniform(-20.0, 20.0)])
        radius = float(rng.uniform(0.2, 2.5))
        pan = float(rng.uniform(-0.5, 0.5))
        heading = pan + math.pi / 2   # the segment across the optical axis
        exact = float(gap(footprint_corners(pos[None], np.array([heading]), 2 * radius, 0.0),
                          ego)[0])
        centre = float(outline_gap(pos, mount, 0.0))
        got = near_side_gap(pos, radius, mount, pan)
        assert exact - 1e-9 <= got <= min(exact + radius / 32, centre) + 1e-9
        closer += got < centre - 0.05
    assert closer > 100   # beside the car's path the near side is nearer than the centre


def looming_points(center: tuple[float, float], ratio: float, n: int = 30, seed: int = 0
                   ) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    prev = np.asarray(center) + rng.uniform(-15, 15, (n, 2))
    cur = np.asarray(center) + np.array([0.4, -0.1]) + ratio * (prev - np.asarray(center))
    return cur, cur - prev


def test_scale_change_measured_from_correspondences() -> None:
    cur, flow = looming_points((400.0, 260.0), 1.02)
    m = measure_expansion(cur, flow, np.ones(len(cur)), None, CAM)
    assert m is not None and m.kappa == pytest.approx(0.02, abs=1e-6)
    # a camera rotation adds its own flow; with the refined rotation given it is removed
    r = np.array([0.004, -0.006, 0.003])
    prev = cur - flow
    R = euler_to_matrix(r)
    cur_rot = cur + rotational_flow(CAM, cur, R)
    flow_rot = cur_rot - prev
    m2 = measure_expansion(cur_rot, flow_rot, np.ones(len(cur)), r, CAM)
    assert m2 is not None and m2.kappa == pytest.approx(0.02, abs=2e-3)
    # outliers (a few wrong flows) are rejected
    flow_bad = flow.copy()
    flow_bad[:3] += 5.0
    m3 = measure_expansion(cur, flow_bad, np.ones(len(cur)), None, CAM)
    assert m3 is not None and m3.kappa == pytest.approx(0.02, abs=2e-3)
    assert measure_expansion(cur[:3], flow[:3], np.ones(3), None, CAM) is None


def test_a_box_cut_by_the_border_has_its_scale_fitted_along_v_only() -> None:
    """Half of a looming car (2 %/frame) moving right as it enters from the left border, the
    other half the static scene beside it streaming out left: fitted on both axes the
    mixture looks like a fast expansion; along v (which the border does not cut) the car's
    own 2 % is found (the static points at that depth expand alike)."""
    car, car_flow = looming_points((40.0, 260.0), 1.02, n=40, seed=1)
    car_flow = car_flow + [1.5, 0.0]
    car = car + [1.5, 0.0]
    scene, scene_flow = looming_points((15.0, 260.0), 1.02, n=40, seed=2)
    scene_flow = scene_flow + [-3.0, 0.0]        # outward, to the left border
    scene = scene + [-3.0, 0.0]
    pos, flow = np.vstack([car, scene]), np.vstack([car_flow, scene_flow])
    both = measure_expansion(pos, flow, np.ones(len(pos)), None, CAM)
    along_v = measure_expansion(pos, flow, np.ones(len(pos)), None, CAM, axes=(1,))
    assert both is not None and along_v is not None
    assert both.kappa > 0.05                       # TTC under a second at 30 frames/s
    assert along_v.kappa == pytest.approx(0.02, abs=2e-3)
    assert measure_expansion(pos, flow, np.ones(len(pos)), None, CAM, axes=()) is None


def test_expansion_variance_counts_overlapping_lk_windows_once() -> None:
    """Forty flows on a pedestrian-sized box (10 x 32 px) whose errors are shared by
    each 9 px LK window: the kappa they give scatters as four measurements would, not
    forty. With the window given the variance says so; without it, it is ~3x too small."""
    rng = np.random.default_rng(7)
    kappas, var_win, var_iid = [], [], []
    for _ in range(300):
        prev = np.column_stack([rng.uniform(400.0, 410.0, 40), rng.uniform(230.0, 262.0, 40)])
        cur = 405.0 + 1.01 * (prev - 405.0)
        cur[:, 1] = 246.0 + 1.01 * (prev[:, 1] - 246.0)
        # one error per 9 px window (rows of the box), shared by the flows inside it
        cell = ((prev[:, 1] - 230.0) // 9).astype(int)
        cur = cur + rng.normal(0.0, 0.15, (cell.max() + 1, 2))[cell] + rng.normal(0.0, 0.02, cur.shape)
        flow = cur - prev
        m_win = measure_expansion(cur, flow, np.ones(40), None, CAM, window_px=9)
        m_iid = measure_expansion(cur, flow, np.ones(40), None, CAM)
        assert m_win is not None and m_iid is not None
        kappas.append(m_win.kappa)
        var_win.append(m_win.var)
        var_iid.append(m_iid.var)
    scatter = float(np.var(kappas))
    assert np.median(var_win) == pytest.approx(scatter, rel=0.6)
    assert np.median(var_iid) < scatter / 3.0
    assert independent_windows(np.array([[0.0, 0.0], [100.0, 60.0]]), 9.0) == pytest.approx(100 * 60 / 81)
    assert independent_windows(np.array([[5.0, 5.0], [8.0, 40.0]]), 9.0) == pytest.approx(35 / 9)


def test_scale_filter_converges_to_ttc_of_a_constant_approach() -> None:
    dt, c = 1.0 / 30.0, 10.0
    rng = np.random.default_rng(1)
    s = None
    Z = 25.0
    for k in range(45):
        Z_new = Z - c * dt
        cur, flow = looming_points((300.0, 240.0), Z / Z_new, seed=k)
        flow = flow + rng.normal(0, 0.1, flow.shape)
        m = measure_expansion(cur, flow, np.ones(len(cur)), None, CAM)
        assert m is not None
        if s is not None:
            s = scale_predict(s, dt, 0.3)
        s = scale_update(s, m, dt)
        Z = Z_new
    est = scale_ttc(s, 5)
    assert est is not None and est[0] == pytest.approx(Z / c, rel=0.1)
    # a receding object has no TTC
    s_away = None
    for k in range(10):
        cur, flow = looming_points((300.0, 240.0), 0.99, seed=k)
        m = measure_expansion(cur, flow, np.ones(len(cur)), None, CAM)
        assert m is not None
        s_away = scale_update(s_away, m, dt)
    assert scale_ttc(s_away, 5) is None


def test_bumper_correction_and_fusion(default_config: Config) -> None:
    mount = default_config.mount  # camera 2.0 m behind the bumper
    assert bumper_ttc((2.0, 0.1), 20.0, mount) == pytest.approx((1.8, 0.09))
    assert bumper_ttc((2.0, 0.1), None, mount) == (2.0, 0.1)
    f = fuse((2.0, 0.1), (2.4, 0.2))
    expected = (2.0 / 0.01 + 2.4 / 0.04) / (1 / 0.01 + 1 / 0.04)
    assert f is not None and f[0] == pytest.approx(expected)
    assert f[1] < 0.1
    assert fuse(None, (1.0, 0.1)) == (1.0, 0.1) and fuse(None, None) is None


@pytest.mark.parametrize("pan", [0.0, 0.4])
def test_the_expansion_a_path_implies_is_the_image_growth_of_the_object(pan: float) -> None:
    """An object 1.8 m wide at depth Z seen by a camera looking along ``pan``: the growth of its
    image width over a short step, ln(w' / w) / dt, is what ``path_expansion`` implies from its
    velocity over ground and the ego speed; one driving along with the car at its speed does
    not grow at all."""
    axis = np.array([math.cos(pan), math.sin(pan)])
    cam = np.array([1.6, 0.0])
    obj = cam + 25.0 * axis + 3.0 * np.array([-axis[1], axis[0]])   # 3 m off the axis
    speed, dt, fx = 14.0, 1e-3, 800.0

    def width_px(t: float, vel: np.ndarray) -> float:
        rel = obj + (vel - np.array([speed, 0.0])) * t - cam   # the ego drives along x
        return fx * 1.8 / float(axis @ rel)

    for vel in (np.zeros(2), np.array([4.0, -1.5]), np.array([speed, 0.0])):
        measured = math.log(width_px(dt, vel) / width_px(0.0, vel)) / dt
        depth = float(axis @ (obj - cam))
        implied = path_expansion(depth, axis, vel, speed)
        assert implied == pytest.approx(measured, rel=1e-2, abs=1e-4), vel
    assert path_expansion(25.0, np.array([1.0, 0.0]), np.array([speed, 0.0]), speed) == 0.0
    assert path_expansion(0.3, np.array([1.0, 0.0]), np.zeros(2), speed) is None


def test_outlier_contacts_are_skipped_and_a_run_of_them_restarts(default_config: Config) -> None:
    from appliance.decision.ground_state import ground_absorb

    cfg = GroundModel()
    R = np.diag([0.3, 0.1]) ** 2
    g = None
    for k in range(10):
        g = ground_absorb(g, GroundContact(np.array([20.0, 2.0]), R), k / 30, cfg)
    assert g is not None and g.updates == 10
    # a stray particle puts one contact 6 m short: skipped, the state is unchanged
    skipped = ground_absorb(g, GroundContact(np.array([14.0, 2.0]), R), 10 / 30, cfg)
    assert skipped.updates == 10 and skipped.rejected == 1
    np.testing.assert_allclose(skipped.x, g.x)
    # the object really is elsewhere (a new association): five outliers in a row restart
    for k in range(4):
        skipped = ground_absorb(skipped, GroundContact(np.array([14.0, 2.0]), R), 1.0, cfg)
    assert skipped.updates == 1 and skipped.position == pytest.approx([14.0, 2.0])
    # the same with a prediction before every contact, as the pipeline runs it: the count of
    # outliers in a row survives the predictions
    standing = SensorSample(0.0, 0.0, 0.0)
    run = g
    for k in range(5):
        run = ground_absorb(ground_predict(run, 1 / 30, standing, cfg),
                            GroundContact(np.array([14.0, 2.0]), R), (11 + k) / 30, cfg)
        assert run.rejected == (k + 1 if k < 4 else 0)
    assert run.updates == 1 and run.position == pytest.approx([14.0, 2.0])


def test_moving_over_ground_needs_speed_significance_and_contacts(default_config: Config) -> None:
    from appliance.decision.cues.motion import moves_over_ground

    cfg = default_config.cue.motion  # 0.5 m/s, 3 sigma, 10 contacts
    P = np.diag([0.1, 0.1, 0.2, 0.2]) ** 2
    walking = GroundTrack(np.array([15.0, -3.0, 0.0, 1.4]), P, 0.0, 30)
    assert moves_over_ground(walking, cfg)
    assert not moves_over_ground(GroundTrack(walking.x, P, 0.0, 5), cfg)  # too few contacts
    assert not moves_over_ground(GroundTrack(np.array([15.0, -3.0, 0.1, 0.3]), P, 0.0, 30), cfg)
    vague = np.diag([0.1, 0.1, 3.0, 3.0]) ** 2  # 1.4 m/s but +-3 m/s: not shown to move
    assert not moves_over_ground(GroundTrack(walking.x, vague, 0.0, 30), cfg)


def test_fading_memory_recovers_from_a_wrong_start(default_config: Config) -> None:
    """A state that started with a wrong velocity (a wrong association) recovers faster
    with the fading memory than without."""
    def run(memory: float) -> float:
        cfg = GroundModel(memory_s=memory)
        R = np.diag([0.5, 0.2]) ** 2
        P = np.diag([0.5, 0.2, 0.3, 0.3]) ** 2
        g = GroundTrack(np.array([30.0, 0.0, 6.0, 0.0]), P, 0.0, 20)  # believes 6 m/s away
        sensors = SensorSample(0.0, 10.0, 0.0)
        for k in range(1, 31):
            g = ground_update(ground_predict(g, 1 / 30, sensors, cfg),
                              GroundContact(np.array([30.0 - 10.0 * k / 30, 0.0]), R), k / 30)
        return abs(float(g.velocity[0]))  # truth: 0 m/s over ground

    assert run(1.0) < 0.8 * run(0.0)


def test_velocity_prior_from_the_bearing_rate(default_config: Config) -> None:
    """A car crossing at 8 m/s, 30 m ahead: its speed across the line of sight is known from
    the first frames (bearing rate), along it nothing is."""
    from appliance.decision.ground_state import velocity_prior

    cfg = GroundModel()
    z, v_og, speed = np.array([30.0, 5.0]), np.array([0.0, -8.0]), 10.0
    d = z - [1.9, 0.0]
    rel = v_og - [speed, 0.0]
    rate = (d[0] * rel[1] - d[1] * rel[0]) / (d @ d)
    mean, cov = velocity_prior(z, rate, speed, 0.0, (1.9, 0.0), cfg)
    b = math.atan2(d[1], d[0])
    tangent, radial = np.array([-math.sin(b), math.cos(b)]), np.array([math.cos(b), math.sin(b)])
    assert mean @ tangent == pytest.approx(v_og @ tangent, abs=1e-6)
    assert mean @ radial == pytest.approx(0.0, abs=1e-9)
    assert math.sqrt(radial @ cov @ radial) == pytest.approx(cfg.initial_velocity_std_m_s)
    assert math.sqrt(tangent @ cov @ tangent) < 1.0
    # a static point: its bearing turns only because the car moves; prior = standing still
    rel_static = -np.array([speed, 0.0])
    rate0 = (d[0] * rel_static[1] - d[1] * rel_static[0]) / (d @ d)
    mean0, _ = velocity_prior(z, rate0, speed, 0.0, (1.9, 0.0), cfg)
    np.testing.assert_allclose(mean0, 0.0, atol=1e-9)


def test_the_bearing_rate_is_known_as_well_as_its_fit() -> None:
    """A steady bearing gives a precise rate; a young track whose first box was a sliver of
    the object (its bearing off by 0.015 rad) gives a rate that far off, and a standard
    error that says so: the 3-D state it starts may then follow its contacts across."""
    from appliance.decision.cues.bearing import bearing_fit

    ts = np.arange(10) / 25.0
    rng = np.random.default_rng(0)
    steady = tuple(zip(ts, 0.19 - 0.02 * ts + rng.normal(0.0, 0.0005, 10)))
    fit = bearing_fit(steady)
    assert fit is not None
    rate, std = fit
    assert rate == pytest.approx(-0.02, abs=3 * std) and std < 0.01
    sliver = ((0.0, 0.2148), (0.04, 0.1984), (0.08, 0.1914), (0.12, 0.1877))
    fit = bearing_fit(sliver)
    assert fit is not None
    rate, std = fit
    assert rate < -0.2 and std > 0.04
    assert bearing_fit(sliver[:2]) is None


def test_a_fast_mover_is_judged_by_the_speed_it_moves_at_least() -> None:
    """A pedestrian's 3-D state a few contacts after its range jumped: 6 m/s along x with a
    std of 2 m/s there is not a car (5 m/s or more at 2 std); a lead car's 10 +- 0.5 m/s is."""
    P = np.diag([0.1, 0.1, 4.0, 0.04])
    assert significant_speed(np.array([-6.0, 0.0]), P, 2.0) == pytest.approx(2.0)
    assert significant_speed(np.array([-6.0, 0.0]), P, 2.0) < 5.0
    assert significant_speed(np.array([10.0, 0.0]), np.diag([0.1, 0.1, 0.25, 0.25]), 2.0) \
        == pytest.approx(9.0)
    # along its own direction: the lateral std counts for a lateral motion
    assert significant_speed(np.array([0.0, 6.0]), P, 2.0) == pytest.approx(5.6)
    assert significant_speed(np.zeros(2), P, 2.0) == 0.0
    assert significant_speed(np.array([1.0, 0.0]), P, 2.0) == 0.0


def test_insignificant_velocity_components_are_predicted_as_zero(default_config: Config) -> None:
    """A pedestrian crossing 2 m in front of the car's path (passes_front-like numbers): its
    range rate is a noise value (-1.0 +- 1.0 m/s over ground), its lateral speed is known
    (1.4 +- 0.2 m/s). Taken at face value the noise makes it meet the car; predicted as 0
    the pedestrian passes in front, as it does."""
    mount = default_config.mount
    pos = np.array([19.4, -0.45])
    vel = np.array([-1.0, 1.1])
    P = np.diag([0.1, 0.05, 1.0, 0.04])
    assert predict_path(pos, vel, 8.33, 0.0, mount, 0.3, 0.25, 6.0).ttc is not None
    v = significant_velocity(vel, P, 2.0)
    np.testing.assert_allclose(v, [0.0, 1.1])
    assert predict_path(pos, v, 8.33, 0.0, mount, 0.3, 0.25, 6.0).ttc is None
    # a significant component is kept, and 0 sigmas changes nothing
    np.testing.assert_allclose(significant_velocity(np.array([-5.0, 1.1]), P, 2.0), [-5.0, 1.1])
    np.testing.assert_allclose(significant_velocity(vel, P, 0.0), vel)


def _sight_state(pos: np.ndarray, mount: MountConfig, position_var: tuple[float, float],
                 along_std: float, across_std: float) -> tuple[np.ndarray, np.ndarray]:
    """The unit vector along the line of sight to ``pos`` (vehicle frame, m) and a state
    covariance (4, 4) of ``[x, y, vx, vy]``: position variances ``position_var``, velocity std
    ``along_std`` along the line of sight (the range rate) and ``across_std`` across it."""
    theta = math.atan2(pos[1] - mount.y_m, pos[0] - mount.x_m)
    along = np.array([math.cos(theta), math.sin(theta)])
    across = np.array([-math.sin(theta), math.cos(theta)])
    P = np.zeros((4, 4))
    P[:2, :2] = np.diag(position_var)
    P[2:, 2:] = along_std ** 2 * np.outer(along, along) + across_std ** 2 * np.outer(across, across)
    return along, P


def test_a_far_pedestrian_walking_into_the_path_keeps_its_velocity_across_the_line_of_sight(
        default_config: Config) -> None:
    """A pedestrian 38 m ahead, 5 m to the right, walking 1.4 m/s into the path of a car at
    35 km/h (constant bearing: it meets the car). Its range rate is a noise value (std 5 m/s
    along the line of sight), the velocity across the line of sight is known (std 0.1 m/s).
    The uncertain range rate spreads into the lateral velocity (1.2 +- 0.65 m/s); the
    longitudinal velocity is a noise value and predicted as 0, and given that, the lateral
    one is the walking speed, known to 0.1 m/s: the pedestrian still walks into the path."""
    mount = default_config.mount
    pos = np.array([mount.x_m + 38.0, -5.0])
    along, P = _sight_state(pos, mount, (4.0, 0.1), 5.0, 0.1)
    vel = np.array([0.0, 1.4]) + 1.5 * along            # the range rate off by 1.5 m/s
    assert math.sqrt(P[3, 3]) > 0.5 * vel[1]             # per vehicle axis: "insignificant"
    v = significant_velocity(vel, P, 2.0)
    assert v[0] == 0.0
    assert vel[1] < 1.25
    assert v[1] == pytest.approx(1.4, abs=0.01)
    assert predict_path(pos, v, 9.72, 0.0, mount, 0.3, 0.25, 6.0).ttc is not None
    # the same walker standing still (nothing significant): it stays beside the path
    still = significant_velocity(1.5 * along, P, 2.0)
    np.testing.assert_allclose(still, [0.0, 0.0], atol=1e-9)
    assert predict_path(pos, still, 9.72, 0.0, mount, 0.3, 0.25, 6.0).ttc is None


def test_a_cyclist_riding_into_the_path_from_far_aside_meets_the_car(
        default_config: Config) -> None:
    """A cyclist 40 m ahead and 16.6 m to the right rides at 4.6 m/s into the path of a car at
    40 km/h (kitti-street's nearside cyclist, 3.4 s before contact). Its range rate is 4.8 m/s
    off (the state has it riding away along the line of sight, std 4.9 m/s); across the line of
    sight it is known to 0.2 m/s. The longitudinal velocity is a noise value, predicted as 0;
    the lateral velocity is then the one that moves it across the line of sight as measured,
    and the cyclist meets the car. Kept as the state has it (2.8 m/s) beside a longitudinal 0,
    the cyclist would cross the line of sight too slowly and pass metres in front."""
    mount = default_config.mount
    pos = np.array([mount.x_m + 40.1, -16.56])
    along, P = _sight_state(pos, mount, (25.0, 4.0), 4.9, 0.2)
    vel = np.array([0.0, 4.6]) + 4.8 * along
    speed = 11.2
    v = significant_velocity(vel, P, 2.0)
    assert v[0] == 0.0
    assert v[1] == pytest.approx(4.6, abs=0.05)
    assert predict_path(pos, v, speed, 0.0, mount, 0.3, 0.3, 6.0).ttc is not None
    kept = np.array([0.0, vel[1]])
    assert vel[1] < 3.0
    assert predict_path(pos, kept, speed, 0.0, mount, 0.3, 0.3, 6.0).ttc is None


def test_bearing_rate_update_corrects_the_velocity_across_the_line_of_sight(
        default_config: Config) -> None:
    """A pedestrian on a constant bearing (collision course) whose state says standing still:
    the zero bearing rate moves its velocity across the line of sight to the true value."""
    from appliance.decision.ground_state import GroundTrack, bearing_rate_update

    speed, cam = 10.0, (1.9, 0.0)
    z = np.array([31.9, -4.0])
    d = z - cam
    v_true = np.array([0.0, speed * d[1] / d[0] * -1.0])  # keeps y/x constant: rate 0
    g = GroundTrack(x=np.concatenate([z, [0.0, 0.0]]), P=np.diag([4.0, 0.3, 9.0, 4.0]),
                    t_update=0.0, updates=5)
    g2 = bearing_rate_update(g, 0.0, speed, 0.0, cam, 0.005)
    b = math.atan2(d[1], d[0])
    tangent = np.array([-math.sin(b), math.cos(b)])
    assert g2.velocity @ tangent == pytest.approx(v_true @ tangent, abs=0.1)
    assert tangent @ g2.P[2:, 2:] @ tangent < tangent @ g.P[2:, 2:] @ tangent
    np.testing.assert_allclose(g2.position, g.position, atol=1e-9)  # no cross-covariance


@pytest.mark.parametrize(("pan", "obj_vel"), [(0.0, (0.0, 0.0)), (0.0, (-5.0, 1.0)), (0.3, (2.0, 1.5))])
def test_range_rate_from_the_expansion_rate(pan: float, obj_vel: tuple[float, float]) -> None:
    """An object at 20 m ahead, ego at 10 m/s: its image expands at (closing speed along the
    camera axis) / depth. Fed that rate, the velocity along the (panned) axis becomes the true
    one; the component across it keeps its prior; a NaN rate changes nothing."""
    pose = CameraPose((1.9, 0.0, 1.3), 0.0, pan, 0.0)
    pos = np.array([22.0, 2.0])
    P = np.diag([1.0, 1.0, 25.0, 25.0])
    g = GroundTrack(np.array([pos[0], pos[1], 0.0, 0.0]), P, 0.0, 10)
    R = pose.rotation()
    d = R[:2, 2] / np.hypot(*R[:2, 2])
    z = float(R[:, 2] @ (np.array([pos[0], pos[1], 0.0]) - np.array(pose.position)))
    closing = float((np.array([10.0, 0.0]) - np.array(obj_vel)) @ d)
    out = range_rate_update(g, closing / z, 0.01 ** 2, pose, 10.0)
    assert float(out.velocity @ d) == pytest.approx(float(np.array(obj_vel) @ d), abs=0.05)
    across = np.array([-d[1], d[0]])
    assert float(out.velocity @ across) == pytest.approx(0.0, abs=1e-9)
    # the measurement std is 0.01 /s x the depth (~20 m): 0.2 m/s along d; the prior (5 m/s) across
    assert out.P[2:, 2:] @ d @ d < 0.05 and out.P[2:, 2:] @ across @ across == pytest.approx(25.0)
    assert range_rate_update(g, math.nan, 0.01, pose, 10.0) is g


def test_range_rate_far_from_a_confident_state_is_skipped() -> None:
    """A state sure of standing still (velocity std 0.1 m/s): an expansion rate saying it
    comes at the car at 5 m/s is 50 sigma off and skipped with a 3.5 sigma gate, taken without."""
    pose = CameraPose((1.9, 0.0, 1.3), 0.0, 0.0, 0.0)
    g = GroundTrack(np.array([22.0, 0.0, 0.0, 0.0]), np.diag([1.0, 1.0, 0.01, 0.01]), 0.0, 30)
    rate = 15.0 / 20.1          # (10 + 5) m/s closing at 20.1 m depth
    assert range_rate_update(g, rate, 0.001 ** 2, pose, 10.0, gate_sigmas=3.5) is g
    taken = range_rate_update(g, rate, 0.001 ** 2, pose, 10.0)
    assert taken.velocity[0] < -4.0


def test_a_bearing_corrects_only_across_the_line_of_sight() -> None:
    """A coasted state 20 m ahead, 3 m right, whose position and velocity are correlated both
    along and across the line of sight; a bearing 0.5 m further left at that range. The
    position moves toward the ray (by most of the 0.5 m: the bearing is far more precise), the
    velocity across the ray follows through its correlation, and the range and the velocity
    along the ray stay as they were (a bearing says nothing about them)."""
    cam = (1.9, 0.0)
    x = np.array([21.9, -3.0, 0.0, 1.2])
    A = np.array([[1.0, 0.3, 0.5, 0.2], [0.0, 1.0, 0.1, 0.6], [0.0, 0.0, 0.8, 0.1], [0.0, 0.0, 0.0, 0.7]])
    P = A @ A.T
    g = GroundTrack(x, P, 1.0, 12)
    az = math.atan2(-2.5, 20.0)
    out = bearing_update(g, az, cam, 2.0 / 700.0)
    d = np.array([math.cos(az), math.sin(az)])
    n = np.array([-math.sin(az), math.cos(az)])
    rel0, rel1 = g.x[:2] - np.array(cam), out.x[:2] - np.array(cam)
    assert abs(n @ rel1) < 0.2 * abs(n @ rel0)                   # onto the measured ray
    assert d @ rel1 == pytest.approx(d @ rel0, abs=1e-9)         # range along it unchanged
    assert d @ out.velocity == pytest.approx(d @ g.velocity, abs=1e-9)
    assert abs(n @ (out.velocity - g.velocity)) > 0.05           # the correlated velocity follows
    assert (out.t_update, out.updates) == (g.t_update, g.updates)  # no ground contact
    assert np.all(np.linalg.eigvalsh(out.P) > 0.0)
    assert float(n @ out.P[:2, :2] @ n) < float(n @ g.P[:2, :2] @ n)
    assert bearing_update(g, math.nan, cam, 0.003) is g


def test_a_bearing_is_gated_by_the_coasted_states_own_uncertainty() -> None:
    """A hidden pedestrian's state coasted 20 m ahead, 3 m right, on a lateral speed its last
    sightings underestimated: its head shows 0.5 m further left (17 px at fx 700, beyond 3 std
    of the head column alone). While the state is 0.3 m unsure across the ray the head is
    within 3 std of the innovation and corrects it; a state sure to 5 cm rejects it."""
    cam = (1.9, 0.0)
    x = np.array([21.9, -3.0, 0.0, 1.0])
    az = math.atan2(-2.5, 20.0)
    std = 2.0 / 700.0
    r = math.hypot(20.0, 3.0)
    assert abs(0.5 / r * 700.0) > BEARING_GATE_SIGMAS * BEARING_STD_PX
    for pos_std, inside in ((0.3, True), (0.05, False)):
        g = GroundTrack(x, np.diag([pos_std ** 2, pos_std ** 2, 0.25, 0.25]), 1.0, 12)
        nu, S = bearing_innovation(g, az, cam, std)
        n = np.array([-math.sin(az), math.cos(az)])
        assert nu == pytest.approx(-float(n @ (x[:2] - np.array(cam))))
        assert abs(nu) == pytest.approx(0.5 * 20.0 / r, rel=0.02)    # 0.5 m across the ray
        assert S == pytest.approx(pos_std ** 2 + (r * std) ** 2)
        assert (nu * nu <= BEARING_GATE_SIGMAS ** 2 * S) is inside


def _follow_braking_car(cfg: GroundModel, seed: int = 0, mount: MountConfig | None = None,
                        rate_std: float = 0.03, std_gain: float = 1.0) -> tuple[GroundTrack, float]:
    """Ego at 50 km/h behind a car 16 m ahead (rear axle frame) at the same speed, which brakes
    at 2 m/s^2 from t = 0.5 s; contacts every 1/30 s with 0.3 m noise in range, 1.5 s of
    braking; the state starts at the car's speed +- 1 m/s (as from a track followed for a
    while). With ``mount`` the state also takes the car's expansion rate every frame, as the
    pipeline does (``rate_std`` 1/s noise, counted ``std_gain`` times, ``cue.range_rate.std_gain``). Returns the
    state and the car's true velocity over ground."""
    rng = np.random.default_rng(seed)
    dt, v0, decel = 1 / 30, 50 / 3.6, 2.0
    R = np.diag([0.3, 0.05]) ** 2
    g = None
    for k in range(61):
        t = k * dt
        tb = max(t - 0.5, 0.0)
        gap = 16.0 - 0.5 * decel * tb * tb  # ego and car at v0 until the car brakes
        z = np.array([gap, 0.0]) + rng.normal(0.0, [0.3, 0.05])
        contact = GroundContact(z=z, R=R)
        sensors = SensorSample(t, v0, 0.0)
        if g is None:
            g = ground_init(contact, t, cfg, (np.array([v0, 0.0]), np.eye(2)))
            continue
        g = ground_update(ground_predict(g, dt, sensors, cfg), contact, t)
        if mount is not None:
            rate = decel * tb / (gap - mount.x_m) + rng.normal(0.0, rate_std)
            g = range_rate_update(g, rate, (std_gain * rate_std) ** 2,
                                  camera_pose(mount, 0.0, sensors), v0, cfg.gate_sigmas)
    assert g is not None
    return g, v0 - decel * (60 * dt - 0.5)


def test_acceleration_state_follows_a_braking_car(default_config: Config) -> None:
    """With the acceleration model (Singer) the state's velocity keeps up with a car braking at
    2 m/s^2 and its acceleration says so; the constant-velocity state lags behind (its
    velocity still near the speed before braking)."""
    ca_cfg = GroundModel(accel_std_m_s2=3.0)
    cv_cfg = GroundModel(accel_std_m_s2=0.0)
    lags_ca, lags_cv, accels = [], [], []
    for seed in range(20):
        ca, v_true = _follow_braking_car(ca_cfg, seed)
        cv, _ = _follow_braking_car(cv_cfg, seed)
        assert len(ca.x) == 6 and len(cv.x) == 4
        lags_ca.append(abs(float(ca.velocity[0]) - v_true))
        lags_cv.append(abs(float(cv.velocity[0]) - v_true))
        accels.append(float(ca.acceleration[0]))
    assert np.median(lags_ca) < 0.6 * np.median(lags_cv)
    assert -3.0 < np.median(accels) < -1.0


def test_a_braking_cars_time_to_collision_keeps_its_deceleration(default_config: Config) -> None:
    """The path prediction keeps an estimated braking at the default significance: followed
    with noisy contacts and an expansion rate every frame (as the pipeline does), a car 12 m
    ahead braking at 2 m/s^2 is estimated at about 2 m/s^2 with a std the Singer model keeps
    near 1.7 m/s^2, and 1.5 s into the braking its TTC is within a few percent of the truth
    (median of 20 seeds). Tested at 2 std, as velocities are, the same estimates counted a
    fraction of themselves and the TTC came out about 60 % long."""
    cfg, mount = default_config, default_config.mount
    v0, decel, r = 50 / 3.6, 2.0, 0.9
    # 1.5 s into the braking: 13.75 m ahead of the rear axle, closing at 3 m/s
    gap, closing = 16.0 - 0.5 * decel * 1.5 ** 2 - r - mount.vehicle_front_m, decel * 1.5
    truth = (-closing + math.sqrt(closing ** 2 + 2 * decel * gap)) / decel

    errors: dict[float, list[float]] = {ACCELERATION_SIGNIFICANCE: [], 2.0: []}
    for seed in range(20):
        g, _ = _follow_braking_car(GroundModel(), seed, mount,
                                   std_gain=cfg.cue.range_rate.std_gain)
        for sigmas, err in errors.items():
            a = significant_acceleration(g.velocity, g.acceleration, g.P, sigmas)
            ttc = predict_path(g.position, g.velocity, v0, 0.0, mount,
                               cfg.warning.corridor_margin_m, r, 6.0, accel=a).ttc
            err.append(abs(ttc - truth) / truth if ttc is not None else math.inf)
    assert np.median(errors[ACCELERATION_SIGNIFICANCE]) < 0.15
    assert np.median(errors[2.0]) > 0.3


def test_coasting_forgets_the_acceleration(default_config: Config) -> None:
    """Without contacts (``steady``) the state moves at constant velocity: an acceleration
    cannot be followed while the object is hidden."""
    cfg = GroundModel(accel_std_m_s2=3.0)
    P = np.diag([0.2, 0.2, 0.3, 0.3, 0.5, 0.5]) ** 2
    g = GroundTrack(np.array([20.0, -8.0, 0.0, 8.0, 0.0, 1.5]), P, 0.0, 30)  # a crossing car
    sensors = SensorSample(0.0, 10.0, 0.0)
    coasted, followed = g, g
    for _ in range(30):
        coasted = ground_predict(coasted, 1 / 30, sensors, cfg, steady=True)
        followed = ground_predict(followed, 1 / 30, sensors, cfg)
    np.testing.assert_allclose(coasted.velocity, [0.0, 8.0], atol=1e-9)
    np.testing.assert_allclose(coasted.position, [10.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(coasted.acceleration, 0.0)
    np.testing.assert_allclose(coasted.P[4:, :4], 0.0)  # uncorrelated: no update moves it
    assert coasted.P[4, 4] >= cfg.accel_std_m_s2 ** 2
    assert followed.velocity[1] > 8.8  # the acceleration, decaying over 2 s, went on


def test_slow_objects_are_followed_at_constant_velocity(default_config: Config) -> None:
    """Below ``accel_min_speed_m_s`` (a pedestrian) the acceleration is not estimated: the
    state is updated exactly as the constant-velocity one (its range noise would otherwise
    come out as acceleration and make its velocity noisier)."""
    ca = GroundModel(accel_std_m_s2=3.0)
    cv = GroundModel(accel_std_m_s2=0.0)
    rng = np.random.default_rng(3)
    R = np.diag([0.4, 0.1]) ** 2
    sensors = SensorSample(0.0, 10.0, 0.0)
    first = GroundContact(np.array([25.0, -4.0]), R)
    prior = (np.array([0.0, 1.4]), np.eye(2) * 0.25)  # walking, as a crossing prior says
    a, b = ground_init(first, 0.0, ca, prior), ground_init(first, 0.0, cv, prior)
    for k in range(1, 40):
        z = np.array([25.0 - 10.0 * k / 30, -4.0 + 1.4 * k / 30]) + rng.normal(0, [0.4, 0.1])
        c = GroundContact(z, R)
        a = ground_update(ground_predict(a, 1 / 30, sensors, ca), c, k / 30)
        b = ground_update(ground_predict(b, 1 / 30, sensors, cv), c, k / 30)
    np.testing.assert_allclose(a.x[:4], b.x, atol=1e-9)
    np.testing.assert_allclose(a.P[:4, :4], b.P, atol=1e-9)
    np.testing.assert_allclose(a.acceleration, 0.0)


def test_braking_object_path_stops_and_meets_the_car_sooner(default_config: Config) -> None:
    """A lead car (radius 0.9 m) 8 m ahead of the bumper, both at 13.9 m/s, braking at 2 m/s^2:
    at constant velocity it never meets the car; with its deceleration kept it does when the
    gap has closed (sqrt(2 gap / a) = 2.83 s). 20 m ahead braking at 6 m/s^2 it stops first
    (2.32 s), and the ego vehicle covers the gap and its stopping distance at its own speed."""
    mount, w = default_config.mount, default_config.warning
    front, r = mount.vehicle_front_m, 0.9

    def ttc(gap: float, accel: float) -> float | None:
        return predict_path(np.array([front + gap + r, 0.0]), np.array([13.9, 0.0]), 13.9, 0.0,
                            mount, w.corridor_margin_m, r, 6.0, accel=accel).ttc

    assert ttc(8.0, 0.0) is None
    assert ttc(8.0, -2.0) == pytest.approx(math.sqrt(2 * 8.0 / 2.0), abs=0.06)
    hard = ttc(20.0, -6.0)
    assert hard is not None and hard > 13.9 / 6.0
    assert hard == pytest.approx((20.0 + 13.9 ** 2 / 12.0) / 13.9, abs=0.06)


def test_significant_acceleration() -> None:
    """Along the direction of travel: whole from ``sigmas`` std, 0 below ``sigmas - 1`` std,
    scaled linearly in between (no jump of the TTC when it hovers there); 0 without the
    model or standing still."""
    P6 = np.diag([0.1, 0.1, 0.2, 0.2, 0.5, 0.5]) ** 2
    v = np.array([10.0, 0.0])
    assert significant_acceleration(v, np.array([-2.0, 0.3]), P6, 2.0) == pytest.approx(-2.0)
    assert significant_acceleration(v, np.array([-1.0, 0.0]), P6, 2.0) == pytest.approx(-1.0)
    assert significant_acceleration(v, np.array([-0.75, 0.0]), P6, 2.0) == pytest.approx(-0.375)
    assert significant_acceleration(v, np.array([-0.4, 0.0]), P6, 2.0) == 0.0
    a = [significant_acceleration(v, np.array([x, 0.0]), P6, 2.0) for x in np.linspace(-2, 0, 41)]
    assert np.all(np.diff(a) >= -1e-12)  # monotonic: no jump as the estimate moves
    assert significant_acceleration(v, np.array([-2.0, 0.0]), np.eye(4), 2.0) == 0.0
    assert significant_acceleration(np.zeros(2), np.array([-2.0, 0.0]), P6, 2.0) == 0.0


def test_the_measured_covariance_is_kept_while_coasting(default_config: Config) -> None:
    """``P_measured`` is P after the last measurement: predictions grow P and leave it, a
    contact or a bearing sets it again; the velocity it makes significant stays so."""
    cfg = GroundModel(process_accel_m_s2=4.0)
    R = np.diag([0.4, 0.1]) ** 2
    sensors = SensorSample(0.0, 10.0, 0.0)
    g = ground_init(GroundContact(np.array([25.0, -4.0]), R), 0.0, cfg,
                    (np.array([0.0, 1.4]), np.eye(2) * 0.04))
    g = ground_update(ground_predict(g, 1 / 30, sensors, cfg),
                      GroundContact(np.array([24.67, -3.95]), R), 1 / 30)
    seen = g.P.copy()
    np.testing.assert_array_equal(g.measured_covariance, seen)
    for _ in range(30):
        g = ground_predict(g, 1 / 30, sensors, cfg, steady=True)
    assert g.P[3, 3] > 4.0 * seen[3, 3]
    np.testing.assert_array_equal(g.measured_covariance, seen)
    # tested with the grown P the walking speed is noise; with the measured one it is not
    assert significant_velocity(g.velocity, g.P, 2.0)[1] == 0.0
    assert significant_velocity(g.velocity, g.measured_covariance, 2.0)[1] > 1.0
    b = bearing_update(g, float(np.arctan2(g.x[1], g.x[0] - 2.0)), (2.0, 0.0), 0.002)
    np.testing.assert_array_equal(b.measured_covariance, b.P)
    # a state built without one (as before P_measured existed) falls back to P
    bare = GroundTrack(g.x, g.P, 0.0, 3)
    np.testing.assert_array_equal(bare.measured_covariance, g.P)



def _crossing_contacts(high_share: float, seed: int) -> list[tuple[float, GroundContact, float]]:
    """A pedestrian crossing 1.4 m/s into the path of a car at 10 m/s, from 30 m to 12 m ahead,
    its contact row 1 px noisy; on ``high_share`` of the frames the feet are found 8-16 px
    too high (the legs lost). (t, contact, true range ahead of the vehicle origin)."""
    return _contacts(seed, lambda k, rng: bool(rng.random() < high_share))


def _contacts(seed: int, high: Callable[[int, np.random.Generator], bool]
              ) -> list[tuple[float, GroundContact, float]]:
    """The crossing pedestrian of :func:`_crossing_contacts`, its feet found 8-16 px too high
    in frame k where ``high(k, rng)``."""
    pose = CameraPose((1.9, 0.0, 1.3), 0.0, 0.0, 0.0)
    rng = np.random.default_rng(seed)
    out = []
    for k in range(45):
        t = k / 25.0
        obj = np.array([30.0 - 10.0 * t, -1.4 * (1.8 - t), 0.0])
        uv = project(CAM, pose, obj)[0] + np.array([0.0, rng.normal(0.0, 1.0)])
        if high(k, rng):
            uv[1] -= rng.uniform(8.0, 16.0)
        contact = ground_contact(CAM, (float(uv[0]), float(uv[1])), pose, GroundModel())
        assert contact is not None
        out.append((t, contact, float(obj[0])))
    return out


def _range_error(contacts: list[tuple[float, GroundContact, float]], above: bool,
                 far_factor: float | None = None) -> float:
    """Median relative range error of the 3-D state over the last 20 contacts."""
    from appliance.decision.ground_state import ground_absorb

    cfg = GroundModel()
    sensors = SensorSample(0.0, 10.0, 0.0)
    g = None
    errors = []
    for t, contact, truth in contacts:
        if g is not None:
            g = ground_predict(g, 1.0 / 25.0, sensors, cfg)
        g = ground_absorb(g, contact, t, cfg, above_feet=above, far_factor=far_factor)
        errors.append((float(g.position[0]) - truth) / truth)
    return float(np.median(errors[-20:]))


def test_contacts_of_an_object_reaching_below_its_cluster_are_taken_as_one_sided() -> None:
    """Feet found too high read too far, never too near: where the object is known to reach
    below its cluster, a contact farther than predicted counts less and the range follows the
    near readings; contacts with a symmetric error keep about their mean."""
    lost_legs = [_crossing_contacts(0.5, seed) for seed in range(3)]
    assert min(_range_error(c, above=False) for c in lost_legs) > 0.04
    assert max(abs(_range_error(c, above=True)) for c in lost_legs) < 0.015
    honest = [_crossing_contacts(0.0, seed) for seed in range(3)]
    assert max(abs(_range_error(c, above=True)) for c in honest) < 0.025


def _walker_contacts(seed: int) -> list[tuple[float, GroundContact, float]]:
    """The pedestrian of :func:`_crossing_contacts` walking at 2 steps/s: its feet are found
    while a foot swings (a quarter of each step) and 8-16 px too high between (the planted foot
    flows like the road, the legs are narrower than the flow's window)."""
    return _contacts(seed, lambda k, rng: k % 12 >= 3)


def test_far_walkers_contacts_between_steps_are_all_but_ignored() -> None:
    """A walker's feet show only while a foot swings. Where its legs are thinner than the flow's
    window, a contact reading farther than predicted counts 10 times less, and the range keeps
    to the steps' readings; with the 3 times of the near regime it reads 2-4 % too far."""
    from appliance.decision.cues.ground import THIN_FAR_FACTOR, far_factor

    # a leg 0.15 m wide is 9 px at 11.7 m with fx 700: farther, it is thinner than the window
    assert far_factor(20.0, 700.0, 9, 3.0) == THIN_FAR_FACTOR
    assert far_factor(11.0, 700.0, 9, 3.0) == 3.0
    assert far_factor(20.0, 1400.0, 9, 3.0) == 3.0

    walkers = [_walker_contacts(seed) for seed in range(3)]
    assert min(_range_error(c, True, 3.0) for c in walkers) > 0.02
    assert max(abs(_range_error(c, True, THIN_FAR_FACTOR)) for c in walkers) < 0.016
