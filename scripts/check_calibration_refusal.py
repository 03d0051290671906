"""Measure the calibration checks of gaitcap.session_check on sessions: the geometry and the silhouettes of
the first frames under each session's calibration (must pass), and under wrong variants of it (extrinsics
swapped between the first two cameras, rotations transposed, the second camera turned about its own axes).

    PYTHONPATH=src python scripts/check_calibration_refusal.py SESSION [SESSION ...]

For each session (a folder with calibration.toml, videos/ and background/, e.g. ``gaitcap synth``'s or
../shared/data/external_sessions/ktk_a), the backgrounds are fitted and the first 8 frames' silhouettes
extracted as ``gaitcap track`` does, then ``check_silhouettes_meet`` judges them under each calibration.
Prints, per session, a line with the seconds taken and the verdict under its own calibration ("pass" and,
for each of the first 5 frames, the cameras whose silhouette is not where the calibration puts the subject:
[] when none, None when fewer than 2 cameras see a silhouette; or "REFUSED:" and the error ``gaitcap track``
would give), then one indented line per wrong variant (the rotated ones cut to 60 characters): the check
should pass the true calibration and refuse the wrong ones (a symmetric rig's swapped extrinsics and small
rolls can pass: the check refuses what cannot be right, it does not prove a calibration). A session whose
own geometry or videos are refused (``check_session_videos``) prints "REFUSED:" and nothing else.
"""
import argparse
import logging
import sys
import time
from dataclasses import replace

import cv2
from pathlib import Path
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.body.model import load_body_model
from gaitcap.camera import CameraRig
from gaitcap.errors import GaitcapError
from gaitcap.pipeline import Stages, _observations
from gaitcap.session import Session
from gaitcap.session_check import _misses, check_session_videos, check_silhouettes_meet
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.tracking.config import load_tracking_config
from gaitcap.tracking.observation import tracking_views


def measure(root: str, cfg) -> None:
    """Print the session's verdicts under its calibration and under each wrong variant."""
    t0 = time.perf_counter()
    ses = Session.open(root)
    try:
        videos = check_session_videos(ses)
    except GaitcapError as e:
        print(root, "REFUSED:", e)
        return
    rig = videos.rig
    views = tracking_views(rig, cfg.scale)
    obs = []
    for o in _observations(ses, rig.names, views, SilhouetteConfig.load(), min(videos.n_frames, 8), Stages()):
        obs.append(o)
    def verdict(vs):
        try:
            check_silhouettes_meet(vs, obs, "calibration.toml"); return "pass " + str([_misses(vs, o) for o in obs[:5]])
        except GaitcapError as e:
            return "REFUSED: " + str(e)
    print(root, f"({time.perf_counter() - t0:.1f} s)", verdict(views))
    cams = list(rig)
    swapped = [replace(cams[0], rvec=cams[1].rvec, tvec=cams[1].tvec), replace(cams[1], rvec=cams[0].rvec, tvec=cams[0].tvec)] + cams[2:]
    print("   swapped extrinsics:", verdict(tracking_views(CameraRig(tuple(swapped)), cfg.scale)))
    Rt = [replace(c, rvec=cv2.Rodrigues(cv2.Rodrigues(c.rvec)[0].T)[0].ravel()) for c in cams]
    print("   transposed R:", verdict(tracking_views(CameraRig(tuple(Rt)), cfg.scale)))
    # camera 2 yawed by 40 degrees about its own vertical axis: looks beside the subject
    Ry = cv2.Rodrigues(np.array([0.0, np.radians(40), 0.0]))[0]
    yaw = [cams[0], replace(cams[1], rvec=cv2.Rodrigues(Ry @ cams[1].R)[0].ravel(), tvec=Ry @ cams[1].tvec)] + cams[2:]
    print("   cam2 yawed 40 deg:", verdict(tracking_views(CameraRig(tuple(yaw)), cfg.scale)))
    for ang in (10, 15, 20):
        for axis, nm in ((1, "yaw"), (0, "pitch"), (2, "roll")):
            r = np.zeros(3); r[axis] = np.radians(ang)
            Rr = cv2.Rodrigues(r)[0]
            v = [cams[0], replace(cams[1], rvec=cv2.Rodrigues(Rr @ cams[1].R)[0].ravel(), tvec=Rr @ cams[1].tvec)] + cams[2:]
            print(f"   cam2 {nm} {ang} deg:", verdict(tracking_views(CameraRig(tuple(v)), cfg.scale))[:60])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("sessions", nargs="+", help="session folders")
    args = ap.parse_args()
    logging.disable(logging.WARNING)
    cfg = load_tracking_config(None, model=load_body_model())
    for root in args.sessions:
        try:
            measure(root, cfg)
        except GaitcapError as e:
            print(f"error: {e}", file=sys.stderr)
            return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
