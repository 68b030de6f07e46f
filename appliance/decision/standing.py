"""Anything standing in the path: static points in the ego corridor that stand up from the road.

The detector finds what moves over ground; a car standing in the lane is static scene to it.
What sets it apart is parallax. With the refined ego motion and the CAN speed, the flow of a
static point is known up to its depth (``likelihood.static_flow``: ``f_s = g w``, ``g = (K
t)_xy - t_z x`` and ``w`` the inverse of its depth in the previous frame), and below the
horizon the road gives that depth at every pixel. A surface standing up from the road at
distance D is nearer than the road seen at its pixels: its flow is longer by ``w_D - w_road``.

Hypotheses: an upright surface ``D`` m ahead of the camera, on the ego path predicted from the
CAN speed and yaw rate, in one of ``CELLS`` lateral cells across the corridor (the ego width
plus ``warning.corridor_margin_m`` a side) or ``SIDE_CELLS`` beside it, probed at
``HEIGHTS_M`` above the road; the distances form a geometric grid from ``MIN_RANGE_M`` to
``obstacle.max_range_m``. Vision measures the flow at those pixels over ``BASELINE_S``
(:func:`corridor_probe` names them and where each search starts); per point and hypothesis
whose surface its ray meets, the log-likelihood ratio of "a static surface at D" against "the
road", residuals truncated at ``RESIDUAL_CLIP`` std so that no single point decides
(:func:`hypothesis_evidence`). A surface reaching ``SURFACE_M[1]`` and a low one reaching
``LOW_TOP_M`` are both hypothesised; what stands is the better of the two: above a crate the
upper probes see the road behind it, and speak against the taller surface. A point moving
independently (its flow ``CROSS_SIGMAS`` std or more across the static direction, p(x) >=
``MOVER_PROBABILITY``, or on a moving track) says nothing: it is a mover, and the movers'
tracks warn of it.

The evidence of a hypothesis is summed over frames, anchored to the road (a standing object
comes nearer by the distance driven), with a fading memory (``obstacle.memory_s``). Where a
corridor cell's evidence reaches ``obstacle.evidence_threshold``, something stands there: the
nearest such cell's peak along the path finds it, its extent the cells beside it that carry
half of it (:func:`nearest_face`; from ``SUSPECT_SHARE`` of the threshold something only may
stand there, which raises a caution at most), and its depth is fit to the parallax of the
points that peak tests (:func:`face_depth`: the peak lies beyond the face); the roadside test
(:func:`joins_roadside`) and its closing (``Obstacle.closing``) tell it from the outside of a
bend. An obstacle is static: its
time to collision and whether it is in the path come from ``threat.predict_path`` for an
object that does not move, the ego driving its arc and braking as its CAN speed says (a driver
braking to a stop short of it is not warned).

An object approaching along the path at a closing speed below the ego's (a lead car braking
to a stop) looks like a static surface farther away than it is, by the ratio of the two
speeds: the time to contact of that surface (its apparent depth over the speed) is the
object's own at its closing speed of the moment. That surface is far and thin (only the
object's rows that a surface at the apparent depth would cover test it), so it is also
hypothesised where the object stands, closing at ``RATES`` of the ego speed: the flow of a
surface at D closing at r times the ego speed is that of a static one at D / r, the surface's
own rows all test it, its evidence is carried nearer by r times the distance driven, or by up
to ``BRAKING_CARRY`` times that, the best of them (a lead car braking comes nearer faster than
its closing speed of the moment says, and the evidence follows it through the layers to its
stop), and its alternatives are the road and something that keeps its distance (no flow: a
lead car at the ego's speed is no closing surface). Where nothing stands, the strongest face
of those layers is what closes. Its depth is hardly told from a nearer one closing slower (the
flow is the same); its apparent depth ``D / r`` is, and with it the time to collision. An
object that brakes towards the car comes nearer faster than its apparent surface would stand:
by ``1 + D a / c^2`` per metre driven (gap D, closing speed c, closing deceleration a); from that
rate, measured over the frames of one layer, the time to collision at a constant deceleration
(:func:`braking_ttc`), for an obstacle once found closing slower than the ego (what stands
does not brake; its depths' jitter would).

Where it cannot work: objects lower than the lowest probe (``HEIGHTS_M``, flat things on the
road: that is the point); far objects, whose parallax drowns in the flow's error (the
evidence grows with ``(w_D - w_road)^2 |g|^2``, i.e. with the ego speed squared over the
distance to the fourth power); a road that rises ahead (nearer than the flat road
predicts: it stands up by the rise).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from appliance.config import MountConfig, ObstacleConfig, WarningConfig
from appliance.decision.assess import CORRIDOR_HYSTERESIS_M, TrackThreat
from appliance.decision.frame import FrameContext, Motion, frame_motion
from appliance.decision.ground_state import MIN_DOWN, CameraPose
from appliance.decision.threat import near_side_gap, predict_path
from appliance.messages import EgoMotion, SensorSample, TrackReport
from appliance.vision.geometry import FloatArray, PinholeCamera, in_image
from appliance.vision.likelihood import derotate
from appliance.vision.probes import PointFlow

MIN_RANGE_M = 3.0          # m ahead of the camera, the nearest hypothesis
RANGE_RATIO = 1.12         # ratio of successive hypothesis distances
CELLS = 6                  # lateral cells across the corridor
SIDE_CELLS = 2             # cells of the same width beside it, each side (the roadside test)
JOIN_RATIO = 2.0           # a roadside's next cell out stands at most this many times nearer
                           #   than the cell before it (a wall across the path recedes cell by
                           #   cell; a parked car near the camera beside a car far ahead does not)
HEIGHTS_M = (0.4, 0.7)     # m above the road, where each hypothesis is probed (beside the
                           #   corridor: the first only)
RESIDUAL_CLIP = 3.0        # std, a point's residual counts up to this (a truncated Gaussian)
CROSS_SIGMAS = 3.0         # flow across the static direction beyond this (std): moving
MOVER_PROBABILITY = 0.5    # p(x) from which a point belongs to a mover
SIGMA_FLOOR_PX = 0.05      # px, the flow's error is taken to be at least this
SHORT_FLOW_PX = 1.0        # px, a road flow shorter than this has an error of its own, not relative
RELATIVE_ERROR = 0.1       # share of the road's flow added to a point's error (long flows)
SURFACE_M = (0.25, 0.9)    # m above the road: the part of a hypothesised surface its points test
LOW_TOP_M = 0.55           # m, the top of a low standing surface (a crate): its points above
#                            see the road behind it, and are not asked
MIN_POINTS = 20            # measured points a frame needs to say anything
EDGE_MARGIN_PX = 6         # px, probes this close to the border are not measured
BASELINE_S = 0.15          # s, the corridor's flow is measured over about this many seconds
MOTIONS = 6                # frame motions kept: a baseline spans at most this + 1 frames
HISTORY_S = 0.5            # s of driving (at the current speed) an obstacle's closing is fit over
MIN_HISTORY_M = 2.0        # m, an obstacle's closing is known once seen over this much driving
LOST_S = 0.3               # s, an obstacle not seen this long is gone
TOP_M = 1.0                # m, the top of an obstacle's reported box (the probes reach HEIGHTS_M)
RATES = (1.0, 0.7, 0.5, 0.35, 0.25)  # the closing speeds (shares of the ego speed) hypothesised:
                           #   1, it stands; less, it drives ahead on the path, slower
LAYER_RATES = (*RATES, 1.0)  # the closing rate of each evidence layer: RATES, then the low
                           #   standing surface (LOW_TOP_M)
BRAKING_CARRY = 4.5        # what closes slower than the ego comes up to this many times nearer per
                           #   frame than at its closing speed c (``1 + D a / c^2``: a lead car
                           #   braking at 0.5 g 20 m ahead, closing at half of 40 km/h: about 4)
BRAKING_STEPS = 5          # the closings between, tried for the evidence carried
CLOSING_WIDTH_M = 1.2      # m, what closes slower than the ego is a vehicle at least this wide
FIT_RATIO = 1.01           # ratio of successive depths a face's depth is fit over
MIN_FACE_POINTS = 5        # points standing up in a face that measure its depth
SUSPECT_SHARE = 0.5        # share of ``obstacle.evidence_threshold`` from which something may
                           #   stand in the path: a caution, until it reaches the threshold


def compose(motions: tuple[Motion | None, ...], now: Motion, frames: int) -> tuple[Motion, int]:
    """The camera's motion over the last ``frames`` frames (this one's ``now`` and the ones
    before it in ``motions``, oldest first), and how many frames it spans: fewer where a
    motion is unknown or the history is shorter."""
    R, t = now
    n = 1
    for m in reversed(motions):
        if n >= frames or m is None:
            break
        R, t = R @ m[0], R @ m[1] + t
        n += 1
    return (R, t), n


@dataclass(frozen=True)
class CorridorProbe:
    """Pixels (M, 2) of the current frame probing the hypotheses, and what reading them needs:
    where in the frame ``frames_back`` frames ago to start the search at each pixel (where a
    road point seen there was), each pixel's share of the flow it measures (1 over the number of
    probes whose Lucas-Kanade windows overlap its own: those measure the same pixels, and their
    errors with them), its ray in the vehicle frame per unit camera depth (M, 3), the inverse
    depth (previous frame, 1/m) of the road seen there (``w_road``, 0 above the horizon), the
    hypothesis distances (m ahead of the camera), the cells' lateral centres (m, from the path),
    the path's curvature (1/m), the camera's position (vehicle frame, m) and its motion over
    those frames (R (3, 3), t_m (3,) m, ``X_cur = R X_then + t``)."""

    points: FloatArray
    guess: FloatArray
    frames_back: int
    share: FloatArray
    rays: FloatArray
    w_road: FloatArray
    ranges: FloatArray
    offsets: FloatArray
    curvature: float
    origin: FloatArray
    R: FloatArray
    t_m: FloatArray


@dataclass(frozen=True)
class Obstacle:
    """Something standing in the path: its public id, its depth ahead of the camera (m), the
    vehicle-frame lateral extent it was seen over (y0, y1 m, at that depth), its evidence
    (nats), when it was first and last seen (s), whether it was found to continue the roadside,
    and its recent depths against the distance the car drove, each with whether that frame's
    face joined the roadside (``history``: (driven m, apparent depth m where the evidence
    peaked, joined), oldest first,
    at most ``HISTORY_S`` back). ``roadside`` is decided once it has been seen for ``HISTORY_S`` and
    over ``MIN_HISTORY_M`` of driving, by the majority of those frames (:func:`joins_roadside`
    flickers where an object's edge meets the background), and kept for as long as it is
    tracked: what joins the parked row does not stand free of it a moment later. Until then, and
    for ``HISTORY_S`` after a frame whose face joins the roadside, it is not warned of
    (``at_roadside``). ``stopped``: it continues the track of a mover that came to a stop there,
    under its id (handover.py); ``top_m``: how high above the road its reported box reaches
    (the probes reach ``HEIGHTS_M``; a stopped mover's own height, where its track knew it).
    ``rate``: the share of the ego speed it closes at, as the evidence layer it was found in
    says (1: it stands); ``layer_since_m``: the distance driven when it was first found in
    that layer; ``was_closing``: it was found closing slower than the ego drives, i.e. moving
    along the path, in a frame (what was seen to move may brake; what stands does not);
    ``confirmed``: its evidence reaches ``obstacle.evidence_threshold`` this frame; short of
    it, from ``SUSPECT_SHARE`` of it, something only may stand there: one obstacle all the
    same, which raises at most a caution while it is not confirmed, and whose face is tested
    against the roadside at that share too; ``confirmed_at``: when it was first confirmed (s;
    None: not yet). Its ``history``, ``roadside`` and ``was_closing`` start anew then: while
    its evidence built up, the peak lagged behind it, and the weak evidence decides nothing
    the confirmed obstacle keeps."""

    id: int
    depth_m: float
    lateral_m: tuple[float, float]
    evidence: float
    since: float
    seen: float
    roadside: bool = False
    history: tuple[tuple[float, float, bool], ...] = ()
    stopped: bool = False
    top_m: float = TOP_M
    rate: float = 1.0
    layer_since_m: float = 0.0
    was_closing: bool = False
    confirmed: bool = True
    confirmed_at: float | None = 0.0

    @property
    def apparent_m(self) -> float:
        """The depth (m) of the standing surface whose parallax it has: ``depth_m`` over the
        share of the ego speed it closes at."""
        return self.depth_m / self.rate

    @property
    def at_roadside(self) -> bool:
        """Whether it continues the roadside: found to, or a face of it joined it over the
        last ``HISTORY_S``."""
        return self.roadside or any(h[2] for h in self.history)

    @property
    def closing(self) -> float | None:
        """How much nearer it comes per metre driven (1: it stands; the least-squares slope of
        its depths against the distance driven), None before it was seen over
        ``MIN_HISTORY_M`` of driving. The outside of a bend the path is predicted along stays
        ahead as the car turns: it does not come nearer."""
        return fit_closing(self.history)

    @property
    def braking(self) -> float | None:
        """``closing`` over the frames of its present layer only (each layer has a depth of
        its own for the same parallax: a change of layer is no motion), None before it was
        seen in that layer over ``MIN_HISTORY_M`` of driving."""
        return fit_closing(tuple(h for h in self.history if h[0] >= self.layer_since_m))


def fit_closing(history: tuple[tuple[float, float, bool], ...]) -> float | None:
    """The least-squares slope of the depths of ``history`` against the distance driven,
    negated (m nearer per metre driven); None over less than three frames or
    ``MIN_HISTORY_M`` of driving."""
    if len(history) < 3:
        return None
    s = np.array([h[0] for h in history])
    d = np.array([h[1] for h in history])
    if s[-1] - s[0] < MIN_HISTORY_M:
        return None
    return float(-np.polyfit(s, d, 1)[0])


@dataclass(frozen=True)
class StandingState:
    """evidence: (layers, bins, CELLS + 2 SIDE_CELLS) summed log-likelihood ratios on the
    distance grid ``ranges`` (m ahead of the camera, this frame's), a layer per rate of
    ``LAYER_RATES`` (those of ``RATES``, then the low standing surface, ``LOW_TOP_M``);
    obstacle: what stands in the path, if anything; motions: the camera's motion (R, t_m) into
    each of the last frames, oldest first (None where the speed was unknown); driven_m: the
    distance driven since the start (m)."""

    evidence: FloatArray
    obstacle: Obstacle | None = None
    motions: tuple[Motion | None, ...] = ()
    driven_m: float = 0.0


def ranges(cfg: ObstacleConfig) -> FloatArray:
    """The hypothesis distances (m ahead of the camera), a geometric grid."""
    if cfg.max_range_m <= MIN_RANGE_M:
        return np.zeros(0)
    n = int(math.floor(math.log(cfg.max_range_m / MIN_RANGE_M) / math.log(RANGE_RATIO))) + 1
    return np.asarray(MIN_RANGE_M * RANGE_RATIO ** np.arange(n), dtype=np.float64)


def init_standing(cfg: ObstacleConfig) -> StandingState:
    return StandingState(evidence=np.zeros((len(LAYER_RATES), len(ranges(cfg)),
                                            CELLS + 2 * SIDE_CELLS)))


def corridor_width(mount: MountConfig, margin: float) -> float:
    """The corridor's width (m): the ego vehicle and ``margin`` a side."""
    return mount.vehicle_width_m + 2.0 * margin


def cell_offsets(width_m: float) -> FloatArray:
    """The lateral cells' centres (m from the path, left +), right to left: ``SIDE_CELLS``
    beside a corridor ``width_m`` wide, its ``CELLS``, and ``SIDE_CELLS`` beside it."""
    step = width_m / CELLS
    n = CELLS + 2 * SIDE_CELLS
    return np.asarray(-0.5 * width_m + step * (np.arange(n) - SIDE_CELLS + 0.5), dtype=np.float64)


def path_y(x: FloatArray, curvature: float) -> FloatArray:
    """Lateral position (m) of the ego path (a circle through the vehicle origin, tangent to x)
    at vehicle x (m); x beyond the circle's reach gets NaN."""
    if abs(curvature) < 1e-6:
        return np.zeros_like(x)
    k = curvature
    with np.errstate(invalid="ignore"):
        return np.asarray((1.0 - np.sqrt(1.0 - (k * x) ** 2)) / k, dtype=np.float64)


def inside(points: FloatArray, boxes: list[tuple[float, float, float, float]]) -> FloatArray:
    """1 where a point (M, 2) px lies in one of ``boxes`` (u0, v0, u1, v1), else 0: the
    points on a tracked mover are the mover's."""
    out = np.zeros(len(points))
    for u0, v0, u1, v1 in boxes:
        out[(points[:, 0] >= u0) & (points[:, 0] <= u1) & (points[:, 1] >= v0)
            & (points[:, 1] <= v1)] = 1.0
    return out


def window_share(uv: FloatArray, window_px: float) -> FloatArray:
    """Per pixel (M,): 1 over the number of pixels of ``uv`` (itself included) within
    ``window_px`` of it in both directions, i.e. whose Lucas-Kanade windows overlap its own
    by half or more."""
    if len(uv) == 0:
        return np.zeros(0)
    d = np.abs(uv[:, None, :] - uv[None, :, :])
    near = (d[..., 0] < 0.5 * window_px) & (d[..., 1] < 0.5 * window_px)
    return np.asarray(1.0 / near.sum(axis=1), dtype=np.float64)


def corridor_probe(pose: CameraPose, camera: PinholeCamera, ego: EgoMotion,
                   sensors: SensorSample, dt: float, mount: MountConfig, margin: float,
                   window_px: float, motions: tuple[Motion | None, ...], cfg: ObstacleConfig
                   ) -> CorridorProbe | None:
    """The pixels probing every hypothesis this frame, measured over the last
    ``BASELINE_S`` (the parallax grows with the distance driven, the flow's error does not);
    None when nothing can be measured (at a standstill, or the speed unknown)."""
    speed = sensors.speed_m_s
    D = ranges(cfg)
    if ego.standstill or not sensors.can_valid or not math.isfinite(speed) or speed <= 0.1 \
            or len(D) == 0:
        return None
    curvature = sensors.yaw_rate_rad_s / speed if math.isfinite(sensors.yaw_rate_rad_s) else 0.0
    offsets = cell_offsets(corridor_width(mount, margin))
    b, c, h = np.meshgrid(np.arange(len(D)), np.arange(len(offsets)), np.arange(len(HEIGHTS_M)),
                          indexing="ij")
    b, c, h = b.ravel(), c.ravel(), h.ravel()
    side = (c < SIDE_CELLS) | (c >= SIDE_CELLS + CELLS)
    b, c, h = b[~side | (h == 0)], c[~side | (h == 0)], h[~side | (h == 0)]  # one height beside
    x = mount.x_m + D[b]
    y = path_y(x, curvature) + offsets[c]
    p = np.column_stack([x, y, np.asarray(HEIGHTS_M)[h]])
    Rvc = pose.rotation()
    cam = (p - np.asarray(pose.position)) @ Rvc        # camera frame: Rvc^T (p - position)
    uv = camera.project(cam)
    keep = np.isfinite(p[:, 1]) & (cam[:, 2] > 0.5) & in_image(uv, camera.width, camera.height,
                                                             EDGE_MARGIN_PX)
    cam, uv = cam[keep], uv[keep]
    now = frame_motion(ego, sensors, dt)
    if now is None:
        return None
    frames = max(1, int(round(BASELINE_S / dt))) if dt > 0.0 else 1
    (R, t_m), back = compose(motions, now, frames)
    x_cur = camera.undistort(uv)
    rays = (cam / cam[:, 2:3]) @ Rvc.T                 # vehicle frame, per unit camera depth
    with np.errstate(divide="ignore"):
        z_road = np.where(rays[:, 2] < -MIN_DOWN, -pose.position[2] / rays[:, 2], np.inf)
    w_road = np.maximum(np.where(np.isfinite(z_road), 1.0 / (z_road - t_m[2]), 0.0), 0.0)
    # where a road point seen here was ``back`` frames ago (eq. of likelihood.static_flow)
    g = (camera.K @ t_m)[None, :2] - t_m[2] * x_cur
    then = np.column_stack([x_cur - g * w_road[:, None], np.ones(len(uv))]) @ camera.K_inv.T
    guess = camera.project(then @ R)                   # R^T: back through the rotation
    guess = np.where(np.isfinite(guess), guess, uv)
    return CorridorProbe(points=uv, guess=guess, frames_back=back,
                         share=window_share(uv, window_px), rays=rays, w_road=w_road, ranges=D,
                         offsets=offsets, curvature=curvature,
                         origin=np.asarray(pose.position, dtype=np.float64), R=R, t_m=t_m)


@dataclass(frozen=True)
class Parallax:
    """This frame's usable corridor points (those measured, not moving independently) and
    what their flow says: ``rays`` (M, 3) vehicle frame per unit camera depth; ``along`` (M,)
    px, the translational flow along the static direction g; ``g_abs`` (M,) |g| (px per unit
    inverse depth); ``sigma`` (M,) px, the flow's error along g; ``w_road`` (M,) the road's
    inverse depth at each; ``share`` (M,) each pixel's share of its window."""

    rays: FloatArray
    along: FloatArray
    g_abs: FloatArray
    sigma: FloatArray
    w_road: FloatArray
    share: FloatArray


def parallax(p: CorridorProbe, flow: PointFlow | None, mover_p: FloatArray,
             camera: PinholeCamera) -> Parallax | None:
    """The corridor points' flow along the static direction and its error (None: fewer than
    ``MIN_POINTS`` measured). Points not measured or moving independently (``mover_p``: p(x)
    at the points, or 1 on a mover; or flowing ``CROSS_SIGMAS`` std across g) are left out.

    The flow's error is measured on the frame itself (:func:`flow_error`), plus
    ``RELATIVE_ERROR`` of the road's flow at the point."""
    if flow is None or len(p.points) == 0:
        return None
    x_cur = camera.undistort(p.points)
    x_prev = camera.undistort(p.points - flow.flow)
    f_t = x_cur - derotate(camera.K, p.R, x_prev)           # translational flow
    Kt = camera.K @ p.t_m
    g = Kt[None, :2] - p.t_m[2] * x_cur                     # static flow per inverse depth
    g2 = np.einsum("ij,ij->i", g, g)
    with np.errstate(invalid="ignore", divide="ignore"):
        normal = np.column_stack([-g[:, 1], g[:, 0]]) / np.sqrt(g2)[:, None]
    measured = flow.valid & np.all(np.isfinite(f_t), axis=1) & np.all(np.isfinite(normal), axis=1) \
        & (mover_p < MOVER_PROBABILITY)
    if np.count_nonzero(measured) < MIN_POINTS:
        return None
    f_t = f_t - rotation_residual(f_t[measured], normal[measured])
    along = np.einsum("ij,ij->i", f_t, g)                   # |g| times the flow along g
    across = np.abs(np.einsum("ij,ij->i", f_t, normal))
    sigma0 = flow_error(across[measured], (along / np.sqrt(g2) - np.sqrt(g2) * p.w_road)[measured],
                        (np.sqrt(g2) * p.w_road)[measured])
    sigma2 = (sigma0 ** 2 + (RELATIVE_ERROR * p.w_road) ** 2 * g2) \
        * aperture(flow.tensor, g, np.sqrt(g2), measured)
    ok = measured & (across < CROSS_SIGMAS * np.sqrt(sigma2)) & (p.rays[:, 0] > 1e-6)
    return Parallax(rays=p.rays[ok], along=along[ok] / np.sqrt(g2[ok]), g_abs=np.sqrt(g2[ok]),
                    sigma=np.sqrt(sigma2[ok]), w_road=p.w_road[ok], share=p.share[ok])


def surface_hits(p: CorridorProbe, rays: FloatArray, D: FloatArray
                 ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Where each ray (M, 3; vehicle frame per unit camera depth) meets an upright surface
    standing on the path at each distance ``D`` (K,) m ahead of the camera: the camera depth
    there (M, K), its height above the road (M, K) and the corridor cell it falls in (M, K;
    whole numbers, as floats)."""
    offsets = p.offsets
    lam = D[None, :] / rays[:, :1]
    height = p.origin[2] + lam * rays[:, 2:3]
    x = p.origin[0] + lam * rays[:, :1]
    lateral = p.origin[1] + lam * rays[:, 1:2] - path_y(x, p.curvature)
    width = offsets[-1] - offsets[0] + (offsets[1] - offsets[0] if len(offsets) > 1 else 0.0)
    cell = np.floor((lateral - (offsets[0] - 0.5 * width / len(offsets))) * len(offsets) / width)
    return lam, height, cell


def hypothesis_evidence(p: CorridorProbe, flow: PointFlow | None, mover_p: FloatArray,
                        camera: PinholeCamera, rates: tuple[float, ...] = (1.0,),
                        pts: Parallax | None = None, low: bool = False) -> FloatArray:
    """This frame's evidence (len(rates) + low, bins, cells), nats: for each hypothesis (an
    upright surface at a distance, in a cell, closing at a share of the ego speed), the summed
    log-likelihood ratio against the road of the points (:func:`parallax`; ``pts`` where
    already computed) whose ray meets that surface between ``SURFACE_M`` above the road, each
    point's residuals truncated at ``RESIDUAL_CLIP`` std (no single point decides). ``low``: a
    last layer, a low surface standing still, asked only by its points up to ``LOW_TOP_M``."""
    D, offsets = p.ranges, p.offsets
    out = np.zeros((len(rates) + low, len(D), len(offsets)))
    if pts is None:
        pts = parallax(p, flow, mover_p, camera)
    if pts is None:
        return out
    rays, w_road, share = pts.rays, pts.w_road, pts.share
    # where each ray meets each hypothesis' surface (points x hypotheses)
    lam, height, cell = surface_hits(p, rays, D)
    on = (height >= SURFACE_M[0]) & (height <= SURFACE_M[1]) & (cell >= 0) \
        & (cell < len(offsets))
    g_abs = pts.g_abs[:, None]
    a = pts.along[:, None]                                  # the flow along g, px
    sigma = pts.sigma[:, None]
    r_road = np.minimum(((a - g_abs * w_road[:, None]) / sigma) ** 2, RESIDUAL_CLIP ** 2)
    i, k = np.nonzero(on)
    cells = cell[i, k].astype(np.int64)
    a, g_abs, sigma, lam, r_road = a[i, 0], g_abs[i, 0], sigma[i, 0], lam[i, k], r_road[i, 0]
    # the alternatives of a surface that closes slower than the ego drives: the road, or
    # something that keeps its distance (no translational flow)
    r_kept = np.minimum(np.minimum((a / sigma) ** 2, RESIDUAL_CLIP ** 2), r_road)
    for j, rate in enumerate(rates):
        # a surface closing at ``rate`` times the ego speed: its flow is the static flow of a
        # point ``1 / rate`` times as far (the camera moved ``rate t`` relative to it)
        w_hyp = rate / (lam - rate * p.t_m[2])
        r_hyp = np.minimum(((a - g_abs * w_hyp) / sigma) ** 2, RESIDUAL_CLIP ** 2)
        alt = r_road if rate >= 1.0 else r_kept
        llr = 0.5 * (alt - r_hyp) * share[i]        # the part of the flow across g cancels
        ok = np.isfinite(llr)
        np.add.at(out[j], (k[ok], cells[ok]), llr[ok])
        if low and rate >= 1.0:
            # a low surface standing still: only its points up to LOW_TOP_M are asked
            ok = ok & (height[i, k] <= LOW_TOP_M)
            np.add.at(out[-1], (k[ok], cells[ok]), llr[ok])
    return out


def face_depth(pts: Parallax | None, p: CorridorProbe, c0: int, c1: int, seen: float,
               near: float) -> float | None:
    """The depth (m ahead of the camera) of a face standing in cells ``c0..c1``, found where
    the evidence peaked (``seen`` m), from its points' own parallax: the points whose ray
    meets the surface at ``seen`` in those cells between ``SURFACE_M`` above the road see the
    face or, beside a narrow one, the road; the depth between ``near`` and ``seen`` that
    explains them best, each point a surface point there or a road point (an even mixture,
    residuals truncated at ``RESIDUAL_CLIP`` std). None with fewer than ``MIN_FACE_POINTS``.

    The evidence's peak along the path is not the depth: a hypothesis farther than the face
    tests rows where the road behind it is farther, so the face's flow stands out from the road
    there by more, and the evidence against the road peaks beyond the face."""
    if pts is None or len(pts.along) == 0:
        return None
    _, height, cell = surface_hits(p, pts.rays, np.array([seen]))
    height, cell = height[:, 0], cell[:, 0]
    on = (height >= SURFACE_M[0]) & (height <= SURFACE_M[1]) & (cell >= c0) & (cell <= c1)
    if np.count_nonzero(on) < MIN_FACE_POINTS:
        return None
    rays, a, g, sigma = pts.rays[on], pts.along[on], pts.g_abs[on], pts.sigma[on]
    r_road = np.minimum(((a - g * pts.w_road[on]) / sigma) ** 2, RESIDUAL_CLIP ** 2)
    depths = near * FIT_RATIO ** np.arange(int(math.log(seen / near) / math.log(FIT_RATIO)) + 2)
    lam_d = depths[None, :] / rays[:, :1]                   # points x depths
    w = 1.0 / (lam_d - p.t_m[2])
    r_hyp = np.minimum(((a[:, None] - g[:, None] * w) / sigma[:, None]) ** 2, RESIDUAL_CLIP ** 2)
    share = pts.share[on][:, None]
    loglik = (share * np.logaddexp(-0.5 * r_hyp, -0.5 * r_road[:, None])).sum(axis=0)
    return float(depths[int(np.argmax(loglik))])


def aperture(tensor: FloatArray | None, g: FloatArray, g_abs: FloatArray,
             measured: NDArray[np.bool_]) -> FloatArray:
    """Per point (M,), how much larger than the frame's its flow's error along the static
    direction ``g`` is (1 at least): the median texture along g over the point's own (the mean
    squared gradient along g in its window, from the structure ``tensor``). A lane marking
    pointing at the epipole gives its window no texture along g: where along the marking the
    window sits is not measured, and Lucas-Kanade's answer there is noise."""
    n = len(g)
    if tensor is None or n == 0:
        return np.ones(n)
    with np.errstate(invalid="ignore", divide="ignore"):
        du, dv = g[:, 0] / g_abs, g[:, 1] / g_abs
        along = tensor[:, 0] * du * du + 2.0 * tensor[:, 1] * du * dv + tensor[:, 2] * dv * dv
    ok = measured & np.isfinite(along) & (along > 0.0)
    if not np.any(ok):
        return np.ones(n)
    typical = float(np.median(along[ok]))
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = np.where(ok, typical / along, np.inf)
    return np.maximum(ratio, 1.0)


def flow_error(across: FloatArray, road_residual: FloatArray, road_flow: FloatArray) -> float:
    """The flow's error on this frame (px, std): the robust spread (``1.4826`` median absolute
    value) of the flow across the static direction (a static point has none: what it has is
    error), or, where larger, that of the flow along it less the road's at the points whose
    road flow is shorter than ``SHORT_FLOW_PX`` (most of them see the road, and those whose
    error is not yet relative); at least ``SIGMA_FLOOR_PX``."""
    sigma = max(1.4826 * float(np.median(np.abs(across))), SIGMA_FLOOR_PX)
    short = road_flow < SHORT_FLOW_PX
    if np.count_nonzero(short) >= MIN_POINTS:
        r = road_residual[short]
        sigma = max(sigma, 1.4826 * float(np.median(np.abs(r - np.median(r)))))
    return sigma


def rotation_residual(f_t: FloatArray, normal: FloatArray, iterations: int = 3) -> FloatArray:
    """The flow (2,) px the refined rotation left over, taken as the same at every point of
    the corridor (a small rotation, near the image centre): static points have no flow across
    their static direction (``normal``, unit (M, 2)), whatever their depth, so what they have
    there is this shift's component plus noise. Least squares, reweighted (Huber, at
    ``1.345`` std) so that movers do not pull it."""
    b = np.zeros(2)
    c = np.einsum("ij,ij->i", f_t, normal)
    w = np.ones(len(c))
    for _ in range(iterations):
        A = normal * w[:, None]
        M = A.T @ normal
        if abs(np.linalg.det(M)) < 1e-9 * max(float(np.trace(M)) ** 2, 1e-12):
            return np.zeros(2)
        b = np.linalg.solve(M, A.T @ c)
        r = c - normal @ b
        s = max(1.4826 * float(np.median(np.abs(r))), SIGMA_FLOOR_PX)
        w = np.minimum(1.0, 1.345 * s / np.maximum(np.abs(r), 1e-12))
    return b


def carried(evidence: FloatArray, D: FloatArray, travel_m: float, keep: float,
            braking: float = 1.0) -> FloatArray:
    """The evidence of the previous frame on this frame's grid: each hypothesis came
    ``travel_m`` nearer (a standing object stays where it is on the road), faded by ``keep``;
    nothing is known beyond the grid's far end. ``braking`` > 1: each came between
    ``travel_m`` and ``braking`` times that nearer, the best of them (what drives ahead of the
    car may brake, and then comes nearer faster than at its closing speed of the moment)."""
    if len(D) == 0:
        return evidence
    shifts = np.linspace(1.0, braking, BRAKING_STEPS) if braking > 1.0 else np.ones(1)
    x = (D[None, :] + travel_m * shifts[:, None]).ravel()
    out = np.empty_like(evidence)
    for c in range(evidence.shape[1]):
        out[:, c] = np.interp(x, D, evidence[:, c], right=0.0).reshape(len(shifts), len(D)) \
            .max(axis=0)
    return keep * out


def peak(column: FloatArray, D: FloatArray) -> tuple[int, float]:
    """The bin of the largest evidence along the path and its distance (m), refined by a
    parabola through its neighbours on the grid's logarithmic scale."""
    k = int(np.argmax(column))
    if 0 < k < len(column) - 1:
        a, b, c = column[k - 1], column[k], column[k + 1]
        den = a - 2.0 * b + c
        if den < 0.0:
            s = float(np.clip(0.5 * (a - c) / den, -0.5, 0.5))
            return k, float(D[k] * RANGE_RATIO ** s)
    return k, float(D[k])


def nearest_face(evidence: FloatArray, D: FloatArray, threshold: float
                 ) -> tuple[int, float, int, int] | None:
    """The face of what stands nearest in the corridor: (bin, depth m, first and last cell) of
    the nearest peak among the corridor's cells whose evidence reaches ``threshold``, and the
    cells beside it, contiguous, whose evidence at that bin reaches half of it; None when no
    cell does. The nearest, not the strongest: edges mix an object's flow with the
    background's, and look farther than it."""
    corridor = range(SIDE_CELLS, SIDE_CELLS + CELLS)
    peaks = [(*peak(evidence[:, c], D), c) for c in corridor
             if len(D) and evidence[:, c].max() >= threshold]
    if not peaks:
        return None
    k, depth, c = min(peaks, key=lambda kdc: kdc[1])
    c0 = c1 = c
    while c0 - 1 in corridor and evidence[k, c0 - 1] >= 0.5 * threshold:
        c0 -= 1
    while c1 + 1 in corridor and evidence[k, c1 + 1] >= 0.5 * threshold:
        c1 += 1
    return k, depth, c0, c1


def joins_roadside(evidence: FloatArray, D: FloatArray, depth: float, c0: int, c1: int,
                   threshold: float) -> bool:
    """Whether the face (cells ``c0..c1`` at ``depth`` m) continues a roadside that comes
    nearer beside it: on either side, from the cell next to its edge outward, something stands
    a bin or more nearer than the face (evidence at least half ``threshold``), in each cell no
    farther than in the one before, up to a cell beside the corridor. The parked cars and
    facades at the outside of a bend stand across a path predicted straight on, as a wall
    receding from the kerb: it enters the corridor from beside it, nearer the farther out. A
    car or a pedestrian in the lane has free road beside it; a car's own evidence spreads into
    the corridor cells beside its peak, nearer than the peak (the evidence peaks beyond a
    face), but not on out of the corridor, nearer still. The roadside recedes cell by cell: in
    each cell it stands at most ``JOIN_RATIO`` times nearer than in the one before (beside a
    car stopped 40 m ahead, a car parked 10 m ahead is the street's parked row, not a wall
    turning across the path)."""
    n = evidence.shape[1]
    for step, start in ((-1, c0 - 1), (1, c1 + 1)):
        before, limit, c = depth, depth / RANGE_RATIO, start
        while 0 <= c < n:
            strong = np.flatnonzero((evidence[:, c] >= 0.5 * threshold)
                                    & (D >= before / JOIN_RATIO))
            nearest = float(D[strong].min()) if len(strong) else math.inf
            if nearest > limit:
                break
            if c < SIDE_CELLS or c >= SIDE_CELLS + CELLS:
                return True
            before = limit = nearest
            c += step
    return False


def found(evidence: FloatArray, standing: FloatArray, D: FloatArray, threshold: float,
          cell: float) -> tuple[tuple[int, float, int, int] | None, int]:
    """The face of what stands in the path at ``threshold`` (:func:`nearest_face`) and its
    layer: in the standing layer (``standing``, the better of the surface and the low one),
    or, where nothing stands, the strongest face of something closing slower, at least
    ``CLOSING_WIDTH_M`` wide (``cell``: a cell's width, m); (None, 0) where neither is."""
    face = nearest_face(standing, D, threshold)
    if face is not None:
        return face, 0
    faces = [(f, j) for j in range(1, len(RATES))
             if (f := nearest_face(evidence[j], D, threshold)) is not None
             and (f[3] - f[2] + 1) * cell >= CLOSING_WIDTH_M - 1e-9]
    if not faces:
        return None, 0
    return max(faces, key=lambda fj: float(
        evidence[fj[1], fj[0][0], fj[0][2]:fj[0][3] + 1].max()))


def standing_step(state: StandingState, p: CorridorProbe | None, flow: PointFlow | None,
                  mover_p: FloatArray, t: float, dt: float, speed: float, motion: Motion | None,
                  camera: PinholeCamera, mount: MountConfig, margin: float, next_id: int,
                  cfg: ObstacleConfig) -> tuple[StandingState, int]:
    """One frame: the evidence carried on and this frame's added; the obstacle, if one stands
    in the path (a new one takes ``next_id``); ``motion``, the camera's since the previous
    frame, kept for the next frames' probes. Returns the state and the next free id."""
    D = ranges(cfg)
    travel = max(speed, 0.0) * dt
    driven = state.driven_m + travel
    keep = math.exp(-max(dt, 0.0) / cfg.memory_s) if cfg.memory_s > 0.0 else 0.0
    evidence = np.stack([carried(layer, D, rate * travel, keep,
                                 1.0 if rate >= 1.0 else BRAKING_CARRY)
                         for layer, rate in zip(state.evidence, LAYER_RATES)])
    pts = None
    if p is not None:
        pts = parallax(p, flow, mover_p, camera)
        evidence = evidence + hypothesis_evidence(p, flow, mover_p, camera, RATES, pts, True)
    obstacle = state.obstacle
    if obstacle is not None and t - obstacle.seen > LOST_S:
        obstacle = None
    width = corridor_width(mount, margin)
    cell = width / CELLS
    # what stands: the better of a surface up to SURFACE_M[1] and a low one, per hypothesis
    standing = np.maximum(evidence[0], evidence[-1])
    threshold = cfg.evidence_threshold
    face, layer = found(evidence, standing, D, threshold, cell)
    confirmed = face is not None
    if not confirmed:
        # short of the threshold: something only may stand there (a caution)
        threshold = SUSPECT_SHARE * cfg.evidence_threshold
        face, layer = found(evidence, standing, D, threshold, cell)
    if face is not None:
        k, depth, c0, c1 = face
        # where it stands: its points' own parallax (the evidence peaks beyond the face); where
        # too few measure it this frame, where it stood, the distance driven nearer
        face_m = face_depth(pts, p, c0, c1, depth, 0.5 * depth) \
            if layer == 0 and p is not None else None
        if face_m is None:
            face_m = obstacle.depth_m - travel if obstacle is not None and obstacle.rate == 1.0 \
                and layer == 0 else depth
        layered = standing if layer == 0 else evidence[layer]
        offsets = cell_offsets(width)
        half = 0.5 * cell
        lateral = (float(offsets[c0] - half), float(offsets[c1] + half))
        ident, since = (next_id, t) if obstacle is None else (obstacle.id, obstacle.since)
        if obstacle is None:
            next_id += 1
        # once confirmed, what it was taken for while it only may have stood is judged anew:
        # its closing (while its evidence built up, its peak lagged behind it), the roadside
        # and whether it closed slower than the ego (weak evidence, at a bar of its own)
        fresh = obstacle is None or (confirmed and obstacle.confirmed_at is None)
        kept = None if fresh else obstacle
        confirmed_at = kept.confirmed_at if kept is not None else t if confirmed else None
        side = joins_roadside(layered, D, depth, c0, c1,
                              threshold if confirmed_at is None else cfg.evidence_threshold)
        stopped = obstacle is not None and obstacle.stopped
        top = obstacle.top_m if obstacle is not None else TOP_M
        history = () if kept is None else kept.history
        history = tuple(h for h in (*history, (driven, depth / RATES[layer], side))
                        if h[0] >= driven - HISTORY_S * max(speed, 0.1))
        roadside = kept is not None and kept.roadside
        judged = since if confirmed_at is None else confirmed_at
        if t - judged >= HISTORY_S and history[-1][0] - history[0][0] >= MIN_HISTORY_M:
            roadside = roadside or 2 * sum(h[2] for h in history) > len(history)
        obstacle = Obstacle(id=ident, depth_m=face_m, lateral_m=lateral,
                            evidence=float(layered[k, c0:c1 + 1].max()), since=since, seen=t,
                            roadside=roadside, history=history, stopped=stopped,
                            top_m=top, rate=RATES[layer],
                            layer_since_m=driven if kept is None
                            or kept.rate != RATES[layer] else kept.layer_since_m,
                            was_closing=RATES[layer] < 1.0
                            or (kept is not None and kept.was_closing),
                            confirmed=confirmed, confirmed_at=confirmed_at)
    motions = (*state.motions, motion)[-MOTIONS:]
    return StandingState(evidence=evidence, obstacle=obstacle, motions=motions,
                         driven_m=driven), next_id


def obstacle_box(ob: Obstacle, pose: CameraPose, camera: PinholeCamera, mount: MountConfig,
                 curvature: float) -> tuple[float, float, float, float]:
    """The image box (u0, v0, u1, v1) px of the part of ``ob`` the cue measured: its lateral
    extent, from the road up to ``ob.top_m``, clipped to the image."""
    x = mount.x_m + ob.depth_m
    yc = float(path_y(np.array([x]), curvature)[0])
    corners = np.array([[x, yc + y, z] for y in ob.lateral_m for z in (0.0, ob.top_m)])
    cam = (corners - np.asarray(pose.position)) @ pose.rotation()
    uv = camera.project(cam)
    if not np.all(np.isfinite(uv)):
        return (0.0, 0.0, 0.0, 0.0)
    u0, v0 = np.clip(uv.min(axis=0), 0.0, [camera.width - 1.0, camera.height - 1.0])
    u1, v1 = np.clip(uv.max(axis=0), 0.0, [camera.width - 1.0, camera.height - 1.0])
    return (round(float(u0), 1), round(float(v0), 1), round(float(u1), 1), round(float(v1), 1))



def braking_ttc(ttc: float, closing: float) -> float:
    """The time to collision (s) of something whose constant-closing time to collision is
    ``ttc`` and which comes ``closing`` m nearer per metre driven (the rate of change of that
    time is ``-closing``): closing at a constant deceleration of the gap, ``D = c T + a T^2 / 2``
    with ``a / D = (closing - 1) / ttc^2``. A closing of 1 or less (it stands, its speed is
    its own and constant, or it draws away) leaves ``ttc`` as it is: never later."""
    k = closing - 1.0
    if k <= 1e-6:
        return ttc
    return ttc * (math.sqrt(1.0 + 2.0 * k) - 1.0) / k


def obstacle_threat(ob: Obstacle, f: FrameContext, cfg: WarningConfig,
                    evidence_threshold: float) -> TrackThreat:
    """The threat of an obstacle standing in the path: a static object ``ob.depth_m`` ahead,
    across its lateral extent, in the path if the ego vehicle's own width (no margin) meets
    one of its cells' centres; its time to collision from the ego's arc and braking
    (``threat.predict_path``) to its apparent depth, sooner where, once seen moving, it comes
    nearer faster than a standing object (:func:`braking_ttc`); its confidence
    ``1 - exp(-evidence / threshold)``."""
    mount, speed, yaw = f.mount, f.speed, f.yaw_rate
    curvature = yaw / speed if speed > 0.1 else 0.0
    x = mount.x_m + ob.depth_m
    y = float(path_y(np.array([x]), curvature)[0]) + 0.5 * (ob.lateral_m[0] + ob.lateral_m[1])
    pos = np.array([x, y])
    # in the path when the vehicle itself would strike it: the margin a mover's predicted path
    # needs is not for an object that does not move; its extent is known to a cell, so the
    # test is on its cells' centres
    cell = corridor_width(mount, cfg.corridor_margin_m) / CELLS
    radius = max(0.5 * (ob.lateral_m[1] - ob.lateral_m[0]) - 0.5 * cell, 0.0)
    still = np.zeros(2)
    base = predict_path(pos, still, speed, yaw, mount, 0.0, radius, cfg.horizon_s, 0.0,
                        f.braking)
    wide = predict_path(pos, still, speed, yaw, mount, CORRIDOR_HYSTERESIS_M, radius,
                        cfg.horizon_s, 0.0, f.braking)
    ttc = base.ttc if base.ttc is not None else wide.ttc
    if ttc is not None:
        # closing at ``rate`` of the ego speed: the time to reach its apparent depth
        ttc = ttc / ob.rate
    if ttc is not None and ob.was_closing and ob.braking is not None:
        ttc = braking_ttc(ttc, ob.braking)
    azimuth = math.atan2(y - mount.y_m, x - mount.x_m)
    report = TrackReport(
        id=ob.id,
        bbox=obstacle_box(ob, f.pose, f.camera, mount, curvature),
        probability=round(1.0 - math.exp(-ob.evidence / evidence_threshold), 4),
        flow=(0.0, 0.0),
        ttc_s=None if ttc is None else round(max(ttc, 0.0), 3),
        distance_m=round(near_side_gap(pos, radius, mount, f.sensors.pan_rad), 2),
        bearing_rad=round(azimuth, 4),
    )
    return TrackThreat(report=report, on_course=base.ttc is not None,
                       on_course_wide=wide.ttc is not None,
                       miss_m=None if base.ttc is not None else base.closest,
                       miss_ahead=base.ttc is None and base.ahead, moving=False,
                       speed_m_s=0.0, standing=True, roadside=ob.at_roadside, closing=ob.closing,
                       stopped=ob.stopped, suspected=not ob.confirmed and not ob.stopped,
                       ego_known=f.ego_known)
