"""The varied validation suite: accuracy as a distribution over people, clothes, rooms and cameras.

Builds N synthetic sessions (default 24) with ``gaitcap synth`` from the real walks the project has
(the embedded Plug-in-Gait walk, the shared OpenSim walk and the C3D.ORG Plug-in-Gait sample when
gaitcap can read it), each walked by a subject of another height (1.0-1.95 m) and drawn with its own
seed (person, clothes, room, light, cameras: ``gaitcap.synth.variety``), 2 cameras mostly, 3 or 4 in
some; adds the independent external sessions (``../shared/data/external_sessions``), tracks every
one with ``gaitcap track`` (default configuration), evaluates it with ``gaitcap eval`` against its
truth, measures the silhouettes' IoU against the true masks (``gaitcap silhouettes``), and prints
for each metric the median, the 90th percentile and the worst case, then a breakdown by condition.

Deterministic for a given seed list (the renderer and the tracker are seeded). Sessions are kept in
``--work`` and re-used when they exist, so a second run only re-tracks.

    python scripts/bench_suite.py                      # 24 + 6 sessions, about 30-40 min on 2 cores
    python scripts/bench_suite.py --sessions 6 --no-external   # a quick look
    python scripts/bench_suite.py --only-external
    python scripts/bench_suite.py --work DIR --true-masks   # each session tracked from its true masks
    python scripts/bench_suite.py --work DIR --first 24 --sessions 48 --no-external   # 24 held-out sessions

    python scripts/bench_suite.py --work DIR2 --body-from DIR   # each session with its body from DIR's run
    python scripts/bench_suite.py --work DIR2 --only-external --body DIR/runs/ext_ktk_a   # one subject's body

``--first 24 --sessions 48`` draws sessions 24-47 instead (the same generator, other seeds: other people,
clothes, rooms and cameras): a held-out draw that no setting of the project was chosen on, where the
first 24 have been looked at for every change since they were drawn (docs/validation.md, "A held-out
draw").

``--body-from`` / ``--body`` track with an earlier run's body (``gaitcap track --body``: no shape
calibration): with ``--body-from`` each session's own calibrated body (what the calibration's stages
cost, and what tracking a known body gives), with ``--body`` one body for every session (sessions of one
subject, such as the external ones: a body calibrated on one trial used on the others).

``--true-masks`` tracks, instead of each session, a copy whose videos are its true masks drawn white on
black with black plates (built once under ``WORK/true_sessions``): what the tracker makes of perfect
silhouettes. Beside a run on the sessions themselves, it splits each session's error into what its
masks cost and what the tracker does with the right ones.

Per-session rows are written to ``WORK/suite.csv`` and ``WORK/suite.json`` (read by bench_uncertainty.py,
bench_smoothing.py and feet_contrast.py); with ``--silhouettes-only`` to ``WORK/suite_silhouettes.csv`` and
``.json`` instead, so that the tracked runs' rows in the same WORK stay. A run that would replace an earlier
run's results it does not redo is refused before any work, naming them (``--replace`` replaces them): a
WORK whose suite.json holds sessions this run leaves out (``--only`` into a full run's WORK), or runs on
the other videos (``--true-masks`` into a WORK of runs on the sessions' own videos, or the reverse).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

import cv2
import h5py
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "src"))

from gaitcap.body.model import load_body_model  # noqa: E402
from gaitcap.data import embedded_walk  # noqa: E402
from gaitcap.evaluation.report import read_truth_reference  # noqa: E402
from gaitcap.evaluation.silhouettes import camera_iou, part_coverage  # noqa: E402
from gaitcap.io.calibration_toml import read_calibration  # noqa: E402
from gaitcap.io.silhouettes_h5 import read_cameras, read_mask_shape, read_masks  # noqa: E402
from gaitcap.io.track_h5 import read_track_record
from gaitcap.track_summary import TRACK_JSON, is_finished  # noqa: E402
from gaitcap.io.video_write import AtomicVideoWriter  # noqa: E402
from gaitcap.session import BACKGROUND_DIR, CALIBRATION_FILE, SESSION_FILE, VIDEOS_DIR, Session  # noqa: E402
from gaitcap.synth.variety import draw_look  # noqa: E402
from gaitcap.tracking.shape import lowest_points  # noqa: E402
from gaitcap.video import probe_video  # noqa: E402

SHARED = ROOT.parent / "shared" / "data"
WALKS = {
    "vicon": lambda: embedded_walk(),
    "opensim": lambda: SHARED / "walking" / "opensim_gait2354_subject01" / "subject01_walk1.trc",
    "c3dorg": lambda: SHARED / "walking" / "c3d_org_sample03" / "gait-pig.c3d",
}
#: subject heights, cycled through the sessions (children to tall adults)
HEIGHTS = (1.05, 1.72, 1.38, 1.95, 1.60, 1.22, 1.85, 1.48, 1.66, 1.12, 1.78, 1.30)
#: camera counts, cycled (mostly 2)
CAMERAS = (2, 2, 2, 4, 2, 2, 3, 2)
METRICS = (
    ("lower_mm", "lower-limb MPJPE (mm)"),
    ("lower_offset_free_mm", "lower-limb MPJPE, each joint's constant offset removed (mm)"),
    ("knee_deg", "knee flexion RMSE (deg)"),
    ("ankle_deg", "ankle dorsiflexion RMSE (deg)"),
    ("swap_frames", "frames with swapped legs"), ("longest_swap", "longest swap (frames)"),
    ("iou", "silhouette IoU (mean)"), ("iou_p10", "silhouette IoU (10th pct of frames)"),
    ("parts_missing", "camera-frames missing the head or a foot"),
    ("event_ms", "event timing abs. error (ms)"), ("events_missed", "events missed"),
    ("cadence_pct", "cadence abs. error (%)"), ("stride_pct", "stride length abs. error (%)"), ("seconds", "seconds per session"),
)  # fmt: skip
HIGHER_IS_BETTER = {"iou", "iou_p10"}
#: the points whose systematic error (eval.json's bias_mm: mean signed error in the walking frame) is tabled
BIAS_POINTS = ("hip_", "knee_", "ankle_", "heel_", "toe_")


def gaitcap(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "gaitcap", "-q", *args]
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src")}
    return subprocess.run(cmd, check=check, capture_output=True, text=True, env=env)


def plan(n: int, walks: list[str]) -> list[dict]:
    """The suite's own sessions: walk, seed, subject height and cameras of each."""
    return [{"name": f"s{i:02d}_{walks[i % len(walks)]}", "walk": walks[i % len(walks)], "seed": i,
             "height": HEIGHTS[i % len(HEIGHTS)], "cameras": CAMERAS[i % len(CAMERAS)]} for i in range(n)]  # fmt: skip


def unreadable(walk: str) -> str | None:
    """Why gaitcap cannot read ``walk`` here (missing file, unknown marker set), or None."""
    from gaitcap.markers.motion import read_motion

    try:
        read_motion(WALKS[walk]())
    except Exception as e:  # noqa: BLE001 - such a walk's sessions are reported as skipped, with the reason
        return str(e).splitlines()[0][:160]
    return None


def pooled_iou(est_file: Path, truth_masks: Path) -> tuple[float, float, dict[str, float]]:
    """Mean IoU over cameras and frames, its 10th percentile over frames, and the mean per camera
    (frames whose true mask is empty are not scored)."""
    per_cam, frames = {}, []
    truth_cams = read_cameras(truth_masks)
    for cam in (c for c in read_cameras(est_file) if c in truth_cams):
        n = min(read_mask_shape(est_file, cam)[0], read_mask_shape(truth_masks, cam)[0])
        iou = camera_iou(est_file, truth_masks, cam, n)
        iou = iou[np.isfinite(iou)]
        per_cam[cam] = float(iou.mean()) if len(iou) else math.nan
        frames.append(iou)
    pooled = np.concatenate(frames) if frames else np.empty(0)
    if not len(pooled):
        return math.nan, math.nan, per_cam
    return float(pooled.mean()), float(np.percentile(pooled, 10)), per_cam


def longest_run(runs: list) -> int:
    return max((int(r[1]) - int(r[0]) + 1 for r in runs), default=0) if runs else 0


def measure(session: Path, truth: Path, truth_masks: Path, run: Path, reuse: bool = False,
            silhouettes_only: bool = False, config: Path | None = None, re_eval: bool = False,
            body: Path | None = None, true_masks: bool = False, sil_config: Path | None = None) -> dict:  # fmt: skip
    """Track, evaluate and score one session (``reuse``: the row of an earlier run, if it finished
    and tracked the same videos, ``true_masks`` or not; with ``re_eval`` its tracking scored again by
    the current ``gaitcap eval``; ``body``: an earlier run's output whose body is tracked, ``gaitcap
    track --body``; ``sil_config``: the silhouette.yaml of the run, ``gaitcap track --silhouette-config``)."""
    row_file = run / ROW_FILE
    if reuse and row_file.exists() and not silhouettes_only and _row_kind(row_file) == true_masks:
        row = json.loads(row_file.read_text())
        if re_eval and not str(row.get("status", "")).startswith("track failed"):  # scored by the current eval
            row.update(evaluate_run(run, truth))
            row_file.write_text(json.dumps(row, default=str))
        return row
    row = _measure(session, truth, truth_masks, run, silhouettes_only, config, body, sil_config) | {"true_masks": true_masks}
    if silhouettes_only:
        return row
    run.mkdir(parents=True, exist_ok=True)
    row_file.write_text(json.dumps(row, default=str))
    return row


#: each run's row, in its folder (``--reuse`` reads it)
ROW_FILE = "suite_row.json"


def _row_kind(path: Path) -> bool | None:
    """Whether the row (or, for a list, the rows) in ``path`` came from a ``--true-masks`` run (rows
    written before rows recorded it came from the sessions' own videos); None for a file that cannot be
    read or rows of both kinds."""
    try:
        rows = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    kinds = {bool(r.get("true_masks")) for r in (rows if isinstance(rows, list) else [rows]) if isinstance(r, dict)}
    return kinds.pop() if len(kinds) == 1 else None


def _kind(true_masks: bool) -> str:
    return "the sessions' true masks (--true-masks)" if true_masks else "the sessions' own videos"


def replaces_other_run(work: Path, stem: str, names: list[str], true_masks: bool, silhouettes_only: bool) -> str | None:
    """Why writing this run (the sessions ``names``, ``true_masks`` or not) into ``work`` would silently
    replace an earlier run's results that it does not redo: ``work/<stem>.json`` holds rows of sessions
    this run leaves out (a full suite, replaced by the rows of ``--only``), or of the other videos
    (``--true-masks`` or not: its runs under ``work/runs`` too); None when it would not."""
    table = work / f"{stem}.json"
    hint = "give another --work (or --replace to replace them)"
    if table.is_file():
        try:
            rows = json.loads(table.read_text())
            earlier = [r["name"] for r in rows]
        except (OSError, ValueError, TypeError, KeyError):
            return f"{table}: not an earlier run's table, not replaced: {hint}"
        left_out = [n for n in earlier if n not in names]
        if left_out:
            listed = " ".join(left_out[:6]) + (" ..." if len(left_out) > 6 else "")
            return (f"{table}: holds the rows of {len(earlier)} sessions, {len(left_out)} of which this run leaves out "
                    f"({listed}): this run would replace them by its {len(names)}; {hint}")  # fmt: skip
        kind = _row_kind(table)
        if kind is not None and kind != true_masks and not silhouettes_only:
            return f"{table}: holds a run on {_kind(kind)}: this run, on {_kind(true_masks)}, would replace it; {hint}"
    if silhouettes_only:
        return None
    other = [n for n in names if (work / "runs" / n / ROW_FILE).is_file()
             and _row_kind(work / "runs" / n / ROW_FILE) == (not true_masks)]  # fmt: skip
    if other:
        return (f"{work / 'runs'}: holds the runs of {len(other)} of these sessions ({' '.join(other[:6])}) on "
                f"{_kind(not true_masks)}: this run, on {_kind(true_masks)}, would replace them; {hint}")
    return None


#: a body part is missing from a frame when the run's mask holds less than this fraction of its
#: true silhouette (gaitcap.evaluation.silhouettes.part_coverage)
PART_MISSING = 0.5


def missing_parts(masks: Path, truth_masks: Path, session: Path, truth: Path) -> dict:
    """Camera-frames in which the run's masks miss the head or a foot that the true masks show:
    the count, and per part its count and the frames (``camera:frame``)."""
    rig = read_calibration(session / "calibration.toml")
    traj = read_truth_reference(truth).trajectory
    truth_cams = read_cameras(truth_masks)
    by_part: dict[str, list[str]] = {}
    frames: set[tuple[str, int]] = set()
    for cam in (c for c in read_cameras(masks) if c in truth_cams and c in rig.names):
        n = min(read_mask_shape(masks, cam)[0], read_mask_shape(truth_masks, cam)[0])
        for part, cover in part_coverage(masks, truth_masks, rig[cam], traj, n).items():
            lost = np.flatnonzero(cover < PART_MISSING)  # NaN (out of view) compares False
            by_part.setdefault(part, []).extend(f"{cam}:{k}" for k in lost)
            frames.update((cam, int(k)) for k in lost)
    return {"parts_missing": len(frames), "parts_missing_by_part": by_part}


def silhouette_row(masks: Path, truth_masks: Path, session: Path, truth: Path) -> dict:
    """IoU of a run's ``silhouettes.h5`` against the true masks (mean, 10th percentile of frames, per
    camera) and the camera-frames missing the head or a foot (:func:`missing_parts`)."""
    if not masks.exists():
        return {}
    iou, p10, per_cam = pooled_iou(masks, truth_masks)
    return {"iou": iou, "iou_p10": p10, "iou_per_camera": per_cam, **missing_parts(masks, truth_masks, session, truth)}


def _measure(session: Path, truth: Path, truth_masks: Path, run: Path,
             silhouettes_only: bool = False, config: Path | None = None, body: Path | None = None,
             sil_config: Path | None = None) -> dict:  # fmt: skip
    if silhouettes_only:
        gaitcap("silhouettes", str(session), "-o", str(run), "--force", *(["-c", str(sil_config)] if sil_config else []),
                check=False)
        return {"status": "silhouettes only", **silhouette_row(run / "silhouettes.h5", truth_masks, session, truth)}
    t0, started = time.perf_counter(), time.time()
    extra = (["-c", str(config)] if config else []) + (["--body", str(body)] if body else [])
    extra += ["--silhouette-config", str(sil_config)] if sil_config else []
    tr = gaitcap("track", str(session), "-o", str(run), "--force", "--save-masks", *extra, check=False)
    row: dict = {"seconds": time.perf_counter() - t0, "status": "ok"}
    # a run judged failed exits 1 too, but is written: scored; one that wrote nothing leaves the earlier run's
    # outputs in the folder, not scored
    written = is_finished(run) and (run / TRACK_JSON).stat().st_mtime >= started - 1
    row.update(silhouette_row(run / "silhouettes.h5", truth_masks, session, truth) if written else {})
    if tr.returncode != 0 and not written:
        row["status"] = f"track failed (exit {tr.returncode}): " + ((tr.stderr or tr.stdout).strip().splitlines() or [""])[-1]
        return row
    row.update(evaluate_run(run, truth))
    return row


def true_mask_session(session: Path, truth_masks: Path, out: Path) -> Path:
    """``out``, a copy of ``session`` whose videos are the true masks of ``truth_masks`` (a truth or
    silhouettes HDF5 file) drawn white on black at the session's frame rate, with black plates; built
    once (a temporary folder, then renamed), re-used afterwards."""
    if (out / CALIBRATION_FILE).exists():
        return out
    tmp = out.with_name(out.name + ".tmp")
    shutil.rmtree(tmp, ignore_errors=True)
    (tmp / VIDEOS_DIR).mkdir(parents=True)
    (tmp / BACKGROUND_DIR).mkdir()
    for name in (CALIBRATION_FILE, SESSION_FILE):
        if (session / name).exists():
            shutil.copy(session / name, tmp / name)
    videos = Session.open(session).videos
    for cam in read_cameras(truth_masks):
        masks = read_masks(truth_masks, cam)
        h, w = masks.shape[1:]
        with AtomicVideoWriter(tmp / VIDEOS_DIR / f"{cam}.mp4", probe_video(videos[cam]).fps, (w, h)) as writer:
            for mask in masks:
                writer.write(cv2.cvtColor(np.where(mask > 0, 255, 0).astype(np.uint8), cv2.COLOR_GRAY2BGR))
        cv2.imwrite(str(tmp / BACKGROUND_DIR / f"{cam}.png"), np.zeros((h, w, 3), np.uint8))
    tmp.rename(out)
    return out


def sole_height_mm(run: Path) -> float | None:
    """Median over the tracked frames of the height of the tracked body's lowest capsule surface (its
    soles) above the floor (z = 0), mm: one foot stands on the floor in every frame of a walk."""
    record = read_track_record(run / "trajectories.h5")
    proportions = record.proportions() if record is not None else None
    if proportions is None:  # a run that did not record its body's proportions
        return None
    scales, shifts = proportions
    model = load_body_model(height_m=float(record.attrs["height_m"]), scales=scales, shifts=shifts)
    poses = record.poses[np.all(np.isfinite(record.poses), axis=1)]
    return float(1000 * np.median(lowest_points(model, poses))) if len(poses) else None


def evaluate_run(run: Path, truth: Path) -> dict:
    """``gaitcap eval`` of a finished run against its truth: the suite's metrics, or the status
    ``lost: ...`` when eval fails or compares no frame (every frame flagged)."""
    ev = gaitcap("eval", str(run), "--truth", str(truth), "-o", str(run / "eval.json"), "--force", check=False)
    if ev.returncode != 0:
        return {"status": "lost: " + ((ev.stderr or ev.stdout).strip().splitlines() or [""])[-1].removeprefix("Error: ")}
    d = json.loads((run / "eval.json").read_text())
    if not d["frames"]["compared"]:  # every frame of the run flagged: nothing compared
        return {"status": "lost: " + next((n for n in d["notes"] if "no tracked frame" in n), "no frame compared")}
    lower = (d["positions_mm"].get("lower_limb") or {}).get("mpjpe_mm")
    lower_offset_free = (d["positions_mm"].get("lower_limb") or {}).get("offset_free_mpjpe_mm")
    knees = [d["angles_rmse_deg"].get(k) for k in ("knee_flexion_l", "knee_flexion_r")]
    knees = [k for k in knees if k is not None]
    ankles = [d["angles_rmse_deg"].get(k) for k in ("ankle_dorsiflexion_l", "ankle_dorsiflexion_r")]
    ankles = [a for a in ankles if a is not None]
    swaps = d.get("left_right_swaps") or {}
    events = d.get("events") or {}
    params = (d.get("parameters") or {}).get("values") or {}
    sides = (d.get("parameters") or {}).get("sides") or {}

    def pct(name: str) -> float | None:
        """|difference| % of a parameter: the overall value, else the mean over the sides (a truth
        may state stride length per side only, as the external sessions' parameters.json do)."""
        v = params.get(name) or {}
        if v.get("diff_pct") is not None:
            return abs(v["diff_pct"])
        per_side = [abs(s[name]["diff_pct"]) for s in sides.values() if (s.get(name) or {}).get("diff_pct") is not None]
        return float(np.mean(per_side)) if per_side else None

    return dict(
        lower_mm=lower, lower_offset_free_mm=lower_offset_free, knee_deg=float(np.mean(knees)) if knees else None,
        ankle_deg=float(np.mean(ankles)) if ankles else None, swap_frames=swaps.get("n_frames"),
        longest_swap=longest_run(swaps.get("runs") or []), event_ms=events.get("mean_abs_ms"),
        events_missed=events.get("n_missed"), cadence_pct=pct("cadence_steps_per_min"), stride_pct=pct("stride_length_m"),
        flagged=d["frames"]["flagged"], frames=d["frames"]["total"],
        bias_mm={k: v for k, v in (d.get("bias_mm") or {}).items() if k.startswith(BIAS_POINTS)},
        lengths=d.get("segment_lengths") or {}, sole_mm=sole_height_mm(run),
    )  # fmt: skip


def own_sessions(args: argparse.Namespace) -> list[dict]:
    why = {w: unreadable(w) for w in WALKS}
    for w, reason in why.items():
        if reason:
            print(f"# sessions of the {w} walk skipped: {reason}", file=sys.stderr)
    rows = []
    for p in plan(args.sessions, list(WALKS))[args.first :]:
        if why[p["walk"]] or (args.only and p["name"] not in args.only):  # --only: the others are not drawn
            continue
        session = args.work / "sessions" / p["name"]
        if not (session / "truth.h5").exists():
            gaitcap("synth", str(WALKS[p["walk"]]()), "-o", str(session), "--seed", str(p["seed"]),
                    "--cameras", str(p["cameras"]), "--subject-height", str(p["height"]), "--force")  # fmt: skip
        with h5py.File(session / "truth.h5", "r") as f:
            height = float(f.attrs["height_m"])
        cond = draw_look(p["seed"], height, p["cameras"]).describe()
        rows.append({**p, "source": "suite", "session": session, "truth": session / "truth.h5",
                     "masks": session / "truth.h5", "conditions": cond})  # fmt: skip
    return rows


def external_dirs() -> list[Path]:
    """The external sessions' folders (those with a truth), sorted; none without the shared data."""
    return sorted(p for p in (SHARED / "external_sessions").glob("*") if (p / "truth").is_dir())


def external_sessions() -> list[dict]:
    base = SHARED / "external_sessions"
    rows = []
    readme = (base / "README.md").read_text()
    for session in external_dirs():
        info = json.loads((session / "truth" / "info.json").read_text())
        line = next((ln for ln in readme.splitlines() if f"`{session.name}`" in ln), "")
        bare = "shorts" in line
        cams = len(info.get("cameras", [])) or 2
        cond = {"height_m": info.get("height_m"), "legs": "bare" if bare else "covered", "cameras": cams,
                "contrast": "low" if "low contrast" in line else "normal"}  # fmt: skip
        rows.append({"name": f"ext_{session.name}", "walk": "vicon", "seed": None, "height": info.get("height_m"),
                     "cameras": cams, "source": "external", "session": session, "truth": session / "truth",
                     "masks": session / "truth" / "masks.h5", "conditions": cond})  # fmt: skip
    return rows


def value(row: dict, key: str) -> float | None:
    """A row's metric; a run that lost the person counts as infinitely wrong for the tracking metrics."""
    v = row.get(key)
    lost = str(row.get("status", "")).startswith(("lost", "track failed"))
    if v is None and lost and key not in ("iou", "iou_p10", "parts_missing", "seconds"):
        return math.inf
    return v


def stats(values: list[float | None], higher_better: bool) -> tuple[float, float, float]:
    v = np.asarray([x for x in values if x is not None and not math.isnan(x)], float)
    if not len(v):
        return (math.nan,) * 3
    # order statistics, not interpolated: a lost run (inf) among the worst 10 % makes the 90th "lost"
    if higher_better:
        return float(np.median(v)), float(np.percentile(v, 10, method="lower")), float(v.min())
    return float(np.median(v)), float(np.percentile(v, 90, method="higher")), float(v.max())


def fmt(x: float) -> str:
    if x is None or math.isnan(x):
        return "-"
    if math.isinf(x):
        return "lost"
    return f"{x:.3f}" if abs(x) < 2 else f"{x:.1f}"


def print_tables(rows: list[dict]) -> None:
    print(f"\n## Distribution over {len(rows)} sessions (for IoU: median, 10th percentile, worst)\n")
    # the order statistic: numpy's default (interpolated) 90th percentile can be lower (docs quote it as such)
    print("| metric | median | 90th pct (the session value at it, not interpolated) | worst | worst session |")
    print("|---|---|---|---|---|")
    for key, label in METRICS:
        hb = key in HIGHER_IS_BETTER
        med, p90, worst = stats([value(r, key) for r in rows], hb)
        known = [r for r in rows if value(r, key) is not None and not math.isnan(value(r, key))]
        who = (min if hb else max)(known, key=lambda r: value(r, key))["name"] if known else "-"
        print(f"| {label} | {fmt(med)} | {fmt(p90)} | {fmt(worst)} | {who} |")
    failed = [f"{r['name']} ({r['status']})" for r in rows if str(r.get("status", "")).startswith(("lost", "track"))]
    print(f"\nruns without a result (counted as the worst): {'; '.join(failed) or 'none'}")
    groups = {
        "source": lambda r: r["source"], "cameras": lambda r: str(r["cameras"]),
        "legs": lambda r: r["conditions"].get("legs"), "contrast": lambda r: r["conditions"].get("contrast"),
        "subject": lambda r: "child (< 1.5 m)" if (r["height"] or 1.7) < 1.5 else "adult",
        "walk": lambda r: r["walk"],
    }  # fmt: skip
    print("\n## By condition (median [worst]): lower-limb mm, knee deg, IoU, swap frames\n")
    print("| condition | n | lower-limb mm | knee deg | IoU | swap frames |")
    print("|---|---|---|---|---|---|")
    for gname, key in groups.items():
        for level in sorted({key(r) for r in rows}, key=str):
            sub = [r for r in rows if key(r) == level]
            cells = []
            for m in ("lower_mm", "knee_deg", "iou", "swap_frames"):
                med, _, worst = stats([value(r, m) for r in sub], m in HIGHER_IS_BETTER)
                cells.append(f"{fmt(med)} [{fmt(worst)}]")
            print(f"| {gname} = {level} | {len(sub)} | " + " | ".join(cells) + " |")
    print_bias(rows)
    print("\n## Per session\n")
    print("| session | walk | height m | cams | legs | contrast | lower mm | knee deg | swaps | IoU | events ms | s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        c = r["conditions"]
        print(f"| {r['name']} | {r['walk']} | {fmt(r['height'] or math.nan)} | {r['cameras']} | {c.get('legs')} | "
              f"{c.get('contrast')} | {fmt(value(r, 'lower_mm'))} | {fmt(value(r, 'knee_deg'))} | {r.get('swap_frames', '-')} | "
              f"{fmt(r.get('iou'))} | {fmt(r.get('event_ms'))} | {fmt(r.get('seconds'))} |")  # fmt: skip


def print_bias(rows: list[dict]) -> None:
    """The systematic part of the errors over the sessions: each joint's mean signed error (left and
    right pooled) along the walk, outwards and up, and the calibrated thigh and shank against the truth's."""
    with_bias = [r for r in rows if r.get("bias_mm")]
    if not with_bias:
        return
    print(f"\n## Systematic part of the error over {len(with_bias)} sessions (mean signed error per session, mm: "
          "median [10th, 90th pct] over sessions; share: |mean error| / mean |error|)\n")
    print("| joint | forward | outward | up | share |")
    print("|---|---|---|---|---|")
    for joint in BIAS_POINTS:
        cells = []
        for axis in ("forward", "outward", "up", "share"):
            v = [np.nanmean([b[axis] for k, b in r["bias_mm"].items() if k.startswith(joint) and b[axis] is not None])
                 for r in with_bias if any(k.startswith(joint) for k in r["bias_mm"])]  # fmt: skip
            v = np.asarray([x for x in v if np.isfinite(x)])
            digits = 2 if axis == "share" else 1
            cells.append(f"{np.median(v):.{digits}f} [{np.percentile(v, 10):.{digits}f}, {np.percentile(v, 90):.{digits}f}]"
                         if len(v) else "-")  # fmt: skip
        print(f"| {joint.rstrip('_')} | " + " | ".join(cells) + " |")
    print()
    soles = np.asarray([r["sole_mm"] for r in with_bias if r.get("sole_mm") is not None])
    if len(soles):
        print(f"the tracked body's soles above the floor (median over frames, mm): median {np.median(soles):+.1f}, "
              f"10th-90th pct [{np.percentile(soles, 10):+.1f}, {np.percentile(soles, 90):+.1f}]")
    pairs = [(np.mean([r["bias_mm"][f"hip_{s}"]["up"] - r["bias_mm"][f"ankle_{s}"]["up"] for s in "lr"]),
              r["lengths"]["leg"]["tracked_m"] - r["lengths"]["leg"]["reference_m"])
             for r in with_bias if "leg" in (r.get("lengths") or {}) and all(f"{j}_{s}" in r["bias_mm"]
                                                                            for j in ("hip", "ankle") for s in "lr")]  # fmt: skip
    if len(pairs) > 2:
        print(f"hips' minus ankles' vertical offset against the calibrated leg's length error: correlation "
              f"{np.corrcoef(np.array(pairs).T)[0, 1]:.2f} over {len(pairs)} sessions")
    for seg in ("thigh", "shank", "leg"):
        v = np.asarray([r["lengths"][seg]["diff_pct"] for r in with_bias if seg in (r.get("lengths") or {})])
        if len(v):
            print(f"{seg} length, calibrated vs truth (%): median {np.median(v):+.1f}, 10th-90th pct "
                  f"[{np.percentile(v, 10):+.1f}, {np.percentile(v, 90):+.1f}], |error| median {np.median(np.abs(v)):.1f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sessions", type=int, default=24, help="number of the suite's own sessions")
    ap.add_argument("--first", type=int, default=0,
                    help="draw the own sessions from this index on (seeds FIRST..SESSIONS-1): with --first 24 "
                         "--sessions 48, 24 held-out sessions that no choice of the project was judged on")  # fmt: skip
    ap.add_argument("--work", type=Path, default=Path("/tmp/gaitcap_suite"), help="sessions, runs and tables")
    ap.add_argument("--no-external", action="store_true", help="leave out ../shared/data/external_sessions")
    ap.add_argument("--only-external", action="store_true")
    ap.add_argument("--reuse", action="store_true", help="re-use the rows of runs that finished before (same code!)")
    ap.add_argument("--re-eval", action="store_true", help="with --reuse: score the finished runs again with the "
                    "current `gaitcap eval` (new metrics; the tracking is not repeated)")
    ap.add_argument("--silhouettes-only", action="store_true", help="only the silhouettes' IoU (no tracking): a minute")
    ap.add_argument("--config", type=Path, help="tracking configuration YAML given to every `gaitcap track`")
    ap.add_argument("--silhouette-config", type=Path, help="silhouette configuration YAML given to every `gaitcap track` "
                    "(--silhouette-config) and `gaitcap silhouettes` (-c)")
    ap.add_argument("--body", type=Path, help="track every session with this earlier run's body (gaitcap track "
                    "--body): sessions of one subject, with --only")
    ap.add_argument("--body-from", type=Path, metavar="WORK", help="track each session with the body of its own "
                    "run in an earlier suite's WORK/runs/<name> (gaitcap track --body): the calibration's cost and "
                    "what tracking with a known body gives")
    ap.add_argument("--only", nargs="+", metavar="NAME", help="only these sessions (names as in the tables)")
    ap.add_argument("--true-masks", action="store_true", help="track each session's copy drawn from its true masks "
                    "(perfect silhouettes: what the masks cost)")
    ap.add_argument("--replace", action="store_true", help="write into a WORK whose suite.json (or runs) an earlier "
                    "run of other sessions (a full run, for --only) or of the other videos (--true-masks or not) wrote: "
                    "its rows and those sessions' runs are replaced")  # fmt: skip
    ap.add_argument("--tables", type=Path, help="print the tables of an earlier run's suite.json and stop")
    args = ap.parse_args()
    if args.tables:
        if not args.tables.is_file():
            ap.error(f"--tables {args.tables}: no such file (an earlier run's WORK/suite.json)")
        print_tables(json.loads(args.tables.read_text()))
        return
    if args.config is not None and not args.config.is_file():
        ap.error(f"--config {args.config}: no such file (a tracking configuration YAML)")
    if args.silhouette_config is not None and not args.silhouette_config.is_file():
        ap.error(f"--silhouette-config {args.silhouette_config}: no such file (a silhouette configuration YAML)")
    if args.body is not None and not (args.body.is_file() or (args.body / "trajectories.h5").is_file()):
        ap.error(f"--body {args.body}: not a finished gaitcap track output (no trajectories.h5)")
    if args.body_from is not None and not (args.body_from / "runs").is_dir():
        ap.error(f"--body-from {args.body_from}: not a scripts/bench_suite.py work folder (no runs/)")
    names = [] if args.only_external else [p["name"] for p in plan(args.sessions, list(WALKS))[args.first :]]
    if not args.no_external and (SHARED / "external_sessions").is_dir():
        names += [f"ext_{p.name}" for p in external_dirs()]
    if args.only:  # a name that is not in the suite would leave an empty suite.json behind
        unknown = [n for n in args.only if n not in names]
        if unknown:
            ap.error(f"--only: no session named {', '.join(unknown)} in this suite (its sessions: {' '.join(names)})")
        names = [n for n in names if n in args.only]
    stem = "suite_silhouettes" if args.silhouettes_only else "suite"  # a tracked suite's rows stay
    if not args.replace and (why := replaces_other_run(args.work, stem, names, args.true_masks, args.silhouettes_only)):
        ap.error(why)
    args.work.mkdir(parents=True, exist_ok=True)
    todo = [] if args.only_external else own_sessions(args)
    if not args.no_external and (SHARED / "external_sessions").is_dir():
        todo += external_sessions()
    if args.only:
        todo = [s for s in todo if s["name"] in args.only]
    rows = []
    for i, s in enumerate(todo):
        if args.true_masks:
            s = {**s, "session": true_mask_session(s["session"], s["masks"], args.work / "true_sessions" / s["name"])}
        r = {k: v for k, v in s.items() if k not in ("session", "truth", "masks")} | {"true_masks": args.true_masks}
        body = args.body or (args.body_from / "runs" / s["name"] if args.body_from else None)
        r.update(measure(s["session"], s["truth"], s["masks"], args.work / ("sil_runs" if args.silhouettes_only else "runs") / s["name"], args.reuse,
                         args.silhouettes_only, args.config, args.re_eval, body, args.true_masks, args.silhouette_config))
        rows.append(r)
        print(f"[{i + 1}/{len(todo)}] {s['name']}: lower {fmt(r.get('lower_mm'))} mm, knee {fmt(r.get('knee_deg'))} deg, "
              f"IoU {fmt(r.get('iou'))}, {r.get('seconds', 0):.0f} s", file=sys.stderr, flush=True)  # fmt: skip
    (args.work / f"{stem}.json").write_text(json.dumps(rows, indent=1, default=str))
    keys = ["name", "source", "walk", "seed", "height", "cameras", "status"] + [k for k, _ in METRICS]
    with open(args.work / f"{stem}.csv", "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(keys + ["legs", "contrast"])
        for r in rows:
            w.writerow([r.get(k) for k in keys] + [r["conditions"].get("legs"), r["conditions"].get("contrast")])
    print_tables(rows)


if __name__ == "__main__":
    main()
