"""A subject walking backwards, as a TRC of joint centres for ``gaitcap synth``: the embedded walk
played in reverse (the body faces one way and moves the other, as in a backward-walking exercise).

    python scripts/make_backward_walk.py -o backward_walk.trc
    gaitcap synth backward_walk.trc -o SESSION --seed 3 --height 1.639
    gaitcap track SESSION -o OUT && gaitcap eval OUT --truth SESSION/truth.h5

Played in reverse, a forward walk's kinematics are a backward walk's in the sagittal plane (each
foot's contact starts at the toe and ends at the heel); the events are left out (the reference's
are detected on its joint centres by ``gaitcap eval``). A test of the initialisation's facing
check (``gaitcap.tracking.init._facing``): the walking direction from the first frames points
behind the subject.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace
from pathlib import Path

from gaitcap.data import embedded_walk
from gaitcap.errors import GaitcapError
from gaitcap.io.trc import write_trc
from gaitcap.markers.motion import read_motion


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("-o", "--out", type=Path, required=True, help="the TRC to write")
    args = ap.parse_args()
    walk = read_motion(embedded_walk())
    points = walk.points[::-1].copy()
    try:
        write_trc(args.out, replace(walk, points=points, events=()), units="mm")
    except GaitcapError as e:
        sys.exit(f"error: {e}")
    print(f"{args.out}: {len(points)} samples at {walk.rate_hz:g} Hz ({len(points) / walk.rate_hz:.2f} s); "
          f"synth it with --height {walk.meta.get('height_m', 1.639):g}")  # fmt: skip


if __name__ == "__main__":
    main()
