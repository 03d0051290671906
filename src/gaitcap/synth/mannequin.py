"""The synthetic person: a clothed mannequin that is not the tracker's body model.

The tracker matches capsules (:mod:`gaitcap.body`); drawing the test subject with those same
capsules would let the tracker fit its own making (the "inverse crime"). This module never
imports :mod:`gaitcap.body`. It builds, for each frame, a triangle mesh around the joint centres
of the recorded walk (``gaitcap.trajectory.POINT_NAMES``), so the segment lengths are the
motion's own, frame by frame:

- limbs are stacks of elliptic rings that taper (thigh, shank with a calf, upper arm, forearm),
  with a ball at the knee and elbow;
- the trunk is one ring stack from the buttocks to the shoulders: broad hips, a narrower waist,
  the chest, the shoulders; its sideways axis turns from the hips' line to the shoulders' line;
- the head is an ellipsoid with a hair volume (none, short or long), on a neck;
- hands are flat ellipsoids beyond the wrists; shoes are rounded boxes from heel to toe;
- clothing colours the rings band by band: trousers, shorts or a skirt, long or short sleeves,
  so shins, forearms and faces may be bare skin; a top may be striped.

Every size is a fraction of the subject's height, drawn per subject (:class:`Build`), so two
seeds give two different bodies. A mesh has the same triangles in every frame; only the vertices
move.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from gaitcap.trajectory import POINT_NAMES

AROUND = 16  # vertices per ring
_P = {name: i for i, name in enumerate(POINT_NAMES)}
UP = np.array([0.0, 0.0, 1.0])

Color = tuple[float, float, float]


@dataclass(frozen=True)
class Build:
    """Girths and sizes of one subject, as fractions of the height (semi-axes of cross-sections)."""

    height_m: float
    thigh: float = 0.052  # thigh radius just below the buttock
    knee: float = 0.033
    calf: float = 0.035
    ankle: float = 0.021
    upper_arm: float = 0.027
    forearm: float = 0.023
    wrist: float = 0.016
    hip_width: float = 0.105  # half breadth of the hips
    waist_width: float = 0.085
    chest_width: float = 0.095
    shoulder_width: float = 0.108
    hip_depth: float = 0.072  # half depth (front to back)
    waist_depth: float = 0.064
    chest_depth: float = 0.074
    neck: float = 0.036
    head: tuple[float, float, float] = (0.056, 0.046, 0.066)  # half length, breadth, height
    hand: tuple[float, float, float] = (0.055, 0.026, 0.012)  # half length, breadth, thickness
    shoe: tuple[float, float] = (0.030, 0.045)  # half width, height at the heel

    def scaled(self, factor: float, names: tuple[str, ...]) -> Build:
        """A copy with the fields ``names`` multiplied by ``factor``."""
        values = {}
        for n in names:
            v = getattr(self, n)
            values[n] = tuple(factor * x for x in v) if isinstance(v, tuple) else factor * v
        return replace(self, **values)


@dataclass(frozen=True)
class Outfit:
    """What the subject wears, and the colours (BGR 0-255) of skin, hair, clothes and shoes."""

    skin: Color = (120.0, 150.0, 200.0)
    hair: Color = (35.0, 45.0, 60.0)
    hair_style: str = "short"  # none | short | long
    top: Color = (60.0, 60.0, 175.0)
    stripe: Color | None = None  # second colour of a striped top
    sleeves: float = 1.0  # covered fraction of the arm from the shoulder: 0 none .. 1 long sleeves
    bottom: Color = (120.0, 80.0, 50.0)
    lower: str = "trousers"  # trousers | shorts | skirt
    legs_cover: float = 1.0  # covered fraction of the leg from the hip (1: to the ankle)
    loose: float = 1.0  # trouser girth factor
    shoes: Color = (235.0, 235.0, 235.0)

    def __post_init__(self) -> None:
        if self.hair_style not in ("none", "short", "long"):
            raise ValueError(f"unknown hair_style {self.hair_style!r}")
        if self.lower not in ("trousers", "shorts", "skirt"):
            raise ValueError(f"unknown lower garment {self.lower!r}")
        if not (0.0 <= self.sleeves <= 1.0 and 0.0 <= self.legs_cover <= 1.0):
            raise ValueError("sleeves and legs_cover are fractions in [0, 1]")


@dataclass
class _Part:
    """One ring stack: K rings of AROUND vertices plus two cap centres."""

    kind: str  # the _Geometry method that builds it
    side: str  # "_l", "_r" or "" (the method's argument when not empty)
    n_rings: int
    band_colors: list[Color]  # K - 1 band colours
    first: int = 0  # index of its first vertex in the mesh
    tris: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.int64))
    colors: np.ndarray = field(default_factory=lambda: np.zeros((0, 3), np.float32))


def _ring_stack_triangles(K: int, offset: int) -> np.ndarray:
    """(M, 3) triangles of K rings of AROUND vertices followed by the two cap centres."""
    tris = []
    for k in range(K - 1):
        for j in range(AROUND):
            a, b = k * AROUND + j, k * AROUND + (j + 1) % AROUND
            c, d = a + AROUND, b + AROUND
            tris += [(a, b, d), (a, d, c)]
    c0, c1 = K * AROUND, K * AROUND + 1
    for j in range(AROUND):
        tris.append((c0, (j + 1) % AROUND, j))
        tris.append((c1, (K - 1) * AROUND + j, (K - 1) * AROUND + (j + 1) % AROUND))
    return np.asarray(tris, np.int64) + offset


def _band_colors(K: int, band_colors: list[Color]) -> np.ndarray:
    per_band = np.repeat(np.asarray(band_colors, np.float32), 2 * AROUND, axis=0)
    caps = np.asarray([band_colors[0], band_colors[-1]] * AROUND, np.float32)
    return np.vstack([per_band, caps])


def _unit(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-12)


_THETA = np.linspace(0.0, 2 * np.pi, AROUND, endpoint=False)
_COS, _SIN = np.cos(_THETA), np.sin(_THETA)


def rings(centres: np.ndarray, side: np.ndarray, a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and normals of a ring stack.

    Args:
        centres: (K, 3) ring centres along the part's axis.
        side: (K, 3) or (3,) a direction across the part (made orthogonal to the axis).
        a, b: (K,) semi-axes along ``side`` and along the third direction.

    Returns:
        vertices and unit normals, each (K * AROUND + 2, 3): the rings, then the two cap centres.
    """
    K = len(centres)
    axis = np.gradient(centres, axis=0) if K > 1 else np.tile(UP, (1, 1))
    axis = _unit(axis)
    side = np.broadcast_to(side, (K, 3))
    u = side - np.sum(side * axis, axis=1, keepdims=True) * axis
    bad = np.linalg.norm(u, axis=1) < 1e-6
    if bad.any():
        alt = np.cross(axis[bad], UP)
        alt[np.linalg.norm(alt, axis=1) < 1e-6] = (1.0, 0.0, 0.0)
        u[bad] = alt
    u = _unit(u)
    v = np.cross(axis, u)
    cos, sin = _COS[None, :, None], _SIN[None, :, None]
    offs = a[:, None, None] * cos * u[:, None] + b[:, None, None] * sin * v[:, None]
    verts = centres[:, None] + offs
    normals = _unit(cos * u[:, None] / np.maximum(a, 1e-6)[:, None, None] + sin * v[:, None] / np.maximum(b, 1e-6)[:, None, None])
    verts = np.vstack([verts.reshape(-1, 3), centres[:1], centres[-1:]])
    normals = np.vstack([normals.reshape(-1, 3), -axis[:1], axis[-1:]])
    return verts, normals


def ellipsoid_stations(n: int) -> tuple[np.ndarray, np.ndarray]:
    """Positions t in [-1, 1] and radius factors of ``n`` rings approximating an ellipsoid."""
    phi = np.linspace(0.06 * np.pi, 0.94 * np.pi, n)
    return -np.cos(phi), np.sin(phi)


class Mannequin:
    """A subject's mesh generator: :meth:`mesh` gives the vertices of one frame.

    Args:
        build: the subject's sizes.
        outfit: clothing and colours.
    """

    def __init__(self, build: Build, outfit: Outfit) -> None:
        self.build = build
        self.outfit = outfit
        self._parts: list[_Part] = []
        self._layout()
        offset = 0
        for p in self._parts:
            p.first = offset
            p.tris = _ring_stack_triangles(p.n_rings, offset)
            p.colors = _band_colors(p.n_rings, p.band_colors)
            offset += p.n_rings * AROUND + 2
        self.n_vertices = offset
        self.triangles = np.vstack([p.tris for p in self._parts])
        self.colors = np.vstack([p.colors for p in self._parts]).astype(np.float32)

    # ------------------------------------------------------------------ layout (colours per band)
    _LEG_T = np.array([-0.12, 0.0, 0.2, 0.4, 0.6, 0.8, 0.92, 1.0])
    _SHANK_T = np.array([0.0, 0.12, 0.3, 0.5, 0.7, 0.85, 0.95, 1.0])
    _UPPER_ARM_T = np.array([-0.05, 0.2, 0.4, 0.6, 0.8, 1.0])
    _FOREARM_T = np.array([0.0, 0.25, 0.5, 0.75, 1.0])
    _TRUNK_T = np.linspace(0.0, 1.0, 12)
    _BALL_N = 7

    def _leg_colors(self, t: np.ndarray, start: float, end: float) -> list[Color]:
        """Band colours of a leg segment spanning [start, end] of the leg (hip 0, ankle 1)."""
        o = self.outfit
        mids = start + (end - start) * 0.5 * (t[:-1] + t[1:])
        covered = o.lower == "trousers" and o.legs_cover >= 0.999
        return [o.bottom if (covered or (o.lower == "shorts" and m <= o.legs_cover)) else o.skin for m in mids]

    def _arm_colors(self, t: np.ndarray, start: float, end: float) -> list[Color]:
        o = self.outfit
        mids = start + (end - start) * 0.5 * (t[:-1] + t[1:])
        return [o.top if m <= o.sleeves else o.skin for m in mids]

    def _trunk_colors(self) -> list[Color]:
        o = self.outfit
        out: list[Color] = []
        for k in range(len(self._TRUNK_T) - 1):
            if k < 4:
                out.append(o.bottom)
            elif o.stripe is not None and k % 2:
                out.append(o.stripe)
            else:
                out.append(o.top)
        return out

    def _layout(self) -> None:
        o = self.outfit
        add = self._parts.append
        add(_Part("trunk", "", len(self._TRUNK_T), self._trunk_colors()))
        for s in ("_l", "_r"):
            add(_Part("thigh", s, len(self._LEG_T), self._leg_colors(self._LEG_T, 0.0, 0.5)))
            add(_Part("knee", s, self._BALL_N, [self._leg_colors(np.array([0.5, 0.5]), 0.0, 1.0)[0]] * (self._BALL_N - 1)))
            add(_Part("shank", s, len(self._SHANK_T), self._leg_colors(self._SHANK_T, 0.5, 1.0)))
            add(_Part("shoe", s, 6, [o.shoes] * 5))
            add(_Part("upper_arm", s, len(self._UPPER_ARM_T), self._arm_colors(self._UPPER_ARM_T, 0.0, 0.55)))
            add(_Part("elbow", s, self._BALL_N, [self._arm_colors(np.array([0.55, 0.55]), 0.0, 1.0)[0]] * (self._BALL_N - 1)))
            add(_Part("forearm", s, len(self._FOREARM_T), self._arm_colors(self._FOREARM_T, 0.55, 1.0)))
            add(_Part("hand", s, self._BALL_N, [o.skin] * (self._BALL_N - 1)))
        if o.lower == "skirt":
            add(_Part("skirt", "", 6, [o.bottom] * 5))
        add(_Part("neck", "", 4, [o.skin] * 3))
        add(_Part("head", "", 9, [o.skin] * 8))
        if o.hair_style != "none":
            add(_Part("hair", "", 8, [o.hair] * 7))

    # ------------------------------------------------------------------ geometry
    def mesh(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vertices and normals (V, 3) of the mesh around one frame's joint centres.

        Args:
            points: (P, 3) metres, in the order of ``gaitcap.trajectory.POINT_NAMES``; every
                point must be finite.
        """
        pts = np.asarray(points, np.float64)
        if pts.shape != (len(POINT_NAMES), 3) or not np.all(np.isfinite(pts)):
            raise ValueError(f"mesh: points must be finite, shape ({len(POINT_NAMES)}, 3), got {pts.shape}")
        g = _Geometry(pts, self.build, self.outfit)
        verts, normals = [], []
        for p in self._parts:
            build = getattr(g, p.kind)
            v, n = build(p.side) if p.side else build()
            verts.append(v)
            normals.append(n)
        return np.vstack(verts), np.vstack(normals)


class _Geometry:
    """Ring stacks of every part for one frame (method per part name, side suffix as argument)."""

    def __init__(self, pts: np.ndarray, build: Build, outfit: Outfit) -> None:
        self.p = {n: pts[i] for n, i in _P.items()}
        self.b = build
        self.o = outfit
        self.H = build.height_m
        left = self.p["hip_l"] - self.p["hip_r"]
        self.lateral = _unit(left - left[2] * UP)
        sh = self.p["shoulder_l"] - self.p["shoulder_r"]
        self.shoulder_lateral = _unit(sh)
        self.forward = _unit(np.cross(self.lateral, UP))

    def _limb(self, p0: np.ndarray, p1: np.ndarray, t: np.ndarray, r: np.ndarray, flat: float = 0.92):
        centres = p0 + t[:, None] * (p1 - p0)
        return rings(centres, self.lateral, flat * r, r)

    def _loose(self, radii: np.ndarray, t_leg: np.ndarray) -> np.ndarray:
        """Trousers widen the covered part of a leg by the outfit's looseness."""
        o = self.o
        if o.lower == "trousers" or o.lower == "shorts":
            covered = t_leg <= (o.legs_cover if o.lower == "shorts" else 1.0)
            return np.where(covered, radii * o.loose, radii)
        return radii

    def _ball(self, centre: np.ndarray, axis: np.ndarray, radii: tuple[float, float, float], side: np.ndarray):
        t, f = ellipsoid_stations(Mannequin._BALL_N)
        centres = centre + t[:, None] * radii[0] * axis
        return rings(centres, side, f * radii[1], f * radii[2])

    def trunk(self):
        H, b, p = self.H, self.b, self.p
        pelvis, thorax, neck = p["pelvis"], p["thorax"], p["neck"]
        low_axis = _unit(thorax - pelvis)
        bottom = pelvis - 0.07 * H * low_axis
        t = Mannequin._TRUNK_T
        # polyline bottom -> pelvis -> thorax -> neck, stations by arc length
        nodes = np.array([bottom, pelvis, thorax, neck - 0.01 * H * _unit(neck - thorax)])
        seg = np.linalg.norm(np.diff(nodes, axis=0), axis=1)
        s = np.concatenate([[0], np.cumsum(seg)]) / seg.sum()
        centres = np.stack([np.interp(t, s, nodes[:, k]) for k in range(3)], axis=1)
        # half widths and depths: crotch, hips, waist, chest, shoulders, base of the neck
        width_key = np.interp(t, [0, 0.12, 0.25, 0.45, 0.62, 0.85, 1.0],
                              [0.85 * b.hip_width, b.hip_width, 0.97 * b.hip_width, b.waist_width,
                               b.chest_width, b.shoulder_width, 0.8 * b.shoulder_width])
        depth = np.interp(t, [0, 0.12, 0.25, 0.45, 0.62, 0.85, 1.0],
                          [0.8 * b.hip_depth, b.hip_depth, b.hip_depth, b.waist_depth, b.chest_depth,
                           0.9 * b.chest_depth, 0.7 * b.chest_depth])
        mix = np.clip((t - 0.3) / 0.6, 0, 1)[:, None]
        side = _unit((1 - mix) * self.lateral + mix * self.shoulder_lateral)
        return rings(centres, side, width_key * H, depth * H)

    def thigh(self, s: str):
        b, H = self.b, self.H
        t = Mannequin._LEG_T
        r = np.interp(t, [-0.12, 0.1, 0.6, 1.0], [0.95 * b.thigh, b.thigh, 0.85 * b.thigh, b.knee]) * H
        r = self._loose(r, 0.5 * t)
        return self._limb(self.p[f"hip{s}"], self.p[f"knee{s}"], t, r)

    def knee(self, s: str):
        r = self.b.knee * self.H
        r = float(self._loose(np.array([r]), np.array([0.5]))[0])
        axis = _unit(self.p[f"knee{s}"] - self.p[f"hip{s}"])
        return self._ball(self.p[f"knee{s}"], axis, (1.05 * r, 0.95 * r, r), self.lateral)

    def shank(self, s: str):
        b, H = self.b, self.H
        t = Mannequin._SHANK_T
        r = np.interp(t, [0.0, 0.3, 0.75, 1.0], [b.knee, b.calf, 0.7 * b.calf + 0.3 * b.ankle, b.ankle]) * H
        r = self._loose(r, 0.5 + 0.5 * t)
        return self._limb(self.p[f"knee{s}"], self.p[f"ankle{s}"], t, r)

    def shoe(self, s: str):
        H = self.H
        heel, toe, ankle = self.p[f"heel{s}"], self.p[f"toe{s}"], self.p[f"ankle{s}"]
        axis = _unit(toe - heel)
        up = ankle - heel
        up = _unit(up - np.dot(up, axis) * axis)
        half_w, h_heel = self.b.shoe
        length = np.linalg.norm(toe - heel)
        t = np.array([-0.03, 0.0, 0.3, 0.65, 1.0, 1.07]) * length + np.array([-0.01, 0, 0, 0, 0.02, 0.03]) * H
        height = np.array([0.5, 0.95, 1.0, 0.6, 0.45, 0.3]) * h_heel * H
        width = np.array([0.6, 0.85, 0.9, 1.0, 0.9, 0.5]) * half_w * H
        sole = heel - 0.006 * H * up
        centres = sole + t[:, None] * axis + 0.5 * height[:, None] * up
        side = _unit(np.cross(up, axis))
        return rings(centres, side, width, 0.5 * height + 1e-4)

    def upper_arm(self, s: str):
        b, H = self.b, self.H
        t = Mannequin._UPPER_ARM_T
        r = np.interp(t, [-0.05, 0.3, 1.0], [1.1 * b.upper_arm, b.upper_arm, 0.85 * b.upper_arm]) * H
        return self._limb(self.p[f"shoulder{s}"], self.p[f"elbow{s}"], t, r, flat=1.0)

    def elbow(self, s: str):
        r = 0.85 * self.b.upper_arm * self.H
        axis = _unit(self.p[f"elbow{s}"] - self.p[f"shoulder{s}"])
        return self._ball(self.p[f"elbow{s}"], axis, (r, r, r), self.lateral)

    def forearm(self, s: str):
        b, H = self.b, self.H
        t = Mannequin._FOREARM_T
        r = np.interp(t, [0.0, 0.3, 1.0], [0.9 * b.forearm, b.forearm, b.wrist]) * H
        return self._limb(self.p[f"elbow{s}"], self.p[f"wrist{s}"], t, r, flat=0.8)

    def hand(self, s: str):
        L, W, T = (x * self.H for x in self.b.hand)
        axis = _unit(self.p[f"wrist{s}"] - self.p[f"elbow{s}"])
        centre = self.p[f"wrist{s}"] + 0.85 * L * axis
        return self._ball(centre, axis, (L, T, W), self.lateral)

    def skirt(self):
        H, b, p = self.H, self.b, self.p
        top = p["pelvis"] + 0.06 * H * UP
        knee_z = 0.5 * (p["knee_l"][2] + p["knee_r"][2])
        hem = np.array([top[0], top[1], knee_z + 0.02 * H])
        knees = 0.5 * (p["knee_l"] + p["knee_r"])
        hem[:2] = 0.5 * (top[:2] + knees[:2])
        spread = max(np.linalg.norm(p["knee_l"] - p["knee_r"]) / 2 + b.knee * H, 1.3 * b.hip_width * H)
        t = np.linspace(0, 1, 6)
        centres = top + t[:, None] * (hem - top)
        a = (b.hip_width * H) + t * (spread - b.hip_width * H)
        d = (b.hip_depth * H) + t * (spread - b.hip_width * H) * 0.9 + 0.01 * H
        return rings(centres, self.lateral, a * 1.05, d)

    def neck(self):
        H = self.H
        base, head = self.p["neck"], self.p["head"]
        axis = _unit(head - base)
        t = np.array([-0.02, 0.02, 0.06, 0.09]) * H
        centres = base + t[:, None] * axis
        r = np.full(4, self.b.neck * H)
        return rings(centres, self.lateral, r, r)

    def _head_frame(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        up = _unit(self.p["head"] - self.p["neck"])
        fwd = self.forward - np.dot(self.forward, up) * up
        return up, _unit(fwd), _unit(np.cross(up, fwd))

    def head(self):
        L, W, Hh = (x * self.H for x in self.b.head)
        up, fwd, side = self._head_frame()
        t, f = ellipsoid_stations(9)
        centres = self.p["head"] - 0.2 * Hh * up + t[:, None] * Hh * up + 0.08 * L * fwd
        return rings(centres, side, f * W, f * L)

    def hair(self):
        L, W, Hh = (x * self.H for x in self.b.head)
        up, fwd, side = self._head_frame()
        t, f = ellipsoid_stations(8)
        long_hair = self.o.hair_style == "long"
        height = (1.35 if long_hair else 0.72) * Hh
        centre = self.p["head"] - 0.2 * Hh * up + (Hh + 0.012 * self.H - height) * up - 0.12 * L * fwd
        centres = centre + t[:, None] * height * up
        return rings(centres, side, f * (W + 0.008 * self.H), f * (L + 0.006 * self.H))
