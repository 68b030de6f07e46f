"""warning_quality's second world: kitti-street's own scores in our columns, and the page."""

from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

import pytest

from appliance.cli import main
from appliance.evaluation import pooled
from appliance.sim.drive import simulate
from benchmarks import _kitti_street as ks
from benchmarks._results_page import write_page
from benchmarks.warning_quality import World

WORLD = ks.default_world()


@pytest.mark.skipif(not (WORLD / "score.py").is_file(), reason=f"no kitti-street world at {WORLD}")
def test_the_worlds_scores_map_to_our_columns(tmp_path: Path) -> None:
    # the world's score.py scores any recording with a spec truth.json: one of ours will do
    rec = Path(simulate("lead_car_braking", tmp_path / "data" / "lead", seed=1, duration=3.0))
    assert main(["replay", str(rec), "--out", str(tmp_path / "runs" / "lead"),
                 "--no-progress"]) == 0
    python, _ = ks.find_python(None)
    raw = ks.score(python, WORLD, [rec], tmp_path / "runs")["lead"]
    m = raw["metrics"]
    ev = ks.as_evaluation(raw, ks.duration_s(rec))
    assert ev["duration_s"] == pytest.approx(3.0, abs=0.05)
    assert ev["collision"] is raw["collision"] is True
    assert ev["lead_time_s"] == m["lead_time_s"]["value"]
    assert ev["false_level2"] == m["false_level2"]["value"]
    assert ev["level1_per_min"] == pytest.approx(m["level1_count"]["value"] / (3.0 / 60), 0.02)
    assert ev["worst_detection_delay_frames"] == m["detection_delay_frames"]["value"]
    assert ev["objects"][0]["tracked_fraction"] == m["tracked_fraction"]["value"]
    assert ev["ttc_rel_error_median"] == m["ttc_rel_error"]["value"]
    for ours, theirs in (("lead_time", "lead_time_s"), ("detection", "detection_delay_frames"),
                         ("rotation", "rotation_error_deg")):
        assert ev["targets"][ours] is {"PASS": True, "FAIL": False}[m[theirs]["status"]]
    row = pooled.aggregate([ev])[0]
    assert row["ghosts/min"] == "-" and row["runs"] == "1/1" and row["coll"] == "yes"


@pytest.mark.skipif(not (WORLD / "score.py").is_file(), reason=f"no kitti-street world at {WORLD}")
def test_the_world_also_has_cars_standing_and_braking_in_the_lane() -> None:
    """Through the world's own mover hook: its scenarios and four more, whose cars the world's
    collision test finds where they were planned (the braking car stopped before it)."""
    python, _ = ks.find_python(None)
    names = ks.scenarios(python, WORLD)
    assert {"static_bend", "lead_car_away", "car_stopped_k00", "car_stopped_k06",
            "lead_braking_k06", "car_stopped_next_lane_k06"} <= set(names)
    code = (
        "import sys; sys.path.insert(0, sys.argv[1]); sys.path.insert(0, sys.argv[2]);"
        "import numpy as np, scenarios as S, _kitti_street_standing as K; K.register(S);"
        "out = []\n"
        "for n in ('car_stopped_k06', 'lead_braking_k06', 'car_stopped_next_lane_k06'):\n"
        "    sc = S.Scenario(n, 0); m = sc.movers[0]\n"
        "    v = [float(np.ptp(m.motion(np.array([t - 0.1, t]))[3])) / 0.1\n"
        "         for t in (1.0, sc.t_conflict - 0.3)]\n"
        "    out.append((sc.collision_t, sc.t_conflict, v[0], v[1]))\n"
        "print(out)")
    p = subprocess.run([python, "-c", code, str(WORLD), str(ks.STANDING.parent)],
                       capture_output=True, text=True, check=True)
    (ct0, tc0, a0, b0), (ct1, tc1, a1, b1), (ct2, _, _, _) = eval(p.stdout)
    assert ct0 == pytest.approx(tc0, abs=0.3) and a0 == b0 == 0.0    # it stands
    assert ct1 == pytest.approx(tc1, abs=0.3)
    assert a1 > 8.0 and b1 < 0.3 * a1                # at the ego's speed, then braking hard
    assert ct2 is None                               # the next lane: no contact


def test_a_directory_that_is_not_the_world_is_named_not_a_traceback(tmp_path: Path) -> None:
    (tmp_path / "generate.py").write_text("")        # half a world: no scenarios.py
    p = subprocess.run([sys.executable, str(ks.STANDING), str(tmp_path), "--list"],
                       capture_output=True, text=True, check=False)
    assert p.returncode == 2 and "Traceback" not in p.stderr
    assert p.stderr.strip() == f"{tmp_path}: not the kitti-street world (no scenarios.py)"
    with pytest.raises(ks.WorldError, match=f"{ks.STANDING.name} {tmp_path} --list failed"):
        ks.scenarios(sys.executable, tmp_path)


def test_an_unscored_run_is_an_error_not_a_clean_run() -> None:
    raw = {"scenario": "static_bend", "collision": False,
           "metrics": {"false_level2": {"value": None, "status": "FAIL"}}}
    assert "error" in ks.as_evaluation(raw, 10.0)


def test_the_page_gives_every_table_its_command(tmp_path: Path) -> None:
    own = World("own", ["bend_static"], tmp_path)
    own.results = [{"scenario": "bend_static", "seed": 4, "world": "own",
                    "error": "frames.csv:9: unreadable line"}]
    kitti = World("kitti-street", ["static_bend"], tmp_path)
    args = argparse.Namespace(world="both", seeds=2, first_seed=4, scenarios=None,
                              config="cfg.toml")
    tables = {"own": pooled.aggregate(own.results), "kitti-street": []}
    page = tmp_path / "results.md"
    write_page(page, args, [own, kitti], tables, [], "abc123")
    text = page.read_text()
    assert ("`python -m benchmarks warning_quality --world own --seeds 2 --first-seed 4 "
            "--config cfg.toml`") in text
    assert "--world kitti-street --seeds 2 --first-seed 4" in text
    assert "--world both --seeds 2 --first-seed 4 --config cfg.toml --markdown FILE" in text
    assert "| bend_static | 0/1 |" in text
    assert "- bend_static#4: frames.csv:9: unreadable line" in text
    assert "seeds 4-5" in text and "abc123" in text
