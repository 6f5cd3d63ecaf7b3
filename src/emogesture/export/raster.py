"""The MP4 preview's rasteriser, compiled with numba: lit capsules into an RGB frame with a z-buffer, and the
frame into the YUV 4:2:0 planes H.264 takes (:mod:`emogesture.export.video` draws with it).

A capsule is the set of points within ``radius`` of a segment, seen from the front (orthographic): each pixel
it covers is shaded from the capsule's analytic normal there (ambient + Lambert + a little specular, a dark
rim as outline), kept where it is nearer than what the frame holds, with one pixel of edge anti-aliasing.
Only the pixels of each row that the capsule can cover are visited.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

#: one capsule's row in :func:`draw_capsules`: its ends in pixels and depth, its radius, its colour (0-255)
AX, AY, AZ, BX, BY, BZ, RADIUS_PX, RADIUS_M, RED, GREEN, BLUE = range(11)
RIM = 0.88  # share of the radius beyond which a capsule is drawn darker (its outline)


@njit(cache=True, nogil=True, error_model="numpy", fastmath=True)
def _row_span(y: float, ax: float, ay: float, bx: float, by: float, r: float) -> tuple[float, float]:
    """The x interval of row ``y`` within ``r`` of the segment (a, b) (empty: lo > hi)."""
    lo, hi = np.inf, -np.inf
    for cx, cy in ((ax, ay), (bx, by)):
        dy = y - cy
        if dy * dy < r * r:
            half = math.sqrt(r * r - dy * dy)
            lo, hi = min(lo, cx - half), max(hi, cx + half)
    length = math.hypot(bx - ax, by - ay)
    if length > 1e-9:  # the band along the segment: a parallelogram, where each of its edges crosses the row
        nx, ny = -(by - ay) / length * r, (bx - ax) / length * r
        corners = ((ax + nx, ay + ny), (bx + nx, by + ny), (bx - nx, by - ny), (ax - nx, ay - ny))
        for i in range(4):
            x0, y0 = corners[i]
            x1, y1 = corners[(i + 1) % 4]
            if (y0 - y) * (y1 - y) <= 0.0 and y0 != y1:
                x = x0 + (y - y0) * (x1 - x0) / (y1 - y0)
                lo, hi = min(lo, x), max(hi, x)
    return lo, hi


@njit(cache=True, nogil=True, error_model="numpy", fastmath=True)
def draw_capsules(img: np.ndarray, zbuf: np.ndarray, capsules: np.ndarray, light: np.ndarray,
                  half: np.ndarray) -> None:
    """Draw ``capsules [K, 11]`` (columns :data:`AX` ... :data:`BLUE`; depth larger = nearer) into ``img
    [H, W, 3]`` uint8 and ``zbuf [H, W]`` float32, in order; ``light`` and ``half`` are the unit light and
    half-way vectors (x right, y up, z to the viewer)."""
    h, w = zbuf.shape
    for k in range(capsules.shape[0]):
        ax, ay, za, bx, by, zb = capsules[k, 0], capsules[k, 1], capsules[k, 2], capsules[k, 3], capsules[k, 4], \
            capsules[k, 5]
        r, radius = capsules[k, 6], capsules[k, 7]
        red, green, blue = capsules[k, 8], capsules[k, 9], capsules[k, 10]
        reach = r + 0.5
        y0 = max(int(math.floor(min(ay, by) - reach)), 0)
        y1 = min(int(math.ceil(max(ay, by) + reach)) + 1, h)
        abx, aby = bx - ax, by - ay
        length2 = abx * abx + aby * aby
        inv = 1.0 / r
        for y in range(y0, y1):
            lo, hi = _row_span(float(y), ax, ay, bx, by, reach)
            if lo > hi:
                continue
            x0, x1 = max(int(math.floor(lo)), 0), min(int(math.ceil(hi)) + 1, w)
            for x in range(x0, x1):
                t = 0.0
                if length2 > 1e-9:
                    t = min(max(((x - ax) * abx + (y - ay) * aby) / length2, 0.0), 1.0)
                dx, dy = x - (ax + t * abx), y - (ay + t * aby)
                d2 = dx * dx + dy * dy
                if d2 >= reach * reach:
                    continue
                dist = math.sqrt(d2)
                rel = min(dist * inv, 1.0)
                nz = math.sqrt(1.0 - rel * rel)
                depth = za + t * (zb - za) + radius * nz
                if depth <= zbuf[y, x]:
                    continue
                nx, ny = dx * inv, -dy * inv
                lambert = max(nx * light[0] + ny * light[1] + nz * light[2], 0.0)
                s1 = max(nx * half[0] + ny * half[1] + nz * half[2], 0.0)
                s2 = s1 * s1
                s8 = s2 * s2 * s2 * s2
                spec = 40.8 * s8 * s8 * s8  # a highlight of power 24
                shade = (0.36 + 0.64 * lambert) * (0.55 if rel > RIM else 1.0)
                alpha = min(reach - dist, 1.0)
                old = float(img[y, x, 0])
                img[y, x, 0] = min(alpha * (red * shade + spec - old) + old + 0.5, 255.0)
                old = float(img[y, x, 1])
                img[y, x, 1] = min(alpha * (green * shade + spec - old) + old + 0.5, 255.0)
                old = float(img[y, x, 2])
                img[y, x, 2] = min(alpha * (blue * shade + spec - old) + old + 0.5, 255.0)
                if alpha >= 0.5:
                    zbuf[y, x] = depth


@njit(cache=True, nogil=True, error_model="numpy", fastmath=True)
def rgb_to_yuv420(img: np.ndarray, out: np.ndarray) -> None:
    """``img [H, W, 3]`` uint8 (even H and W) -> ``out [H * W * 3 // 2]`` uint8: the Y, U and V planes of
    yuv420p, BT.601 limited range (what ffmpeg assumes for raw yuv420p), chroma averaged over 2 x 2 pixels."""
    h, w = img.shape[0], img.shape[1]
    u0, v0, half = h * w, h * w + (h // 2) * (w // 2), w // 2
    for y in range(0, h, 2):
        for x in range(0, w, 2):
            rs = gs = bs = 0.0
            for dy in range(2):
                for dx in range(2):
                    r, g, b = float(img[y + dy, x + dx, 0]), float(img[y + dy, x + dx, 1]), float(img[y + dy, x + dx, 2])
                    out[(y + dy) * w + x + dx] = np.uint8(16.5 + 0.2568 * r + 0.5041 * g + 0.0979 * b)
                    rs += r
                    gs += g
                    bs += b
            rs, gs, bs = 0.25 * rs, 0.25 * gs, 0.25 * bs
            out[u0 + (y // 2) * half + x // 2] = np.uint8(128.5 - 0.1482 * rs - 0.2910 * gs + 0.4392 * bs)
            out[v0 + (y // 2) * half + x // 2] = np.uint8(128.5 + 0.4392 * rs - 0.3678 * gs - 0.0714 * bs)
