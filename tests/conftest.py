from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[1]
FIXTURES = Path(__file__).resolve().parent / "fixtures"


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(12345)


@pytest.fixture
def read_only_dir(tmp_path):
    """A folder nobody may write into (skips where chmod has no effect, as for root)."""
    import os

    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        if os.access(folder, os.W_OK):
            pytest.skip("chmod has no effect (running as root)")
        yield folder
    finally:
        folder.chmod(0o755)


@pytest.fixture(scope="session")
def embedded_session(tmp_path_factory):
    """The embedded walk rendered once per test run (2 cameras, 640x480, 56 frames)."""
    from gaitcap.data import embedded_walk
    from gaitcap.synth.session import SynthOptions, synthesize

    out = tmp_path_factory.mktemp("embedded") / "session"
    return synthesize(embedded_walk(), out, SynthOptions(), progress=False)


@pytest.fixture(scope="session")
def tracked_session(embedded_session, tmp_path_factory):
    """The first 20 frames of the embedded session tracked with the default factored IPF."""
    from gaitcap.pipeline import run_track

    out = tmp_path_factory.mktemp("tracked") / "out"
    summary = run_track(embedded_session.session, out, progress=False, max_frames=20)
    return embedded_session, out, summary
