"""gaitcap's entry points as a library: ``gaitcap.NAME`` (README, "From Python")."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from gait_walker import Walker

import gaitcap

README = Path(__file__).resolve().parents[1] / "README.md"


def test_every_entry_point_resolves_and_the_readme_names_it():
    section = README.read_text().split("## From Python", 1)[1].split("\n## ", 1)[0]
    for name in gaitcap.__all__:
        if name == "__version__":
            continue
        assert callable(getattr(gaitcap, name)), name
        assert f"`{name}`" in section or name in ("Trajectory", "GaitEvent"), name
    with pytest.raises(AttributeError, match="has no attribute 'nope'"):
        gaitcap.nope  # noqa: B018


def test_importing_gaitcap_loads_none_of_them():
    """The command line imports gaitcap first: its start-up must not pay for the library's modules."""
    code = "import sys, gaitcap; print(sorted(m for m in sys.modules if m.startswith('gaitcap')))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "['gaitcap']"


def test_the_readme_example_runs(tmp_path):
    """The README's example, on a trajectory written where it reads one."""
    block = re.search(r"## From Python.*?```python\n(.*?)```", README.read_text(), re.S).group(1)
    out = tmp_path / "out" / "walk01"
    gaitcap.write_trajectory(out / "trajectories.h5", Walker(duration=4.0, rate_hz=25.0).trajectory())
    scope: dict = {}
    import os

    cwd = os.getcwd()
    os.chdir(tmp_path)
    try:
        exec(compile(block, "README.md", "exec"), scope)  # noqa: S102
    finally:
        os.chdir(cwd)
    assert scope["knee"].shape[1] == 101 and np.isfinite(scope["knee"]).all()


def test_typed_constructors_refuse_a_bad_size():
    """Camera(size=[640]) or size='ab' raised a bare ValueError of unpacking and size (640.7, 480) became
    640 silently. (A Trajectory holds the caller's float64 array, not a copy: a clip's passes are views of
    its frames, gaitcap.gait.passes.within.)"""
    from gaitcap.errors import CalibrationError

    K = np.array([[500.0, 0, 320], [0, 500, 240], [0, 0, 1]])
    for size in ((640,), "ab", (640.7, 480), (640, None)):
        with pytest.raises(CalibrationError, match=r"camera 'c': size must be two positive integers \[w, h\], got"):
            gaitcap.Camera("c", size, K, np.zeros(5), np.zeros(3), np.zeros(3))
    assert gaitcap.Camera("c", (640.0, 480), K, np.zeros(5), np.zeros(3), np.zeros(3)).size == (640, 480)
