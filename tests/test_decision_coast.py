"""Velocity across the line of sight end to end, and a hidden track assessed from its
coasted 3-D state (``hidden.warn_s``), on the constructed scenes of test_decision_decide.

A cue's contribution is measured by running the decision stage without it: the cues are a
list (``appliance.decision.cues.CUES``), and a missing cue's state reads as "no opinion"."""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

import pytest
from test_decision_decide import Step, crossing, run, scene

from appliance.config import Config
from appliance.decision import cues, decide
from appliance.decision.cues import ground
from appliance.decision.lost_tracks import LostTrack
from appliance.messages import ParticleSet


def without(monkeypatch: pytest.MonkeyPatch, *names: str) -> None:
    """Run the decision stage without the named cues."""
    monkeypatch.setattr(cues, "CUES", tuple(c for c in cues.CUES if c.name not in names))


def covered_without_images(monkeypatch: pytest.MonkeyPatch) -> None:
    """These constructed scenes have no images, so the occlusion test (occlusion.py) cannot
    see an occluder: every hidden track counts as covered."""
    monkeypatch.setattr(LostTrack, "covered", lambda self: True)


def test_line_of_sight_cues_give_a_far_crossing_pedestrian_its_ttc(
        default_config: Config, monkeypatch: pytest.MonkeyPatch) -> None:
    """A pedestrian on a collision course 33-35 m ahead. From the ground contacts alone its
    crossing speed is significant once its longitudinal speed is taken as zero (its lateral
    std given that, not the range rate's share of it: ``threat.significant_velocity``): the
    TTC is there from frame 3. The cues that measure its velocity across and along the line
    of sight (the crossing and range-rate cues) keep it there and right from frame 12 on."""
    obj0, vel = crossing(8.0, 1.4, 5.0, -0.45)
    cfg = default_config
    with monkeypatch.context() as m:
        without(m, "crossing", "range_rate")
        off = run(cfg, scene(cfg, obj0, vel, 8.0, 40))
    on = run(cfg, scene(cfg, obj0, vel, 8.0, 40))
    # contact with the bumper is 5.0 s in (the pedestrian's half depth ahead of it); the
    # ground contact of the constructed cloud puts it about 0.5 s late at this range
    for out, first in ((off, 3), (on, 12)):
        ttcs = [(s.t, tr.ttc_s) for s, o in out[first:39] for tr in o.tracks]
        assert len(ttcs) == 39 - first and all(ttc is not None for _, ttc in ttcs)
        assert all(abs(t + ttc - 5.0) < 0.6 for t, ttc in ttcs)


def test_range_rate_from_the_scale_cue_alone_gives_the_far_pedestrian_its_ttc(
        default_config: Config, monkeypatch: pytest.MonkeyPatch) -> None:
    """The same pedestrian without the crossing cue: the expansion rate of its cluster
    (closing speed / depth) fixes the velocity along the line of sight (the range-rate cue),
    and the TTC is right and steady."""
    obj0, vel = crossing(8.0, 1.4, 5.0, -0.45)
    cfg = default_config
    with monkeypatch.context() as m:
        without(m, "crossing")
        on = run(cfg, scene(cfg, obj0, vel, 8.0, 40))
    ttcs = [(s.t, tr.ttc_s) for s, o in on[28:39] for tr in o.tracks]
    assert ttcs and all(ttc is not None for _, ttc in ttcs)
    # contact 5.0 s in, late by the constructed cloud's contact bias (as above), and steady
    ends = [t + ttc for t, ttc in ttcs]
    assert all(abs(e - 5.0) < 0.5 for e in ends) and max(ends) - min(ends) < 0.15


def test_hidden_track_keeps_its_ttc_from_the_coasted_state(
        default_config: Config, monkeypatch: pytest.MonkeyPatch) -> None:
    """Hidden for 1.5 s on a collision course: with ``hidden.warn_s`` the lost track is still
    reported under its id while hidden, its TTC counting down with the clock, until
    ``warn_s`` after its last ground contact; without it nothing is reported, nor when
    nothing shows an occluder."""
    hidden = frozenset(range(40, 85))
    obj0, vel = crossing(8.0, 1.4, 5.0, -0.45)
    base = default_config.with_overrides({"hidden": {"keep_s": 2.0, "warn_s": 0.0}})
    off = run(base, scene(base, obj0, vel, 8.0, 90, hidden=hidden))
    gated = base.with_overrides({"hidden": {"warn_s": 1.0}})
    unseen = run(gated, scene(gated, obj0, vel, 8.0, 90, hidden=hidden))
    covered_without_images(monkeypatch)
    on = run(gated, scene(gated, obj0, vel, 8.0, 90, hidden=hidden))
    before = {tr.id for tr in on[38][1].tracks}
    assert len(before) == 1
    assert not off[60][1].tracks  # the image tracker has lost it
    # with no image to show an occluder, it is not assessed
    assert all(not o.tracks for _, o in unseen[50:82])
    coasted = [(s.t, o.tracks) for s, o in on[60:68]]
    assert all(len(trs) == 1 and trs[0].id in before and trs[0].ttc_s is not None
               for _, trs in coasted)
    # constant velocity while hidden: t + TTC stays put (to the 0.05 s path step)
    ends = [t + trs[0].ttc_s for t, trs in coasted]
    assert max(ends) - min(ends) <= 0.11
    assert abs(ends[0] - 5.0) < 0.5
    # 1 s after its last ground contact (t = 1.3 s) it is no longer assessed
    assert all(not o.tracks for _, o in on[72:82])


def test_a_hidden_tracks_velocity_is_as_significant_as_when_last_seen(
        default_config: Config, monkeypatch: pytest.MonkeyPatch) -> None:
    """Coasting grows the 3-D state's covariance (process noise) but is no evidence that the
    object stopped: its velocity is tested for significance with the covariance of its last
    measurement (``GroundTrack.P_measured``). With a large process noise the coasted vy's std
    passes half its value within frames; tested with that, the hidden pedestrian would be
    predicted standing at the roadside (no TTC), as nearside seed 9 was before."""
    hidden = frozenset(range(40, 85))
    obj0, vel = crossing(8.0, 1.4, 5.0, -0.45)
    cfg = default_config.with_overrides({"hidden": {"keep_s": 2.0, "warn_s": 1.0}})
    covered_without_images(monkeypatch)
    model = ground.ground_model
    for module in (ground, decide):
        monkeypatch.setattr(module, "ground_model", lambda table: dataclasses.replace(
            model(table), process_accel_m_s2=4.0))
    on = run(cfg, scene(cfg, obj0, vel, 8.0, 90, hidden=hidden))
    before = {tr.id for tr in on[38][1].tracks}
    assert len(before) == 1
    coasted = [o.tracks for _, o in on[48:68]]
    assert all(len(trs) == 1 and trs[0].id in before and trs[0].ttc_s is not None
               for trs in coasted)


def _spurious_expansion(steps: Iterator[Step], frames: range, kappa: float) -> Iterator[Step]:
    """The object's particles (weight > 0.5) measure an expansion of ``kappa`` per frame
    about their centre in ``frames`` that the object does not have."""
    for s in steps:
        if s.frame in frames:
            p = s.particles
            obj = p.weights > 0.5
            flow = p.flow.copy()
            flow[obj] += kappa * (p.positions[obj] - p.positions[obj].mean(axis=0))
            s = dataclasses.replace(s, particles=ParticleSet(p.positions, flow, p.weights, p.valid,
                                                             p.window_px, p.flow_std_px))
        yield s


def test_a_new_tracks_first_expansions_do_not_set_its_range_rate(default_config: Config) -> None:
    """An object standing 3.5 m right of the lane, 28 m ahead, whose first 7 frames of flow
    expand at 3 %/frame (a new track's outline settling): taken at once as closing speed
    (the range rate from the scale cue), the velocity along the line of sight put it on a
    collision course with a TTC under 1 s for a second; the range rate waits for
    ``cue.scale.min_frames`` scale measurements, so no TTC and no warning."""
    cfg = default_config
    res = run(cfg, _spurious_expansion(scene(cfg, (28.0, -3.5), (0.0, 0.0), 8.3, 40), range(1, 8), 0.03))
    assert all(len(o.tracks) == 1 for _, o in res[5:])
    assert all(tr.ttc_s is None for _, o in res for tr in o.tracks)
    assert not any(o.warnings for _, o in res)
