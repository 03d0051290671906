from __future__ import annotations

import numpy as np
import pytest
from silhouette_scene import walk_across, write_video

from gaitcap.errors import InputError
from gaitcap.video import VideoReader, iter_synchronised, probe_video, sample_frames, sample_indices


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    """A 20-frame 96x64 video whose frame k has mean grey level ~ 10 * k (readable after MJPEG)."""
    frames = np.stack([np.full((64, 96, 3), 10 * k + 5, np.uint8) for k in range(20)])
    path = tmp_path_factory.mktemp("video") / "ramp.avi"
    return write_video(path, frames, fps=20.0)


def _level(frame: np.ndarray) -> int:
    return int(round((float(frame.mean()) - 5) / 10))


def test_probe_reports_size_fps_and_count(clip):
    info = probe_video(clip)
    assert info.size == (96, 64)
    assert info.fps == pytest.approx(20.0)
    assert info.frame_count == 20


def test_reader_yields_every_frame_in_order(clip):
    with VideoReader(clip) as video:
        seen = [(i, _level(f)) for i, f in video]
    assert seen == [(k, k) for k in range(20)]


def test_reader_range_and_seek(clip):
    with VideoReader(clip, start=5, stop=9) as video:
        assert [_level(f) for _, f in video] == [5, 6, 7, 8]
    with VideoReader(clip) as video:
        video.seek(17)
        assert _level(video.read()) == 17
        video.seek(3)  # backwards: container seek
        assert _level(video.read()) == 3


def test_sample_indices_spread_and_bounded():
    idx = sample_indices(1000, 10)
    assert len(idx) == 10 and idx.min() >= 0 and idx.max() < 1000
    assert np.all(np.diff(idx) == 100)
    assert list(sample_indices(4, 10)) == [0, 1, 2, 3]
    assert len(sample_indices(0, 5)) == 0


def test_sample_frames_cover_the_whole_video(clip):
    frames = sample_frames(clip, 5)
    assert frames.shape == (5, 64, 96, 3)
    assert [_level(f) for f in frames] == [2, 6, 10, 14, 18]
    small = sample_frames(clip, 3, scale=0.5)
    assert small.shape == (3, 32, 48, 3)


def test_synchronised_iteration_stops_at_shortest(tmp_path, clip, caplog):
    short = write_video(tmp_path / "short.avi", walk_across(96, 64, 12).frames)
    steps = list(iter_synchronised({"a": clip, "b": short}))
    assert len(steps) == 12
    assert [i for i, _ in steps] == list(range(12))
    assert steps[3][1]["a"].shape == (64, 96, 3) and _level(steps[3][1]["a"]) == 3
    assert "different lengths" in caplog.text and "b ended" in caplog.text


def test_synchronised_iteration_skips_a_cameras_first_frames(clip):
    """offsets (session.yaml's skip_frames): step k holds frame k + offset of that camera's video, and
    the steps end with the video that runs out first after its skip."""
    steps = list(iter_synchronised({"a": clip, "b": clip}, offsets={"b": 3}))
    assert [(i, _level(f["a"]), _level(f["b"])) for i, f in steps] == [(k, k, k + 3) for k in range(17)]
    ranged = list(iter_synchronised({"a": clip, "b": clip}, 2, 6, offsets={"a": 1}))
    assert [(i, _level(f["a"]), _level(f["b"])) for i, f in ranged] == [(k, k + 1, k) for k in range(2, 6)]


def test_the_report_draws_a_skipped_cameras_frames_at_the_sessions_index(clip):
    """report.html's contact sheet reads frame k of the session from frame k + skip of the video."""
    from gaitcap.report.sheet import _session_frames

    frames = _session_frames(clip, [0, 4, 16, 18], 3)
    assert {k: _level(f) for k, f in frames.items()} == {0: 3, 4: 7, 16: 19}  # 18 + 3 is past the end


def test_missing_video(tmp_path):
    with pytest.raises(InputError, match="not found"):
        probe_video(tmp_path / "nope.mp4")


def test_corrupt_video(tmp_path):
    bad = tmp_path / "bad.mp4"
    bad.write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(InputError, match="bad.mp4"):
        probe_video(bad)


def test_zero_frame_video(tmp_path):
    import cv2

    empty = tmp_path / "empty.avi"
    w = cv2.VideoWriter(str(empty), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (64, 48))
    w.release()
    with pytest.raises(InputError, match="empty.avi"):
        probe_video(empty)


def test_truncated_video_reads_what_decodes(tmp_path, caplog):
    path = write_video(tmp_path / "cut.avi", walk_across(96, 64, 30).frames)
    data = path.read_bytes()
    cut = tmp_path / "cut_half.avi"
    cut.write_bytes(data[: len(data) // 2])
    with VideoReader(cut) as video:
        n = sum(1 for _ in video)
    assert 0 < n < 30
