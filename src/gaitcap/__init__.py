"""gaitcap: markerless 3D gait analysis from two or more calibrated cameras."""

import os
from importlib.metadata import PackageNotFoundError, version

# The compiled kernels run on numba's OpenMP pool. By default its idle threads spin for a while
# after each parallel region; under CPU contention (the prefetch thread, a second run, other
# users) they steal the cores the other threads need: gaitcap track on the embedded walk took
# 142 s instead of 24 s with another process busy on one of 2 cores. Passive waiting: the threads
# sleep at once. Read when the OpenMP runtime loads (numba's first parallel call), so set here,
# before any of it; an explicit OMP_WAIT_POLICY in the environment wins.
os.environ.setdefault("OMP_WAIT_POLICY", "passive")

try:
    __version__ = version("gaitcap")
except PackageNotFoundError:  # running from a source tree without installation
    __version__ = "0.0.0+src"

#: the library's entry points, ``gaitcap.NAME``: imported on first use (PEP 562), so that ``import
#: gaitcap`` (and the command line's start-up) loads none of them. See the README, "From Python".
_API = {
    "Trajectory": "gaitcap.trajectory",
    "GaitEvent": "gaitcap.trajectory",
    "read_trajectory": "gaitcap.io.trajectories_h5",
    "write_trajectory": "gaitcap.io.trajectories_h5",
    "read_motion": "gaitcap.markers.motion",
    "read_markers": "gaitcap.markers.motion",
    "analyse": "gaitcap.gait.analysis",
    "joint_angles": "gaitcap.gait.angles",
    "estimate_walking_direction": "gaitcap.gait.events",
    "GaitOptions": "gaitcap.gait.options",
    "read_calibration": "gaitcap.io.calibration_toml",
    "Camera": "gaitcap.camera",
    "CameraRig": "gaitcap.camera",
    "read_masks": "gaitcap.io.silhouettes_h5",
    "read_cameras": "gaitcap.io.silhouettes_h5",
    "load_tracking_config": "gaitcap.tracking.config",
    "run_track": "gaitcap.pipeline",
    "run_report": "gaitcap.report.pipeline",
    "evaluate": "gaitcap.evaluation.compare",
    "read_truth": "gaitcap.synth.truth",
}

__all__ = ["__version__", *_API]


def __getattr__(name: str) -> object:
    module = _API.get(name)
    if module is None:
        raise AttributeError(f"module 'gaitcap' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_API))
