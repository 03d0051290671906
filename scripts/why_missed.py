"""Which test loses the person's pixels that a session's masks miss? (a diagnostic, not a test)

    PYTHONPATH=src python scripts/why_missed.py SESSION... [--feet] [--every K]

For a synthetic session (``gaitcap synth`` or the suite's: ``truth.h5`` with the true masks), runs
the silhouette extraction as ``gaitcap track`` does (:class:`JointExtractor`, its ``observe`` and
``finish`` steps) and sorts every true pixel the masks miss by the first test that lost it:

- ``below weak``: the difference from the background is under the weak (hysteresis) level and no
  texture test caught it;
- ``shadow``: a photometric shadow candidate (darker, same chromaticity, same texture) that the
  floor check kept as shadow; ``deep shadow``: darker than the photometric test alone accepts,
  confirmed by the floor check;
- ``clean-up``: weak foreground, not shadow, dropped by the connection to the confident body, the
  opening, the component selection or the matte.

Then, of the pixels kept as photometric shadow by the floor check, why it kept them: the other
camera sees the floor point darkened by the same ratio (``same ratio``), it sees the person there
and cannot tell (``person in front``, the rest), or no other camera sees that floor point
(``unseen``). ``--feet`` counts only the pixels of the feet in the camera-frames where the masks hold
less than half of a foot (``gaitcap.evaluation.silhouettes.part_coverage``'s discs and threshold).
Prints one row per camera (shares of the missed pixels) and the frames scored every ``--every``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import h5py
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from bench_suite import PART_MISSING  # scripts/ is on the path when run as a script

from gaitcap.errors import GaitcapError, InputError
from gaitcap.evaluation.report import read_truth_reference
from gaitcap.evaluation.silhouettes import part_centres, part_pixels, project_part
from gaitcap.session import Session
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.silhouette.joint import JointExtractor
from gaitcap.silhouette.run import prepare_extractor, sources_from_session
from gaitcap.video import iter_synchronised

CAUSES = ("below weak", "shadow", "deep shadow", "clean-up")
RULES = ("same ratio", "person in front", "unseen")


def foot_pixels(truth: np.ndarray, mask: np.ndarray, camera, centres: dict, k: int) -> np.ndarray:
    """(H, W) bool: the true pixels of the feet the mask misses in frame k (``bench_suite``'s test)."""
    out = np.zeros_like(truth)
    for part in ("foot_l", "foot_r"):
        pix, radius = project_part(camera, centres[part][k : k + 1], part)
        found = part_pixels(truth, pix[0], radius[0])
        if found is not None and (mask[found[0]][found[1]] > 0).mean() < PART_MISSING:
            out[found[0]] |= found[1]
    return out


def why(session: Path, feet: bool, every: int) -> dict[str, dict[str, int]]:
    """Counts per camera: missed and true pixels, each cause, each rule (see the module docstring)."""
    config = SilhouetteConfig.load()
    sources = sources_from_session(session)
    joint = JointExtractor([prepare_extractor(s, config)[0] for s in sources], [s.calibration for s in sources])
    truth_masks = h5py.File(session / "truth.h5")["masks"]
    centres = part_centres(read_truth_reference(session / "truth.h5").trajectory)
    tol = config.shadow.floor_ratio_tolerance
    counts = {s.camera: dict.fromkeys(("missed", "true", *CAUSES, *RULES), 0) for s in sources}
    for k, images in iter_synchronised({s.camera: s.video for s in sources}, 0, None):
        evidence, shadows = joint.observe([images[s.camera] for s in sources])
        by_ratio = None
        if joint.floor is not None and k % every == 0:  # the floor check without "the person in front confirms"
            ratios = [ex.log_brightness(e) for ex, e in zip(joint.extractors, evidence)]
            by_ratio = joint.floor.relabel([e.shadow for e in evidence], [e.darkening for e in evidence],
                                           [e.deep_shadow for e in evidence], ratios, None, tol)  # fmt: skip
        results = joint.finish(evidence, shadows)
        if k % every:
            continue
        for i, (src, e, kept, (mask, _)) in enumerate(zip(sources, evidence, shadows, results)):
            true = truth_masks[src.camera][k] > 0
            missed = true & (mask == 0)
            if feet:
                missed &= foot_pixels(true, mask, src.calibration, centres, k)
            c = counts[src.camera]
            c["true"] += int(true.sum())
            c["missed"] += int(missed.sum())
            weak = missed & e.weak
            c["below weak"] += int((missed & ~e.weak).sum())
            c["shadow"] += int((weak & kept & e.shadow).sum())
            c["deep shadow"] += int((weak & kept & ~e.shadow).sum())
            c["clean-up"] += int((weak & ~kept).sum())
            if by_ratio is not None:
                photo = weak & kept & e.shadow
                unseen = photo & ~joint.floor.seen[i]
                c["unseen"] += int(unseen.sum())
                c["same ratio"] += int((photo & by_ratio[i] & ~unseen).sum())
                c["person in front"] += int((photo & ~by_ratio[i] & ~unseen).sum())
    return counts


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sessions", type=Path, nargs="+")
    ap.add_argument("--feet", action="store_true", help="only the feet missing from a camera-frame")
    ap.add_argument("--every", type=int, default=1, help="score every K-th frame (all are extracted)")
    args = ap.parse_args()
    for session in args.sessions:  # a wrong path ends the script before any work
        Session.open(session)
        if not (session / "truth.h5").is_file():
            raise InputError(f"{session}: no truth.h5 (a synthetic session with its true masks is needed)")
    print(f"| session | camera | missed / true | {' | '.join(CAUSES)} | of the shadow: {' | '.join(RULES)} |")
    print("|---|---|---|" + "---|" * (len(CAUSES) + len(RULES)))
    for session in args.sessions:
        for cam, c in why(session, args.feet, args.every).items():
            m = max(c["missed"], 1)
            s = max(c["shadow"], 1)
            print(f"| {session.name} | {cam} | {c['missed']} / {c['true']} ({c['missed'] / max(c['true'], 1):.3f}) | "
                  + " | ".join(f"{c[k] / m:.2f}" for k in CAUSES) + " | "
                  + " | ".join(f"{c[k] / s:.2f}" for k in RULES) + " |")


if __name__ == "__main__":
    try:
        main()
    except GaitcapError as e:
        sys.exit(f"error: {e}")
