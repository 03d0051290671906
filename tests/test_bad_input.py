"""Bad input, each with the message the user sees (the ``track`` command is tested by the lead;
here: Session.open, check_session_videos, gaitcap.video, configs, eval outputs, batch, writers)."""

from __future__ import annotations

import errno
import os
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from session_factory import make_session

from gaitcap.config import load_yaml_model
from gaitcap.errors import CalibrationError, ConfigError, InputError, OutputError
from gaitcap.gait.options import GaitOptions
from gaitcap.io.atomic import write_text_atomic
from gaitcap.io.trajectories_h5 import write_trajectory
from gaitcap.session import Session
from gaitcap.session_check import check_session_videos
from gaitcap.tracking.config import load_tracking_config
from gaitcap.trajectory import POINT_NAMES, Trajectory
from gaitcap.video import VideoReader


def message(excinfo: pytest.ExceptionInfo) -> str:
    return str(excinfo.value)


# ------------------------------------------------------------------------------- videos
def test_corrupt_video(tmp_path):
    root = make_session(tmp_path / "s")
    (root / "videos" / "cam1.avi").write_bytes(np.random.default_rng(0).integers(0, 256, 5000, dtype=np.uint8).tobytes())
    with pytest.raises(InputError) as e:
        check_session_videos(Session.open(root))
    assert message(e) == f"{root / 'videos' / 'cam1.avi'}: cannot open as a video (unreadable, corrupt or unsupported format)"


def test_truncated_video_reads_what_decodes_and_warns(tmp_path, caplog):
    root = make_session(tmp_path / "s", frames={"cam0": 30})
    video = root / "videos" / "cam0.avi"
    video.write_bytes(video.read_bytes()[: video.stat().st_size // 2])
    with VideoReader(video) as reader:
        n = sum(1 for _ in reader)
    assert 0 < n < 30
    assert f"{video}: decoding stopped at frame {n} of 30 declared (truncated or corrupt file?)" in caplog.text


def test_zero_frame_video(tmp_path):
    root = make_session(tmp_path / "s")
    path = root / "videos" / "cam1.avi"
    cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 25.0, (96, 64)).release()
    with pytest.raises(InputError) as e:
        check_session_videos(Session.open(root))
    assert message(e) == f"{path}: the video has no decodable frame (empty or corrupt)"


def test_frame_count_mismatch_is_a_warning_and_rate_mismatch_an_error(tmp_path, caplog):
    counts = check_session_videos(Session.open(make_session(tmp_path / "a", frames={"cam0": 20, "cam1": 17})))
    assert counts.n_frames == 17
    (record,) = [r for r in caplog.records if "different lengths" in r.getMessage()]
    assert record.levelname == "WARNING"
    assert record.getMessage() == "videos of different lengths (cam0 20, cam1 17 frames); using the 17 frames common to all cameras"
    with pytest.raises(InputError) as e:
        check_session_videos(Session.open(make_session(tmp_path / "b", fps={"cam1": 30.0})))
    assert message(e) == ("the cameras' frame rates differ: cam0 25 fps, cam1 30 fps; "
                          "re-encode the videos at one rate")  # fmt: skip


# -------------------------------------------------------------------- session folder
def test_camera_without_a_video(tmp_path):
    root = make_session(tmp_path / "s")
    (root / "videos" / "cam1.avi").rename(root / "videos" / "camera1.avi")
    with pytest.raises(InputError) as e:
        Session.open(root)
    assert message(e) == f"{root / 'videos'}: no video for camera 'cam1' from calibration.toml (files: cam0.avi, camera1.avi)"


def test_malformed_calibration_toml(tmp_path):
    root = make_session(tmp_path / "s")
    (root / "calibration.toml").write_text("[cam0]\nsize = [96, 64\n")
    with pytest.raises(CalibrationError) as e:
        Session.open(root)
    assert message(e) == f"{root / 'calibration.toml'}: not valid TOML: Unclosed array (at end of document)"


def test_calibration_missing_a_key(tmp_path):
    root = make_session(tmp_path / "s")
    toml = root / "calibration.toml"
    toml.write_text(toml.read_text().replace("matrix", "matrx"))
    with pytest.raises(CalibrationError) as e:
        Session.open(root)
    assert message(e) == f"{toml}: camera 'cam0': missing key 'matrix'"


@pytest.mark.parametrize(
    ("yaml_text", "expected"),
    [
        ("subjet: {height_m: 1.7}\n", "subjet: unknown key (did you mean 'subject'?)"),
        ("subject: {heigth_m: 1.7}\n", "subject.heigth_m: unknown key (did you mean 'height_m'?)"),
        ("subject: {height_m: tall}\n", "subject.height_m: Input should be a valid number, unable to parse string as a number"),
        ("subject: {height_m: 172}\n", "subject.height_m: Input should be less than 2.6"),
        ("subject: {height_m: true}\n", "subject.height_m: Value error, a number is expected, not a boolean (YAML "
                                        "reads true/false, yes/no, on/off as booleans)"),  # was a 1.0 m subject
    ],
)
def test_session_yaml_errors(tmp_path, yaml_text, expected):
    root = make_session(tmp_path / "s", session_yaml=yaml_text)
    with pytest.raises(ConfigError) as e:
        Session.open(root)
    assert message(e) == f"{root / 'session.yaml'}: {expected}"


def test_unknown_gait_option_suggests_the_key(tmp_path):
    path = tmp_path / "gait.yaml"
    path.write_text("lowpass_hz: 6\nmin_promincence: 0.3\nrefine: maybe\n")
    with pytest.raises(ConfigError) as e:
        load_yaml_model(GaitOptions, path)
    assert message(e).splitlines() == [
        f"{path}: refine: Input should be a valid boolean, unable to interpret input",
        f"{path}: min_promincence: unknown key (did you mean 'min_prominence'?)",
    ]


def test_a_key_given_twice_is_refused(tmp_path):
    """PyYAML keeps the last of two equal keys without a word: a key added to a file that already
    has it further down would be ignored. The loader names the key and both lines."""
    path = tmp_path / "tracking.yaml"
    path.write_text("seed: 1\nbackward:\n  stretch_frames: 5\n  restart: true\n  stretch_frames: 25\n")
    with pytest.raises(ConfigError) as e:
        load_tracking_config(path)
    assert message(e).startswith(f"{path}: not valid YAML: key 'stretch_frames' given twice (first on line 3)")
    assert "line 5" in message(e)


# ------------------------------------------------------------------------------ outputs
def small_trajectory() -> Trajectory:
    pts = np.random.default_rng(3).normal(0, 1, (5, len(POINT_NAMES), 3))
    return Trajectory(POINT_NAMES, pts, 25.0)


def test_output_under_a_file_is_refused(tmp_path):
    blocker = tmp_path / "results"
    blocker.write_text("a file, not a folder")
    with pytest.raises(OutputError) as e:
        write_trajectory(blocker / "OUT" / "trajectories.h5", small_trajectory())
    assert message(e) == f"{blocker}: is a file, not a folder: cannot write {blocker / 'OUT' / 'trajectories.h5'} under it"


def test_read_only_output_folder(read_only_dir):
    with pytest.raises(OutputError) as e:
        write_text_atomic(read_only_dir / "eval.json", "{}")
    assert message(e) == f"{read_only_dir / 'eval.json'}: cannot write here (Permission denied)"


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_disk_full_while_writing_text_leaves_the_old_file(tmp_path, monkeypatch):
    target = tmp_path / "eval.json"
    target.write_text('{"old": true}')
    real_write_text = Path.write_text

    def full(self: Path, data: str, *args, **kwargs) -> int:
        real_write_text(self, data[: len(data) // 2], *args, **kwargs)  # part written, then the disk is full
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(self))

    monkeypatch.setattr(Path, "write_text", full)
    with pytest.raises(OutputError) as e:
        write_text_atomic(target, '{"new": true, "padding": "' + "x" * 1000 + '"}')
    monkeypatch.undo()
    assert message(e) == f"{target}: write failed (No space left on device)"
    assert _leftovers(tmp_path) == ["eval.json"]
    assert target.read_text() == '{"old": true}'


def test_disk_full_while_writing_hdf5_leaves_no_partial_file(tmp_path, monkeypatch):
    real = h5py.Group.create_dataset

    def full(self, name, *args, **kwargs):
        if name == "times":  # /points is written, then the disk is full
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return real(self, name, *args, **kwargs)

    monkeypatch.setattr(h5py.Group, "create_dataset", full)
    out = tmp_path / "OUT"
    with pytest.raises(OutputError) as e:
        write_trajectory(out / "trajectories.h5", small_trajectory())
    assert message(e) == f"{out / 'trajectories.h5'}: write failed (No space left on device)"
    assert _leftovers(out) == []


def test_a_corrupt_video_is_named_without_ffmpegs_noise(tmp_path):
    """The command line's own message, not FFmpeg's and OpenCV's before it."""
    import subprocess
    import sys

    root = make_session(tmp_path / "s")
    whole = tmp_path / "whole.mp4"
    writer = cv2.VideoWriter(str(whole), cv2.VideoWriter_fourcc(*"mp4v"), 25.0, (64, 48))
    for _ in range(10):
        writer.write(np.zeros((48, 64, 3), np.uint8))
    writer.release()
    (root / "videos" / "cam1.avi").unlink()
    (root / "videos" / "cam1.mp4").write_bytes(whole.read_bytes()[:600])  # the header cut: no 'moov' box
    env = {k: v for k, v in os.environ.items() if not k.startswith("OPENCV_")}
    res = subprocess.run([sys.executable, "-m", "gaitcap", "-q", "track", str(root), "-o", str(tmp_path / "out")],
                         capture_output=True, text=True, env=env, timeout=120)  # fmt: skip
    assert res.returncode == 1, res.stderr
    assert "cam1.mp4: cannot open as a video" in res.stderr
    assert "moov" not in res.stderr and "WARN" not in res.stderr, res.stderr


def test_a_negative_seed_is_refused_before_the_run(tmp_path):
    """Found with ``seed: -3`` in a copy of tracking.yaml, and ``--seed -1`` on track and synth: numpy's
    seed sequences take no negative number, so the run ended in a traceback after reading the videos."""
    from click.testing import CliRunner

    from gaitcap.cli.main import cli
    from gaitcap.config import default_config_path

    path = tmp_path / "tracking.yaml"
    path.write_text(default_config_path("tracking.yaml").read_text().replace("\nseed: 0 ", "\nseed: -3 "))
    with pytest.raises(ConfigError) as e:
        load_tracking_config(path)
    assert message(e) == f"{path}: seed: Input should be greater than or equal to 0"
    for command in (["track", str(tmp_path), "-o", str(tmp_path / "out")], ["synth", "-o", str(tmp_path / "out")]):
        result = CliRunner().invoke(cli, [*command, "--seed", "-1"])
        assert result.exit_code == 2 and "Invalid value for '--seed': -1 is not in the range x>=0" in result.output
    assert not (tmp_path / "out").exists()


def test_a_yaml_file_not_in_utf8_is_named(tmp_path):
    """Found with a session.yaml saved in Latin-1 (``notes: "café"``): every command that read it ended in
    a UnicodeDecodeError traceback."""
    root = make_session(tmp_path / "s")
    (root / "session.yaml").write_bytes('subject: {height_m: 1.7}\nnotes: "caf\u00e9"\n'.encode("latin-1"))
    with pytest.raises(ConfigError) as e:
        Session.open(root)
    assert message(e) == f"{root / 'session.yaml'}: line 2: not UTF-8 text (byte 0xe9); save the file as UTF-8"


def test_a_yaml_syntax_error_is_one_line_with_its_line_number(tmp_path):
    """Found with a session.yaml whose ``notes`` line lost an indent: PyYAML's message spanned four lines
    and gave the line against ``"<unicode string>"``, not the file; now one line, after the file's name."""
    root = make_session(tmp_path / "s", session_yaml="subject:\n  height_m: 1.7\n notes: x\n")
    with pytest.raises(ConfigError) as e:
        Session.open(root)
    assert message(e) == (f"{root / 'session.yaml'}: not valid YAML: did not find expected key at line 3, column 2 "
                          "(while parsing a block mapping at line 1)")  # fmt: skip


def test_a_rotation_matrix_in_calibration_toml_is_named_as_such(tmp_path):
    """Found by writing a camera's rotation as its 3x3 matrix (as other tools export it): the message said
    'rotation and translation must be 3 finite numbers', though both were finite; now it says what the file
    takes instead."""
    import tomllib

    import tomli_w

    root = make_session(tmp_path / "s")
    toml = root / "calibration.toml"
    data = tomllib.loads(toml.read_text())
    data["cam1"]["rotation"] = cv2.Rodrigues(np.asarray(data["cam1"]["rotation"]))[0].tolist()
    toml.write_text(tomli_w.dumps(data))
    with pytest.raises(CalibrationError) as e:
        Session.open(root)
    assert message(e) == (f"{toml}: camera 'cam1': rotation is a 3x3 matrix; calibration.toml takes the Rodrigues "
                          "vector [rx, ry, rz] (radians, world -> camera): convert it with cv2.Rodrigues")  # fmt: skip


def test_two_cameras_of_one_name_in_calibration_toml_name_the_file_and_tables(tmp_path):
    """Found by giving a session's second table the first one's ``name``: the error said 'duplicate camera
    names: cam0', without the file or the tables."""
    root = make_session(tmp_path / "s")
    toml = root / "calibration.toml"
    toml.write_text(toml.read_text().replace('name = "cam1"', 'name = "cam0"'))
    with pytest.raises(CalibrationError) as e:
        Session.open(root)
    assert message(e) == (f"{toml}: the tables [cam0], [cam1] give the same camera name 'cam0': each camera needs its "
                          "own (its video's name)")  # fmt: skip


def test_an_output_folder_that_is_a_file_is_named_before_the_work(tmp_path):
    """Found with ``gaitcap silhouettes SESSION -o FILE`` and ``gaitcap report OUT -o FILE``: the error came
    after the backgrounds were fitted (or the gait analysed) and said 'FILE/silhouettes_quality.csv: cannot
    write here (File exists)', of a file that did not exist; now it names the file in the way, and
    silhouettes says so before reading the videos."""
    from gaitcap.silhouette.run import run_silhouettes, sources_from_session

    blocker = tmp_path / "results"
    blocker.write_text("a file, not a folder")
    with pytest.raises(OutputError) as e:
        write_text_atomic(blocker / "events.csv", "")
    assert message(e) == f"{blocker}: is a file, not a folder: cannot write {blocker / 'events.csv'} under it"
    sources = sources_from_session(make_session(tmp_path / "s"))
    sources[0] = sources[0].__class__(sources[0].camera, tmp_path / "missing.avi", None, sources[0].calibration)
    for out in (blocker, blocker / "sub"):  # refused before the (here missing) video is opened
        with pytest.raises(OutputError) as e:
            run_silhouettes(sources, out)
        assert message(e).startswith(f"{blocker}: is a file, not a folder; give an output folder")


def test_an_infinite_or_nan_number_in_a_config_is_refused_naming_the_key(tmp_path):
    """YAML's .inf and .nan passed every bound of the schemas (beta: .inf tracked on, verdict doubtful)."""
    import yaml

    from gaitcap.config import default_config_path
    from gaitcap.errors import ConfigError
    from gaitcap.tracking.config import load_tracking_config

    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    for key, value in (("beta", ".inf"), ("beta", ".nan")):
        text = yaml.safe_dump({**data, key: 1.0}).replace(f"{key}: 1.0", f"{key}: {value}")
        path = tmp_path / "t.yaml"
        path.write_text(text)
        with pytest.raises(ConfigError, match=rf"t\.yaml: {key}: .*finite"):
            load_tracking_config(path)


def test_a_boolean_where_a_config_expects_a_number_is_refused_naming_the_key(tmp_path):
    """Pydantic's lax mode read YAML's true/false (yes/no, on/off) as 1 and 0: ``beta: yes`` tracked with
    beta 1, ``seed: true`` with seed 1, ``height_m: true`` in session.yaml as a 1.0 m subject."""
    import yaml

    from gaitcap.config import default_config_path
    from gaitcap.errors import ConfigError
    from gaitcap.tracking.config import load_tracking_config

    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    for key, value in (("beta", "yes"), ("seed", "true"), ("threads", "off")):
        text = yaml.safe_dump({**data, key: 12345}).replace(f"{key}: 12345", f"{key}: {value}")
        path = tmp_path / "t.yaml"
        path.write_text(text)
        with pytest.raises(ConfigError, match=rf"t\.yaml: {key}: Value error, a number is expected, not a boolean"):
            load_tracking_config(path)
    path.write_text(yaml.safe_dump({**data, "soft_silhouettes": True}))  # a boolean where one is expected
    assert load_tracking_config(path).soft_silhouettes is True


def test_a_disk_about_to_be_full_stops_the_stream_before_hdf5_fails(tmp_path, monkeypatch):
    """On a full disk the HDF5 library cannot close a file cleanly (a 300 kB tmpfs: 'gaitcap silhouettes'
    crashed with a segmentation fault, exit 139, after screens of h5py tracebacks). The writers stop while
    32 MB are still free, with one error naming the folder, and leave no file under the final name."""
    import shutil
    from collections import namedtuple

    import numpy as np

    from gaitcap.errors import OutputError
    from gaitcap.io import atomic
    from gaitcap.io.silhouettes_h5 import _QUALITY, SilhouetteWriter

    usage = namedtuple("usage", "total used free")
    real = shutil.disk_usage
    free = {"bytes": 10**9}
    monkeypatch.setattr(atomic.shutil, "disk_usage", lambda p: usage(*real(p)[:2], free["bytes"]))
    target = tmp_path / "out" / "silhouettes.h5"
    target.parent.mkdir()
    with pytest.raises(OutputError, match=r"out: 20\.0 MB free on its disk, under the 32 MB a run keeps"):
        with SilhouetteWriter(target) as w:
            w.add_camera("c", 64, 48, None, {})
            for t in range(10):
                if t == 5:
                    free["bytes"] = 20_000_000  # the disk fills while the run writes
                w.append("c", np.zeros((48, 64), np.uint8), {k: 0 for k in _QUALITY})
    assert list(target.parent.iterdir()) == []
    with pytest.raises(OutputError, match=r"new/deeper: 20\.0 MB free"):  # before the work, of a folder not made yet
        atomic.check_free_space(tmp_path / "new" / "deeper")


def test_calibration_metadata_of_a_missing_or_malformed_file_is_a_calibration_error(tmp_path):
    """read_calibration_metadata (public, beside read_calibration) raised FileNotFoundError and tomllib's
    TOMLDecodeError where read_calibration names the file in a CalibrationError."""
    from gaitcap.io.calibration_toml import read_calibration_metadata

    with pytest.raises(CalibrationError, match=r"none\.toml: calibration file not found"):
        read_calibration_metadata(tmp_path / "none.toml")
    (tmp_path / "bad.toml").write_text("[cam1\n")
    with pytest.raises(CalibrationError, match=r"bad\.toml: not valid TOML"):
        read_calibration_metadata(tmp_path / "bad.toml")


def test_mask_attributes_of_a_camera_not_in_the_file_name_the_cameras_it_has(tmp_path):
    """read_mask_attrs raised h5py's KeyError for a camera the file does not hold, where read_masks and
    read_quality name the file and the camera."""
    from gaitcap.io.silhouettes_h5 import SilhouetteWriter, read_mask_attrs

    path = tmp_path / "silhouettes.h5"
    with SilhouetteWriter(path) as w:
        w.add_camera("cam1", 8, 6, None, {"fps": 25.0})
    assert read_mask_attrs(path, "cam1") == {"fps": 25.0}
    with pytest.raises(InputError, match=r"silhouettes\.h5: no masks for camera 'cam2' \(have: cam1\)"):
        read_mask_attrs(path, "cam2")


def test_a_config_value_refused_on_assignment_is_a_config_error_naming_the_key():
    """A configuration loaded and edited from Python (``cfg.smoothing.cutoff_hz = -1``) raised pydantic's
    ValidationError, not a GaitcapError; the value is still refused and the old one kept, and the
    message names the schema and the key, with a suggestion for a misspelt one."""
    cfg = load_tracking_config()
    with pytest.raises(ConfigError, match=r"^SmoothingConfig: cutoff_hz: Input should be greater than 0$"):
        cfg.smoothing.cutoff_hz = -1
    assert cfg.smoothing.cutoff_hz == 4.5
    with pytest.raises(ConfigError, match=r"SmoothingConfig: cutof_hz: unknown key \(did you mean 'cutoff_hz'\?\)"):
        cfg.smoothing.cutof_hz = 3
    with pytest.raises(ConfigError, match="GaitOptions: lowpass_hz: Input should be greater than or equal to 0"):
        GaitOptions().lowpass_hz = -1.0
    cfg.smoothing.cutoff_hz = 6.0  # a value it takes is set as before
    assert cfg.smoothing.cutoff_hz == 6.0
