"""A walk that turns back, as a TRC of joint centres for ``gaitcap synth``: the embedded walk, a standing
pivot about the pelvis, then the walk again, turned round, from the frame whose legs match the last one's.

    python scripts/make_turn_walk.py -o turn_walk.trc [--turn-seconds 1.0] [--degrees 180] [--turns 1] [--strides 1]
    python scripts/make_turn_walk.py -o turn_walk.trc --radius 0.75 [--turns 1]
    gaitcap synth turn_walk.trc -o SESSION --seed 3 --height 1.639
    gaitcap track SESSION -o OUT && gaitcap eval OUT --truth SESSION/truth.h5

The pivot keeps the walk's last pose and turns it about the vertical through the pelvis, with a
smooth start and stop (the angle follows half a cosine), so its fastest rate is pi/2 times the mean.
The walk back starts from the frame at least 0.6 s before the end whose legs, relative to the pelvis,
are nearest the last frame's (a stride earlier), so that the pose does not jump. The feet slide
during the pivot: a test of the tracker's heading through a turn, not of a turning gait.

``--radius R``: the turn is walked instead, round a half circle of radius R metres, without a pause:
the walk (its last stride repeated) is bent along a path of the walk's length, the half circle and as
long a walk back; each frame's pose is turned about the pelvis by the path's heading where its pelvis
has come to (the pelvis's sway kept across the path). The feet slide while the heading turns under
them: a test of the tracker and of the gait analysis through a turn that does not stop, not a model
of turning gait.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.data import embedded_walk
from gaitcap.errors import GaitcapError
from gaitcap.io.trc import write_trc
from gaitcap.markers.motion import read_motion
from gaitcap.trajectory import Trajectory

#: the walk back starts at least this long before the walk's last frame
MIN_BACK_S = 0.6


def turned_walk(points: np.ndarray, pelvis: int, rate_hz: float, turn_s: float, degrees: float,
                turns: int = 1, strides: int = 1) -> np.ndarray:  # fmt: skip
    """Points (T, P, 3) of a walk (z up) -> the walk, a pivot of ``degrees`` over ``turn_s`` seconds about
    the pelvis, and the walk again from a stride before its end (that stride ``strides`` times, each
    from where the last ended), turned by the same angle; ``turns`` times, each pivot turning the same
    way (180 degrees: up and down a walkway): (T', P, 3)."""
    n_turn = max(1, round(turn_s * rate_hz))
    total = np.radians(degrees)
    angles = total * (1 - np.cos(np.linspace(0, np.pi, n_turn + 1)[1:])) / 2
    relative = points - points[:, pelvis : pelvis + 1]
    earliest = len(points) - max(1, round(MIN_BACK_S * rate_hz))
    k = int(np.argmin(np.linalg.norm(relative[:earliest] - relative[-1], axis=-1).mean(axis=1)))
    stride = points[k:] - points[k, pelvis] * [1.0, 1.0, 0.0]  # its pelvis starts above the origin
    step = (points[-1, pelvis] - points[k, pelvis]) * [1.0, 1.0, 0.0]
    leg = np.concatenate([stride] + [stride[1:] + j * step for j in range(1, strides)])
    pieces = [points]
    for turn in range(1, turns + 1):
        end = pieces[-1][-1]
        centre = end[pelvis] * [1.0, 1.0, 0.0]
        pivot = (end - centre) @ Rotation.from_euler("z", angles[:, None]).as_matrix().transpose(0, 2, 1) + centre
        turn_round = Rotation.from_euler("z", turn * total).as_matrix()
        back = leg @ turn_round.T + pivot[-1][pelvis] * [1.0, 1.0, 0.0]
        back[..., 2] = leg[..., 2]
        pieces += [pivot, back[1:]]
    return np.concatenate(pieces)


def walked_turns(points: np.ndarray, pelvis: int, rate_hz: float, radius: float, turns: int = 1) -> np.ndarray:
    """Points (T, P, 3) of a walk (z up) -> the walk, then ``turns`` times a half circle of ``radius``
    metres walked without stopping (each turning the same way) and the walk's length walked back:
    (T', P, 3). The walk's last stride is repeated for as long as the path needs; each frame's pose is
    turned about the vertical through its pelvis by the path's heading at the pelvis's distance walked,
    and the pelvis's sway off the walk's line is kept across the path."""
    # the walk's line: its pelvis's net horizontal travel
    xy = points[:, pelvis, :2]
    travel = xy[-1] - xy[0]
    length = float(np.linalg.norm(travel))
    line = travel / length
    normal = np.array([-line[1], line[0]])
    arc = np.pi * radius
    total = length + turns * (arc + length)
    # the walk made long enough: its last stride (from the frame a stride before its end) repeated
    relative = points - points[:, pelvis : pelvis + 1]
    earliest = len(points) - max(1, round(MIN_BACK_S * rate_hz))
    k = int(np.argmin(np.linalg.norm(relative[:earliest] - relative[-1], axis=-1).mean(axis=1)))
    step = (points[-1, pelvis] - points[k, pelvis]) * [1.0, 1.0, 0.0]
    pieces = [points]
    while (pieces[-1][-1, pelvis, :2] - xy[0]) @ line < total:
        pieces.append(points[k + 1 :] + (len(pieces)) * step)
    straight = np.concatenate(pieces)
    along = (straight[:, pelvis, :2] - xy[0]) @ line
    sway = (straight[:, pelvis, :2] - xy[0]) @ normal
    straight = straight[: int(np.searchsorted(along, total)) + 1]
    axes = np.stack([line, normal])  # (along, across) -> world xy, as rows
    out = straight.copy()
    for t, frame in enumerate(straight):
        (u, v), heading = _path(float(along[t]), length, radius)
        c, s = np.cos(heading), np.sin(heading)
        rel = (frame[:, :2] - frame[pelvis, :2]) @ axes.T  # (P, 2) along and across the walk
        turned = rel @ np.array([[c, s], [-s, c]])  # rotated by the heading
        centre = np.array([u, v]) + sway[t] * np.array([-s, c])
        out[t, :, :2] = (turned + centre) @ axes + xy[0]
    return out


def _path(s: float, length: float, radius: float) -> tuple[tuple[float, float], float]:
    """The point (along, across) metres and heading (radians, 0 along the walk) of the path at
    ``s`` metres: ``length`` straight, a half circle of ``radius`` turning left, ``length`` straight
    back, and so on."""
    arc = np.pi * radius
    u, v, heading = 0.0, 0.0, 0.0
    while True:
        if s <= length:
            return (u + np.cos(heading) * s, v + np.sin(heading) * s), heading
        u, v = u + np.cos(heading) * length, v + np.sin(heading) * length
        s -= length
        cu, cv = u - np.sin(heading) * radius, v + np.cos(heading) * radius  # the circle's centre, on the left
        if s <= arc:
            h = heading + s / radius
            return (cu + np.sin(h) * radius, cv - np.cos(h) * radius), h
        heading += np.pi
        u, v = cu + np.sin(heading) * radius, cv - np.cos(heading) * radius
        s -= arc


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", type=Path, required=True, help="the TRC to write")
    ap.add_argument("--turn-seconds", type=float, default=1.0, help="the pivot's duration (s, > 0)")
    ap.add_argument("--degrees", type=float, default=180.0, help="the pivot's angle (degrees)")
    ap.add_argument("--turns", type=int, default=1, help="pivots, each followed by the walk again (>= 1)")
    ap.add_argument("--strides", type=int, default=1, help="strides walked after each pivot (>= 1)")
    ap.add_argument("--radius", type=float, default=None,
                    help="walk each turn round a half circle of this radius (metres, > 0) instead of a pivot")
    args = ap.parse_args()
    if args.turn_seconds <= 0:
        ap.error("--turn-seconds must be > 0")
    if args.turns < 1 or args.strides < 1:
        ap.error("--turns and --strides must be >= 1")
    if args.radius is not None and args.radius <= 0:
        ap.error("--radius must be > 0")
    walk = read_motion(embedded_walk())
    pelvis = walk.names.index("pelvis")
    if args.radius is not None:
        write_walk(args.out, walk, walked_turns(walk.points, pelvis, walk.rate_hz, args.radius, args.turns))
        return
    write_walk(args.out, walk, turned_walk(walk.points, walk.names.index("pelvis"), walk.rate_hz, args.turn_seconds,
                                           args.degrees, args.turns, args.strides))  # fmt: skip


def write_walk(out: Path, walk: Trajectory, points: np.ndarray) -> None:
    """Write ``walk`` with its points replaced by ``points`` (T', P, 3) and no events as the TRC ``out``
    (millimetres) and say how to synthesise it; an unwritable ``out`` ends the script in one line."""
    try:
        write_trc(out, replace(walk, points=points, events=()), units="mm")
    except GaitcapError as e:
        sys.exit(f"error: {e}")
    print(f"{out}: {len(points)} samples at {walk.rate_hz:g} Hz ({len(points) / walk.rate_hz:.2f} s); "
          f"synth it with --height {walk.meta.get('height_m', 1.639):g}")  # fmt: skip


if __name__ == "__main__":
    main()
