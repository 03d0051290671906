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

__all__ = ["__version__"]
