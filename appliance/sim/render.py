"""Rasteriser: textured planar faces through the pinhole camera, with an object-id buffer.

Each visible face is clipped in 3-D against the near plane and cut into depth
slabs (geometric steps in camera depth); each slab is drawn with one
``cv2.warpPerspective`` of the homography texture -> image into the slab's
bounding rectangle only, masked by its polygon. The texture level (rip-map,
see :mod:`appliance.sim.textures`) is chosen per slab from the size of one
image pixel in texels along each texture axis, so distant and grazing surfaces
are pre-filtered instead of aliasing.

Drawing order: road-level layers first (ground, raised surfaces, markings) in
that order, then upright faces front to back with a per-pixel inverse-depth
test. ``1/z`` is affine in the pixel coordinates over a plane, so the test costs
one ``addWeighted`` per slab; it makes occlusion exact where a painter's order
by distance fails (a long facade behind a parked car, a mover between two
cars). The id buffer records which object each pixel shows (0 = road, sky).

Pixel coordinates follow the camera model: integer values are pixel centres.
Images are rendered on the ideal pinhole and remapped once when the camera has
lens distortion.

Every frame is rendered twice as finely along each axis and filtered down
(``supersample``, ``cv2.pyrDown``: a 5-tap Gaussian centred on every other pixel), as a
sensor integrates light over each pixel: polygon edges drawn with binary masks otherwise
alias into stair steps that crawl along the edge as it moves (a kerb seen at a shallow
angle steps every ~8 px), and Lucas-Kanade follows the steps, not the edge. The id
buffer keeps the fine sample at each pixel centre.
"""

from __future__ import annotations

import bisect
from collections.abc import Sequence
from dataclasses import dataclass
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from appliance.sim.polygons import Point, clip_rect, clip_z
from appliance.sim.texture_warp import FaceFrame, warp_texture
from appliance.sim.textures import Texture
from appliance.sim.world import FLAT, FaceSet, Layer
from appliance.vision.geometry import PinholeCamera

FloatArray = NDArray[np.float64]
_SUB = 16  # fillPoly sub-pixel factor (shift = 4 bits)
_NEIGHBOURS = cv2.getStructuringElement(cv2.MORPH_RECT, (3, 3))
FINE_SAMPLES = 1_000_000  # samples of a mover's coverage mask at most (see _draw_mover; 4 M
                          # cost the simulator 5 % of its speed)
TINY_PX = 48  # slabs whose bounding box is at most this many pixels get the texture's mean


class _Job(NamedTuple):
    """One visible face in camera coordinates (plain floats: the per-face loop is Python)."""

    corners: list[list[float]]
    n_c: list[float]
    o_c: list[float]
    eu_c: list[float]
    ev_c: list[float]
    texel: list[float]
    texture: int
    obj: int
    value: float
    layer: int
    key: float


@dataclass(frozen=True)
class RenderSettings:
    """near_m/far_m: clip distances (camera depth, m); fog ramps from fog_start_m to far_m
    towards ``haze``; slab_ratio: depth ratio of the slabs (finer, fog_slab_ratio, in the fog);
    lod_bias: level = floor(log2(texels per pixel) + lod_bias); supersample: 2 renders the
    frame twice as finely along each axis and filters it down (1 = off)."""

    near_m: float = 0.3
    far_m: float = 160.0
    fog_start_m: float = 90.0
    slab_ratio: float = 1.41
    fog_slab_ratio: float = 1.12
    haze: float = 178.0
    lod_bias: float = 0.5
    ground_extent_m: float = 250.0
    supersample: int = 2


class Renderer:
    """Renders frames of one camera; holds the reusable buffers (not thread-safe)."""

    def __init__(
        self,
        camera: PinholeCamera,
        textures: Sequence[Texture],
        ground_texture: int,
        settings: RenderSettings | None = None,
    ) -> None:
        self.s = settings or RenderSettings()
        self.out_size = (camera.width, camera.height)
        if self.s.supersample not in (1, 2):
            raise ValueError(f"supersample must be 1 or 2, got {self.s.supersample}")
        if self.s.supersample == 2:  # pixel x of the frame is pixel 2x here (centres at integers)
            camera = PinholeCamera(2 * camera.width, 2 * camera.height, 2 * camera.fx,
                                   2 * camera.fy, 2 * camera.cx, 2 * camera.cy,
                                   tuple(camera.distortion))
        self.camera = camera
        self.textures = list(textures)
        self.ground_texture = ground_texture
        W, H = camera.width, camera.height
        self.W, self.H = W, H
        self.K = camera.K
        rows = np.arange(H, dtype=np.float32)[:, None]
        self.sky = np.repeat(np.clip(212.0 - 30.0 * rows / H, 0, 255).astype(np.uint8), W, axis=1)
        self.col_grid = np.ascontiguousarray(
            np.broadcast_to(np.arange(W, dtype=np.float32), (H, W))
        )
        self.row_grid = np.ascontiguousarray(np.broadcast_to(rows, (H, W)))
        self.zbuf = np.zeros((H, W), np.float32)
        # a mover is drawn on its own first (see _draw_mover); kept zero outside its use
        self._mover_img = np.zeros((H, W), np.uint8)
        self._mover_ids = np.zeros((H, W), np.uint16)
        self._mover_z = np.zeros((H, W), np.float32)
        self.slab_z = self._slab_boundaries()
        self._slab_list = self.slab_z.tolist()
        self._k = (camera.fx, camera.fy, camera.cx, camera.cy)
        self._mean = {i: float(tex.levels[-1][-1].mean()) for i, tex in enumerate(self.textures)}
        self._maps: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None
        if camera.has_distortion:
            grid = np.stack(
                np.meshgrid(np.arange(W, dtype=np.float64), np.arange(H, dtype=np.float64)), axis=-1
            ).reshape(-1, 2)
            ideal = camera.undistort(grid).reshape(H, W, 2).astype(np.float32)
            self._maps = (np.ascontiguousarray(ideal[..., 0]), np.ascontiguousarray(ideal[..., 1]))

    def _slab_boundaries(self) -> FloatArray:
        s = self.s
        z = [s.near_m]
        while z[-1] * s.slab_ratio < s.fog_start_m:
            z.append(z[-1] * s.slab_ratio)
        z.append(s.fog_start_m)
        while z[-1] * s.fog_slab_ratio < s.far_m:
            z.append(z[-1] * s.fog_slab_ratio)
        z.append(s.far_m)
        return np.array(z)

    # ------------------------------------------------------------ per frame

    def render(
        self, camera_from_world: FloatArray, face_sets: Sequence[FaceSet],
        movers: Sequence[FaceSet] = (),
    ) -> tuple[NDArray[np.uint8], NDArray[np.uint16]]:
        """Image (H, W) uint8 and object ids (H, W) uint16 seen by a camera at this pose.

        ``camera_from_world`` is the 4x4 inverse of the camera pose. ``movers``: faces drawn
        last, over the finished scene, with anti-aliased silhouettes (:meth:`_draw_mover`).
        """
        R = np.asarray(camera_from_world[:3, :3], float)
        t = np.asarray(camera_from_world[:3, 3], float)
        img = self.sky.copy()
        ids = np.zeros((self.H, self.W), np.uint16)
        self.zbuf.fill(0.0)
        jobs = self._ground_jobs(img, R, t)
        for fs in face_sets:
            if len(fs):
                jobs += self._jobs(fs, R, t)
        # road layers back to front (painter's order), upright faces front to back (the depth
        # test then skips the warps of hidden faces)
        jobs.sort(key=lambda j: (j.layer, j.key))
        for job in jobs:
            self._draw_face(img, ids, self.zbuf, job)
        placed = [self._jobs(fs, R, t) for fs in movers if len(fs)]
        for mover in sorted((m for m in placed if m), key=lambda m: -min(j.key for j in m)):
            self._draw_mover(img, ids, mover)   # far to near: a nearer mover covers a farther one
        if self._maps is not None:
            img = np.asarray(
                cv2.remap(
                    img,
                    self._maps[0],
                    self._maps[1],
                    cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE,
                ),
                np.uint8,
            )
            ids = np.asarray(
                cv2.remap(
                    ids,
                    self._maps[0],
                    self._maps[1],
                    cv2.INTER_NEAREST,
                    borderMode=cv2.BORDER_REPLICATE,
                ),
                np.uint16,
            )
        if self.s.supersample == 2:
            img = np.asarray(cv2.pyrDown(img, dstsize=self.out_size), np.uint8)
            ids = np.ascontiguousarray(ids[::2, ::2])
        return img, ids

    def _jobs(self, fs: FaceSet, R: FloatArray, t: FloatArray) -> list[_Job]:
        """Frustum and back-face culling (vectorised); the visible faces in camera coordinates."""
        cam = self.camera
        Pc = fs.corners @ R.T + t
        x, y, z = Pc[..., 0], Pc[..., 1], Pc[..., 2]
        m = 2.0
        out = (z < self.s.near_m).all(1) | (z > self.s.far_m).all(1)
        out |= (cam.fx * x + (cam.cx + m) * z < 0).all(1)
        out |= (cam.fx * x - (self.W - 1 - cam.cx + m) * z > 0).all(1)
        out |= (cam.fy * y + (cam.cy + m) * z < 0).all(1)
        out |= (cam.fy * y - (self.H - 1 - cam.cy + m) * z > 0).all(1)
        n_c = fs.normal @ R.T
        facing = np.einsum("ij,ij->i", n_c, Pc[:, 0, :]) < 0
        idx = np.flatnonzero(~out & (facing | fs.two_sided))
        if len(idx) == 0:
            return []
        upright = fs.layer[idx] == Layer.UPRIGHT
        key = np.where(upright, z[idx].min(1), -z[idx].max(1))
        o_c = fs.origin[idx] @ R.T + t
        eu_c, ev_c = fs.eu[idx] @ R.T, fs.ev[idx] @ R.T
        cols = zip(
            Pc[idx].tolist(),
            n_c[idx].tolist(),
            o_c.tolist(),
            eu_c.tolist(),
            ev_c.tolist(),
            fs.texel[idx].tolist(),
            fs.texture[idx].tolist(),
            fs.obj[idx].tolist(),
            fs.value[idx].tolist(),
            fs.layer[idx].tolist(),
            key.tolist(),
        )
        return [_Job(*c) for c in cols]

    def _ground_jobs(self, img: NDArray[np.uint8], R: FloatArray, t: FloatArray) -> list[_Job]:
        """Draws the haze beyond the far plane; returns the road plane (z = 0) around the camera."""
        cam_w = -R.T @ t
        cx, cy = float(cam_w[0]), float(cam_w[1])
        s = self.s
        far = 20.0 * s.far_m
        quad = (
            np.array(
                [
                    [cx - far, cy - far, 0],
                    [cx + far, cy - far, 0],
                    [cx + far, cy + far, 0],
                    [cx - far, cy + far, 0],
                ],
                float,
            )
            @ R.T
            + t
        )
        poly = clip_z([tuple(p) for p in quad.tolist()], s.far_m * 0.95, True)
        haze = self._pts(poly) if len(poly) >= 3 else None
        if haze is not None:
            cv2.fillPoly(img, [haze[0]], int(s.haze), cv2.LINE_8, 4)
        e = s.ground_extent_m
        corners = np.array(
            [[cx - e, cy - e, 0], [cx + e, cy - e, 0], [cx + e, cy + e, 0], [cx - e, cy + e, 0]],
            float,
        )
        tex = self.textures[self.ground_texture]
        ground = FaceSet(
            corners[None],
            np.array([[0, 0, 1.0]]),
            np.zeros((1, 3)),
            np.array([[1.0, 0, 0]]),
            np.array([[0, 1.0, 0]]),
            np.array([tex.texel_m]),
            np.array([self.ground_texture]),
            np.array([int(Layer.GROUND)]),
            np.array([0]),
            np.array([0.0]),
            np.array([False]),
        )
        return self._jobs(ground, R, t)

    def _pts(
        self, poly: Sequence[Point]
    ) -> tuple[NDArray[np.int32], tuple[float, float, float, float]] | None:
        """fillPoly vertices (sub-pixel) and pixel bounds of a polygon in front of the camera,
        clipped to the image (so a wide ground slab gets a tight ROI even when rolled)."""
        fx, fy, cx, cy = self._k
        uv = [(fx * p[0] / p[2] + cx, fy * p[1] / p[2] + cy) for p in poly]
        us, vs = [q[0] for q in uv], [q[1] for q in uv]
        bounds = (min(us), min(vs), max(us), max(vs))
        lo_u, lo_v, hi_u, hi_v = -2.0, -2.0, self.W + 1.0, self.H + 1.0
        if bounds[0] < lo_u or bounds[1] < lo_v or bounds[2] > hi_u or bounds[3] > hi_v:
            uv = clip_rect(uv, lo_u, lo_v, hi_u, hi_v)
            if len(uv) < 3:
                return None
            us, vs = [q[0] for q in uv], [q[1] for q in uv]
            bounds = (min(us), min(vs), max(us), max(vs))
        return np.rint(np.array(uv) * _SUB).astype(np.int32), bounds

    def _draw_face(self, img: NDArray[np.uint8], ids: NDArray[np.uint16],
                   zbuf: NDArray[np.float32], job: _Job) -> None:
        s = self.s
        clipped = self._clipped(job)
        if clipped is None:
            return
        poly, zmin, zmax = clipped
        if (
            job.texture == FLAT and job.layer != Layer.UPRIGHT
        ):  # markings, kerbs: one anti-aliased polygon
            fog = self._fog(0.5 * (zmin + zmax))
            val = (1.0 - fog) * job.value + fog * s.haze
            flat = self._pts(poly)
            if flat is not None:
                cv2.fillPoly(img, [flat[0]], int(round(val)), cv2.LINE_AA, 4)
            return
        k0 = max(bisect.bisect_right(self._slab_list, zmin) - 1, 0)
        k1 = bisect.bisect_left(self._slab_list, zmax)
        bounds = self._slab_list[k0 : k1 + 1]
        if len(bounds) < 2:
            bounds = [zmin, zmax]
        bounds[0], bounds[-1] = zmin, zmax
        if (
            len(bounds) > 2 and bounds[-1] / bounds[-2] < 1.08
        ):  # merge slivers into their neighbours
            del bounds[-2]
        if len(bounds) > 2 and bounds[1] / bounds[0] < 1.08:
            del bounds[1]
        for j in range(len(bounds) - 1):
            slab = poly
            if j > 0:
                slab = clip_z(slab, bounds[j], True)
            if j < len(bounds) - 2:
                slab = clip_z(slab, bounds[j + 1], False)
            if len(slab) >= 3:
                self._draw_slab(img, ids, zbuf, job, slab, (bounds[j] * bounds[j + 1]) ** 0.5)

    def _draw_mover(self, img: NDArray[np.uint8], ids: NDArray[np.uint16],
                    jobs: list[_Job]) -> None:
        """One mover's faces over the finished scene, its silhouette anti-aliased.

        A sensor integrates light over each pixel: a silhouette moving 0.1 px changes the
        pixels along it by a tenth of the contrast. Faces drawn with binary masks (at twice
        the resolution, then filtered down) move in 0.5 px steps instead, which buries a far
        pedestrian's own motion (0.2 px per frame across the image at 50 m) in the steps.
        So a mover is first drawn on its own as every face is (binary masks, its faces
        hiding each other), which gives its colour and depth at every pixel centre it
        covers. Inside its silhouette those pixels are copied where it is nearer than the
        scene (the depth test). In the band along the silhouette it is blended over the
        scene with its coverage of each pixel, measured on a finer mask of all its faces
        (``cv2.INTER_AREA``: the share of each pixel's f x f samples it covers; f = 16 for a
        small mover, down to 2 as its size asks). The coverage is of the whole silhouette,
        so edges between the mover's own faces stay closed; a static object in front keeps
        its own edge. Band pixels no face centre covered take the mean of their drawn
        neighbours. The id buffer takes the mover where it covers the pixel's centre, as for
        every face. Only movers are drawn this way: the static scene's faces are many and
        drawn with early rejection of hidden faces.
        """
        outlines = []
        for job in jobs:
            clipped = self._clipped(job)
            if clipped is not None:
                projected = self._pts(clipped[0])
                if projected is not None:
                    outlines.append(projected)
        if not outlines:
            return
        x0 = max(int(min(b[0] for _, b in outlines)) - 2, 0)
        y0 = max(int(min(b[1] for _, b in outlines)) - 2, 0)
        x1 = min(int(max(b[2] for _, b in outlines)) + 3, self.W)
        y1 = min(int(max(b[3] for _, b in outlines)) + 3, self.H)
        if x1 <= x0 or y1 <= y0:
            return
        h, w = y1 - y0, x1 - x0
        for job in sorted(jobs, key=lambda j: j.key):
            self._draw_face(self._mover_img, self._mover_ids, self._mover_z, job)
        mover_img = self._mover_img[y0:y1, x0:x1]
        mover_ids = self._mover_ids[y0:y1, x0:x1]
        mover_z = self._mover_z[y0:y1, x0:x1]
        scene_z = self.zbuf[y0:y1, x0:x1]
        region = img[y0:y1, x0:x1]
        drawn = (mover_ids != 0).view(np.uint8)
        # inside, where all neighbours are the mover too: its pixels as drawn (by depth)
        inner = cv2.erode(drawn, _NEIGHBOURS, borderValue=0)
        own = cv2.bitwise_and(drawn, cv2.compare(mover_z, scene_z, cv2.CMP_GT))
        cv2.copyTo(mover_img, cv2.bitwise_and(inner, own), region)
        # the silhouette band: blended with the mover's coverage, measured on an f x finer
        # mask (16 x for a small mover, coarser where that would pass FINE_SAMPLES); fine
        # sample j of a pixel row lies at f (u - x0) + (f - 1) / 2
        v, u = np.nonzero(cv2.dilate(drawn, _NEIGHBOURS) > inner)
        if len(v):
            f = 16
            while f > 2 and f * f * w * h > FINE_SAMPLES:
                f //= 2
            fine = np.zeros((f * h, f * w), np.uint8)
            offset = np.array([x0 * _SUB, y0 * _SUB], np.int32)
            for pts, _ in outlines:
                cv2.fillPoly(fine, [(pts - offset) * f + (f - 1) * _SUB // 2], 255, cv2.LINE_8, 4)
            cover = cv2.resize(fine, (w, h), interpolation=cv2.INTER_AREA)[v, u] / 255.0
            colour = mover_img[v, u].astype(np.float64)
            invz = mover_z[v, u].astype(np.float64)
            fringe = drawn[v, u] == 0
            if np.any(fringe):  # band pixels no face centre covered: mean of drawn neighbours
                d = drawn.astype(np.float32)
                den = cv2.boxFilter(d, -1, (3, 3), normalize=False)[v, u]
                num_c = cv2.boxFilter(mover_img.astype(np.float32) * d, -1, (3, 3),
                                      normalize=False)[v, u]
                num_z = cv2.boxFilter(mover_z * d, -1, (3, 3), normalize=False)[v, u]
                colour[fringe] = num_c[fringe] / den[fringe]
                invz[fringe] = num_z[fringe] / den[fringe]
            alpha = np.where(invz > scene_z[v, u], cover, 0.0)
            blended = alpha * colour + (1.0 - alpha) * region[v, u]
            region[v, u] = np.clip(blended + 0.5, 0.0, 255.0).astype(np.uint8)
        hit = own.view(bool)   # the id buffer keeps the centre sample, as for every face
        ids[y0:y1, x0:x1][hit] = mover_ids[hit]
        scene_z[hit] = mover_z[hit]
        mover_img.fill(0)
        mover_ids.fill(0)
        mover_z.fill(0.0)

    def _clipped(self, job: _Job) -> tuple[list[Point], float, float] | None:
        """The face's polygon clipped to the near and far planes, with its depth range."""
        s = self.s
        poly: list[Point] = [tuple(p) for p in job.corners]  # type: ignore[misc]
        zs = [p[2] for p in poly]
        zmin, zmax = min(zs), max(zs)
        if zmin < s.near_m:
            poly = clip_z(poly, s.near_m, True)
            zmin = s.near_m
        if zmax > s.far_m:
            poly = clip_z(poly, s.far_m, False)
            zmax = s.far_m
        return (poly, zmin, zmax) if len(poly) >= 3 else None


    def _fog(self, z: float) -> float:
        s = self.s
        return min(max((z - s.fog_start_m) / (s.far_m - s.fog_start_m), 0.0), 1.0)

    def _draw_slab(
        self,
        img: NDArray[np.uint8],
        ids: NDArray[np.uint16],
        zbuf: NDArray[np.float32],
        job: _Job,
        slab: list[Point],
        z_rep: float,
    ) -> None:
        s = self.s
        projected = self._pts(slab)
        if projected is None:
            return
        pts, (umin, vmin, umax, vmax) = projected
        x0, y0 = max(int(umin), 0), max(int(vmin), 0)
        x1, y1 = min(int(umax) + 2, self.W), min(int(vmax) + 2, self.H)
        if x1 <= x0 or y1 <= y0:
            return
        w, h = x1 - x0, y1 - y0
        fog = self._fog(z_rep)
        depth_test = job.layer == Layer.UPRIGHT
        pts -= np.array([x0 * _SUB, y0 * _SUB], np.int32)
        flat = (
            job.texture == FLAT or w * h <= TINY_PX
        )  # a few pixels: the texture's mean is all one sees
        if flat:
            val = int(
                round(
                    (1.0 - fog) * (job.value if job.texture == FLAT else self._mean[job.texture])
                    + fog * s.haze
                )
            )
            if not depth_test:
                cv2.fillPoly(img[y0:y1, x0:x1], [pts], val, cv2.LINE_8, 4)
                return
        mask = np.zeros((h, w), np.uint8)
        cv2.fillPoly(mask, [pts], 1, cv2.LINE_8, 4)
        invz = None
        if depth_test:
            nx, ny, nz = job.n_c
            d = nx * job.o_c[0] + ny * job.o_c[1] + nz * job.o_c[2]
            if abs(d) < 1e-9:
                return
            fx, fy, cx, cy = self._k
            a, b = nx / (fx * d), ny / (fy * d)
            c = (nx * (x0 - cx) / fx + ny * (y0 - cy) / fy + nz) / d
            invz = cv2.addWeighted(self.col_grid[:h, :w], a, self.row_grid[:h, :w], b, c)
            closer = cv2.compare(invz, zbuf[y0:y1, x0:x1], cv2.CMP_GT)
            cv2.bitwise_and(mask, closer, dst=mask)
            if not cv2.countNonZero(mask):
                return
        if flat:
            warped = np.full((h, w), val, np.uint8)
        else:
            frame = FaceFrame(job.o_c, job.eu_c, job.ev_c, job.texel)
            warped = warp_texture(
                self.textures[job.texture],
                frame,
                slab,
                (pts / _SUB).tolist(),
                (x0, y0, w, h),
                self._k,
                self.s.lod_bias,
            )
            if fog > 0.0:
                warped = np.asarray(
                    cv2.addWeighted(warped, 1.0 - fog, warped, 0.0, fog * s.haze), np.uint8
                )
        cv2.copyTo(warped, mask, img[y0:y1, x0:x1])
        if invz is not None:
            cv2.copyTo(invz, mask, zbuf[y0:y1, x0:x1])
            np.copyto(ids[y0:y1, x0:x1], job.obj, where=mask.view(bool))
