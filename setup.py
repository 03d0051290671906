"""The build step that compiles the numba kernels into the wheel (gaitcap.tracking.precompile).

Everything else about the package is in pyproject.toml. After the standard build_py has copied the
sources into the build folder, the kernels are compiled there, so that their cache files ship in the
wheel and the first run after ``pip install .`` compiles nothing. A failure only costs that: the
wheel is built without the cache, and the kernels compile at their first use. Skipped for editable
installs (``pip install -e .``), whose source tree caches the kernels at their first use.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py


class BuildWithKernels(build_py):
    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False) or os.environ.get("GAITCAP_NO_PRECOMPILE"):
            return
        # a build folder reused by pip keeps the cache of earlier sources: ship only this build's
        for stale in Path(self.build_lib, "gaitcap").rglob("__pycache__/*.nb[ic]"):
            stale.unlink()
        # numba's in-tree cache (the package's __pycache__), not a user's NUMBA_CACHE_DIR
        env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
        # the built package first; pip's isolated build environment is found through PYTHONPATH too
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [os.path.abspath(self.build_lib), env.get("PYTHONPATH")]))
        cmd = [sys.executable, "-m", "gaitcap.tracking.precompile"]
        try:
            done = subprocess.run(cmd, env=env, cwd=self.build_lib, check=False).returncode == 0
        except OSError:
            done = False
        if not done:
            self.warn("the numba kernels could not be compiled into the wheel: they will compile at first use")


setup(cmdclass={"build_py": BuildWithKernels})
