"""Small polygon helpers of the rasteriser (plain floats: they run per face in Python)."""

from __future__ import annotations

Point = tuple[float, float, float]


def clip_z(poly: list[Point], zc: float, keep_above: bool) -> list[Point]:
    """Sutherland-Hodgman: the part of a convex polygon with z >= zc (or <= zc)."""
    out: list[Point] = []
    n = len(poly)
    sgn = 1.0 if keep_above else -1.0
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        da, db = sgn * (a[2] - zc), sgn * (b[2] - zc)
        if da >= 0.0:
            out.append(a)
        if (da >= 0.0) != (db >= 0.0):
            s = da / (da - db)
            out.append(
                (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2]))
            )
    return out


def clip_rect(
    poly: list[tuple[float, float]], u0: float, v0: float, u1: float, v1: float
) -> list[tuple[float, float]]:
    """Sutherland-Hodgman: the part of a convex image polygon inside [u0, u1] x [v0, v1]."""
    for axis, bound, sgn in ((0, u0, 1.0), (0, u1, -1.0), (1, v0, 1.0), (1, v1, -1.0)):
        out: list[tuple[float, float]] = []
        n = len(poly)
        for i in range(n):
            a, b = poly[i], poly[(i + 1) % n]
            da, db = sgn * (a[axis] - bound), sgn * (b[axis] - bound)
            if da >= 0.0:
                out.append(a)
            if (da >= 0.0) != (db >= 0.0):
                t = da / (da - db)
                out.append((a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])))
        poly = out
        if not poly:
            break
    return poly


def inverse3(m: list[list[float]]) -> list[list[float]]:
    """Inverse of a 3x3 matrix (adjugate / determinant), plain floats."""
    (a, b, c), (d, e, f), (g, h, i) = m
    A, B, C = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * A + b * B + c * C
    return [
        [A / det, (c * h - b * i) / det, (b * f - c * e) / det],
        [B / det, (a * i - c * g) / det, (c * d - a * f) / det],
        [C / det, (b * g - a * h) / det, (a * e - b * d) / det],
    ]
