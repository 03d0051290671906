"""Per-seed variety of the synthetic sessions: who walks, in what clothes, in which room, under
which light, seen by which cameras.

``draw_look(seed, height_m)`` draws everything a session's appearance depends on from one seed,
so a seed list is a reproducible suite of different people, clothes and rooms. The ranges:

- body build: slim to heavy (girths x0.85-1.25), each girth jittered by +-7 %; children (below
  1.5 m) get a relatively larger head;
- clothes: long trousers, shorts (bare shins and knees) or, rarely, a skirt; long, short or no
  sleeves; loose or tight; colours anywhere in the range, and in a quarter of the garments within
  20 grey levels of the floor or wall (low contrast); striped tops;
- skin from light to dark; hair black, brown, blond, red, grey or white, short, long or none;
  shoes of any colour, sometimes the walkway mat's;
- rooms: floor of tiles, wood, carpet or plain lino, light to dark, with or without a walkway
  mat; walls of any pale-to-mid colour, doors, posters;
- light: direction, hard to soft shadow, strength, a second light, drift; sensor noise and JPEG
  compression;
- cameras: 3-6 m from the walk, 0.8-2 m high, lateral, oblique and frontal placements.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from gaitcap.synth.mannequin import Build, Color, Outfit
from gaitcap.synth.placement import DEFAULT_AZIMUTHS

SKIN_TONES: tuple[Color, ...] = (
    (190, 205, 240), (160, 185, 225), (130, 160, 210), (105, 140, 190), (80, 110, 160),
    (60, 85, 130), (45, 60, 95), (35, 45, 70),
)  # BGR, light to dark  # fmt: skip
HAIR_COLORS: dict[str, Color] = {
    "black": (25, 25, 30), "brown": (35, 55, 85), "blond": (110, 175, 215), "red": (40, 70, 150),
    "grey": (165, 165, 165), "white": (215, 215, 215),
}  # fmt: skip
FLOOR_KINDS = ("tiles", "wood", "carpet", "lino")


@dataclass(frozen=True)
class RoomStyle:
    """The look of the room: floor, optional walkway mat, walls, doors and posters."""

    floor_kind: str = "tiles"
    floor_color: Color = (118.0, 120.0, 121.0)
    tile_m: float = 0.6
    mat_color: Color | None = None  # a walkway mat along the walk, or none
    mat_width_m: float = 0.9
    wall_color: Color = (185.0, 190.0, 195.0)
    door_color: Color | None = None
    n_posters: int = 2
    seed: int = 0

    def __post_init__(self) -> None:
        if self.floor_kind not in FLOOR_KINDS:
            raise ValueError(f"unknown floor kind {self.floor_kind!r} (choose from {', '.join(FLOOR_KINDS)})")


@dataclass(frozen=True)
class Lighting:
    """Lights and sensor: direction the main light travels (z < 0), its shadow, a second light."""

    direction: tuple[float, float, float] = (0.35, 0.45, -0.82)
    shadow_strength: float = 0.55  # fraction of light the shadow removes, 0-1
    shadow_blur_m: float = 0.05  # penumbra width (0: hard shadow)
    second_direction: tuple[float, float, float] | None = None
    second_strength: float = 0.0
    ambient: float = 0.45  # share of the body's light that is not directional
    drift: float = 0.06  # global gain goes from 1 - drift to 1 + drift over the session
    noise_sigma: float = 2.5  # grey levels
    jpeg_quality: int | None = None  # re-compress each frame (None: only the video codec)

    def __post_init__(self) -> None:
        if self.direction[2] >= 0 or (self.second_direction is not None and self.second_direction[2] >= 0):
            raise ValueError("light directions must point downwards (negative z)")


@dataclass(frozen=True)
class CameraPlan:
    """Where the cameras stand: azimuths from the walking direction (degrees, left positive)."""

    azimuths_deg: tuple[float, ...]
    distances_m: tuple[float, ...]
    heights_m: tuple[float, ...]
    k1: float = -0.06


@dataclass(frozen=True)
class Look:
    """Everything a synthetic session's appearance depends on (see the module docstring)."""

    build: Build
    outfit: Outfit
    room: RoomStyle
    lighting: Lighting
    cameras: CameraPlan
    seed: int

    def describe(self) -> dict[str, object]:
        """Conditions for the benchmark's breakdown (plain values)."""
        o = self.outfit
        bare = o.lower != "trousers"
        return {
            "seed": self.seed, "height_m": round(self.build.height_m, 3), "legs": "bare" if bare else "covered",
            "lower": o.lower, "sleeves": round(o.sleeves, 2), "hair": o.hair_style,
            "floor": self.room.floor_kind, "mat": self.room.mat_color is not None, "cameras": len(self.cameras.azimuths_deg),
            "contrast": self.contrast(),
        }  # fmt: skip

    def contrast(self) -> str:
        """"low" when the legs' surface (trousers, or the skin of bare legs) is within 15 grey
        levels of the floor, the mat or the wall behind them."""
        o, room = self.outfit, self.room
        grounds = [room.floor_color, room.wall_color] + ([room.mat_color] if room.mat_color is not None else [])
        legs = o.bottom if o.lower == "trousers" else o.skin
        return "low" if min(_grey_distance(legs, g) for g in grounds) <= 15 else "normal"


def _grey(c: Color) -> float:
    return 0.114 * c[0] + 0.587 * c[1] + 0.299 * c[2]


def _grey_distance(a: Color, b: Color) -> float:
    return abs(_grey(a) - _grey(b))


def _color(rng: np.random.Generator, lo: float = 20, hi: float = 235) -> Color:
    base = rng.uniform(lo, hi)
    tint = rng.uniform(-1, 1, 3) * rng.uniform(0, 70)
    return tuple(float(np.clip(base + t, 5, 250)) for t in tint)  # type: ignore[return-value]


def _near(rng: np.random.Generator, ground: Color, levels: float = 20) -> Color:
    """A colour within ``levels`` grey levels of ``ground``, of another hue."""
    target = _grey(ground) + rng.uniform(-levels, levels)
    c = np.asarray(ground, float) + rng.uniform(-30, 30, 3)
    c += target - _grey(tuple(c))  # type: ignore[arg-type]
    return tuple(float(v) for v in np.clip(c, 3, 252))  # type: ignore[return-value]


def draw_build(rng: np.random.Generator, height_m: float) -> Build:
    """Girths varied per subject; a child's head is relatively larger (Snyder et al. 1977)."""
    base = Build(height_m=height_m)
    bulk = rng.uniform(0.85, 1.25)
    girths = ("thigh", "knee", "calf", "ankle", "upper_arm", "forearm", "wrist", "hip_width", "waist_width",
              "chest_width", "shoulder_width", "hip_depth", "waist_depth", "chest_depth", "neck")  # fmt: skip
    values = {}
    for name in girths:
        values[name] = getattr(base, name) * bulk * rng.uniform(0.93, 1.07)
    values["waist_width"] *= rng.uniform(0.9, 1.1) * (1.0 if bulk < 1.1 else 1.1)
    child = float(np.clip(1.70 / height_m, 1.0, 1.6)) ** 0.75
    values["head"] = tuple(x * child * rng.uniform(0.94, 1.06) for x in base.head)
    values["hand"] = tuple(x * rng.uniform(0.9, 1.1) for x in base.hand)
    values["shoe"] = (base.shoe[0] * rng.uniform(0.9, 1.15), base.shoe[1] * rng.uniform(0.8, 1.3))
    return replace(base, **values)


def draw_room(rng: np.random.Generator, seed: int) -> RoomStyle:
    kind = str(rng.choice(FLOOR_KINDS))
    floor = _color(rng, 45, 215)
    if kind == "wood":
        floor = (float(rng.uniform(40, 110)), float(rng.uniform(70, 150)), float(rng.uniform(110, 200)))
    mat = _color(rng, 20, 200) if rng.random() < 0.45 else None
    return RoomStyle(
        floor_kind=kind, floor_color=floor, tile_m=float(rng.choice([0.3, 0.45, 0.6])), mat_color=mat,
        mat_width_m=float(rng.uniform(0.7, 1.3)), wall_color=_color(rng, 120, 235),
        door_color=_color(rng, 40, 200) if rng.random() < 0.6 else None, n_posters=int(rng.integers(0, 4)), seed=seed,
    )  # fmt: skip


def draw_outfit(rng: np.random.Generator, room: RoomStyle) -> Outfit:
    grounds = [room.floor_color, room.wall_color] + ([room.mat_color] if room.mat_color is not None else [])

    def garment() -> Color:
        if rng.random() < 0.25:
            return _near(rng, grounds[int(rng.integers(len(grounds)))])
        return _color(rng)

    u = rng.random()
    lower = "trousers" if u < 0.55 else ("shorts" if u < 0.9 else "skirt")
    legs_cover = 1.0 if lower == "trousers" else float(rng.uniform(0.25, 0.45))
    v = rng.random()
    sleeves = 1.0 if v < 0.45 else (float(rng.uniform(0.15, 0.35)) if v < 0.85 else 0.0)
    hair_style = str(rng.choice(["short", "short", "long", "none"]))
    top = garment()
    return Outfit(
        skin=tuple(float(c) * rng.uniform(0.95, 1.05) for c in SKIN_TONES[int(rng.integers(len(SKIN_TONES)))]),  # type: ignore[arg-type]
        hair=HAIR_COLORS[str(rng.choice(list(HAIR_COLORS)))], hair_style=hair_style, top=top,
        stripe=_color(rng) if rng.random() < 0.2 else None, sleeves=sleeves, bottom=garment(), lower=lower,
        legs_cover=legs_cover, loose=float(rng.uniform(1.0, 1.35)) if lower == "trousers" else 1.0,
        shoes=(room.mat_color if room.mat_color is not None and rng.random() < 0.2 else _color(rng, 10, 245)),
    )  # fmt: skip


def draw_lighting(rng: np.random.Generator) -> Lighting:
    def direction(elev_lo: float, elev_hi: float) -> tuple[float, float, float]:
        az, el = rng.uniform(0, 2 * np.pi), np.radians(rng.uniform(elev_lo, elev_hi))
        return (float(np.cos(el) * np.cos(az)), float(np.cos(el) * np.sin(az)), float(-np.sin(el)))

    second = rng.random() < 0.4
    return Lighting(
        direction=direction(35, 80), shadow_strength=float(rng.uniform(0.2, 0.7)),
        shadow_blur_m=float(rng.choice([0.0, 0.02, 0.05, 0.1])),
        second_direction=direction(30, 70) if second else None, second_strength=float(rng.uniform(0.15, 0.35)) if second else 0.0,
        ambient=float(rng.uniform(0.3, 0.6)), drift=float(rng.uniform(0.0, 0.1)), noise_sigma=float(rng.uniform(1.0, 5.0)),
        jpeg_quality=int(rng.integers(40, 95)) if rng.random() < 0.5 else None,
    )  # fmt: skip


#: camera layouts (azimuths from the walking direction, degrees; 90 = lateral on the left,
#: 0 = in front, facing the subject)
LAYOUTS: tuple[tuple[float, ...], ...] = (
    (90.0, -45.0), (90.0, 45.0), (-90.0, 30.0), (90.0, 0.0), (60.0, -60.0), (90.0, -135.0),
    (90.0, -45.0, -135.0), (90.0, -90.0, 20.0), (90.0, -45.0, -135.0, 45.0), (60.0, -60.0, 150.0, -150.0),
)  # fmt: skip


def draw_cameras(rng: np.random.Generator, n_cameras: int | None) -> CameraPlan:
    """Camera azimuths, distances (3-6 m) and heights (0.8-2 m), with a jitter of +-15 degrees."""
    layouts = [lay for lay in LAYOUTS if n_cameras is None or len(lay) == n_cameras]
    if not layouts:
        layouts = [DEFAULT_AZIMUTHS[:n_cameras]]
    lay = layouts[int(rng.integers(len(layouts)))]
    az = tuple(float(a + rng.uniform(-15, 15)) for a in lay)
    return CameraPlan(
        azimuths_deg=az, distances_m=tuple(float(rng.uniform(3.0, 6.0)) for _ in az),
        heights_m=tuple(float(rng.uniform(0.8, 2.0)) for _ in az), k1=float(rng.uniform(-0.12, 0.02)),
    )  # fmt: skip


def draw_look(seed: int, height_m: float, n_cameras: int | None = 2) -> Look:
    """Everything of a session's appearance, from ``seed`` (see the module docstring)."""
    rng = np.random.default_rng([seed, 20261125])
    room = draw_room(rng, seed)
    return Look(build=draw_build(rng, height_m), outfit=draw_outfit(rng, room), room=room,
                lighting=draw_lighting(rng), cameras=draw_cameras(rng, n_cameras), seed=seed)  # fmt: skip
