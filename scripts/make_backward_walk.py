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
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from make_turn_walk import write_walk  # scripts/ is on the path when run as a script

from gaitcap.data import embedded_walk
from gaitcap.markers.motion import read_motion


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("-o", "--out", type=Path, required=True, help="the TRC to write")
    args = ap.parse_args()
    walk = read_motion(embedded_walk())
    write_walk(args.out, walk, walk.points[::-1].copy())


if __name__ == "__main__":
    main()
