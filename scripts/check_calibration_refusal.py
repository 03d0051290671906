"""Measure the calibration checks of gaitcap.session_check on sessions: the geometry and the silhouettes of
the first frames under each session's calibration (must pass), and under wrong variants of it (extrinsics
swapped between the first two cameras, rotations transposed, the second camera turned about its own axes).

Usage: PYTHONPATH=src python scripts/check_calibration_refusal.py SESSION [SESSION ...]"""
import sys, logging, time
from dataclasses import replace
import numpy as np, cv2
logging.disable(logging.WARNING)
from gaitcap.session import Session
from gaitcap.session_check import check_session_videos, check_silhouettes_meet, _misses
from gaitcap.camera import CameraRig
from gaitcap.errors import GaitcapError
from gaitcap.pipeline import _observations
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.tracking.config import load_tracking_config
from gaitcap.body.model import load_body_model
from gaitcap.tracking.observation import tracking_views

cfg = load_tracking_config(None, model=load_body_model())
for root in sys.argv[1:]:
    t0 = time.perf_counter()
    ses = Session.open(root)
    try:
        videos = check_session_videos(ses)
    except GaitcapError as e:
        print(root, "REFUSED:", e); continue
    rig = videos.rig
    views = tracking_views(rig, cfg.scale)
    obs = []
    for o in _observations(ses, rig.names, views, SilhouetteConfig.load(), min(videos.n_frames, 8)):
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
