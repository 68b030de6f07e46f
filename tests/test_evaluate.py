"""``collision-warning evaluate`` on hand-made runs with known lead time and false warnings."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from appliance.cli import main as cli_main
from appliance.config import Config
from appliance.errors import UsageError
from appliance.evaluation.report import evaluate_run
from appliance.evaluation.metrics import ego_motion, ground_speed
from appliance.evaluation.runfiles import TruthObject
from conftest import write_small_recording

FPS = 30.0
T0 = 100.0  # write_small_recording's first frame time
N = 90
CT = T0 + 2.5  # collision 2.5 s into the recording (frame 75)


def small_cfg(cfg: Config) -> Config:
    return cfg.with_overrides({"camera": {"width": 320, "height": 240, "cx": 159.5, "cy": 119.5}})


def mover_box(f: int) -> list[float]:
    """A mover growing from 10 px (frame 0) to 100 px tall (frame 89), centred at (160, 120)."""
    h = 10.0 + f
    return [160 - h / 4, 120 - h / 2, 160 + h / 4, 120 + h / 2]


def truth(collision: bool) -> dict[str, object]:
    frames = {}
    for f in range(N):
        t = T0 + f / FPS
        x = 3.9 + 10.0 * (CT - t) if collision else 3.9 + 10.0 * (CT - t) + 0.0
        y = 0.0 if collision else 5.0
        frames[str(f)] = {"bbox": mover_box(f), "visible": 1.0, "pos_vehicle": [x, y],
                          "vel_vehicle": [-10.0, 0.0]}
    return {"scenario": "hand_made_collision" if collision else "hand_made_pass",
            "collision": collision, "collision_t": CT if collision else None,
            "objects": [{"id": 1, "class": "pedestrian", "moving": True, "frames": frames},
                        {"id": 2, "class": "car", "moving": False,
                         "frames": {"0": {"bbox": [10, 10, 60, 40], "visible": 1.0}}}],
            "camera_poses": {}}


def write_recording(path: Path, cfg: Config, collision: bool = True) -> Path:
    write_small_recording(path, small_cfg(cfg), n_frames=N)
    (path / "truth.json").write_text(json.dumps(truth(collision)))
    return path


def write_run(run: Path, tracks: list[dict[str, object]], warnings: list[dict[str, object]]
              ) -> Path:
    run.mkdir(parents=True, exist_ok=True)
    by_frame: dict[int, list[dict[str, object]]] = {f: [] for f in range(N)}
    for tr in tracks:
        by_frame[int(tr.pop("frame"))].append(tr)  # type: ignore[call-overload]
    with (run / "tracks.jsonl").open("w") as fh:
        for f in range(N):
            fh.write(json.dumps({"t": T0 + f / FPS, "frame": f, "tracks": by_frame[f]}) + "\n")
    with (run / "warnings.jsonl").open("w") as fh:
        for w in warnings:
            fh.write(json.dumps(w) + "\n")
    # a finished run ends with its summary (what evaluate reads is only whether it is there)
    (run / "summary.json").write_text(json.dumps({"frames_read": N, "frames_processed": N}))
    return run


def warning(f: int, level: int, track: int | None, bbox: list[float] | None) -> dict[str, object]:
    return {"t": T0 + f / FPS, "frame": f, "level": level, "track": track, "bbox": bbox,
            "ttc_s": None, "distance_m": None, "bearing_rad": None}


def collision_run(run: Path) -> Path:
    tracks = []
    for f in range(10, N):  # detected from frame 10; eligible (>= 15 px) from frame 5
        t = T0 + f / FPS
        remaining = CT - t
        tracks.append({"frame": f, "id": 5, "bbox": mover_box(f), "probability": 0.8,
                       "flow": [0.0, 0.0],
                       "ttc_s": 1.1 * remaining if remaining > 0 else 0.0,
                       "distance_m": 0.95 * 10.0 * remaining if remaining > 0 else 0.0})
    for f in range(30, 34):  # a ghost track on the static scene
        tracks.append({"frame": f, "id": 9, "bbox": [250, 20, 280, 60], "probability": 0.5,
                       "flow": [0.0, 0.0], "ttc_s": 1.0, "distance_m": 8.0})
    warnings = [
        warning(15, 1, 5, mover_box(15)),
        warning(32, 2, 9, [250, 20, 280, 60]),  # false: on the static scene
        warning(36, 1, 5, mover_box(36)),
        warning(21 + 2 * 10, 2, 5, mover_box(41)),  # frame 41: 2.5 - 41/30 = 1.1333 s lead
        warning(80, 0, 5, None),
    ]
    return write_run(run, tracks, warnings)


def test_collision_run_lead_time_false_warnings_and_errors(tmp_path: Path,
                                                           default_config: Config) -> None:
    rec = write_recording(tmp_path / "rec", default_config)
    run = collision_run(tmp_path / "run")
    r = evaluate_run(rec, run)
    assert r["collision"] is True and r["colliding_object"] == 1
    assert r["lead_time_s"] == pytest.approx(2.5 - 41 / FPS, abs=1e-3)
    # the first caution on the mover (frame 15) came before its level 2; the level 2 at
    # frame 32 on the static scene is not on it
    assert r["caution_lead_s"] == pytest.approx(2.5 - 15 / FPS, abs=1e-3)
    assert r["false_level2"] == 1
    assert r["false_level2_t"] == [pytest.approx(T0 + 32 / FPS, abs=1e-3)]
    assert r["level2_onsets"] == 2
    obj = r["objects"][0]
    assert obj["first_eligible_frame"] == 5 and obj["first_detection_frame"] == 10
    assert obj["detection_delay_frames"] == 5 and obj["track_ids"] == [5]
    assert obj["tracked_fraction"] == pytest.approx(80 / 85)
    # 10 % TTC error and 5 % distance error, by construction
    assert r["ttc_rel_error_median"] == pytest.approx(0.1, abs=1e-3)
    assert r["distance_rel_error_median"] == pytest.approx(0.05, abs=1e-3)
    assert r["targets"]["lead_time"] is False and r["targets"]["no_false_level2"] is False
    assert r["targets"]["ttc_error"] is True and r["targets"]["detection"] is True
    saved = json.loads((run / "evaluation.json").read_text())
    assert saved["lead_time_s"] == r["lead_time_s"]
    # track 9 is on the static scene for 4 frames: one ghost; track 5 is on the mover
    assert (r["ghost_tracks"], r["ghost_track_frames"]) == (1, 4)
    assert r["ghost_tracks_per_min"] == pytest.approx(60.0 / r["duration_s"], abs=1e-2)
    png = (run / "timeline.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_distance_error_is_measured_against_the_footprint_gap_where_the_truth_has_it(
        tmp_path: Path, default_config: Config) -> None:
    """A car ahead is reported at the gap to its near side; its ``pos_vehicle`` is its centre,
    half its length (here 2.2 m) farther. With ``gap_m`` in the truth the estimate is compared
    with the gap; without it, with the centre's (older recordings)."""
    rec = write_recording(tmp_path / "rec", default_config)
    data = json.loads((rec / "truth.json").read_text())
    for f, row in data["objects"][0]["frames"].items():
        remaining = CT - (T0 + int(f) / FPS)
        row["pos_vehicle"] = [3.9 + 2.2 + 10.0 * remaining, 0.0]
        row["gap_m"] = 10.0 * remaining
    (rec / "truth.json").write_text(json.dumps(data))
    run = collision_run(tmp_path / "run")   # distance_m: 0.95 x the near-side gap
    assert evaluate_run(rec, run)["distance_rel_error_median"] == pytest.approx(0.05, abs=1e-3)
    for row in data["objects"][0]["frames"].values():
        del row["gap_m"]
    (rec / "truth.json").write_text(json.dumps(data))
    without = evaluate_run(rec, run)["distance_rel_error_median"]
    assert without > 0.15   # against the centre: |0.95 g - (g + 2.2)| / (g + 2.2), 0.21 at g = 11 m


def test_no_collision_counts_every_level2_and_level1_rate(tmp_path: Path,
                                                          default_config: Config) -> None:
    rec = write_recording(tmp_path / "rec", default_config, collision=False)
    warnings = [warning(10, 1, 3, None), warning(20, 0, 3, None), warning(30, 1, 3, None),
                warning(33, 2, 3, mover_box(33)), warning(50, 0, 3, None)]
    run = write_run(tmp_path / "run", [], warnings)
    r = evaluate_run(rec, run, plot=False)
    assert r["lead_time_s"] is None and r["false_level2"] == 1
    assert r["level1_onsets"] == 2
    assert r["level1_per_min"] == pytest.approx(2 / ((N - 1) / FPS / 60), rel=1e-3)
    assert r["targets"]["level1_rate"] is False and r["targets"]["lead_time"] is None
    assert r["objects"][0]["first_detection_frame"] is None
    assert r["targets"]["detection"] is False


def test_missed_warning_has_no_lead_time(tmp_path: Path, default_config: Config) -> None:
    rec = write_recording(tmp_path / "rec", default_config)
    run = write_run(tmp_path / "run", [], [warning(85, 2, 1, mover_box(85))])  # after contact
    r = evaluate_run(rec, run, plot=False)
    assert r["lead_time_s"] is None and r["targets"]["lead_time"] is False
    assert r["caution_lead_s"] is None


def test_a_caution_alone_gives_a_caution_lead_but_no_lead_time(tmp_path: Path,
                                                                default_config: Config) -> None:
    rec = write_recording(tmp_path / "rec", default_config)
    run = write_run(tmp_path / "run", [], [warning(30, 1, 1, mover_box(30)),
                                           warning(60, 0, 1, None)])
    r = evaluate_run(rec, run, plot=False)
    assert r["caution_lead_s"] == pytest.approx(2.5 - 30 / FPS, abs=1e-3)
    assert r["lead_time_s"] is None


def test_cli_errors_are_one_line_exit_2(tmp_path: Path, default_config: Config,
                                        capsys: pytest.CaptureFixture[str]) -> None:
    rec = write_recording(tmp_path / "rec", default_config)
    no_truth = tmp_path / "plain"
    write_small_recording(no_truth, small_cfg(default_config), n_frames=3)
    run = collision_run(tmp_path / "run")
    assert cli_main(["evaluate", str(no_truth), str(run)]) == 2
    err = capsys.readouterr().err
    assert "no truth.json" in err and len(err.strip().splitlines()) == 1
    empty = tmp_path / "empty"
    empty.mkdir()
    assert cli_main(["evaluate", str(rec), str(empty)]) == 2
    err = capsys.readouterr().err
    assert "tracks.jsonl: missing" in err and len(err.strip().splitlines()) == 1
    (run / "warnings.jsonl").write_text('{"t": 1.0, "frame": 1, "level": 2}\n{oops\n')
    assert cli_main(["evaluate", str(rec), str(run)]) == 2
    assert "warnings.jsonl:2: invalid JSON" in capsys.readouterr().err
    with pytest.raises(UsageError, match="level must be 0, 1 or 2"):
        (run / "warnings.jsonl").write_text('{"t": 1.0, "frame": 1, "level": 7}\n')
        evaluate_run(rec, run, plot=False)


def test_cli_prints_the_table(tmp_path: Path, default_config: Config,
                              capsys: pytest.CaptureFixture[str]) -> None:
    rec = write_recording(tmp_path / "rec", default_config)
    run = collision_run(tmp_path / "run")
    assert cli_main(["evaluate", str(rec), str(run)]) == 0
    out = capsys.readouterr().out
    assert "hand_made_collision" in out and "1.13" in out and "FAIL" in out
    assert "evaluate --help" in out  # where the columns are explained


def test_a_run_that_stopped_half_way_is_refused(tmp_path: Path, default_config: Config,
                                                capsys: pytest.CaptureFixture[str]) -> None:
    rec = write_recording(tmp_path / "rec", default_config)
    run = collision_run(tmp_path / "run")
    (run / "summary.json").unlink()  # a replay killed half way writes no summary
    lines = (run / "tracks.jsonl").read_text().splitlines()[:40]
    (run / "tracks.jsonl").write_text("\n".join(lines) + "\n")
    assert cli_main(["evaluate", str(rec), str(run)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1, err
    assert "incomplete run: no summary.json" in err and f"40 of {N} frames" in err
    assert not (run / "evaluation.json").exists()


def test_help_explains_every_column_of_the_table(capsys: pytest.CaptureFixture[str]) -> None:
    from appliance.evaluation.report import TABLE_COLUMNS

    with pytest.raises(SystemExit) as exc:
        cli_main(["evaluate", "--help"])
    assert exc.value.code == 0
    help_text = capsys.readouterr().out
    legend = help_text[help_text.index("columns of the table:"):]
    entries = {line.split()[0] for line in legend.splitlines()[1:] if line[:3].strip()}
    assert entries == {head for _, head, _ in TABLE_COLUMNS}
    readme = (Path(__file__).parents[1] / "README.md").read_text()
    for _, head, _ in TABLE_COLUMNS:
        assert f"| `{head}` |" in readme, head


def test_collision_object_from_truth_wins_over_geometry(default_config: Config) -> None:
    import numpy as np

    from appliance.evaluation.metrics import evaluate
    from appliance.evaluation.runfiles import parse_truth

    data = truth(True)
    near = json.loads(json.dumps(data["objects"][0]))  # type: ignore[index]
    near["id"] = 3
    data["objects"] = [near, *data["objects"]]  # type: ignore[misc]
    far = data["objects"][1]  # type: ignore[index]
    for rec in far["frames"].values():
        rec["pos_vehicle"][1] = 20.0
    times = T0 + np.arange(N) / FPS
    assert evaluate(parse_truth(data, "t"), [], [], times, (320, 240),
                    default_config.mount)["colliding_object"] == 3
    data["collision_object"] = 1
    assert evaluate(parse_truth(data, "t"), [], [], times, (320, 240),
                    default_config.mount)["colliding_object"] == 1


def test_switch_of_track_during_level2_is_not_a_new_warning(tmp_path: Path,
                                                            default_config: Config) -> None:
    rec = write_recording(tmp_path / "rec", default_config)
    run = collision_run(tmp_path / "run")
    # the ghost's level 2 continues and switches to the mover's track without a drop
    warnings = [warning(32, 2, 9, [250, 20, 280, 60]), warning(41, 2, 5, mover_box(41)),
                warning(80, 0, 5, None)]
    with (run / "warnings.jsonl").open("w") as fh:
        for w in warnings:
            fh.write(json.dumps(w) + "\n")
    r = evaluate_run(rec, run, plot=False)
    assert r["level2_onsets"] == 1 and r["false_level2"] == 1
    assert r["lead_time_s"] == pytest.approx(2.5 - 41 / FPS, abs=1e-3)


def test_a_warning_on_part_of_a_visible_mover_is_on_it(tmp_path: Path, default_config: Config) -> None:
    """A level 2 whose box is the lower quarter of the mover's (IoU 0.22) counts as
    on the mover, for the lead time and not as false; the same box off the mover is false."""
    rec = write_recording(tmp_path / "rec", default_config)
    u0, v0, u1, v1 = mover_box(60)
    legs = [u0 + 2, v1 - 0.25 * (v1 - v0), u1 - 2, v1]
    off = [u1 + 5, v0, u1 + 25, v0 + 20]
    run = write_run(tmp_path / "run", [], [warning(60, 2, 4, legs)])
    r = evaluate_run(rec, run, plot=False)
    assert r["false_level2"] == 0
    assert r["lead_time_s"] == pytest.approx(2.5 - 60 / FPS, abs=1e-3)
    run2 = write_run(tmp_path / "run2", [], [warning(60, 2, 4, off)])
    r2 = evaluate_run(rec, run2, plot=False)
    assert r2["false_level2"] == 1 and r2["lead_time_s"] is None


def test_a_mover_waiting_at_the_kerb_is_eligible_once_it_walks(tmp_path: Path,
                                                                default_config: Config) -> None:
    """Detection delay counts from the first frame the mover moves over the ground: a
    pedestrian standing until frame 40 (relative velocity = the ego's, told by a static
    object's) and tracked from frame 45 is 5 frames late, not 40; standing frames are not
    in the tracked fraction."""
    rec = write_recording(tmp_path / "rec", default_config)
    data = json.loads((rec / "truth.json").read_text())
    ped = data["objects"][0]["frames"]
    for f in range(N):
        ped[str(f)]["vel_vehicle"] = [-10.0, 1.4 if f >= 40 else 0.0]
    data["objects"][1]["frames"] = {str(f): {"bbox": [10, 10, 60, 40], "visible": 1.0,
                                             "pos_vehicle": [30.0, 4.0], "vel_vehicle": [-10.0, 0.0]}
                                    for f in range(N)}
    (rec / "truth.json").write_text(json.dumps(data))
    tracks: list[dict[str, object]] = [
        {"frame": f, "id": 5, "bbox": mover_box(f), "probability": 0.8, "flow": [0.0, 0.0],
         "ttc_s": None, "distance_m": None} for f in range(45, N)]
    r = evaluate_run(rec, write_run(tmp_path / "run", tracks, []), plot=False)
    obj = r["objects"][0]
    assert obj["first_eligible_frame"] == 40 and obj["first_detection_frame"] == 45
    assert obj["detection_delay_frames"] == 5 and r["targets"]["detection"] is True
    assert obj["eligible_frames"] == N - 40
    assert obj["tracked_fraction"] == pytest.approx((N - 45) / (N - 40))


def test_ego_motion_from_a_static_object_with_yaw() -> None:
    """v and w from a static object's relative velocity (-v + w p_y, -w p_x); the ground
    speed of a mover is its relative velocity minus a static point's at its position."""
    v, w = 12.0, 0.1
    static = TruthObject(id=2, cls="car", moving=False, frames=np.array([3, 4]),
                         bbox=np.zeros((2, 4)), visible=np.ones(2),
                         pos=np.array([[20.0, -3.0], [2.0, 1.0]]),
                         vel=np.array([[-v + w * -3.0, -w * 20.0], [-v + w * 1.0, -w * 2.0]]))
    ego = ego_motion([static])
    assert ego[3] == pytest.approx((v, w)) and ego[4] == pytest.approx((v, w))
    walker = TruthObject(id=1, cls="pedestrian", moving=True, frames=np.array([3, 5]),
                         bbox=np.zeros((2, 4)), visible=np.ones(2),
                         pos=np.array([[10.0, 2.0], [9.0, 2.0]]),
                         vel=np.array([[-v + w * 2.0 + 1.0, -w * 10.0 - 1.0], [-v, 0.0]]))
    speed = ground_speed(walker, ego)
    assert speed[0] == pytest.approx(math.sqrt(2.0)) and np.isnan(speed[1])   # frame 5: no ego


def test_a_warning_from_the_objects_own_track_while_it_is_hidden_is_on_it(
        tmp_path: Path, default_config: Config) -> None:
    """The mover is hidden (10 % visible) from frame 45 to 70; its track matched it until
    frame 40 and warns at frame 60 (20 frames later) from its coasted state, with a box where
    nothing of the mover shows: that is a warning on the mover (lead 2.5 - 60/30 s), not a
    false one. The same when the track last matched 21 frames before the occlusion: false."""
    rec = write_recording(tmp_path / "rec", default_config)
    data = json.loads((rec / "truth.json").read_text())
    for f in range(45, 71):
        data["objects"][0]["frames"][str(f)]["visible"] = 0.1
    (rec / "truth.json").write_text(json.dumps(data))
    elsewhere = [10.0, 200.0, 20.0, 210.0]

    def run_with(last: int, name: str) -> dict[str, object]:
        tracks: list[dict[str, object]] = [
            {"frame": f, "id": 5, "bbox": mover_box(f), "probability": 0.8, "flow": [0.0, 0.0],
             "ttc_s": None, "distance_m": None} for f in range(10, last + 1)]
        run = write_run(tmp_path / name, tracks, [warning(60, 2, 5, elsewhere)])
        return evaluate_run(rec, run, plot=False)

    r = run_with(40, "run")
    assert r["false_level2"] == 0
    assert r["lead_time_s"] == pytest.approx(2.5 - 60 / FPS, abs=1e-3)
    r2 = run_with(24, "run2")
    assert r2["false_level2"] == 1 and r2["lead_time_s"] is None


def test_a_level1_onset_is_checked_against_the_truth_course_at_that_moment(
        tmp_path: Path, default_config: Config) -> None:
    # the collision truth: closing at 10 m/s in the lane, the bumper met 2.5 s after frame 0;
    # a caution at frame 10 has the truth course meet the outline 2.17 s later (0.05 s steps)
    rec = write_recording(tmp_path / "rec", default_config)
    run = write_run(tmp_path / "run", [], [warning(10, 1, 3, None), warning(20, 0, 3, None)])
    r = evaluate_run(rec, run, plot=False)
    (c,) = r["level1_courses"]
    assert c["object"] == 1 and c["truth_closest_m"] == 0.0
    assert c["truth_meets_s"] == pytest.approx(2.2)
    assert r["level1_on_truth_course"] == 1
    # the passing truth: 5 m to the side, parallel: 5 - 0.9 (half width) - 0.3 (margin) away
    rec = write_recording(tmp_path / "rec2", default_config, collision=False)
    run = write_run(tmp_path / "run2", [], [warning(10, 1, 3, None), warning(20, 0, 3, None)])
    r = evaluate_run(rec, run, plot=False)
    (c,) = r["level1_courses"]
    assert c["truth_meets_s"] is None and c["truth_closest_m"] == pytest.approx(3.8)
    assert r["level1_on_truth_course"] == 0 and r["level1_onsets"] == 1


def test_the_truth_course_of_a_braking_car_stops_it(default_config: Config) -> None:
    from appliance.evaluation.metrics import truth_course

    # ego at 10 m/s (a static post ahead says so); a lead car 11.73 m ahead of the bumper,
    # braking at 6 m/s^2 from 10 m/s 0.3 s ago: it stops 5.6 m on, the ego car reaches it 1.73 s
    # from now; kept at its present speed (8.2 m/s) it would still be 6.3 m ahead in 3 s
    front = 3.9
    frames, pos, vel = [], [], []
    for k in range(10):                    # frames 0-9, braking from frame 0 (t = 0)
        t = k / FPS
        ground = 10.0 - 6.0 * t
        frames.append(k)
        pos.append([front + 12.0 - 3.0 * t * t, 0.0])
        vel.append([ground - 10.0, 0.0])
    lead = TruthObject(id=1, cls="car", moving=True, frames=np.array(frames),
                       bbox=np.zeros((10, 4)), visible=np.ones(10), pos=np.array(pos),
                       vel=np.array(vel))
    post = TruthObject(id=2, cls="post", moving=False, frames=np.array(frames),
                       bbox=np.zeros((10, 4)), visible=np.ones(10),
                       pos=np.array([[50.0, 5.0]] * 10), vel=np.array([[-10.0, 0.0]] * 10))
    ego = ego_motion([lead, post])
    times = np.arange(10) / FPS
    oid, meets, closest = truth_course([lead], 9, ego, times, default_config.mount, 0.3, 3.0)
    assert oid == 1 and closest == 0.0
    assert meets == pytest.approx(1.75, abs=0.06)


def test_a_narrow_track_on_a_mover_is_no_ghost(tmp_path: Path, default_config: Config) -> None:
    """Ghost tracks are confirmed tracks never on a mover. A far pedestrian's track box can be
    2 px wide inside the pedestrian's (IoU far below 0.3, no match): its centre is inside the
    mover's box, so it is on the mover, not a ghost. A track beside the mover is one."""
    rec = write_recording(tmp_path / "rec", default_config)
    tracks: list[dict[str, object]] = []
    for f in range(20, 26):
        u0, v0, u1, v1 = mover_box(f)
        cu = 0.5 * (u0 + u1)
        tracks.append({"frame": f, "id": 3, "bbox": [cu - 1, v0 + 2, cu + 1, v1 - 2],
                       "probability": 0.5, "flow": [0.0, 0.0], "ttc_s": None, "distance_m": None})
        tracks.append({"frame": f, "id": 4, "bbox": [u1 + 20, v0, u1 + 40, v1],
                       "probability": 0.5, "flow": [0.0, 0.0], "ttc_s": None, "distance_m": None})
    r = evaluate_run(rec, write_run(tmp_path / "run", tracks, []))
    assert r["objects"][0]["first_detection_frame"] is None     # no IoU match at all
    assert (r["ghost_tracks"], r["ghost_track_frames"]) == (1, 6)


def test_a_standing_object_the_drive_collides_with_is_scored_like_a_mover(
        tmp_path: Path, default_config: Config) -> None:
    # a car stopped in the lane: not moving, named as the collision object
    rec = write_recording(tmp_path / "rec", default_config)
    t = json.loads((rec / "truth.json").read_text())
    t["objects"][0]["moving"] = False
    t["objects"][0]["class"] = "car"
    t["collision_object"] = 1
    (rec / "truth.json").write_text(json.dumps(t))
    r = evaluate_run(rec, collision_run(tmp_path / "run"), plot=False)
    assert r["colliding_object"] == 1
    assert r["lead_time_s"] == pytest.approx(2.5 - 41 / FPS, abs=1e-3)
    assert r["false_level2"] == 1            # only the one on the static scene
    assert r["ttc_rel_error_median"] == pytest.approx(0.1, abs=1e-3)
    assert r["objects"] == [] and r["targets"]["detection"] is None   # it never moves
    # without that name it is static scenery like any parked car: no colliding object
    del t["collision_object"]
    (rec / "truth.json").write_text(json.dumps(t))
    r = evaluate_run(rec, tmp_path / "run", plot=False)
    assert r["colliding_object"] is None and r["false_level2"] == 2
