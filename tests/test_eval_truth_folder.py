"""``gaitcap eval --truth DIR`` with a truth folder in the product's own formats (joints.csv,
events.csv, parameters.json, masks.h5), checked against direct numpy computations."""

from __future__ import annotations

import json
from dataclasses import replace

import h5py
import numpy as np
import pytest
from click.testing import CliRunner
from gait_walker import Walker
from quick_config import quick_tracking

from gaitcap.cli.main import cli
from gaitcap.errors import InputError
from gaitcap.io.gait_outputs import write_events_csv
from gaitcap.io.silhouettes_h5 import SilhouetteWriter
from gaitcap.io.trajectories_h5 import write_trajectory
from gaitcap.io.truth_folder import read_joints_csv, read_truth_folder
from gaitcap.pipeline import write_joints_csv
from gaitcap.trajectory import LOWER_LIMB

CAMERAS = ("cam01", "cam02")
SIZE = (24, 32)  # H, W of the tiny masks
STATED = {"overall": {"cadence_steps_per_min": 109.1, "speed_m_s": 1.2, "not_a_gaitcap_name": 3.0},
          "left": {"stride_length_m": 1.32, "stance_pct": 62.0}, "right": {"stride_length_m": 1.32},
          "counts": {"left": {"strides": 2}}}  # fmt: skip


def _masks(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, H, W) uint8 0/1: a box of random size per frame (frame 3 empty: nobody in view)."""
    m = np.zeros((n, *SIZE), np.uint8)
    for t in range(n):
        if t != 3:
            y, x = rng.integers(2, 8, 2)
            m[t, y : y + rng.integers(8, 14), x : x + rng.integers(6, 18)] = 1
    return m


@pytest.fixture
def case(tmp_path):
    """A truth folder (walker at 25 Hz + events + parameters + masks) and an OUT folder (the walk
    with seeded noise, masks with flipped pixels)."""
    rng = np.random.default_rng(7)
    walk = Walker(rate_hz=25.0, duration=3.0)
    truth = walk.trajectory().with_events(walk.truth_events())
    folder = tmp_path / "truth"
    folder.mkdir()
    write_joints_csv(folder / "joints.csv", truth)
    write_events_csv(folder / "events.csv", truth.events, truth)
    (folder / "parameters.json").write_text(json.dumps(STATED))
    true_masks = {cam: _masks(rng, truth.n_frames) for cam in CAMERAS}
    with h5py.File(folder / "masks.h5", "w") as f:
        for cam, m in true_masks.items():
            f.create_dataset(cam, data=m)
    out = tmp_path / "OUT"
    out.mkdir()
    est = truth.points + rng.normal(0.0, 0.01, truth.points.shape)
    write_trajectory(out / "trajectories.h5", replace(truth, points=est, events=(), meta={}))
    est_masks = {cam: m ^ (rng.random(m.shape) < 0.05).astype(np.uint8) for cam, m in true_masks.items()}
    with SilhouetteWriter(out / "silhouettes.h5") as w:
        quality = {"fraction": 0.0, "shadow_fraction": 0.0, "components": 1, "flags": 0, "bbox": (-1, -1, -1, -1)}
        for cam, m in est_masks.items():
            w.add_camera(cam, SIZE[1], SIZE[0], None, {})
            for frame in m:
                w.append(cam, frame, quality)
    return folder, out, est, true_masks, est_masks


def test_eval_with_a_truth_folder_agrees_with_numpy(case):
    folder, out, est, true_masks, est_masks = case
    res = CliRunner().invoke(cli, ["eval", str(out), "--truth", str(folder)])
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "eval.json").read_text())
    # lower-limb MPJPE straight from the CSV, read with numpy alone
    header = (folder / "joints.csv").read_text().splitlines()[0].split(",")
    table = np.genfromtxt(folder / "joints.csv", delimiter=",", skip_header=1)
    names = [h[:-2] for h in header[2::3]]
    ref = table[:, 2:].reshape(len(table), len(names), 3)
    idx = [names.index(n) for n in LOWER_LIMB]
    direct = 1000 * np.linalg.norm(est[:, idx] - ref[:, idx], axis=2).mean()
    assert doc["positions_mm"]["lower_limb"]["mpjpe_mm"] == pytest.approx(direct, rel=1e-4)
    assert 10 < direct < 20  # 1 cm per axis: about 16 mm in 3D
    # IoU per camera, frames whose true mask is empty left out
    for cam in CAMERAS:
        a, b = est_masks[cam].astype(bool), true_masks[cam].astype(bool)
        keep = b.any(axis=(1, 2))
        iou = (a & b).sum(axis=(1, 2))[keep] / (a | b).sum(axis=(1, 2))[keep]
        got = doc["silhouette_iou"][cam]
        assert got["n_frames"] == keep.sum() == len(keep) - 1 and got["frames_without_person"] == 1
        assert got["mean"] == pytest.approx(iou.mean()) and got["median"] == pytest.approx(np.median(iou))
        assert got["p10"] == pytest.approx(np.percentile(iou, 10))
        assert got["mean"] < 0.95
    assert "silhouette IoU" in res.output and "cam02" in res.output
    # events from events.csv; parameters against the stated ones (shared names only, per side too)
    assert doc["events"]["reference_events"] == "recorded in the reference"
    assert doc["events"]["n_reference"] == len(folder.joinpath("events.csv").read_text().splitlines()) - 1
    assert doc["events"]["n_matched"] >= 4
    params = doc["parameters"]
    assert params["reference_status"] == "stated in the truth's parameters.json"
    assert set(params["values"]) == {"cadence_steps_per_min", "speed_m_s"}
    cad = params["values"]["cadence_steps_per_min"]
    assert cad["reference"] == 109.1 and cad["diff"] == pytest.approx(cad["out"] - 109.1)
    assert set(params["sides"]["left"]) == {"stride_length_m", "stance_pct"} and set(params["sides"]["right"]) == {"stride_length_m"}
    assert params["sides"]["left"]["stride_length_m"]["out"] == pytest.approx(Walker().stride_length, abs=0.05)


def test_joints_csv_round_trip_and_rate(tmp_path):
    walk = Walker(rate_hz=25.0, duration=1.0).trajectory()
    write_joints_csv(tmp_path / "joints.csv", walk)
    back = read_joints_csv(tmp_path / "joints.csv")
    assert back.names == walk.names and back.rate_hz == pytest.approx(25.0)
    np.testing.assert_allclose(back.points, walk.points, atol=1e-6)  # NaN in the same places


def _cli_error(folder, out) -> str:
    res = CliRunner().invoke(cli, ["eval", str(out), "--truth", str(folder), "--force"])
    assert res.exit_code == 1, res.output
    return res.output


def test_bad_truth_folders_name_the_file(case, tmp_path):
    folder, out, *_ = case
    lines = (folder / "joints.csv").read_text().splitlines()
    (folder / "joints.csv").write_text("\n".join([lines[0].replace("knee_l_y", "knee_l_q"), *lines[1:]]) + "\n")
    assert "joints.csv: columns" in _cli_error(folder, out) and "knee_l_q" in _cli_error(folder, out)
    (folder / "joints.csv").write_text("\n".join([lines[0], *lines[1:-5]]) + "\n")  # 5 rows short of the masks
    assert "masks.h5: camera 'cam01' has 75 frames but joints.csv has 70 rows" in _cli_error(folder, out)
    (folder / "joints.csv").unlink()
    assert "joints.csv: missing" in _cli_error(folder, out)
    empty = tmp_path / "empty"
    empty.mkdir()
    assert "neither joints.csv" in _cli_error(empty, out)
    with pytest.raises(InputError, match="events.csv: line 2"):
        (folder / "joints.csv").write_text("\n".join(lines) + "\n")
        (folder / "events.csv").write_text("side,event,frame,time_s\nmiddle,foot_strike,3,0.12\n")
        read_truth_folder(folder)


def test_track_save_masks_streams_the_silhouettes(embedded_session, tmp_path):
    """``--save-masks``: silhouettes.h5 holds, per camera, the masks the cameras' joint extractor gives on each frame."""
    from gaitcap.io.silhouettes_h5 import read_cameras, read_masks
    from gaitcap.pipeline import run_track
    from gaitcap.io.calibration_toml import read_calibration
    from gaitcap.silhouette.config import SilhouetteConfig
    from gaitcap.silhouette.joint import JointExtractor
    from gaitcap.silhouette.run import Source, prepare_extractor
    from gaitcap.video import iter_synchronised

    config = quick_tracking(tmp_path)
    ses = embedded_session.session
    run_track(ses, tmp_path / "out", config=config, progress=False, max_frames=3, save_masks=True)
    h5 = tmp_path / "out" / "silhouettes.h5"
    cams = read_cameras(h5)
    assert len(cams) == 2
    rig = read_calibration(ses / "calibration.toml")
    extractors = [prepare_extractor(Source(cam, ses / "videos" / f"{cam}.mp4", ses / "background" / f"{cam}.png"),
                                    SilhouetteConfig.load())[0] for cam in cams]  # fmt: skip
    joint = JointExtractor(extractors, [rig[cam] for cam in cams])
    videos = {cam: ses / "videos" / f"{cam}.mp4" for cam in cams}
    expected = [joint.process([images[c] for c in cams]) for _, images in iter_synchronised(videos, 0, 3)]
    for k, cam in enumerate(cams):
        masks = read_masks(h5, cam)
        assert masks.shape == (3, 480, 640) and masks[0].any()
        np.testing.assert_array_equal(masks, np.stack([frame[k][0] for frame in expected]))
    # again into the same folder (a finished run there, --force): the frames decoded before the
    # output folder is prepared are held, not written into a temporary file that the preparation
    # removes as a killed run's leftover
    run_track(ses, tmp_path / "out", config=config, progress=False, max_frames=4, save_masks=True, force=True)
    assert read_masks(h5, cams[0]).shape == (4, 480, 640)
    assert not list((tmp_path / "out").glob(".*.part*"))
    # again without --save-masks: the older run's silhouettes go, eval must not score them as this run's;
    # its evaluation and gait report go too (read as this run's), anything else stays
    out = tmp_path / "out"
    (out / "gait").mkdir()
    for name in ("eval.json", "gait/report.html", "notes.txt"):
        (out / name).write_text("of the run before\n")
    run_track(ses, out, config=config, progress=False, max_frames=3, force=True)
    assert not h5.exists()
    assert not (out / "eval.json").exists() and not (out / "gait").exists()
    assert (out / "notes.txt").read_text() == "of the run before\n"


def test_track_stopped_half_way_over_an_earlier_run_leaves_none_of_its_outputs(embedded_session, tmp_path,
                                                                              monkeypatch):
    """``track -o OUT --force`` over a finished run, stopped while tracking (Ctrl-C, SIGTERM): none of the
    earlier run's outputs stay beside the new run's partial ones (``gaitcap report OUT`` read the earlier
    run's trajectories.h5, joints.csv/.trc stayed as if finished)."""
    import gaitcap.pipeline as pipeline_module
    from gaitcap.pipeline import run_track

    config = quick_tracking(tmp_path)
    out = tmp_path / "out"
    run_track(embedded_session.session, out, config=config, progress=False, max_frames=3, save_masks=True)
    (out / "eval.json").write_text("{}")
    (out / "notes.txt").write_text("the lab's own\n")
    outputs = ("track.json", "trajectories.h5", "joints.csv", "joints.trc", "silhouettes.h5", "eval.json")
    assert all((out / name).is_file() for name in outputs)

    def stopped(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(pipeline_module, "_track_session", stopped)
    for save_masks in (True, False):
        with pytest.raises(KeyboardInterrupt):
            run_track(embedded_session.session, out, config=config, progress=False, max_frames=3, force=True,
                      save_masks=save_masks)  # fmt: skip
        assert [name for name in outputs if (out / name).exists()] == []
        assert (out / "notes.txt").read_text() == "the lab's own\n"  # not an output of gaitcap's
    res = CliRunner().invoke(cli, ["report", str(out)])
    assert res.exit_code == 1 and "no trajectories.h5 in this folder" in res.output


def test_track_takes_a_silhouette_configuration(embedded_session, tmp_path):
    """``gaitcap track --silhouette-config``: the silhouettes a lab tuned with ``gaitcap silhouettes -c`` are the
    ones tracked (the run's silhouettes.h5 records the configuration it used)."""
    import h5py
    import yaml
    from click.testing import CliRunner

    from gaitcap.cli.main import cli
    from gaitcap.config import default_config_path

    tracking = quick_tracking(tmp_path)
    sil = yaml.safe_load(default_config_path("silhouette.yaml").read_text())
    sil["background"]["samples"] = 17
    mine = tmp_path / "silhouette.yaml"
    mine.write_text(yaml.safe_dump(sil))
    out = tmp_path / "out"
    res = CliRunner().invoke(cli, ["track", str(embedded_session.session), "-o", str(out), "-c", str(tracking),
                                   "--silhouette-config", str(mine), "--max-frames", "3", "--save-masks"])  # fmt: skip
    assert res.exit_code == 0, res.output
    with h5py.File(out / "silhouettes.h5", "r") as f:
        used = yaml.safe_load(f.attrs["config"])
    assert used["background"]["samples"] == 17
