"""The per-frame trace of one mover (``python -m appliance.evaluation.trace``)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from conftest import write_small_recording

from appliance.config import Config
from appliance.decision.clustering import Cluster
from appliance.decision.decide import DecisionOutput
from appliance.evaluation.trace import main, run_trace, trace_row
from appliance.messages import ProbabilityMap, TrackReport
from appliance.sim.drive import simulate


def cluster(box: tuple[float, float, float, float], n: int, q: float) -> Cluster:
    z = np.zeros((n, 2))
    return Cluster(bbox=box, region_bbox=box, n=n, foot_v=box[3], mean_flow=(0.0, 0.0),
                   mean_probability=q, positions=z, flows=z, s=np.full(n, q),
                   weights=np.full(n, q))


def report(tid: int, box: tuple[float, float, float, float]) -> TrackReport:
    return TrackReport(id=tid, bbox=box, probability=0.8, flow=(0.0, 0.0), ttc_s=2.5,
                       distance_m=12.0)


def test_a_row_lists_what_is_near_the_truth_box() -> None:
    p = np.zeros((60, 80), np.float32)           # scale 4: a 320 x 240 image
    p[25:30, 25:28] = 0.6                          # under the truth box (100-110, 100-118)
    p[5:8, 70:75] = 0.9                            # far away: not this object's
    out = DecisionOutput(
        prob_map=ProbabilityMap(p=p, scale=4),
        clusters=(cluster((102.0, 112.0, 108.0, 118.0), 40, 0.45),
                  cluster((280.0, 20.0, 300.0, 30.0), 9, 0.9)),
        tracks=(report(3, (100.0, 100.0, 110.0, 109.0)), report(4, (250.0, 10.0, 270.0, 40.0))),
        warnings=(), warning_level=1, warning_track=None)
    row = trace_row(7, 1.25, (100.0, 100.0, 110.0, 118.0), 0.9, True, out)
    assert row.p_max == pytest.approx(0.6)
    assert [c[1:] for c in row.clusters] == [(40, 0.45)]
    assert [(t[0], t[2]) for t in row.tracks] == [(3, 0.5)]      # IoU 90 / 180
    assert row.level == 1 and row.eligible and row.frame == 7


@pytest.fixture(scope="module")
def crossing_car(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return simulate("car_crossing_intersection", tmp_path_factory.mktemp("trace") / "car",
                    seed=1, duration=3.0)


def test_trace_follows_a_crossing_car_from_eligible_to_tracked(crossing_car: Path) -> None:
    truth = json.loads((crossing_car / "truth.json").read_text())
    obj, first_eligible, rows = run_trace(crossing_car)
    assert obj.id == truth["collision_object"]
    frames = truth["objects"][[o["id"] for o in truth["objects"]].index(obj.id)]["frames"]
    assert [r.frame for r in rows] == sorted(int(k) for k in frames)
    assert first_eligible is not None
    tracked = [r.frame for r in rows if any(t[2] >= 0.3 for t in r.tracks)]
    # the car is confirmed within the detection target and followed to the end
    assert tracked and tracked[0] - first_eligible <= 10
    assert all(r.p_max >= 0.3 and r.clusters for r in rows if r.frame in tracked[-10:])
    assert rows[-1].level == 2


def test_frames_window_and_json_lines(crossing_car: Path, capsys: pytest.CaptureFixture[str]
                                      ) -> None:
    assert main([str(crossing_car), "--frames", "40:44", "--json"]) == 0
    lines = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    assert [x["frame"] for x in lines] == [40, 41, 42, 43, 44]
    assert {"truth", "p_max", "clusters", "tracks", "level", "eligible"} <= set(lines[0])


def test_bad_input_is_one_line_exit_2(tmp_path: Path, default_config: Config,
                                      crossing_car: Path, capsys: pytest.CaptureFixture[str]
                                      ) -> None:
    plain = tmp_path / "plain"
    write_small_recording(plain, default_config, n_frames=3)
    assert main([str(plain)]) == 2
    err = capsys.readouterr().err
    assert "no truth.json" in err and len(err.strip().splitlines()) == 1
    assert main([str(crossing_car), "--object", "99"]) == 2
    err = capsys.readouterr().err
    assert "no object 99" in err and len(err.strip().splitlines()) == 1
