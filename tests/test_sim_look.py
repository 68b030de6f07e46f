"""Every drive is seen with its own look (camera, mount, materials, bounce, sensor), drawn from
its seed: the looks cover their ranges, reach the recording, keep the truth right for any
camera, and the camera model does what it says (colour, exposure, vignetting, blur, noise)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import cv2
import numpy as np
import pytest

from appliance.config import load_config
from appliance.recording import Recording, apply_meta
from appliance.sim import object_textures as ot
from appliance.sim import textures as tx
from appliance.sim.drive import SimulatedDrive, drive_look, simulate
from appliance.sim.effects import Effects, EffectsPipeline, palette
from appliance.sim.ego import BodyBounce
from appliance.sim.look import RANGES, Look
from appliance.sim.materials import TextureBank
from appliance.sim.scenarios import SCENARIOS


def _within(x: float, lo_hi: tuple[float, float]) -> bool:
    return lo_hi[0] <= x <= lo_hi[1]


def test_looks_cover_their_ranges() -> None:
    looks = [Look.draw(np.random.default_rng(s), 640, 480) for s in range(400)]
    fx = np.array([lk.fx for lk in looks])
    assert all(_within(f, RANGES.fx_px) for f in fx)
    assert fx.min() < 470 and fx.max() > 1050  # both ends are reached
    assert 640 < np.median(fx) < 770  # log-uniform: the median near sqrt(450 * 1100) = 704
    for lk in looks:
        assert abs(lk.fy / lk.fx - 1.0) <= 0.01
        assert abs(lk.cx - 319.5) <= 16.0 and abs(lk.cy - 239.5) <= 12.0
        assert _within(lk.mount_height_m, RANGES.mount_height_m)
        assert _within(lk.mount_pitch_rad, RANGES.mount_pitch_rad)
        assert _within(lk.texture_contrast, RANGES.texture_contrast)
        assert _within(lk.bounce_pitch_scale, RANGES.bounce_scale)
        e = lk.effects
        assert _within(e.noise_sigma, RANGES.noise_sigma)
        assert _within(e.blur_sigma, RANGES.blur_sigma_px)
        assert _within(e.vignetting, RANGES.vignetting)
        assert _within(e.exposure, RANGES.exposure) and _within(e.drift, RANGES.drift)
        assert (e.saturation > 0.0) == e.colour
    share = {
        "colour": np.mean([lk.effects.colour for lk in looks]),
        "plain": np.mean([lk.plain_movers for lk in looks]),
        "flicker": np.mean([lk.effects.flicker > 0 for lk in looks]),
        "motion blur": np.mean([lk.effects.blur_exposure > 0 for lk in looks]),
    }
    assert 0.4 < share["colour"] < 0.6 and 0.2 < share["plain"] < 0.4, share
    assert 0.4 < share["flicker"] < 0.6 and 0.25 < share["motion blur"] < 0.45, share


def test_each_drive_has_its_own_look_and_keeps_it() -> None:
    a = drive_look("pedestrian_crossing_nearside", 0)
    assert drive_look("pedestrian_crossing_nearside", 0) == a
    assert drive_look("pedestrian_crossing_nearside", 1).fx != a.fx
    assert drive_look("car_crossing_intersection", 0).fx != a.fx
    # fx is drawn from a continuous range: distinct to the thousandth of a pixel per drive
    fx = {round(drive_look(name, 0).fx, 3) for name in SCENARIOS}
    assert len(fx) == len(SCENARIOS)
    assert SimulatedDrive("pedestrian_crossing_nearside", 0).look == a


def _seed_with(scenario: str, colour: bool) -> int:
    return next(s for s in range(50) if drive_look(scenario, s).effects.colour is colour)


@pytest.mark.parametrize("colour", [True, False])
def test_the_recording_carries_the_looks_camera_and_mount(tmp_path: Path, colour: bool) -> None:
    name = "car_crossing_intersection"
    seed = _seed_with(name, colour)
    drive = SimulatedDrive(name, seed, duration=0.2)
    look = drive.look
    steps = list(drive)
    out = simulate(name, tmp_path / "rec", seed=seed, duration=0.2)
    rec = Recording(out)
    cam, mount = rec.meta.camera, rec.meta.mount
    assert (cam.width, cam.height) == (640, 480)
    assert (cam.fx, cam.fy, cam.cx, cam.cy) == pytest.approx((look.fx, look.fy, look.cx, look.cy))
    assert mount.z_m == pytest.approx(look.mount_height_m)
    assert mount.pitch_rad == pytest.approx(look.mount_pitch_rad)
    cfg = apply_meta(load_config(), rec.meta)  # what replay runs with
    assert cfg.camera.fx == pytest.approx(look.fx) and cfg.mount.z_m == pytest.approx(
        look.mount_height_m
    )
    sim = rec.meta.extra["simulator"]
    assert sim["colour"] is colour and sim["noise_sigma"] == pytest.approx(
        look.effects.noise_sigma, abs=1e-4
    )
    cap = cv2.VideoCapture(str(out / "video.mkv"))
    ok, raw = cap.read()
    cap.release()
    assert ok and raw.ndim == 3  # OpenCV decodes every video as BGR
    channels_differ = bool(np.abs(raw[..., 0].astype(int) - raw[..., 2]).mean() > 1.0)
    assert channels_differ is colour
    assert all(s.image.ndim == (3 if colour else 2) for s in steps)
    for step, frame in zip(steps, rec.frames()):  # the reader gives the appliance gray
        expected = cv2.cvtColor(step.image, cv2.COLOR_BGR2GRAY) if colour else step.image
        np.testing.assert_array_equal(frame.image, expected)


def test_a_colour_drive_is_identical_for_the_same_seed(tmp_path: Path) -> None:
    name = "pedestrian_passes_front"
    seed = _seed_with(name, True)
    a = simulate(name, tmp_path / "a", seed=seed, duration=0.2)
    b = simulate(name, tmp_path / "b", seed=seed, duration=0.2)
    for f in ("meta.toml", "frames.csv", "can.log", "truth.json"):
        assert (a / f).read_bytes() == (b / f).read_bytes()
    fa = [f.image for f in Recording(a).frames()]
    fb = [f.image for f in Recording(b).frames()]
    assert len(fa) == 7 and all(np.array_equal(x, y) for x, y in zip(fa, fb))


def _id_box(ids: np.ndarray, obj: int) -> tuple[int, int, int, int] | None:
    ys, xs = np.nonzero(ids == obj)
    if len(xs) == 0:
        return None
    return int(xs.min()), int(ys.min()), int(xs.max()), int(ys.max())


@pytest.mark.parametrize("fx", [450.0, 1100.0])
@pytest.mark.parametrize(
    "scenario,offsets_s",
    [
        ("pedestrian_crossing_nearside", (0.5, 1.0, 3.5)),
        ("car_crossing_intersection", (0.5, 1.5, 3.0)),
        ("lead_car_braking", (0.5, 2.0)),
    ],
)
def test_truth_boxes_match_the_rendered_movers_for_extreme_cameras(
    scenario: str, offsets_s: tuple[float, ...], fx: float
) -> None:
    wide = fx < 700.0
    look = dataclasses.replace(
        drive_look(scenario, 2),
        fx=fx,
        fy=fx * 1.01,
        cx=319.5 - 16.0,
        cy=239.5 + 12.0,
        mount_height_m=RANGES.mount_height_m[0 if wide else 1],
        mount_pitch_rad=RANGES.mount_pitch_rad[0 if wide else 1],
        bounce_pitch_scale=RANGES.bounce_scale[1],
        effects=Effects.none(),
    )
    drive = SimulatedDrive(scenario, seed=2, look=look)
    compared = 0
    for off in offsets_s:
        step = drive.snapshot(drive.n_frames - 1 - round(off * 30))
        oid = str(drive.truth_header["collision_object"])
        rec = step.truth_frame["objects"][oid]
        u0, v0, u1, v1 = rec["bbox"]
        drawn = _id_box(step.ids, int(oid))
        assert drawn is not None
        assert drawn[0] >= u0 - 1.5 and drawn[1] >= v0 - 1.5
        assert drawn[2] <= u1 + 1.5 and drawn[3] <= v1 + 1.5
        if rec["visible"] < 0.97:
            continue
        np.testing.assert_allclose(drawn, [u0, v0, u1, v1], atol=2.0, err_msg=f"{off} s")
        compared += 1
    assert compared >= 1


@pytest.mark.parametrize("name", list(SCENARIOS))
def test_every_scenario_simulates_with_its_look(tmp_path: Path, name: str) -> None:
    seed = 7
    out = simulate(name, tmp_path / name, seed=seed, duration=0.2)
    rec = Recording(out)
    assert rec.n_frames == 7
    assert rec.meta.camera.fx == pytest.approx(drive_look(name, seed).fx)
    images = [f.image for f in rec.frames()]
    assert all(img.shape == (480, 640) and 20 < img.mean() < 235 for img in images)


def test_colour_keeps_the_luminance_and_gives_objects_their_own_colour() -> None:
    h, w = 120, 160
    ids = np.zeros((h, w), np.uint16)
    ids[20:100, 10:70], ids[20:100, 90:150] = 101, 102
    img = np.tile(np.linspace(20, 200, w).astype(np.uint8), (h, 1))
    fx = Effects(colour=True, saturation=0.6, white_balance=0.08)
    bgr = EffectsPipeline(fx, np.random.default_rng(3)).apply(img, 0.0, (0.0, 0.0), ids)
    assert bgr.shape == (h, w, 3)
    gray = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
    unsaturated = bgr.max(axis=2) < 255
    assert unsaturated.mean() > 0.9
    diff = np.abs(gray.astype(int) - img)[unsaturated]
    assert diff.max() <= 1
    # each object has its own colour: the blue-to-red ratio differs between them
    ratio = bgr[..., 0].astype(float) / np.maximum(bgr[..., 2], 1)
    assert abs(np.median(ratio[30:90, 20:60]) - np.median(ratio[30:90, 100:140])) > 0.05
    gains = palette(np.random.default_rng(0), 1000, 0.6, 0.08)
    np.testing.assert_allclose(gains @ np.array([0.114, 0.587, 0.299]), 1.0, atol=1e-6)
    # noise per channel: the gray the appliance reads has about 0.67 of its std
    flat = np.full((h, w), 128, np.uint8)
    noisy = EffectsPipeline(
        Effects(colour=True, saturation=0.0, noise_sigma=3.0), np.random.default_rng(1)
    ).apply(flat, 0.0, (0.0, 0.0), np.zeros((h, w), np.uint16))
    assert np.std(noisy[..., 1].astype(float)) == pytest.approx(3.0, rel=0.1)
    assert np.std(cv2.cvtColor(noisy, cv2.COLOR_BGR2GRAY).astype(float)) == pytest.approx(
        2.0, rel=0.15
    )


def test_exposure_drift_vignetting_and_optical_blur() -> None:
    flat = np.full((120, 160), 150, np.uint8)
    vig = EffectsPipeline(Effects(vignetting=0.3), np.random.default_rng(0)).apply(
        flat, 0.0, (0.0, 0.0)
    )
    assert vig[60, 80] == 150 and vig[0, 0] == pytest.approx(150 * 0.7, abs=1.5)
    assert vig[0, 80] == pytest.approx(150 * (1 - 0.3 / 2), abs=1.5)  # edge midpoint
    drift = EffectsPipeline(Effects(exposure=1.1, drift=0.1, drift_period_s=10.0),
                            np.random.default_rng(0))
    means = np.array([drift.apply(flat, t, (0.0, 0.0)).mean() for t in np.arange(0, 20, 1 / 30)])
    assert np.mean(means) == pytest.approx(150 * 1.1, abs=1.0)
    assert np.ptp(means) == pytest.approx(2 * 0.1 * 150 * 1.1, abs=2.0)
    assert np.abs(np.diff(means)).max() <= 1.0  # slow: at most 1 DN from frame to frame
    bars = np.tile(np.repeat(np.array([60, 190], np.uint8), 4), (120, 20))
    blurred = EffectsPipeline(Effects(blur_sigma=0.9), np.random.default_rng(0)).apply(
        bars, 0.0, (0.0, 0.0)
    )
    step = np.abs(np.diff(blurred.astype(float), axis=1)).max()
    assert 40 < step < 0.6 * 130


def test_texture_contrast_scales_every_rip_map_level() -> None:
    tex = tx.asphalt(np.random.default_rng(0), size=256)
    low = tx.with_contrast(tex, 0.5)
    for lu, lv in ((0, 0), (2, 0), (3, 3)):
        a, b = tex.level(lu, lv).astype(float), low.level(lu, lv).astype(float)
        assert b.std() == pytest.approx(0.5 * a.std(), rel=0.05, abs=0.3)
        assert b.mean() == pytest.approx(a.mean(), abs=0.6)
    bank = TextureBank.generate(np.random.default_rng(1), contrast=1.3)
    ref = TextureBank.generate(np.random.default_rng(1))
    k = ref["facade0"]
    assert bank.textures[k].levels[0][0].std() > 1.2 * ref.textures[k].levels[0][0].std()


def test_plain_movers_are_nearly_flat() -> None:
    for s in range(10):
        rng = np.random.default_rng(s)
        person = ot.pedestrian(rng, False, plain=True).astype(float)
        assert person[40:200, 12:52].std() < 12.0  # clothing of one colour around the person
        car = ot.car_side(rng, float(rng.uniform(30, 220)), plain=True).astype(float)
        assert car[10:60, 80:180].std() < 8.0  # glass, doors and handles nearly the paint
    regular = [
        ot.pedestrian(np.random.default_rng(s), False)[40:200, 12:52].std() for s in range(10)
    ]
    assert np.median(regular) > 25.0
    name = "pedestrian_crossing_nearside"
    look = dataclasses.replace(drive_look(name, 0), plain_movers=True)
    drive = SimulatedDrive(name, 0, duration=0.2, look=look)
    names = {drive.bank.textures[int(t)].name for t in drive.movers[0].body.faces.texture}
    assert names == {"ped_front_plain", "ped_side_plain"}


def test_bounce_scales_pitch_and_roll_and_draws_the_same_bumps() -> None:
    tau = np.arange(0.0, 20.0, 0.01)
    base = BodyBounce.random(np.random.default_rng(4), 0.0, 20.0).at(tau)
    scaled = BodyBounce.random(np.random.default_rng(4), 0.0, 20.0, 2.0, 0.5).at(tau)
    np.testing.assert_allclose(scaled[0], 2.0 * base[0], atol=1e-12)
    np.testing.assert_allclose(scaled[1], 0.5 * base[1], atol=1e-12)
    np.testing.assert_array_equal(scaled[2], base[2])
