"""One pipeline step per frame: the only place that strings vision and decision together.

``step(state, frame, sensors, cfg, camera) -> (state, StepOutput, DecisionOutput)`` is pure
in everything that matters: time comes in with the frame and the sensors, the
random numbers come from the state's seeded generator, so a replay is
deterministic and a live run can be reproduced from its recording. Live, replay
and demo all call this function; only where the frames come from differs.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.config import Config
from appliance.decision.decide import (
    DecisionOutput,
    DecisionState,
    decide,
    init_decision_state,
    observe,
)
from appliance.messages import (
    EgoMotion,
    Frame,
    ParticleSet,
    ProbabilityMap,
    SensorSample,
    StepOutput,
)
from appliance.vision.geometry import PinholeCamera
from appliance.vision.perception import VisionState, check_frame, init_vision_state, perceive
from appliance.vision.probes import measure_from, measure_points

STAGES = ("vision", "decision", "total")
HISTORY = 8   # frames whose images are kept for probes measured over several frames


@dataclass(frozen=True)
class PipelineState:
    vision: VisionState
    decision: DecisionState
    prob_map: ProbabilityMap | None
    frames: int = 0
    images: tuple[NDArray[np.uint8], ...] = ()   # the last HISTORY frames' images, oldest first


def camera_from_config(cfg: Config) -> PinholeCamera:
    c = cfg.camera
    return PinholeCamera(c.width, c.height, c.fx, c.fy, c.cx, c.cy, tuple(c.distortion))


def init_state(cfg: Config, camera: PinholeCamera) -> PipelineState:
    return PipelineState(
        vision=init_vision_state(cfg, camera, cfg.runtime.seed),
        decision=init_decision_state(cfg, camera),
        prob_map=None,
    )


def decision_step(
    state: DecisionState,
    frame_index: int,
    t: float,
    particles: ParticleSet,
    ego: EgoMotion,
    sensors: SensorSample,
    cfg: Config,
    camera: PinholeCamera,
    images: tuple[NDArray[np.uint8], ...] | None = None,
) -> tuple[DecisionState, DecisionOutput]:
    """The decision stage of one frame: :func:`decide.observe`, the flow vision measures at the
    pixels it asks about (outlines, hidden tracks, the corridor) in ``images`` (recent frames,
    8-bit gray, oldest first, this frame last; fewer than two: nothing is measured), then
    :func:`decide.decide`. Decision never sees the images."""
    obs = observe(state, frame_index, t, particles, ego, sensors, cfg, camera)
    flows = None
    if images is not None and len(images) >= 2:
        flows = measure_points(images[-2], images[-1], obs.requests(), ego.rotation, camera,
                               cfg.flow)
        for key, (points, guess, back) in obs.spanning_requests().items():
            if back < len(images):
                flows[key] = measure_from(images[-1 - back], images[-1], points, guess, cfg.flow)
    return decide(state, obs, flows, cfg)


def step(
    state: PipelineState,
    frame: Frame,
    sensors: SensorSample,
    cfg: Config,
    camera: PinholeCamera,
    clock: Callable[[], float] = time.perf_counter,
) -> tuple[PipelineState, StepOutput, DecisionOutput]:
    """Process one frame. ``clock`` only measures stage durations; it never steers the result."""
    check_frame(frame, camera)
    t0 = clock()
    vision, ego, particles = perceive(state.vision, frame, sensors, state.prob_map, cfg, camera)
    t1 = clock()
    images: tuple[NDArray[np.uint8], ...] = ()
    if vision.prev_image is not None:
        images = (*state.images, vision.prev_image)[-HISTORY:]
    decision, out = decision_step(state.decision, frame.index, frame.t, particles, ego, sensors,
                                  cfg, camera, images)
    t2 = clock()
    result = StepOutput(
        frame=frame.index,
        t=frame.t,
        ego=ego,
        particles=particles,
        tracks=out.tracks,
        warnings=out.warnings,
        warning_level=out.warning_level,
        stage_ms={"vision": (t1 - t0) * 1e3, "decision": (t2 - t1) * 1e3, "total": (t2 - t0) * 1e3},
    )
    new_state = PipelineState(
        vision=vision, decision=decision, prob_map=out.prob_map, frames=state.frames + 1,
        images=images,
    )
    return new_state, result, out
