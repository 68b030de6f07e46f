"""Flow over a span of frames: each particle's point traced back m frames, not one.

Eqs. 5-6 weigh the flow of one frame. Far away, where road users appear, that flow is
about as short as its own error: a pedestrian walking towards the road at 5 km/h,
50 m ahead of a car at 30 km/h, moves 0.2 px per frame against the static scene's
0.4 px the other way, and with sigma_p = 0.5 px eq. 5's sigma_l is then so wide that
eq. 6 cannot see even the opposite direction. Over m frames the displacement is m
times longer while Lucas-Kanade's error (a fraction of a pixel, from the patch's
texture and noise) is not, so eq. 6 measures the angle about m times more sharply.

Per frame, after this frame's flow ``x_prev -> x_cur``, each particle's start
``x_prev`` is tracked back into the frame m - 1 frames before it (LK started where
this frame's flow, repeated, puts it; forward-backward checked), and the flow
``x_old -> x_cur`` is weighed with the camera motion composed over the m frames
(:func:`span_motion`). The particle filter is unchanged: a particle just drawn from
g is measured over the span at once. Where the trace back fails (occlusion, a
displacement beyond LK's reach) or a standstill falls in the span, the particle
keeps its one-frame likelihood.
"""

from __future__ import annotations

import numpy as np

from appliance.vision.likelihood import CameraMotion


def compose(first: CameraMotion, then: CameraMotion) -> CameraMotion:
    """The motion of ``first`` followed by ``then`` (``X_c = R_t (R_f X_a + t_f) + t_t``).

    The metric translation composes when both are metric; otherwise the directions
    are composed as if each frame's translation had the same length (the direction
    test only needs the direction) and the result is not metric.
    """
    R = then.R @ first.R
    t_m = None if first.t_m is None or then.t_m is None else then.R @ first.t_m + then.t_m
    t = then.R @ first.t_dir + then.t_dir if t_m is None else t_m
    n = float(np.linalg.norm(t))
    t_dir = t / n if n > 0.0 else np.zeros(3)
    return CameraMotion(R=R, t_dir=t_dir, t_m=t_m,
                        standstill=first.standstill or then.standstill, K=then.K)


def span_motion(current: CameraMotion, earlier: tuple[CameraMotion, ...], frames: int) -> CameraMotion:
    """The camera motion over the last ``frames`` frame pairs: ``earlier[frames - 2]`` (the
    oldest needed; ``earlier`` newest first) through ``earlier[0]``, then ``current``."""
    if frames - 1 > len(earlier):
        raise ValueError(f"a span of {frames} frames needs {frames - 1} earlier motions, "
                         f"got {len(earlier)}")
    motion = current
    for m in earlier[: frames - 1]:
        motion = compose(m, motion)
    return motion
