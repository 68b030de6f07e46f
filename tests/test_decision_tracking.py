"""The paper's five Kalman tracking rules, each on a constructed cluster sequence."""

from __future__ import annotations

import numpy as np
import pytest
from filterpy.kalman import KalmanFilter

from appliance.config import Config
from appliance.decision.clustering import Cluster
from appliance.decision.tracking import ImageModel, TrackerState, track_step


def cluster(u: float, v: float, flow: tuple[float, float] = (0.0, 0.0), size: float = 20.0,
            prob: float = 0.8) -> Cluster:
    pos = np.array([[u - 5, v - 5], [u + 5, v + 5], [u, v]], dtype=float)
    return Cluster(bbox=(u - size / 2, v - size / 2, u + size / 2, v + size / 2),
                   region_bbox=(u - size, v - size, u + size, v + size), n=3, foot_v=v + size / 2,
                   mean_flow=flow, mean_probability=prob, positions=pos,
                   flows=np.tile(flow, (3, 1)).astype(float), s=np.full(3, prob),
                   weights=np.full(3, prob))


def run(cfg: Config, frames: list[list[Cluster]]) -> list[TrackerState]:
    state, out = TrackerState(), []
    for clusters in frames:
        state = track_step(state, tuple(clusters), cfg.tracking)
        out.append(state)
    return out


def test_rule1_every_filter_is_predicted_with_its_velocity(default_config: Config) -> None:
    # a target moving 4 px/frame to the right, measured for 5 frames, then missing once
    frames = [[cluster(100 + 4 * k, 200, (4.0, 0.0))] for k in range(5)] + [[]]
    states = run(default_config, frames)
    before, after = states[-2].tracks[0], states[-1].tracks[0]
    assert after.misses == 1 and after.cluster is None
    # coasting moves it by its velocity (+ half its small acceleration), not 0
    assert after.position[0] - before.position[0] == pytest.approx(before.velocity[0], abs=0.5)
    assert after.position[0] - before.position[0] > 3.0


def test_rule1_2_axes_match_filterpy_kalmanfilter(default_config: Config) -> None:
    """Two independent filters per cluster (eqs. 21-24), identical to filterpy's KalmanFilter."""
    cfg = default_config.tracking
    model = ImageModel.from_config(cfg)
    rng = np.random.default_rng(3)
    meas = [(100 + 3 * k + rng.normal(0, 1), 50 + 0.5 * k + rng.normal(0, 1),
             3 + rng.normal(0, 0.2), 0.5 + rng.normal(0, 0.2)) for k in range(8)]
    frames = [[cluster(u, v, (fu, fv))] for u, v, fu, fv in meas]
    states = run(default_config, frames)
    kfs = []
    for axis in range(2):
        kf = KalmanFilter(dim_x=3, dim_z=2)
        kf.F, kf.H, kf.Q, kf.R, kf.P = model.F, model.H, model.Q, model.R, model.P0.copy()
        kf.x = np.array([meas[0][axis], meas[0][2 + axis], 0.0])
        kfs.append(kf)
    for u, v, fu, fv in meas[1:]:
        for axis, kf in enumerate(kfs):
            kf.predict()
            kf.update(np.array([(u, v)[axis], (fu, fv)[axis]]))
    track = states[-1].tracks[0]
    for axis, kf in enumerate(kfs):
        np.testing.assert_allclose(track.x[axis], kf.x, atol=1e-9)
        np.testing.assert_allclose(track.P[axis], kf.P, atol=1e-9)


def test_rule2_gate_7px_or_3_sigma(default_config: Config) -> None:
    # with the sigma gate switched off only the 7 px gate applies
    cfg = default_config.with_overrides({"tracking": {"gate_sigmas": 1e-6}})
    near = run(cfg, [[cluster(100, 100)], [cluster(106, 100)]])[-1]
    assert len(near.tracks) == 1 and near.tracks[0].cluster is not None
    far = run(cfg, [[cluster(100, 100)], [cluster(112, 100)]])[-1]
    # not used as a measurement: the old filter missed (and, tentative, died), a new one was born
    assert [t.uid for t in far.tracks] == [2]
    # with the paper's 3-sigma gate a young (uncertain) filter takes the 12 px region
    wide = run(default_config, [[cluster(100, 100)], [cluster(112, 100)]])[-1]
    assert [t.uid for t in wide.tracks] == [1] and wide.tracks[0].cluster is not None


def test_rule2_closest_region_is_the_measurement(default_config: Config) -> None:
    states = run(default_config, [[cluster(100, 100)], [cluster(104, 100), cluster(97, 100)]])
    t1 = [t for t in states[-1].tracks if t.uid == 1][0]
    assert t1.cluster is not None and t1.cluster.center == (97.0, 100.0)


def test_rule3_tentative_filter_must_be_updated_in_its_first_steps(default_config: Config) -> None:
    cfg = default_config  # confirm_frames = 3, max_missed = 3
    states = run(cfg, [[cluster(100, 100)], [cluster(100, 100)], [], [cluster(100, 100)]])
    assert [t.uid for t in states[1].tracks] == [1]
    assert states[2].tracks == ()  # missed in its second step: removed
    assert [t.uid for t in states[3].tracks] == [2]  # the region starts a new filter
    # updated in each of its first three steps -> confirmed with public id 1
    ok = run(cfg, [[cluster(100, 100)]] * 4)
    assert [t.id for t in ok[2].tracks] == [None]
    assert [t.id for t in ok[3].tracks] == [1]


def test_rule3_confirmed_filter_deleted_after_max_missed(default_config: Config) -> None:
    frames = [[cluster(100, 100)]] * 5 + [[]] * 3
    states = run(default_config, frames)
    assert states[4].tracks[0].confirmed
    assert [t.misses for t in states[5].tracks] == [1]
    assert [t.misses for t in states[6].tracks] == [2]
    assert states[7].tracks == ()


def test_rule4_new_filter_for_every_unassigned_region(default_config: Config) -> None:
    states = run(default_config, [[cluster(100, 100)],
                                  [cluster(100, 100), cluster(300, 50), cluster(500, 400)]])
    assert [t.uid for t in states[-1].tracks] == [1, 2, 3]
    assert sorted(t.position for t in states[-1].tracks)[1] == (300.0, 50.0)


def test_rule5_younger_of_two_close_filters_is_deleted(default_config: Config) -> None:
    cfg = default_config.with_overrides({"tracking": {"gate_sigmas": 1e-6}})
    # two filters 20 px apart whose regions converge until they are within 7 px
    frames = [[cluster(100, 100), cluster(120, 100)]]
    frames += [[cluster(100 + 2 * k, 100, (2.0, 0.0)), cluster(120 - 3 * k, 100, (-3.0, 0.0))]
               for k in range(1, 5)]
    states = run(cfg, frames)
    assert [len(s.tracks) for s in states] == [2, 2, 2, 1, 1]
    # while both lived they were >= 7 px apart; the younger (uid 2) went when they came closer
    assert all(abs(s.tracks[0].position[0] - s.tracks[1].position[0]) >= 7.0 for s in states[:3])
    assert [t.uid for t in states[-1].tracks] == [1]
    # without rule 5 (merge_px = 0) both would have lived on
    both = run(cfg.with_overrides({"tracking": {"merge_px": 0.0}}), frames)
    assert all(len(s.tracks) >= 2 for s in both)


def test_ids_are_stable_and_sequential(default_config: Config) -> None:
    frames = [[cluster(100 + 2 * k, 100), cluster(400 - 2 * k, 300)] for k in range(12)]
    states = run(default_config, frames)
    ids = [[t.id for t in s.tracks] for s in states]
    assert ids[3] == [1, 2]
    assert all(i == [1, 2] for i in ids[3:])
