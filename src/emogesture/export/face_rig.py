"""A face for the mannequin's head with Apple's 52 ARKit blendshapes as morph targets, built here (no scanned
or third-party head; it is the project's own, under the project's licence).

The face is a few simple parts laid onto the front of the mannequin's head: eyeballs with dark irises, upper
and lower lids, brows, a nose, cheeks, two lips, the mouth's dark inside and a tongue. Every vertex follows
the head joint; the face moves only by its 52 morph targets, one per name of
:data:`emogesture.types.ARKIT_NAMES`, each a displacement of the parts it moves (``eyeBlinkLeft`` turns the
left upper lid down over the eye, ``jawOpen`` drops the lower lip and the tongue, ``mouthClose`` lifts them
back, ``eyeLookUpLeft`` turns the left iris up, ``browInnerUp`` raises the brows' inner ends, ...). "Left" is
the character's left (+X: it faces +Z with +Y up).

:func:`face_rig` returns the mesh at rest and its targets; :mod:`emogesture.export.gltf` writes it into the glb
(and so the fbx) beside the mannequin when the sequence has a face track.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from emogesture.types import ARKIT_NAMES

HEAD = 15  # SMPL-X joint the face is bound to
#: vertex colours (linear RGB) of the parts
COLORS = dict(sclera=(0.92, 0.92, 0.90), iris=(0.06, 0.045, 0.035), lid=(0.60, 0.43, 0.28), brow=(0.16, 0.10, 0.06),
              nose=(0.70, 0.52, 0.35), cheek=(0.76, 0.50, 0.38), lip=(0.62, 0.22, 0.20), inside=(0.10, 0.03, 0.03),
              tongue=(0.80, 0.36, 0.36))
EYE_TURN = 0.45  # rad an eyeLook* target turns the iris
LID_TOP, LID_OPEN, LID_CLOSED, LID_WIDE = 1.35, 0.45, -0.42, 0.75  # rad: upper lid's elevations on the eye
LOWER_OPEN, LOWER_SQUINT = -0.6, -0.2  # rad: the lower lid's upper edge, at rest and squinting


class _Mesh:
    """Parts appended into one vertex list: positions, colours, triangles and per-vertex part labels."""

    def __init__(self) -> None:
        self.positions: list[np.ndarray] = []
        self.colors: list[np.ndarray] = []
        self.triangles: list[np.ndarray] = []
        self.count = 0

    def grid(self, points: np.ndarray, color: tuple | np.ndarray, wrap: bool = False) -> np.ndarray:
        """Append an ``[U, V, 3]`` grid of points coloured ``color`` (RGB, or ``[U, V, 3]``) as quads (two
        triangles each; ``wrap`` joins the last column to the first) and return its vertex indices ``[U, V]``."""
        u, v = points.shape[:2]
        index = self.count + np.arange(u * v).reshape(u, v)
        cols = np.arange(v if wrap else v - 1)
        a, b = index[:-1][:, cols], index[:-1][:, (cols + 1) % v]
        c, d = index[1:][:, cols], index[1:][:, (cols + 1) % v]
        self.triangles.append(np.stack([np.stack([a, c, b], -1), np.stack([b, c, d], -1)], -2).reshape(-1, 3))
        self.positions.append(points.reshape(-1, 3))
        self.colors.append(np.broadcast_to(np.asarray(color, np.float32), (u, v, 3)).reshape(-1, 3))
        self.count += u * v
        return index


def _sphere(center: np.ndarray, radius: float, elevation: np.ndarray, azimuth: np.ndarray) -> np.ndarray:
    """Points ``[len(elevation), len(azimuth), 3]`` on a sphere; elevation from the equator (+Y up), azimuth
    about +Y from the front (+Z)."""
    e, a = np.meshgrid(elevation, azimuth, indexing="ij")
    return center + radius * np.stack([np.cos(e) * np.sin(a), np.sin(e), np.cos(e) * np.cos(a)], -1)


def _turn(points: np.ndarray, center: np.ndarray, pitch: float, yaw: float) -> np.ndarray:
    """Displacement of ``points`` turned about ``center`` by ``yaw`` (about +Y) then ``pitch`` (about +X;
    positive turns the front down)."""
    cp, sp, cy, sy = np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    rx = np.array([[1, 0, 0], [0, cp, -sp], [0, sp, cp]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    local = points - center
    return local @ (rx @ ry).T - local


def _smoothstep(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    t = np.clip((x - lo) / (hi - lo), 0.0, 1.0)
    return t * t * (3 - 2 * t)


def _surface(corners: np.ndarray):
    """``z(x, y)``: the front of the head's surface, where a ray along -Z from the front first meets one of its
    triangles ``corners [F, 3, 3]`` (the nearest triangle's plane where none is met)."""
    a, b, c = corners[:, 0], corners[:, 1], corners[:, 2]
    det = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (b[:, 1] - a[:, 1])
    keep = np.abs(det) > 1e-12
    a, b, c, det = a[keep], b[keep], c[keep], det[keep]
    centre = (a + b + c) / 3

    def z(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        x, y = np.broadcast_arrays(np.asarray(x, np.float64), np.asarray(y, np.float64))
        px, py = x.reshape(-1, 1), y.reshape(-1, 1)
        u = ((px - a[:, 0]) * (c[:, 1] - a[:, 1]) - (c[:, 0] - a[:, 0]) * (py - a[:, 1])) / det
        v = ((b[:, 0] - a[:, 0]) * (py - a[:, 1]) - (px - a[:, 0]) * (b[:, 1] - a[:, 1])) / det
        depth = a[:, 2] + u * (b[:, 2] - a[:, 2]) + v * (c[:, 2] - a[:, 2])
        inside = (u >= -1e-9) & (v >= -1e-9) & (u + v <= 1 + 1e-9)
        nearest = np.argmin((px - centre[:, 0]) ** 2 + (py - centre[:, 1]) ** 2, 1)
        hit = np.where(inside, depth, -np.inf).max(1)
        return np.where(np.isfinite(hit), hit, depth[np.arange(len(px)), nearest]).reshape(x.shape)
    return z


def face_rig(head: np.ndarray, triangles: np.ndarray) -> dict[str, np.ndarray]:
    """The face laid onto the head mesh ``head [N, 3]`` (rest vertices, metres; +Y up, facing +Z) with
    ``triangles [F, 3]`` (indices into ``head``): ``positions [V, 3]``, ``normals [V, 3]``, ``colors [V, 3]``
    float32, ``indices [F * 3]`` uint32 and ``targets [52, V, 3]`` float32, the displacement of each ARKit
    blendshape at weight 1."""
    corners = np.asarray(head, np.float64)[np.asarray(triangles)]
    return {k: v.copy() for k, v in _face_rig(corners.round(6).tobytes(), len(corners)).items()}


@lru_cache(maxsize=4)
def _face_rig(key: bytes, n: int) -> dict[str, np.ndarray]:
    corners = np.frombuffer(key, np.float64).reshape(n, 3, 3)
    head = corners.reshape(-1, 3)
    z_of = _surface(corners)
    lo, hi = head[:, 1].min(), head[:, 1].max()
    h = hi - lo  # every size below is a share of the head's height
    cx = float(head[:, 0].mean())
    mesh, moves = _Mesh(), {name: [] for name in ARKIT_NAMES}  # moves[name]: (vertex indices, displacements)

    def move(name: str, index: np.ndarray, disp: np.ndarray) -> None:
        moves[name].append((index.reshape(-1), np.asarray(disp, np.float64).reshape(-1, 3)))

    # the eyes: eyeball, iris, upper and lower lid
    ye, re = lo + 0.53 * h, 0.064 * h
    for side, name in ((1, "Left"), (-1, "Right")):
        xe = cx + side * 0.165 * h
        c = np.array([xe, ye, float(z_of(xe, ye)) - 0.3 * re])
        mesh.grid(_sphere(c, re, np.linspace(-1.45, 1.45, 9), np.linspace(-np.pi, np.pi, 16, endpoint=False)),
                  COLORS["sclera"], wrap=True)
        iris_pts = _sphere(c, 1.012 * re, np.linspace(-0.42, 0.42, 5), np.linspace(-0.42, 0.42, 5))
        iris = mesh.grid(iris_pts, COLORS["iris"])
        look = dict(Up=(-EYE_TURN, 0.0), Down=(EYE_TURN, 0.0), In=(0.0, -side * EYE_TURN), Out=(0.0, side * EYE_TURN))
        for where, (pitch, yaw) in look.items():
            move(f"eyeLook{where}{name}", iris, _turn(iris_pts.reshape(-1, 3), c, pitch, yaw))
        azimuth = np.linspace(-1.3, 1.3, 11)
        span = np.linspace(0.0, 1.0, 5)[:, None]

        def lid(edge: float, top: float = LID_TOP) -> np.ndarray:
            return _sphere(c, 1.16 * re, top + (edge - top) * span[:, 0], azimuth)
        upper = mesh.grid(lid(LID_OPEN), COLORS["lid"])
        rest = lid(LID_OPEN)
        move(f"eyeBlink{name}", upper, lid(LID_CLOSED) - rest)
        move(f"eyeWide{name}", upper, lid(LID_WIDE) - rest)
        move(f"eyeSquint{name}", upper, lid(LID_OPEN - 0.12) - rest)
        lower_rest = lid(LOWER_OPEN, -LID_TOP)
        lower = mesh.grid(lower_rest, COLORS["lid"])
        move(f"eyeSquint{name}", lower, lid(LOWER_SQUINT, -LID_TOP) - lower_rest)
        move(f"cheekSquint{name}", lower, lid(LOWER_OPEN + 0.12, -LID_TOP) - lower_rest)

        # the brow: a flat bar above the eye, s from its inner end (0) to its outer (1)
        s = np.linspace(0.0, 1.0, 9)
        x = xe + side * (-0.10 + 0.21 * s) * h
        y = ye + (0.115 + 0.025 * np.sin(np.pi * s)) * h
        zs = z_of(x, y)
        section = np.array([[0.016, 0.011], [0.016, 0.001], [-0.010, 0.001], [-0.010, 0.011]]) * h  # (dy, dz)
        bar = np.stack([x[:, None] + 0 * section[:, 0], y[:, None] + section[:, 0], zs[:, None] + section[:, 1]], -1)
        brow = mesh.grid(bar, COLORS["brow"], wrap=True)
        inner, outer = ((1 - s) ** 1.5)[:, None], (s ** 1.5)[:, None]
        up = np.zeros((9, 4, 3))
        up[..., 1] = 0.055 * h
        move("browInnerUp", brow, (up * inner[..., None]))
        move(f"browOuterUp{name}", brow, (up * outer[..., None]))
        down = np.zeros((9, 4, 3))
        down[..., 0] = -side * 0.018 * h * (1 - s)[:, None]
        down[..., 1] = -0.04 * h * (1 - 0.4 * s)[:, None]
        down[..., 2] = 0.012 * h
        move(f"browDown{name}", brow, down)

        # the cheek: a low mound, r from its centre (0) to its rim (1)
        r, a = np.linspace(0.0, 1.0, 4), np.linspace(0, 2 * np.pi, 12, endpoint=False)
        rr, aa = np.meshgrid(r, a, indexing="ij")
        x = cx + side * 0.25 * h + 0.075 * h * rr * np.cos(aa)
        y = lo + 0.36 * h + 0.06 * h * rr * np.sin(aa)
        bump = 1 - rr ** 2
        cheek_pts = np.stack([x, y, z_of(x, y) + 0.0015 + 0.004 * h * bump], -1)
        blush = np.asarray(COLORS["nose"]) + (np.asarray(COLORS["cheek"]) - COLORS["nose"]) * bump[..., None]
        cheek = mesh.grid(cheek_pts, blush, wrap=True)
        puff = np.stack([side * 0.03 * h * bump, 0 * bump, 0.05 * h * bump], -1)
        move("cheekPuff", cheek, puff)
        move(f"cheekSquint{name}", cheek, np.stack([0 * bump, 0.03 * h * bump, 0.006 * h * bump], -1))

    # the nose: a wedge from the bridge to the tip and its two wings
    yn = lo + 0.36 * h
    t = np.linspace(0.0, 1.0, 6)[:, None]  # bridge (0) to tip (1)
    across = np.linspace(-1.0, 1.0, 7)[None]
    x = cx + 0.075 * h * across * (0.4 + 0.6 * t)
    y = ye - 0.04 * h + (yn - ye + 0.01 * h) * t + 0 * across
    z = z_of(x, y) + 0.075 * h * t * (1 - across ** 2) + 0.002
    nose_pts = np.stack([x, y, z], -1)
    nose = mesh.grid(nose_pts, COLORS["nose"])
    for side, name in ((1, "Left"), (-1, "Right")):
        wing = (t * np.clip(side * across, 0, 1)) ** 1.5
        move(f"noseSneer{name}", nose, np.stack([0 * wing, 0.035 * h * wing + 0.008 * h * t * (1 - across ** 2),
                                                 0.004 * h * wing], -1))

    # the mouth: two lips as tubes along s (the character's right -1 to its left +1) and the dark inside
    ym, wm = lo + 0.225 * h, 0.115 * h
    s = np.linspace(-1.0, 1.0, 21)
    xs = cx + wm * s
    zs = z_of(xs, np.full_like(xs, ym))
    height = 0.022 * h * (1 - 0.7 * s ** 2)
    depth = 0.018 * h * (1 - 0.4 * s ** 2)
    psi = np.linspace(0, 2 * np.pi, 8, endpoint=False)
    lips, centre = {}, {}
    for which, sign in (("upper", 1), ("lower", -1)):
        cy = ym + sign * height
        centre[which] = np.stack([xs, cy, zs + 0.35 * depth], -1)
        tube = centre[which][:, None] + np.stack([0 * psi[None] + 0 * s[:, None], height[:, None] * np.cos(psi),
                                                  depth[:, None] * np.sin(psi)], -1)
        lips[which] = (mesh.grid(tube, COLORS["lip"], wrap=True), tube.shape[:2])
    k = 7  # stations across the inside, upper lip's centre (0) to the lower's (1)
    inside_t = np.linspace(0.0, 1.0, k)[None, :, None]
    inside_pts = (1 - inside_t) * centre["upper"][:, None] + inside_t * centre["lower"][:, None]
    inside_pts[..., 2] = zs[:, None] + 0.001
    inside = mesh.grid(inside_pts, COLORS["inside"])
    tongue_centre = np.array([cx, ym - 0.01 * h, float(z_of(cx, ym)) - 0.12 * h])
    tongue_pts = tongue_centre + _sphere(np.zeros(3), 1.0, np.linspace(-1.45, 1.45, 7),
                                         np.linspace(-np.pi, np.pi, 12, endpoint=False)) * [0.07 * h, 0.02 * h, 0.06 * h]
    tongue = mesh.grid(tongue_pts, COLORS["tongue"], wrap=True)

    def on_lips(name: str, upper: np.ndarray | float = 0.0, lower: np.ndarray | float = 0.0) -> None:
        """Each lip's centre moved by ``[21, 3]`` (or 0); the lips' tubes and the inside follow."""
        d = {w: np.broadcast_to(np.asarray(v, np.float64), (21, 3)) for w, v in (("upper", upper), ("lower", lower))}
        for which in ("upper", "lower"):
            index, shape = lips[which]
            move(name, index, np.broadcast_to(d[which][:, None], shape + (3,)))
        move(name, inside, (1 - inside_t) * d["upper"][:, None] + inside_t * d["lower"][:, None])

    def along(dx=0.0, dy=0.0, dz=0.0, weight=1.0) -> np.ndarray:
        w = np.broadcast_to(np.asarray(weight, np.float64), s.shape)
        return np.stack([dx * w, dy * w, dz * w], -1)

    middle = 1 - 0.6 * s ** 2
    jaw_drop = along(dy=-0.13 * h, dz=-0.03 * h, weight=middle)
    on_lips("jawOpen", along(dy=0.008 * h, weight=1 - s ** 2), jaw_drop)
    on_lips("mouthClose", along(dy=-0.008 * h, weight=1 - s ** 2), -jaw_drop)
    move("jawOpen", tongue, np.tile([0.0, -0.09 * h, -0.02 * h], (tongue.size, 1)))
    move("mouthClose", tongue, np.tile([0.0, 0.09 * h, 0.02 * h], (tongue.size, 1)))
    on_lips("jawForward", 0.0, along(dz=0.04 * h))
    move("jawForward", tongue, np.tile([0.0, 0.0, 0.03 * h], (tongue.size, 1)))
    for name, sign in (("Left", 1), ("Right", -1)):
        on_lips(f"jaw{name}", 0.0, along(dx=sign * 0.05 * h))
        on_lips(f"mouth{name}", along(dx=sign * 0.05 * h, weight=0.6 + 0.4 * np.abs(s)),
                along(dx=sign * 0.05 * h, weight=0.6 + 0.4 * np.abs(s)))
        corner = np.clip(sign * s, 0, 1) ** 2  # this side's corner
        half = _smoothstep(sign * s, -0.3, 0.6) * (1 - 0.5 * s ** 2)  # this side's half of a lip
        press = np.sqrt(np.clip(sign * s, 0, 1))
        smile = along(dx=sign * 0.03 * h, dy=0.06 * h, dz=-0.02 * h, weight=corner)
        on_lips(f"mouthSmile{name}", smile, smile)
        frown = along(dx=sign * 0.006 * h, dy=-0.06 * h, weight=corner)
        on_lips(f"mouthFrown{name}", frown, frown)
        dimple = along(dx=sign * 0.025 * h, dz=-0.03 * h, weight=corner)
        on_lips(f"mouthDimple{name}", dimple, dimple)
        stretch = along(dx=sign * 0.05 * h, dy=-0.015 * h, weight=corner)
        on_lips(f"mouthStretch{name}", stretch, stretch)
        on_lips(f"mouthPress{name}", along(dx=sign * 0.008 * h, dy=-0.01 * h, weight=press),
                along(dx=sign * 0.008 * h, dy=0.01 * h, weight=press))
        on_lips(f"mouthLowerDown{name}", 0.0, along(dy=-0.07 * h, weight=half))
        on_lips(f"mouthUpperUp{name}", along(dy=0.05 * h, weight=half), 0.0)
        on_lips(f"noseSneer{name}", along(dy=0.015 * h, weight=half), 0.0)
    on_lips("mouthFunnel", along(dx=-0.25 * wm * s, dy=0.03 * h * (1 - s ** 2), dz=0.045 * h),
            along(dx=-0.25 * wm * s, dy=-0.03 * h * (1 - s ** 2), dz=0.045 * h))
    on_lips("mouthPucker", along(dx=-0.4 * wm * s, dy=-0.006 * h, dz=0.055 * h),
            along(dx=-0.4 * wm * s, dy=0.006 * h, dz=0.055 * h))
    on_lips("mouthRollLower", 0.0, along(dy=0.014 * h, dz=-0.025 * h, weight=1 - 0.5 * s ** 2))
    on_lips("mouthRollUpper", along(dy=-0.014 * h, dz=-0.025 * h, weight=1 - 0.5 * s ** 2), 0.0)
    on_lips("mouthShrugLower", 0.0, along(dy=0.025 * h, dz=0.015 * h, weight=1 - s ** 2))
    on_lips("mouthShrugUpper", along(dy=0.025 * h, dz=0.01 * h, weight=1 - s ** 2), 0.0)
    on_lips("cheekPuff", along(dz=0.012 * h, weight=1 - s ** 2), along(dz=0.012 * h, weight=1 - s ** 2))
    move("tongueOut", tongue, np.tile([0.0, -0.03 * h, 0.2 * h], (tongue.size, 1)))

    positions = np.concatenate(mesh.positions)
    targets = np.zeros((len(ARKIT_NAMES),) + positions.shape)
    for i, name in enumerate(ARKIT_NAMES):
        for index, disp in moves[name]:
            np.add.at(targets[i], index, disp)
    triangles = np.concatenate(mesh.triangles)
    normals = np.zeros_like(positions)
    corner = positions[triangles]
    area = np.cross(corner[:, 1] - corner[:, 0], corner[:, 2] - corner[:, 0])
    for k in range(3):
        np.add.at(normals, triangles[:, k], area)
    normals /= np.linalg.norm(normals, axis=1, keepdims=True).clip(1e-12)
    return {"positions": positions.astype(np.float32), "normals": normals.astype(np.float32),
            "colors": np.concatenate(mesh.colors).astype(np.float32), "indices": triangles.reshape(-1).astype(np.uint32),
            "targets": targets.astype(np.float32)}
