"""``run_track``: one session, from videos to joint trajectories. One stage after another:

session + videos -> silhouettes (gaitcap.silhouette, per camera, streamed; optionally saved to
silhouettes.h5) -> observation (soft, undistorted, downscaled) -> initialisation -> the chosen
tracker per frame -> trajectories.h5 (streamed) -> the backward pass (its frames spooled; tracked a
stretch at a time, beside the forward pass and on every core after it) and the legs' support on the
spooled silhouettes (gaitcap.tracking.support) -> zero-lag filtering, the run's verdict and the
calibrated uncertainty (gaitcap.quality) -> joints.csv, joints.trc -> track.json (written last: a
session with it is finished). A run whose legs lie off a camera's masks (the masks lost them) is
not written: the session is tracked again with the faint pixels outside the masks counted as
doubtful (``lost_legs``), and that run is (or, if it fails, the first run, kept meanwhile).
"""

from __future__ import annotations

import csv
import io
import logging
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from contextlib import ExitStack, contextmanager, nullcontext
from dataclasses import dataclass, field, replace
from functools import partial
from itertools import islice
from pathlib import Path

import numba
import numpy as np
import yaml
from tqdm import tqdm

from gaitcap.body.measures import model_lengths, outside_ranges
from gaitcap.body.model import BodyModel, load_body_model
from gaitcap.body.recorded import recorded_model
from gaitcap.camera import CameraRig
from gaitcap.errors import ConfigError, InputError, OutputError, TrackingError
from gaitcap.gait.passes import directed_passes
from gaitcap.io.atomic import (check_free_space, check_output_folder, remove_replaced, remove_stale_parts,
                               write_text_atomic)  # fmt: skip
from gaitcap.io.silhouettes_h5 import SILHOUETTES_FILE, SilhouetteWriter
from gaitcap.io.spool import FrameSpool
from gaitcap.io.track_h5 import (QUALITY_NOT_INITIALISED, QUALITY_OK, QUALITY_OUT_OF_VIEW, QUALITY_POOR_FIT,
                                 TrackWriter, proportions_attrs, read_track_record, skip_frames_attr,
                                 tracked_frames)  # fmt: skip
from gaitcap.io.trc import write_trc
from gaitcap.prefetch import Head, Prefetched
from gaitcap.quality import (assess, facing_in_doubt, legs_in_doubt, no_oblique_view, pivots, unsupported_legs,
                             unsupported_listing, view_angles)
from gaitcap.session import CALIBRATION_FILE, Session
from gaitcap.session_check import SessionVideos, check_session_videos, check_silhouettes_meet
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.silhouette.joint import JointExtractor, floor_check
from gaitcap.silhouette.run import Source, camera_attrs, file_attrs, prepare_extractor, quality_row
from gaitcap.sync_check import MAX_FRAMES, SyncFinding, find_out_of_step, head_top, skip_setting
from gaitcap.timeseries import finite_runs
from gaitcap.track_summary import (EVAL_FILE, GAIT_DIR, JOINTS_CSV, JOINTS_TRC, TRACK_JSON, TRAJECTORIES_H5, TrackSummary,
                                   format_verdict, is_finished, options_record, run_configs, write_track_json)  # fmt: skip
from gaitcap.tracking.backward import (choose_backward, exchanged_legs, leg_points, legs_apart, mean_pose,
                                       merge_passes, order_legs)
from gaitcap.tracking.condensation import Condensation
from gaitcap.tracking.config import TrackingConfig
from gaitcap.tracking.factored_ipf import FactoredIPF
from gaitcap.tracking.init import estimate_height, initialise, settle_legs, subject_positions
from gaitcap.tracking.ipf import IntervalPF
from gaitcap.tracking.likelihood import SilhouetteLikelihood
from gaitcap.tracking.observation import Observation, TrackingView, tracking_views
from gaitcap.tracking.support import FOOT_SEGMENTS, LEG_SEGMENTS, segment_support
from gaitcap.tracking.raster import warm_up
from gaitcap.tracking.shape import ShapeResult, average_shapes, calibrate_shape
from gaitcap.tracking.smoothing import lowpass
from gaitcap.trajectory import Trajectory
from gaitcap.video import iter_synchronised

log = logging.getLogger("gaitcap.pipeline")

TRACKERS = {"condensation": Condensation, "ipf": IntervalPF, "factored-ipf": FactoredIPF}
PREFETCH_FRAMES = 2  # observations prepared ahead of the tracker (bounded: memory stays flat)

__all__ = ["TrackSummary", "run_track", "TRACKERS"]


@dataclass
class FrameTiming:
    """The per-frame loop's time (seconds; ``tracking_s`` without the (re-)initialisations in it,
    timed as their own stage) and how many frames the tracker searched (``searched``: not out of
    view and not taken from the frames the initialisation had tracked already)."""

    tracking_s: float = 0.0
    total_s: float = 0.0
    searched: int = 0


class Stages(dict[str, float]):
    """Wall seconds of a run's stages, in the order they were first timed (track.json's
    ``stages_s``; scripts/bench_speed.py). A stage timed inside another is left out of the outer
    one's time. ``background`` is timed in the prefetch thread, side by side with ``setup``,
    ``kernels`` and ``first_frames`` (the wait for the frames buffered for initialisation)."""

    def __init__(self) -> None:
        super().__init__()
        self._open = threading.local()  # per thread: the inner stages' seconds of each open stage

    @contextmanager
    def timed(self, name: str) -> Iterator[None]:
        stack = self._open.__dict__.setdefault("stack", [])
        stack.append(0.0)
        t0 = time.perf_counter()
        try:
            yield
        finally:
            elapsed = time.perf_counter() - t0
            self[name] = self.get(name, 0.0) + elapsed - stack.pop()
            if stack:
                stack[-1] += elapsed


def _check_out(out: Path, force: bool) -> None:
    """Refuse an output that cannot be written (creates nothing)."""
    if is_finished(out) and not force:
        raise OutputError(f"{out}: already holds a finished run (use --force to redo it)")
    check_output_folder(out)
    check_free_space(out)


#: what a tracking run writes into its output folder, and what is derived from it (track.json first:
#: without it, the folder is not a finished run's)
RUN_OUTPUTS = (TRACK_JSON, TRAJECTORIES_H5, JOINTS_CSV, JOINTS_TRC, SILHOUETTES_FILE, EVAL_FILE, GAIT_DIR)


def _prepare_out(out: Path) -> None:
    """Create the output folder; a previous run's outputs in it (:data:`RUN_OUTPUTS`: its track.json,
    trajectories, joints, silhouettes, evaluation and gait report) are removed first, so that a run
    stopped half-way (Ctrl-C, SIGTERM, an error) leaves only its own files, never the earlier run's
    beside them to be read as this run's (by ``gaitcap report``, ``gaitcap eval``)."""
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(f"{out}: cannot create the output folder ({e.strerror})") from e
    replaced = [out / name for name in RUN_OUTPUTS if (out / name).exists()]
    remove_replaced(replaced)
    if replaced:
        log.info("%s: removed the replaced run's %s", out, ", ".join(p.name for p in replaced))
    remove_stale_parts(out)  # temporary files of a run that was killed


def _height(session: Session, height_m: float | None) -> tuple[float | None, str]:
    if height_m is not None:
        return height_m, "--height"
    if session.info.subject.height_m is not None:
        return session.info.subject.height_m, "session.yaml"
    return None, "estimated"


def run_track(
    session: Path, out: Path, *, config: Path | None = None, tracker: str | None = None,
    height_m: float | None = None, force: bool = False, progress: bool = True, max_frames: int | None = None,
    on_frame: Callable[[int, FrameTiming], None] | None = None, save_masks: bool = False,
    body: Path | None = None, silhouette_config: Path | None = None, seed: int | None = None,
) -> TrackSummary:  # fmt: skip
    """Track one session into ``out`` (see the module docstring). Returns the run's summary.

    ``tracker``, ``seed``: override the configuration's tracker and seed of its random streams.

    ``silhouette_config``: the silhouettes' configuration (None: the shipped silhouette.yaml), as
    ``gaitcap silhouettes -c`` takes it.

    ``save_masks``: also stream the full-resolution silhouettes the tracker saw, frame by frame, to
    ``out/silhouettes.h5`` (the layout of ``gaitcap silhouettes``; ``gaitcap eval`` scores them).
    ``body``: an earlier run's output folder (or its ``trajectories.h5``) whose body model, height
    and calibrated proportions, is tracked as it is (:func:`read_body`): another clip of the same
    subject, without the shape calibration; not with ``height_m``.
    """
    t_start = time.perf_counter()
    stages = Stages()
    session, out = Path(session), Path(out)
    if body is not None and height_m is not None:
        raise ConfigError("give the subject's height (--height) or an earlier run's body (--body), not both: "
                          "the body carries its height")  # fmt: skip
    reused = read_body(body) if body is not None else None
    cfg, sil_cfg = run_configs(config, tracker, seed, silhouette_config)
    options = options_record(cfg, sil_cfg, height_m, max_frames, body)  # for track.json, as given
    if reused is not None:
        cfg.shape.enabled = False  # the body is the subject's already
    ses = Session.open(session)
    videos = check_session_videos(ses)  # the calibration's geometry included
    _check_out(out, force)
    views = tracking_views(videos.rig, cfg.scale)
    likelihood = SilhouetteLikelihood(views, cfg.beta)
    stages["setup"] = time.perf_counter() - t_start
    track = partial(_track_videos, session, out, cfg, sil_cfg, views, likelihood, save_masks, height_m, max_frames,
                    progress, on_frame, t_start, stages, reused, options)  # fmt: skip
    try:
        return track(ses, videos, sync_retrack=cfg.frame_sync.retrack)
    except OutOfStep as late:
        return _track_in_step(track, ses, late)


def _track_videos(session: Path, out: Path, cfg: TrackingConfig, sil_cfg: SilhouetteConfig, views, likelihood,
                  save_masks: bool, height_m: float | None, max_frames: int | None, progress: bool, on_frame,
                  t_start: float, stages: Stages, reused: ReusedBody | None, options: dict, ses: Session,
                  videos: SessionVideos, sync_retrack: bool = False, prepared: bool = False,
                  notes: tuple[str, ...] = ()) -> TrackSummary:  # fmt: skip
    """:func:`run_track` on the checked ``videos`` of ``ses``: the run, and again with doubt where its legs
    lie off the masks (``lost_legs``). ``sync_retrack``: raise :class:`OutOfStep` instead of writing a run
    whose cameras look out of step; ``prepared``, ``notes``: see :func:`_attempt`."""
    n_frames = videos.n_frames if max_frames is None else min(videos.n_frames, max_frames)
    if n_frames < videos.n_frames:
        log.info("tracking the first %d of the %d common frames (--max-frames)", n_frames, videos.n_frames)
    saver = MaskSaver(out / SILHOUETTES_FILE, file_attrs(sil_cfg)) if save_masks else None
    attempt = partial(_attempt, session, out, ses, videos, views, likelihood, save_masks, height_m, n_frames, progress,
                      on_frame, t_start, stages, reused, options=options)  # fmt: skip
    try:
        summary = attempt(cfg, sil_cfg, saver, lost_legs=cfg.lost_legs.retrack and not cfg.soft_silhouettes,
                          sync_retrack=sync_retrack, prepared=prepared, notes=notes)  # fmt: skip
    except OutOfStep as late:
        late.saver = saver  # the first run's masks, kept with it if tracking in step fails
        raise
    except LegsLost as lost:
        if saver is not None:  # the masks, all read: the run tracked again extracts the same ones
            saver.finish()
        log.warning("%s: the masks lost the legs in some camera (%s): tracking again with the faint pixels outside "
                    "them counted as doubtful (lost_legs)", session, lost.listing)  # fmt: skip
        doubt = sil_cfg.foreground.model_copy(update={"soft_min": 1.0, "doubt_min": cfg.lost_legs.doubt_min})
        try:
            summary = attempt(cfg.model_copy(update={"soft_silhouettes": True}),
                              sil_cfg.model_copy(update={"foreground": doubt}), None, lost_legs=False, prepared=True,
                              notes=(*notes, f"tracked twice: the first run's legs lay off a camera's masks "
                                     f"({lost.listing}); this run counted the faint pixels outside the masks as "
                                     "doubtful (tracking.yaml lost_legs)"))  # fmt: skip
        except TrackingError as e:  # the first run stands: its outputs are written now
            log.warning("%s: tracking with the doubtful pixels failed (%s): the first run is kept", session, e)
            return _finish_run(lost.run, notes=(
                f"the first run's legs lay off a camera's masks ({lost.listing}); tracking again with the faint "
                f"pixels outside them counted as doubtful failed ({e}): this is the first run", *lost.notes))  # fmt: skip
        except BaseException as e:
            lost.run.writer.abort(e)
            raise
        lost.run.writer.discard()
        return summary
    if saver is not None:
        saver.finish()
    return summary


class OutOfStep(Exception):
    """A run's cameras look out of step (:mod:`gaitcap.sync_check`): raised before anything of that run
    is written, so that it is tracked again with ``skips`` as session.yaml's ``skip_frames``
    (``frame_sync``); ``run`` holds the run tracked, ``notes`` its notes (the sync's among them),
    ``listing`` the cameras out of step in words, ``lag`` the largest of their offsets (frames, absolute),
    ``saver`` its masks (``--save-masks``)."""

    def __init__(self, skips: dict[str, int], listing: str, run: TrackedRun, notes: tuple[str, ...],
                 lag: float) -> None:  # fmt: skip
        self.skips, self.listing, self.run, self.notes, self.lag = skips, listing, run, notes, lag
        self.saver: MaskSaver | None = None  # the run's masks (--save-masks), set by _track_videos
        super().__init__(listing)

    def keep(self, notes: tuple[str, ...] = ()) -> TrackSummary:
        """Write this run (its masks too), with ``notes`` after its own."""
        if self.saver is not None:
            self.saver.finish()
        return _finish_run(self.run, (*self.notes, *notes))

    def drop(self, error: BaseException | None = None) -> None:
        """Discard this run and its masks (``error``: what stopped the session, else this)."""
        if error is None:
            self.run.writer.discard()
        else:
            self.run.writer.abort(error)
        if self.saver is not None:
            self.saver.done(error or self)


def _track_in_step(track: Callable[..., TrackSummary], ses: Session, late: OutOfStep) -> TrackSummary:
    """The session tracked again (``track``: :func:`_track_videos` bound to the run's arguments) with the
    frames ``late.skips`` skipped, once. That run is kept unless it looks out of step by as much or more
    (the first run's offset was misread: skipping made it worse) or fails: then the first run is kept, with
    its notes and one saying why."""
    setting = skip_setting(late.skips)
    log.warning("%s: the cameras' videos look out of step (%s): tracking again with skip_frames: %s (frame_sync)",
                ses.root, late.listing, setting)  # fmt: skip
    in_step = replace(ses, info=ses.info.model_copy(update={"skip_frames": late.skips}))
    note = (f"tracked twice: the cameras' videos looked out of step ({late.listing}); this run skipped the first "
            f"frames of the videos that began earlier, skip_frames: {setting} (tracking.yaml frame_sync; set it in "
            f"session.yaml to track so at once), so frame k of the run is frame k + n of such a camera's video")
    try:
        summary = track(in_step, check_session_videos(in_step), prepared=True, notes=(note,), sync_retrack=True)
    except OutOfStep as again:  # still out of step: the run less out of step is kept
        if again.lag < late.lag:
            late.drop()
            return again.keep()
        again.drop()
        log.warning("%s: with skip_frames %s the videos look out of step by as much (%s): the first run is kept",
                    ses.root, setting, again.listing)  # fmt: skip
        return late.keep((f"tracking again with skip_frames: {setting} left the videos as far out of step "
                          f"({again.listing}): this is the first run",))  # fmt: skip
    except (TrackingError, InputError) as e:  # the first run stands: its outputs are written now
        log.warning("%s: tracking with skip_frames %s failed (%s): the first run is kept", ses.root, setting, e)
        return late.keep((f"tracking again with skip_frames: {setting} failed ({e}): this is the first run",))
    except BaseException as e:
        late.drop(e)
        raise
    late.drop()
    return summary


class LegsLost(Exception):
    """A run's legs lie off a camera's masks (:func:`gaitcap.quality.unsupported_legs`): raised before
    anything of that run is written, so that it is tracked again (``lost_legs``); ``run`` holds the run
    tracked, its trajectories in the writer's temporary file."""

    def __init__(self, low: dict[str, tuple[int, int]], run: TrackedRun, notes: tuple[str, ...] = ()) -> None:
        self.listing = unsupported_listing(low)  # "thigh_l in 38 of 56 frames, ..."
        self.run = run  # kept (:func:`_finish_run`) if tracking it again fails, else discarded
        self.notes = notes  # the run's own notes (the frame sync's), written with it if it is kept
        super().__init__(self.listing)


def _attempt(session: Path, out: Path, ses: Session, videos, views, likelihood, save_masks: bool,
             height_m: float | None, n_frames: int, progress: bool, on_frame, t_start: float, stages: Stages,
             reused, cfg: TrackingConfig, sil_cfg: SilhouetteConfig, saver: MaskSaver | None, lost_legs: bool,
             notes: tuple[str, ...] = (), prepared: bool = False,
             options: dict | None = None, sync_retrack: bool = False) -> TrackSummary:  # fmt: skip
    """One run of :func:`run_track` with these configurations, from the videos to the outputs (the
    stages' times add up over the runs). ``lost_legs``: raise :class:`LegsLost` instead of writing a
    run whose legs lie off the masks; ``notes``: prepended to the verdict's notes; ``prepared``: the
    output folder was prepared by an earlier run of this session (whose temporary file is kept);
    ``options``: the command's options, for track.json (:func:`gaitcap.track_summary.run_options`);
    ``sync_retrack``: raise :class:`OutOfStep` instead of writing a run whose cameras look out of step."""
    # the videos are read and the silhouettes extracted in a worker thread, a few frames ahead; the
    # first frames (initialisation, shape calibration) are read ahead without waiting for the
    # tracker; once they are in the head, the queue shrinks back to PREFETCH_FRAMES
    buffered = _buffered_frames(cfg)
    tops: list[list[float]] = []  # the silhouettes' tops per frame and camera, for the frame sync's check
    stream = Prefetched(_observations(ses, videos.rig.names, views, sil_cfg, n_frames, stages, saver,
                                      cfg.soft_silhouettes, tops), depth=max(PREFETCH_FRAMES, buffered))  # fmt: skip
    head = Head(stream, buffered, on_read=lambda n: stream.set_depth(max(PREFETCH_FRAMES, buffered - n)))
    with stream, kernel_threads(cfg.threads):
        with _switch_interval(START_SWITCH_S):
            with stages.timed("kernels"):  # while the prefetch thread fits the backgrounds
                warm_up(len(views))
                _import_late()
            with stages.timed("first_frames"):
                _first_observations(session, head, cfg)
        check_silhouettes_meet(views, head, ses.root / CALIBRATION_FILE)
        if not prepared:
            _prepare_out(out)  # only once the inputs are known good: bad input creates nothing
        if saver is not None:
            saver.open()
        return _track_session(session, out, ses, videos, cfg, views, likelihood, head, stream, height_m, n_frames,
                              progress, on_frame, t_start, stages, reused, lost_legs, notes,
                              warn=not prepared, options=options or {}, tops=tops, sync_retrack=sync_retrack)  # fmt: skip


@dataclass(frozen=True)
class ReusedBody:
    """An earlier run's body model (``gaitcap track --body``).

    Attributes:
        model: the model that run tracked, rebuilt exactly (:func:`gaitcap.body.recorded.recorded_model`).
        path: the run's ``trajectories.h5``.
        shape: that run's shape note (how its proportions were found).
    """

    model: BodyModel
    path: Path
    shape: str


def read_body(path: Path) -> ReusedBody:
    """The body model of an earlier run, ``path`` its output folder or its ``trajectories.h5``.

    Raises:
        InputError: the file is missing, not a tracking run's, or its body cannot be rebuilt (named).
    """
    path = Path(path)
    file = path / TRAJECTORIES_H5 if path.is_dir() else path
    if not file.is_file():
        raise InputError(f"{file}: no such file: --body takes an earlier gaitcap track output folder")
    record = read_track_record(file)
    if record is None:
        raise InputError(f"{file}: not a gaitcap track output (no per-frame record): its body cannot be reused")
    model, why = recorded_model(record)
    if model is None:
        raise InputError(f"{file}: its body cannot be reused: {why}")
    shape = str(record.attrs.get("shape", "off"))
    if shape == "off" or shape.startswith(("skipped", "rejected")):  # body.yaml's proportions at that height
        log.warning("%s: its body was not calibrated (shape: %s)", file, shape.split(";")[0])
    return ReusedBody(model, file, shape)


def _buffered_frames(cfg: TrackingConfig) -> int:
    """The first frames kept for the calibration check, the initialisation and the shape calibration."""
    return max(cfg.init.frames, cfg.shape.frames if cfg.shape.enabled else 0)


def _first_observations(session: Path, head: Head[Observation], cfg: TrackingConfig) -> list[Observation]:
    """The frames the initialisation looks at (the rest of the head is read meanwhile)."""
    first = head.take(cfg.init.frames)
    if not first:
        raise TrackingError(f"{session}: no frame could be read")
    return first


#: the interpreter's switch interval (seconds) while the kernels are loaded and the late imports run
#: beside the prefetch thread's background fitting: Python's default, 5 ms, is how long a thread back
#: from a call that released the GIL (a decoded frame, a median) may wait for it while the other runs
#: Python code, and the background's many short calls then spend most of their time waiting
START_SWITCH_S = 0.0005


#: the switch interval is the interpreter's, not a thread's: runs started from several threads share
#: it. The first block to enter saves the interval in force and the last to leave restores it
#: (blocks that overlap, in any order of exit, never leave a run's interval behind them)
_switch_lock = threading.Lock()
_switch_state: dict[str, float] = {"depth": 0, "saved": 0.0}


@contextmanager
def _switch_interval(seconds: float) -> Iterator[None]:
    """``sys.setswitchinterval(seconds)`` inside the block; the interval in force before the first
    of the overlapping blocks (one per thread running a session) is restored when the last one ends."""
    with _switch_lock:
        if _switch_state["depth"] == 0:
            _switch_state["saved"] = sys.getswitchinterval()
        _switch_state["depth"] += 1
        sys.setswitchinterval(seconds)
    try:
        yield
    finally:
        with _switch_lock:
            _switch_state["depth"] -= 1
            if _switch_state["depth"] == 0:
                sys.setswitchinterval(_switch_state["saved"])


def _import_late() -> None:
    """Import the parts of scipy a run needs later (the trajectories' low-pass, the factored tracker's
    joint angles) while the prefetch thread fits the backgrounds, rather than at start-up (a fifth of
    ``gaitcap track``'s imports); the modules that use them import them when first called."""
    import scipy.signal  # noqa: F401
    import scipy.spatial.transform  # noqa: F401


@contextmanager
def kernel_threads(n: int | None) -> Iterator[None]:
    """The compiled kernels launched from this thread run on ``n`` threads (None: numba's
    maximum, one per core), restored on exit."""
    before = numba.get_num_threads()
    numba.set_num_threads(_thread_count(n))
    try:
        yield
    finally:
        numba.set_num_threads(before)


def _thread_count(n: int | None) -> int:
    """The kernels' threads for a configured ``threads`` (None: one per core), within numba's maximum."""
    return min(n or numba.config.NUMBA_NUM_THREADS, numba.config.NUMBA_NUM_THREADS)


class MaskSaver:
    """Appends each frame's masks to ``OUT/silhouettes.h5`` (``track --save-masks``) once the output
    folder is ready (:meth:`open`, called after the checks that must create nothing); the frames
    decoded before that, the few the checks and the initialisation read, are held until then. The
    prefetch thread adds frames and reports its end (:meth:`done`); the tracking thread renames the
    file into place once the stream is closed (:meth:`finish`)."""

    def __init__(self, path: Path, attrs: dict) -> None:
        self.path, self.attrs = path, attrs
        self._ready = threading.Event()
        self._held: list[tuple[int, list]] = []
        self._writer: SilhouetteWriter | None = None
        self._context: tuple[dict, dict] | None = None  # (sources, prepared) of the cameras
        self._error: BaseException | None = None

    def open(self) -> None:
        self._ready.set()

    def add(self, t: int, sources: dict[str, Source], prepared: dict, masks: list) -> None:
        """Frame ``t``'s (mask, quality) per camera, in rig order (prefetch thread)."""
        self._context = (sources, prepared)
        self._held.append((t, masks))
        if self._ready.is_set():
            self._flush()

    def _flush(self) -> None:
        if not self._held or self._context is None:
            return
        if self._writer is None:
            self._writer = SilhouetteWriter(self.path, self.attrs)
        for t, masks in self._held:
            _save_masks(self._writer, t, *self._context, masks)
        self._held.clear()

    def done(self, error: BaseException | None) -> None:
        """The stream ended (prefetch thread); on an error the file is removed."""
        self._error = error
        if error is not None and self._writer is not None:
            self._writer.__exit__(type(error), error, None)
            self._writer = None

    def finish(self) -> None:
        """After the stream is closed and the run succeeded: write what is held, rename into place."""
        if self._error is not None or not self._ready.is_set():
            return
        self._flush()
        if self._writer is not None:
            self._writer.__exit__(None, None, None)
            self._writer = None


def _observations(ses: Session, cams: tuple[str, ...], views, sil_cfg: SilhouetteConfig,
                  n_frames: int, stages: Stages, saver: MaskSaver | None = None,
                  soft: bool = False, tops: list[list[float]] | None = None) -> Iterator[Observation]:  # fmt: skip
    """The session's observations, frame by frame (run by the prefetch thread): each camera's
    background is fitted first, then each frame's silhouettes are extracted and prepared, with
    the row prefix sums and areas the likelihood reads. The frames' cameras are processed side by
    side, one thread each (OpenCV and numpy release the GIL), with the shadows checked on the floor
    across the cameras in between (:class:`JointExtractor`); each camera's frames stay in order,
    and an error is raised for the first camera (rig order) that has one, as one after the other.
    The backgrounds are fitted one after the other: side by side, they raise the peak memory for
    no measurable time; the floor check's geometry (calibration only) is built beside them. With
    ``saver`` the full-resolution masks are kept (:class:`MaskSaver`). With ``soft`` the tracker sees
    each pixel's foreground confidence (:meth:`JointExtractor.process_soft`), otherwise the 0/1 masks.
    With ``tops`` each frame's :func:`gaitcap.sync_check.head_top` per camera is appended to it (the first
    :data:`~gaitcap.sync_check.MAX_FRAMES` frames)."""
    sources = {cam: Source(cam, ses.videos[cam], ses.backgrounds.get(cam), skip=ses.offsets[cam]) for cam in cams}
    error: BaseException | None = None
    try:
        with ThreadPoolExecutor(max_workers=len(cams), thread_name_prefix="gaitcap-camera") as pool:
            floor = pool.submit(floor_check, [ses.rig[c] for c in cams], sil_cfg)  # beside the backgrounds
            with stages.timed("background"):
                prepared = {cam: prepare_extractor(sources[cam], sil_cfg) for cam in cams}
            joint = JointExtractor([prepared[c][0] for c in cams], [ses.rig[c] for c in cams], map_fn=pool.map,
                                   floor=floor.result())  # fmt: skip
            for t, images in iter_synchronised({c: ses.videos[c] for c in cams}, 0, n_frames, ses.offsets):
                frame = [images[c] for c in cams]
                if soft:  # (mask, soft, quality) per camera
                    done, seen = zip(*(((m, q), s) for m, s, q in joint.process_soft(frame)))
                else:  # (mask, quality) per camera
                    done = joint.process(frame)
                    seen = [m for m, _ in done]
                if saver is not None:
                    saver.add(t, sources, prepared, list(done))
                obs = Observation(list(pool.map(lambda c: views[c].prepare(seen[c]), range(len(cams)))))
                if soft and sil_cfg.foreground.doubts:  # |S_c|: the mask's area only
                    inside = pool.map(lambda c: views[c].prepare(seen[c] * (done[c][0] > 0)), range(len(cams)))
                    obs.given_areas = np.array([np.float32(a.sum()) for a in inside], float)
                for c in range(len(cams)):
                    obs.prefix(c)
                obs.areas  # noqa: B018 - cached here, off the tracking thread
                if tops is not None and len(tops) < MAX_FRAMES:  # the check reads the clip's first seconds
                    tops.append([head_top(s) for s in obs.silhouettes])
                yield obs
    except GeneratorExit:  # the tracking took what it needed: the frames decoded so far are kept
        raise
    except BaseException as e:
        error = e
        raise
    finally:
        if saver is not None:
            saver.done(error)


def _save_masks(writer: SilhouetteWriter, t: int, sources: dict[str, Source], prepared: dict, masks: list) -> None:
    """Append frame ``t``'s (H, W) masks and quality rows, one per camera in rig order (each camera's
    datasets are created with its first frame)."""
    for (cam, source), (mask, quality) in zip(sources.items(), masks, strict=True):
        extractor, fps = prepared[cam]
        if t == 0:
            height, width = mask.shape
            writer.add_camera(cam, width, height, extractor.background, camera_attrs(source, extractor.report, fps))
        writer.append(cam, mask, quality_row(quality))


def _track_session(session: Path, out: Path, ses: Session, videos, cfg: TrackingConfig, views, likelihood,
                   head: Head[Observation], stream: Iterator[Observation], height_m: float | None, n_frames: int,
                   progress: bool, on_frame, t_start: float, stages: Stages,
                   reused: ReusedBody | None = None, lost_legs: bool = False,
                   notes: tuple[str, ...] = (), warn: bool = True, options: dict | None = None,
                   tops: list[list[float]] | None = None, sync_retrack: bool = False) -> TrackSummary:  # fmt: skip
    """:func:`run_track` once the output folder is ready: ``head`` the buffered first frames, the
    others read from ``stream``; ``reused``: the body to track (no shape calibration); ``lost_legs``,
    ``notes``, ``options``: see :func:`_attempt`; ``warn``: log the warnings about the subject's
    height and the frame sync (the session's second run, ``lost_legs``, notes them again without
    repeating them); ``tops``: the silhouettes' tops per frame and camera, filled by the stream as it is
    read (:func:`_observations`), for the frame sync's check once every frame is tracked."""
    say = log.warning if warn else log.debug
    if reused is not None:
        height, height_source = reused.model.height_m, "--body"
        if warn:
            _check_reused_height(ses, reused)
    else:
        height, height_source = _height(ses, height_m)
    if height is None:
        est = _silhouette_height(views, head)
        if est is None or not (1.0 < est < 2.3):
            raise TrackingError(f"{session}: cannot estimate the subject's height; give it with --height or in session.yaml")
        height = est
        say("subject height not given: estimated %.2f m from the silhouettes (give --height for accuracy)", height)
    elif reused is None and (mismatch := _height_mismatch(height, height_source, _silhouette_height(views, head))):
        say("%s", mismatch)
        notes = (*notes, mismatch)
    model = load_body_model(height_m=height) if reused is None else reused.model
    filt = _new_tracker(cfg, model, likelihood)
    shape_note = "off" if reused is None else f"reused from {reused.path} (its shape: {reused.shape})"
    start, settled, body_problems = None, False, []
    if cfg.shape.enabled:  # its serial parts on shape.workers kernel threads: the prefetch thread waits meanwhile
        with stages.timed("shape"), kernel_threads(max(_thread_count(cfg.threads), cfg.shape.workers)):
            filt, start, settled, shape_note, body_problems = _calibrate_shape(filt, likelihood, views, cfg, head,
                                                                               stages)  # fmt: skip
    attrs = {"config": yaml.safe_dump(cfg.model_dump(), sort_keys=False), "tracker": cfg.tracker,
             "height_m": float(height), "height_source": height_source, "session": str(session.resolve()),
             "shape": shape_note, "skip_frames": skip_frames_attr(ses.offsets),
             **proportions_attrs(filt.model)}  # fmt: skip
    writer = TrackWriter(out / TRAJECTORIES_H5, model.point_names, model.dof_names, videos.fps, attrs,
                         tuple("rad" if r else "m" for r in model.is_rotation))  # fmt: skip
    timing = FrameTiming()
    support = None
    backward_notes: list[str] = []
    try:
        with ExitStack() as stack:
            spool = stack.enter_context(FrameSpool()) if cfg.backward.enabled else None
            ahead = None if spool is None else stack.enter_context(BackwardAhead(
                partial(_new_tracker, cfg, filt.model, likelihood), filt.model, spool, cfg,
                _concurrent_kernels("the backward pass")))  # fmt: skip
            with stages.timed("tracking"):
                tracked = _track_frames(filt, likelihood, views, cfg, head.take(head.limit), stream, writer, n_frames,
                                        progress, timing, on_frame, start, settled, spool, stages, ahead)  # fmt: skip
            if ahead is not None:
                # the videos are read and the prefetch thread idle: the kernels take every core
                with stages.timed("backward"), kernel_threads(None):
                    backs = ahead.finish()
                    restart = partial(_restart_pass, filt.model, likelihood, views, cfg) if cfg.backward.restart else None
                    early = restart is not None and _concurrent_kernels("the backward pass's fresh start")
                    replaced = _backward_pass(_new_tracker(cfg, filt.model, likelihood), spool, writer, cfg, videos.fps,
                                              restart, backs, early, videos.rig, backward_notes)  # fmt: skip
                log.info("backward pass and leg order: %d of %d frames replaced", replaced, tracked)
                with stages.timed("verdict"):  # the final poses against the spooled silhouettes
                    support = _leg_support(filt.model, likelihood, spool, writer.read_poses())
    except BaseException as e:
        writer.abort(e)
        raise
    found = _sync_note(tops, videos, ses.offsets) if tops else None
    if found is not None:
        say("%s: %s", session, found.note)
        notes = (*notes, found.note)
    run = TrackedRun(session, out, videos, cfg, filt.model, writer, tracked, support, height, height_source,
                     shape_note, tuple(body_problems), timing, stages, t_start, tuple(backward_notes),
                     dict(options or {}), "" if found is None else found.listing)  # fmt: skip
    if sync_retrack and found is not None and found.skips is not None:  # nothing written yet: tracked again in step
        raise OutOfStep(found.skips, found.listing, run, notes, found.lag)  # by run_track
    if lost_legs and support is not None and (low := unsupported_legs(support, cfg.verdict)):
        raise LegsLost(low, run, notes)  # nothing written yet: the run is finished or discarded by run_track
    return _finish_run(run, notes)


def _sync_note(tops: list[list[float]], videos: SessionVideos, skipped: dict[str, int]) -> SyncFinding | None:
    """Cameras whose videos look out of step (:func:`gaitcap.sync_check.find_out_of_step`), ``skipped`` the
    session's own skip_frames, or None."""
    return find_out_of_step(tops, list(videos.rig.names), videos.fps, {c: v.path for c, v in videos.videos.items()},
                            skipped)  # fmt: skip


@dataclass(frozen=True)
class TrackedRun:
    """A run tracked to its end whose outputs are not written yet (:func:`_finish_run`): its
    trajectories in ``writer``'s temporary file (``tracked`` frames), the legs' ``support``
    (:func:`_leg_support`, None without the backward pass), the body tracked and how it was found,
    the run's timings."""

    session: Path
    out: Path
    videos: SessionVideos
    cfg: TrackingConfig
    model: BodyModel
    writer: TrackWriter
    tracked: int
    support: dict[str, np.ndarray] | None
    height: float
    height_source: str
    shape_note: str
    body_problems: tuple[str, ...]
    timing: FrameTiming
    stages: Stages
    t_start: float
    backward_notes: tuple[str, ...] = ()  # what the backward pass did that a reader should know (_mirror_run)
    options: dict = field(default_factory=dict)  # the command's options (track_summary.run_options)
    out_of_step: str = ""  # the cameras whose videos look out of step, in words (sync_check; empty: none)


def _finish_run(run: TrackedRun, notes: tuple[str, ...]) -> TrackSummary:
    """Write a tracked run's outputs: its points filtered and judged (the verdict, ``notes``
    prepended to its notes), trajectories.h5, joints.csv, joints.trc, then track.json. The writer's
    temporary file is removed if this fails."""
    cfg, writer, stages, videos, names = run.cfg, run.writer, run.stages, run.videos, run.model.point_names
    try:
        t_writing = time.perf_counter()
        verdict_before = stages.get("verdict", 0.0)
        raw, quality = writer.read_back()
        if not np.any(tracked_frames(quality)):
            raise TrackingError(
                f"{run.session}: the subject was not found in any of the {run.tracked} frames (every camera needs a "
                f"silhouette covering at least {100 * cfg.quality.min_silhouette_fraction:.1f} % of its image)"
            )
        points, note = _finish_points(raw, quality, videos.fps, cfg)
        with stages.timed("verdict"):
            judged = assess(raw, names, writer.read_fit(), quality, run.height, videos.fps, cfg.verdict,
                            cfg.uncertainty, rig=videos.rig, body_problems=run.body_problems,
                            leg_support=run.support, out_of_step=run.out_of_step)  # fmt: skip
        writer.finish(points, note, uncertainty=judged.uncertainty)
    except BaseException as e:
        writer.abort(e)
        raise
    verdict = f"verdict: {format_verdict(judged.verdict.verdict, judged.verdict.reasons)}"
    log.log(logging.INFO if judged.verdict.verdict == "ok" else logging.WARNING, "%s", verdict)  # -q shows a doubt
    for line in judged.verdict.notes:
        log.info("note: %s", line)
    traj = Trajectory(names, points, videos.fps)
    write_joints_csv(run.out / JOINTS_CSV, traj)
    write_trc(run.out / JOINTS_TRC, traj, units="mm")
    n_flagged = int(np.sum(quality != QUALITY_OK))
    stages["writing"] = time.perf_counter() - t_writing - (stages.get("verdict", 0.0) - verdict_before)
    seconds = time.perf_counter() - run.t_start
    timing = run.timing
    summary = TrackSummary(session=run.session, out=run.out, status="ok", n_frames=run.tracked, n_flagged=n_flagged,
                           seconds=seconds,
                           message=f"{cfg.tracker}: {run.tracked} frames, {n_flagged} flagged, "
                                   f"{1000 * timing.tracking_s / max(timing.searched, 1):.0f} ms/frame tracking "
                                   f"({timing.searched} frames searched), "
                                   f"{run.tracked / seconds:.1f} frames/s end to end",
                           stages=dict(stages),  # a plain dict: a batch's worker process pickles the summary
                           verdict=judged.verdict.verdict, verdict_reasons=list(judged.verdict.reasons),
                           verdict_notes=[*videos.notes, *notes, *run.backward_notes, *judged.verdict.notes],
                           body={"height_m": round(float(run.height), 4), "height_source": run.height_source,
                                 "shape": run.shape_note,
                                 "segment_lengths_m": {k: round(v, 4) for k, v in model_lengths(run.model).items()}},
                           options=run.options)  # fmt: skip
    write_track_json(summary)
    return summary


#: a session's stated height that differs from a reused body's by more than this (metres) is warned about
_HEIGHT_MISMATCH_M = 0.02


#: a given height this far (a fraction) from the silhouettes' estimate is warned about: the estimate is 9 % low
#: to 3 % high on the suite's 30 sessions (docs/validation.md), so a slip of a sixth or more is not missed
HEIGHT_CHECK_TOLERANCE = 0.15


def _silhouette_height(views: list[TrackingView], head: Head[Observation]) -> float | None:
    """The subject's height (m) from the silhouettes' tops in the first frame of the head where every
    camera places the subject (:func:`estimate_height`), or None. The frames are read only as far as that
    one: the initialisation, next, starts once its own first frames are in."""
    for obs in islice(head, head.limit):
        pos = subject_positions(views, [obs])[0]
        if np.all(np.isfinite(pos)):
            return estimate_height(views, obs, pos)
    return None


def _height_mismatch(height: float, source: str, estimate: float | None) -> str | None:
    """A note when the given ``height`` is more than :data:`HEIGHT_CHECK_TOLERANCE` from the silhouettes'
    ``estimate``; None otherwise or without an estimate."""
    if estimate is None or abs(height / estimate - 1.0) <= HEIGHT_CHECK_TOLERANCE:
        return None
    return (f"the subject's height {height:.2f} m ({source}) is {100 * (height / estimate - 1):+.0f} % from the "
            f"{estimate:.2f} m the silhouettes show: if it is wrong, the body and every length are scaled wrong "
            "(check --height or session.yaml)")


def _check_reused_height(ses: Session, reused: ReusedBody) -> None:
    """Warn when the session states a subject height other than the reused body's: another subject?"""
    stated = ses.info.subject.height_m
    if stated is not None and abs(stated - reused.model.height_m) > _HEIGHT_MISMATCH_M:
        log.warning("%s: session.yaml gives the subject %.2f m, the body of %s is %.2f m tall: another subject? "
                    "tracking with the body's", ses.root, stated, reused.path, reused.model.height_m)  # fmt: skip


def _leg_support(model: BodyModel, likelihood, spool: FrameSpool, poses: np.ndarray) -> dict[str, np.ndarray]:
    """Each leg segment's and foot's support (:func:`gaitcap.tracking.support.segment_support`) in every
    frame of the spool at its pose (T, D): segment -> (T,), NaN where the frame has no pose."""
    segments = LEG_SEGMENTS + FOOT_SEGMENTS
    out = {name: np.full(len(poses), np.nan) for name in segments}
    for t in np.flatnonzero(np.all(np.isfinite(poses), axis=1)):
        obs = Observation.from_arrays(spool.read(t))
        for name, share in zip(segments, segment_support(model, likelihood, obs, poses[t], segments)):
            out[name][t] = share
    return out


def _new_tracker(cfg: TrackingConfig, model, likelihood, stretch: int | None = None):
    """A tracker of the configured kind for ``model``, its random stream seeded from ``cfg.seed``
    (and, for the backward pass's ``stretch``-th stretch, :class:`BackwardAhead`, from that index too)."""
    seed = cfg.seed if stretch is None else [cfg.seed, stretch]
    return TRACKERS[cfg.tracker](model, likelihood, cfg, np.random.default_rng(seed))


#: the k-th of ``shape.repeats`` calibrations uses the random streams of tracker seed + k x this
_REPEAT_SEED_STEP = 7919


def _calibrate_shape(filt, likelihood, views, cfg: TrackingConfig, head: Head[Observation],
                     stages: Stages | None = None):  # fmt: skip
    """Fit the subject's proportions on the buffered first frames (gaitcap.tracking.shape), ``head``:
    initialised on its first ``init.frames`` while the others are still being read.

    Returns the tracker to use (with the calibrated model), the pose of the first frame under it
    (None: initialise as usual), whether that pose's leg assignment was settled over the first
    ``init.leg_frames`` frames with that model (:func:`~gaitcap.tracking.init.settle_legs`), a
    note for the output's attributes and the calibrated body's lengths outside ``shape.ranges``
    (then the shipped proportions are tracked). Skipped, with a warning, when the subject is not in every
    view of the first frame or the window is too short. With ``shape.repeats`` > 1 the calibrations
    run side by side, the k-th with the random streams of seed + k x ``_REPEAT_SEED_STEP``, and their factors are
    averaged (:func:`~gaitcap.tracking.shape.average_shapes`).
    """
    stages = Stages() if stages is None else stages  # timed for track.json, or for nobody (an empty one is falsy)
    early = head.take(cfg.init.frames)
    init, error = None, None
    if _in_view(early, cfg):  # else the window is not in view either: no initialisation
        try:
            with stages.timed("initialisation"):
                init = initialise(filt, likelihood, views, early, cfg.init.heading_step_deg, cfg.init.refine_passes,
                                  cfg.init.widen, leg_frames=cfg.init.leg_frames)  # fmt: skip
        except TrackingError as e:
            error = e
    first = head.take(head.limit)  # the window, read while initialising
    if len(first) < 2:  # a clip (or --max-frames) of one frame
        log.warning("shape calibration skipped: %d frame to calibrate on; tracking with the proportions of "
                    "body.yaml", len(first))  # fmt: skip
        return filt, None, False, f"skipped: {len(first)} frame to calibrate on", []
    if not _in_view(first, cfg):
        log.warning("shape calibration skipped: the subject is not in every view of the first %d frames; "
                    "tracking with the proportions of body.yaml", len(first))  # fmt: skip
        return filt, None, False, "skipped: subject not in view in the first frames", []
    if init is None:
        log.warning("shape calibration skipped: %s", error)
        return filt, None, False, f"skipped: {error}", []
    filt.start(init.q, fresh=not init.legs_settled)
    with stages.timed("shape_window"):
        poses = [filt.step(o).q for o in first]
    refit_cfg = cfg.model_copy(deep=True)
    refit_cfg.factored_ipf.passes, refit_cfg.factored_ipf.swap_hypothesis = 1, False
    refit_cfg.factored_ipf.particles, refit_cfg.factored_ipf.root_particles = cfg.shape.refit_particles

    def retrack(model, q0: np.ndarray) -> list[np.ndarray]:
        tracker = _new_tracker(cfg, model, likelihood)
        tracker.start(q0, fresh=not init.legs_settled)  # the legs as the first round had them
        return [tracker.step(o).q for o in first]

    setup = partial(numba.set_num_threads, _thread_count(cfg.threads))
    result = _search_shape(filt.model, likelihood, refit_cfg, first, poses, cfg, retrack, setup)
    factors = ", ".join(f"{k} x{v:.3f}" for k, v in result.factors.items())
    log.info("shape: %s (mean fit %.3f -> %.3f)", factors, result.fit_before, result.fit_after)
    problems = outside_ranges(model_lengths(result.model), result.model.height_m, cfg.shape.ranges)
    if problems:  # a body no person has: the silhouettes misled the fit
        log.warning("shape calibration rejected, tracking with the proportions of body.yaml: %s", "; ".join(problems))
        factors = f"rejected ({'; '.join(problems)}): {factors}"
        result = ShapeResult(model=filt.model, start=poses[0], factors={k: 1.0 for k in result.factors},
                             fit_before=result.fit_before, fit_after=result.fit_before)  # fmt: skip
    tracker = _new_tracker(cfg, result.model, likelihood)
    start = result.start
    settled = cfg.init.leg_frames > 1
    if settled:  # which leg is which, again, with the calibrated model: the assignment it was calibrated
        # with stays unless its mirror fits better by the margin any hypothesis must beat the first by
        with stages.timed("shape_settle"):
            start = settle_legs(tracker, first[: cfg.init.leg_frames], start, cfg.factored_ipf.swap_margin)
    note = f"{factors}; mean fit {result.fit_before:.4f} -> {result.fit_after:.4f} on {len(first)} frames"
    return tracker, start, settled, note, problems


def _in_view(frames: list[Observation], cfg: TrackingConfig) -> bool:
    """Whether every camera sees the subject (``quality.min_silhouette_fraction``) in every frame."""
    return all(np.all(o.fractions() >= cfg.quality.min_silhouette_fraction) for o in frames)


def _search_shape(model, likelihood, refit_cfg: TrackingConfig, first: list[Observation], poses, cfg: TrackingConfig,
                  retrack, setup) -> ShapeResult:  # fmt: skip
    """The shape calibration (:func:`~gaitcap.tracking.shape.calibrate_shape`: every candidate re-fitted),
    ``shape.repeats`` times side by side with their own random streams, the factors averaged."""

    def refitter(m) -> FactoredIPF:  # the re-fits read the pose and the fit only: no uncertainty
        return FactoredIPF(m, likelihood, refit_cfg, np.random.default_rng(cfg.seed), uncertainty=False)

    def calibrate(k: int, workers: int) -> ShapeResult:  # the k-th calibration, its own random streams
        return calibrate_shape(
            model, refitter, first, poses, cfg.shape.parameters, cfg.shape.steps, cfg.shape.bounds, cfg.shape.samples,
            cfg.seed + _REPEAT_SEED_STEP * k, cfg.shape.max_moves, cfg.shape.planted, cfg.shape.random_candidates,
            cfg.shape.random_sigma, retrack if cfg.shape.retrack else None, workers, setup, cfg.shape.limits_of(),
        )  # fmt: skip

    concurrent = (cfg.shape.workers > 1 or cfg.shape.repeats > 1) and _concurrent_kernels()
    if cfg.shape.repeats == 1:
        result = calibrate(0, cfg.shape.workers if concurrent else 1)
    else:
        with ThreadPoolExecutor(cfg.shape.repeats if concurrent else 1, initializer=setup) as pool:
            results = list(pool.map(lambda k: calibrate(k, 1), range(cfg.shape.repeats)))
        for r in results:
            log.info("shape, one calibration: %s", ", ".join(f"{k} x{v:.3f}" for k, v in r.factors.items()))
        result = average_shapes(model, cfg.shape.parameters, results)
    return result


def _concurrent_kernels(what: str = "shape calibration") -> bool:
    """Whether the compiled kernels may run from several threads at once: not with numba's workqueue
    threading layer (neither OpenMP nor TBB available), which is not thread-safe."""
    if numba.threading_layer() == "workqueue":
        log.info("%s on one thread: numba's workqueue threading layer is not thread-safe", what)
        return False
    return True


class BackwardAhead:
    """The backward pass (:func:`_backward_pass`) tracked a stretch at a time: beside the forward
    pass (one worker thread, on the core time the forward pass and the silhouettes leave), and the
    stretches left once it has ended on every core (a thread per stretch, up to one per core; the
    cores left over go to each one's kernels).

    A run of tracked frames is cut into stretches: a stretch ends at a frame where the forward pass
    placed the legs clearly apart (hip flexions ``factored_ipf.swap_within_deg`` apart, fit at least
    ``quality.min_fit``) once it holds ``backward.stretch_frames`` frames, and at the run's end. Each
    stretch is tracked back from the forward pass's pose at its last frame, as a whole run is
    without stretches, by a tracker of its own whose random stream is seeded by the tracker seed and
    the stretch's place in the clip: the result does not depend on which thread tracks it, or when.
    Without ``concurrent`` (numba's workqueue threading layer) every stretch is tracked by
    :meth:`finish`, one after the other, its kernels on every core. Use as a context manager (inside
    the spool's)."""

    def __init__(self, make_tracker: Callable[[int], object], model: BodyModel, spool: FrameSpool,
                 cfg: TrackingConfig, concurrent: bool) -> None:  # fmt: skip
        """``make_tracker(k)``: the k-th stretch's tracker (of ``model``)."""
        self._make, self._spool = make_tracker, spool
        self._every = cfg.backward.stretch_frames
        self._apart = np.radians(cfg.factored_ipf.swap_within_deg)
        self._min_fit = cfg.quality.min_fit
        self._hips = [model.dof_index(f"hip_flexion_{side}") for side in "lr"]
        self._concurrent = concurrent
        setup = partial(numba.set_num_threads, _thread_count(cfg.threads))  # the forward pass's share of the kernels
        self._pool = ThreadPoolExecutor(1, "gaitcap-backward", initializer=setup) if concurrent else None
        self._stretches: list[tuple[int, int, np.ndarray, object]] = []  # (s, e, pose at e - 1, future or None)
        self._open: int | None = None  # first frame of the stretch the forward pass is in (None: none)
        self._last: tuple[int, np.ndarray] | None = None  # the last tracked frame and its pose

    def __enter__(self) -> BackwardAhead:
        return self

    def __exit__(self, *exc: object) -> None:
        if self._pool is not None:  # a stretch being tracked ends before the spool closes
            self._pool.shutdown(wait=True, cancel_futures=True)

    def add(self, t: int, q: np.ndarray | None, fit: float = float("nan")) -> None:
        """The forward pass's frame t: its pose q (D,) and fit, q None where it tracked nothing."""
        if q is None:
            self._close()
            return
        if self._open is None:
            self._open = t
        self._last = (t, q)
        apart = abs(q[self._hips[0]] - q[self._hips[1]]) >= self._apart
        if self._every and t + 1 - self._open >= self._every and fit >= self._min_fit and apart:
            self._close()

    def _track(self, k: int, s: int, e: int, q: np.ndarray) -> list:
        return _tracked_back(self._make(k), self._spool, q, s, e)

    def _close(self, later: bool = False) -> None:
        if self._open is None or self._last is None:
            return
        s, (t, q) = self._open, self._last
        self._open = None
        k = len(self._stretches)
        job = self._pool.submit(self._track, k, s, t + 1, q) if self._pool is not None and not later else None
        self._stretches.append((s, t + 1, q, job))

    def finish(self) -> dict[tuple[int, int], list]:
        """After the forward pass: the stretches not begun tracked on every core; every run of
        tracked frames (first, end) -> its backward estimates, frame by frame."""
        self._close(later=True)
        left = [k for k, (_, _, _, job) in enumerate(self._stretches) if job is None or job.cancel()]
        threads = _thread_count(None)
        workers = max(1, min(threads if self._concurrent else 1, len(left)))
        setup = partial(numba.set_num_threads, max(1, threads // workers))  # the cores left over: each one's kernels
        with ThreadPoolExecutor(workers, "gaitcap-backward", initializer=setup) as pool:
            late = dict(zip(left, pool.map(lambda k: self._track(k, *self._stretches[k][:3]), left)))
        runs: dict[tuple[int, int], list] = {}
        first = None
        for k, (s, e, _, job) in enumerate(self._stretches):
            back = late[k] if k in late else job.result()
            if first is not None and s == first[1]:  # the same run goes on
                runs[(first[0], e)] = runs.pop(first) + back
                first = (first[0], e)
            else:
                runs[(s, e)] = back
                first = (s, e)
        return runs


def _track_frames(filt, likelihood, views, cfg: TrackingConfig, first, stream: Iterator[Observation],
                  writer: TrackWriter, n_frames: int, progress: bool, timing: FrameTiming, on_frame,
                  start=None, settled: bool = False, spool: FrameSpool | None = None,
                  stages: Stages | None = None, ahead: BackwardAhead | None = None) -> int:  # fmt: skip
    """The per-frame loop (streaming): observe, (re)initialise, track, flag, append. ``start``: the
    first frame's pose when already known (shape calibration); ``settled``: whether its leg
    assignment was settled over several frames (else the first frame weighs its mirror too);
    ``spool``: every frame's observation is also stored there, for :func:`_backward_pass`, and
    ``ahead`` told each frame's pose (:class:`BackwardAhead`).
    ``timing.total_s`` also counts the time spent waiting for the next observation; ``stages``: the
    initialisations are timed there (``initialisation``), apart from the tracking."""
    model = filt.model
    stages = Stages() if stages is None else stages
    bar = tqdm(total=n_frames, desc=f"tracking ({cfg.tracker})", unit="frame", leave=False,
               disable=None if progress else True)  # None: off when stderr is not a terminal (a log file)
    lost = True
    pending = list(first)

    def observations():
        yield from pending
        while True:
            t0 = time.perf_counter()
            obs = next(stream, None)
            timing.total_s += time.perf_counter() - t0
            if obs is None:
                return
            yield obs

    count = 0
    for obs in observations():
        t0 = time.perf_counter()
        if spool is not None:
            spool.append(obs.arrays())
        in_view = bool(np.all(obs.fractions() >= cfg.quality.min_silhouette_fraction))
        quality, pose = QUALITY_OK, None  # pose: this frame's estimate, if it was tracked
        init_s = 0.0  # seconds of this frame spent (re-)initialising
        if not in_view:
            quality, lost = QUALITY_OUT_OF_VIEW, True
            est_points = np.full((model.n_points, 3), np.nan)
            writer.append(est_points, np.full(model.n_points, np.nan), np.full(model.n_dofs, np.nan), np.nan, 0.0, quality)
        else:
            if lost and count == 0 and start is not None:
                filt.start(start, fresh=not settled)
                lost = False
            if lost:
                window = pending[count:] if count < len(pending) else [obs]
                t_init = time.perf_counter()
                try:
                    # every core: at the first frame the prefetch thread waits with the frames the
                    # initialisation looks at (a re-initialisation later in the clip shares the cores with it)
                    with stages.timed("initialisation"), kernel_threads(None):
                        init = initialise(filt, likelihood, views, window[: cfg.init.frames] or [obs],
                                          cfg.init.heading_step_deg, cfg.init.refine_passes, cfg.init.widen,
                                          leg_frames=cfg.init.leg_frames)  # fmt: skip
                    filt.start(init.q, fresh=not init.legs_settled)
                    lost = False
                    log.info("frame %d: subject found (fit %.2f)", count, init.fit)
                except TrackingError as e:
                    log.debug("frame %d: %s", count, e)
                finally:
                    init_s = time.perf_counter() - t_init  # not the frame's tracking (its own stage)
            if lost:
                quality = QUALITY_NOT_INITIALISED
                writer.append(np.full((model.n_points, 3), np.nan), np.full(model.n_points, np.nan),
                              np.full(model.n_dofs, np.nan), np.nan, 0.0, quality)  # fmt: skip
            else:
                est = filt.step(obs)
                timing.searched += not filt.last_step_remembered
                quality = _fit_quality(est.fit, cfg)
                writer.append(est.points, est.uncertainty, est.q, est.log_likelihood, est.fit, quality)
                pose = est
        if ahead is not None:
            ahead.add(count, None if pose is None else pose.q, np.nan if pose is None else pose.fit)
        dt = time.perf_counter() - t0
        timing.tracking_s += dt - init_s
        timing.total_s += dt
        count += 1
        bar.update(1)
        if on_frame is not None:
            on_frame(count, timing)
        if count >= n_frames:
            break
    bar.close()
    return count


def _fit_quality(fit: float, cfg: TrackingConfig) -> int:
    """A tracked frame's quality flag: ok, or poor fit below ``quality.min_fit``."""
    return QUALITY_OK if fit >= cfg.quality.min_fit else QUALITY_POOR_FIT


def _restart_pass(model: BodyModel, likelihood, views, cfg: TrackingConfig, spool: FrameSpool, q_last: np.ndarray,
                  s: int, e: int, stop: threading.Event | None = None) -> list | None:  # fmt: skip
    """A second backward hypothesis for the run of frames s..e-1 (a fresh tracker of ``model``): the
    subject initialised afresh on the run's last frames (taken backwards, the heading the forward
    pass's last pose ``q_last`` has, or the opposite one if it fits decisively better), then tracked
    back to s; None when that pose's legs agree with ``q_last``'s. ``stop``: see :func:`_tracked_back`."""
    tracker = _new_tracker(cfg, model, likelihood)
    frames = [Observation.from_arrays(spool.read(t)) for t in range(e - 1, max(s, e - cfg.init.frames) - 1, -1)]
    try:
        init = initialise(tracker, likelihood, views, frames, cfg.init.heading_step_deg, cfg.init.refine_passes,
                          cfg.init.widen, leg_frames=cfg.init.leg_frames,
                          heading_rad=float(q_last[model.dof_index("pelvis_rotation")]))  # fmt: skip
    except TrackingError:
        return None
    legs = leg_points(model.point_names)
    pts = tracker.projector.points(np.stack([init.q, q_last]))[:, legs]
    gap = float(legs_apart(pts[0], pts[1]))
    log.info("backward pass: a fresh start at frame %d, its legs %.0f mm from the forward pass's", e - 1, 1000 * gap)
    if gap < cfg.backward.agree_m:
        return None
    return _tracked_back(tracker, spool, init.q, s, e, fresh=not init.legs_settled, stop=stop, read=frames)


def _tracked_back(tracker, spool: FrameSpool, q0: np.ndarray, s: int, e: int, fresh: bool = False,
                  stop: threading.Event | None = None, read: list[Observation] | None = None) -> list:  # fmt: skip
    """The estimates of frames s..e-1 (in that order), tracked from pose ``q0`` (D,) at frame e - 1 back
    to s. ``stop``: once set, no further frame is tracked (the list is then short: its caller has no
    more use for it). ``read``: the observations of frames e - 1, e - 2, ... already read (those the
    initialisation looked at: the frames its leg check tracked are taken as tracked, Tracker.remember)."""
    tracker.start(q0, fresh=fresh)
    read = read or []
    estimates = []
    for i, t in enumerate(range(e - 1, s - 1, -1)):
        if stop is not None and stop.is_set():
            break
        estimates.append(tracker.step(read[i] if i < len(read) else Observation.from_arrays(spool.read(t))))
    return estimates[::-1]


class _Begun:
    """A call begun in ``pool``'s worker thread, ``fn(*args, stop=event)``: its result when wanted
    (:meth:`result`), else told to stop (:meth:`stop`)."""

    def __init__(self, pool: ThreadPoolExecutor, fn: Callable[..., object], *args: object) -> None:
        self._stop = threading.Event()
        self._future = pool.submit(fn, *args, stop=self._stop)

    def result(self) -> object:
        return self._future.result()

    def stop(self) -> None:
        self._stop.set()


def _backward_pass(tracker, spool: FrameSpool, writer: TrackWriter, cfg: TrackingConfig, rate_hz: float,
                   restart: Callable[..., list | None] | None = None, backs: dict[tuple[int, int], list] | None = None,
                   early: bool = False, rig: CameraRig | None = None,
                   notes: list[str] | None = None) -> int:  # fmt: skip
    """Track every run of tracked frames again from its last frame to its first (``tracker``, a
    fresh one, started from the forward pass's last pose of the run) and overwrite in ``writer``
    the frames :func:`~gaitcap.tracking.backward.choose_backward` gives to the backward pass; then,
    with ``backward.leg_order``, put right the stretches whose leading leg does not alternate
    (:func:`~gaitcap.tracking.backward.order_legs`). A run whose merged legs the verdict would
    doubt (:func:`~gaitcap.quality.legs_in_doubt`: legs crossed or out of rhythm, or a stretch moving
    against the way the body faces), or that pauses at a turn (:func:`~gaitcap.quality.pivots`: a pivot
    on the spot, where the tracker can lose the legs and the rhythm cannot tell), is merged again with
    the backward pass
    ``restart`` gives (:func:`_restart_pass`), merged with the first
    (:func:`~gaitcap.tracking.backward.merge_passes`), if that leaves no more frames in doubt.
    ``backs``: every run's backward estimates, tracked already (:meth:`BackwardAhead.finish`).
    ``early``: a run whose forward pass moves against the way it faces for a stretch
    (:func:`~gaitcap.quality.facing_in_doubt`: a turn the model did not follow, or a subject walking
    backwards; the merge, which exchanges legs, does not clear it), or pauses at a turn (the merge
    does not take the turns away), has its fresh start begun in a
    worker thread while it is merged, on the core the merge leaves idle (called as
    ``restart(..., stop=event)``), and stopped if the merged run is not in doubt: the same
    estimates as a fresh start begun after the merge. ``rig``: the cameras; with ``backward.mirror_run``,
    a run that none of them views obliquely is then tracked again from its legs' mirror
    (:func:`_mirror_run`), and a note appended to ``notes`` where the mirror's run is kept.
    Returns how many frames were overwritten. Memory: the runs' estimates (about a kilobyte a frame)."""
    raw, quality = writer.read_back()
    poses, fit = writer.read_poses(), writer.read_fit()
    names = tracker.model.point_names
    replaced = 0
    with ExitStack() as stack:
        pool = None
        if early and restart is not None:  # one core's share of the kernels; the merge keeps its own
            pool = stack.enter_context(ThreadPoolExecutor(1, "gaitcap-restart", partial(numba.set_num_threads, 1)))
        for s, e in finite_runs(tracked_frames(quality)):
            begun = None
            if pool is not None and (facing_in_doubt(raw[s:e], names, rate_hz) or pivots(raw[s:e], names, rate_hz)):
                log.debug("frames %d-%d: the forward pass moves against the way it faces, or pauses at a turn; the "
                          "fresh start begun beside the merge", s, e - 1)  # fmt: skip
                begun = _Begun(pool, restart, spool, poses[e - 1], s, e)
            try:
                replaced += _merge_back(tracker, spool, writer, raw, poses, fit, backs, s, e, cfg, rate_hz, restart,
                                        begun, rig, notes)  # fmt: skip
            finally:
                if begun is not None:
                    begun.stop()
    return replaced


def _merge_back(tracker, spool: FrameSpool, writer: TrackWriter, raw: np.ndarray, poses: np.ndarray, fit: np.ndarray,
                backs: dict[tuple[int, int], list] | None, s: int, e: int, cfg: TrackingConfig, rate_hz: float,
                restart: Callable[..., list | None] | None, begun: _Begun | None,
                rig: CameraRig | None = None, notes: list[str] | None = None) -> int:  # fmt: skip
    """:func:`_backward_pass` for the run of frames s..e-1 (``begun``: its fresh start, begun already);
    returns how many frames were overwritten."""
    names = tracker.model.point_names
    legs = leg_points(names)
    back = backs[(s, e)] if backs is not None else _tracked_back(tracker, spool, poses[e - 1], s, e)
    with kernel_threads(1) if begun is not None else nullcontext():  # a core each, beside the fresh start
        chosen = _merge_run(tracker, spool, raw, poses, fit, back, s, e, cfg, rate_hz)
    doubt = paused = 0
    if restart is not None:
        merged = _merged_points(raw[s:e], chosen)
        doubt, paused = legs_in_doubt(merged, names, rate_hz, cfg.verdict), pivots(merged, names, rate_hz)
    second = None
    if doubt or paused:
        second = begun.result() if begun is not None else restart(spool, poses[e - 1], s, e)
    elif begun is not None:
        log.debug("frames %d-%d: no legs in doubt once merged; the fresh start begun beside the merge is not used", s,
                  e - 1)  # fmt: skip
    if second is not None:
        back = merge_passes(back, second, legs, cfg.backward.agree_m)
        again = _merge_run(tracker, spool, raw, poses, fit, back, s, e, cfg, rate_hz)
        doubt_again = legs_in_doubt(_merged_points(raw[s:e], again), names, rate_hz, cfg.verdict)
        log.info("frames %d-%d: legs in doubt in %d frames, %d frames pausing at a turn; the backward pass from a "
                 "fresh start at the end (%d of %d frames) leaves %d in doubt: %s", s, e - 1, doubt, paused,
                 sum(b is c for b, c in zip(back, second)), e - s, doubt_again,
                 "kept" if doubt_again <= doubt else "not kept")  # fmt: skip
        if doubt_again <= doubt:
            chosen = again
    if cfg.backward.mirror_run and rig is not None and no_oblique_view(
            view_angles(_merged_points(raw[s:e], chosen), names, rig), cfg.verdict.min_oblique_deg):
        if begun is not None:
            begun.stop()  # not wanted past this point: the core goes to the mirror's passes
        chosen, note = _mirror_run(tracker, spool, raw, poses, fit, chosen, s, e, cfg, rate_hz)
        if note is not None and notes is not None:
            notes.append(note)
    for i, b in chosen.items():
        writer.replace(s + i, b.points, b.uncertainty, b.q, b.log_likelihood, b.fit, _fit_quality(b.fit, cfg))
    if cfg.backward.average:
        _average_agreeing(tracker, spool, writer, raw, poses, back, chosen, s, e, cfg)
    return len(chosen)


def _average_agreeing(tracker, spool: FrameSpool, writer: TrackWriter, raw: np.ndarray, poses: np.ndarray, back: list,
                      chosen: dict, s: int, e: int, cfg: TrackingConfig) -> None:  # fmt: skip
    """``backward.average``: each frame of the run s..e-1 whose merged estimate is one pass's (the
    forward pass's: ``raw`` points (T, P, 3) and ``poses`` (T, D); or the backward pass's ``back``, e - s
    estimates, where ``chosen`` took it) and agrees with the other's (``backward.agree_m``, as
    :func:`~gaitcap.tracking.backward.choose_backward` compares them) takes the mean of the two poses
    (:func:`~gaitcap.tracking.backward.mean_pose`), its points, log-likelihood and fit computed for it,
    its uncertainty kept."""
    legs = leg_points(tracker.model.point_names)
    apart = legs_apart(raw[s:e, legs], np.array([b.points[legs] for b in back]))  # NaN: a pass not tracked
    averaged = 0
    for i in np.flatnonzero(apart < cfg.backward.agree_m):
        b, forward = back[i], poses[s + i]
        if i in chosen and chosen[i] is not b:
            continue  # another estimate (the leg order's, the mirror's): no second pass of it
        one, other = (b.q, forward) if i in chosen else (forward, b.q)
        q = mean_pose(one, other, tracker.model.wrap)
        ll, fit = tracker.full_fit(Observation.from_arrays(spool.read(s + i)), q)
        writer.replace(s + i, tracker.projector.points(q[None])[0], None, q, ll, fit, _fit_quality(fit, cfg))
        averaged += 1
    log.debug("frames %d-%d: %d frames where the passes agree take the mean of their poses", s, e - 1, averaged)


def _merge_run(tracker, spool: FrameSpool, raw: np.ndarray, poses: np.ndarray, fit: np.ndarray, back: list, s: int,
               e: int, cfg: TrackingConfig, rate_hz: float) -> dict:  # fmt: skip
    """The frames of the run s..e-1 (forward pass: ``raw`` points (T, P, 3), ``poses`` (T, D), ``fit``
    (T,)) that take another estimate than the forward pass's: frame of the run -> its estimate,
    from the backward pass ``back`` (e - s estimates) or tracked again by ``backward.leg_order``."""
    legs = leg_points(tracker.model.point_names)
    take = choose_backward(raw[s:e, legs], np.array([b.points[legs] for b in back]), fit[s:e],
                           np.array([b.fit for b in back]), cfg.backward.agree_m)  # fmt: skip
    chosen = {int(i): back[i] for i in np.flatnonzero(take)}
    if cfg.backward.leg_order:

        def again(q0: np.ndarray, a: int, b: int, backwards: bool) -> list:  # frames a..b-1 from q0
            if backwards:
                return _tracked_back(tracker, spool, q0, s + a, s + b)
            tracker.start(q0, fresh=False)
            return [tracker.step(Observation.from_arrays(spool.read(s + t))) for t in range(a, b)]

        def refine(q0: np.ndarray, t: int):  # frame t searched from q0 alone
            return tracker.refine(Observation.from_arrays(spool.read(s + t)), q0)

        passes = _passes(raw[s:e], tracker.model.point_names, rate_hz)
        if len(passes) > 1:  # order_legs's own messages count the frames from each pass's first
            log.debug("frames %d-%d: the leading leg ordered pass by pass, frames %s", s, e - 1,
                      ", ".join(f"{s + a}-{s + b - 1}" for a, b, _ in passes))  # fmt: skip
        for a, b, lines in passes:
            _order_pass(chosen, a, b, lines, raw[s:e], fit[s:e], poses[s:e], back, tracker, rate_hz, again, refine,
                        cfg)  # fmt: skip
    return chosen


def _passes(points: np.ndarray, names: tuple[str, ...], rate_hz: float) -> list[tuple[int, int, np.ndarray | None]]:
    """:func:`gaitcap.gait.passes.directed_passes` of the pelvis of a run's points (T, P, 3): the
    passes the leg order takes, (start, stop, each frame's walking direction or None); [(0, T, None)]
    without a pelvis."""
    if "pelvis" not in names:
        return [(0, len(points), None)]
    return directed_passes(points[:, names.index("pelvis"), :2], rate_hz)


def _order_pass(chosen: dict, a: int, b: int, lines: np.ndarray | None, forward: np.ndarray, fit: np.ndarray,
                poses: np.ndarray, back: list, tracker, rate_hz: float, again: Callable, refine: Callable,
                cfg: TrackingConfig) -> None:  # fmt: skip
    """:func:`~gaitcap.tracking.backward.order_legs` over the frames a..b-1 of a run (one pass along
    the walkway, with its own walking line, or each frame's direction ``lines``, and its own
    alternation of the leading leg: a turn breaks both), ``chosen`` (frame of the run -> estimate)
    updated in place; the run's ``forward`` points, ``fit``, ``poses`` and ``back`` estimates, and
    ``again`` and ``refine`` on the run's frames."""
    part = {t - a: est for t, est in chosen.items() if a <= t < b}
    order_legs(part, forward[a:b], fit[a:b], poses[a:b], back[a:b], tracker.model.point_names, rate_hz,
               lambda q0, i, j, backwards: again(q0, a + i, a + j, backwards), tracker.mirrored, cfg.backward,
               cfg.verdict.exchanged_margin_m, lambda q0, t: refine(q0, a + t), lines)  # fmt: skip
    for t in range(a, b):
        if t - a in part:
            chosen[t] = part[t - a]
        else:
            chosen.pop(t, None)


#: the random stream of a mirror's backward pass (:func:`_mirror_run`) is the tracker seed's with this
#: index plus the run's first frame: apart from the backward pass's stretches (0, 1, ...)
_MIRROR_STREAM = 1_000_000


def _mirror_run(tracker, spool: FrameSpool, raw: np.ndarray, poses: np.ndarray, fit: np.ndarray, chosen: dict, s: int,
                e: int, cfg: TrackingConfig, rate_hz: float) -> tuple[dict, str | None]:  # fmt: skip
    """The merged run s..e-1 (the forward pass's ``raw`` points (T, P, 3), ``poses`` (T, D) and ``fit``
    (T,), with ``chosen``'s estimates where it has one), or the same run tracked again from its legs'
    mirror where that holds the legs the other way round and fits the silhouettes better over all its
    frames (mean fit): frame of the run -> its estimate, every frame for the mirror's; and a note for
    track.json when the mirror's is kept.

    Seen from beside and along the walkway only, the leg assignments fit a frame nearly alike (the
    perspective of the nearer and the farther leg tells them apart by a few thousandths of fit), so
    which one the forward pass keeps is settled over its first few frames, where that difference is
    noise; over the whole run it adds up. The mirror's run is tracked as the run was: forwards from
    the mirror of the merged first pose, backwards from that of the merged last pose, the two merged
    and their legs' order put right (:func:`_merge_run`). It replaces the run only if its legs are the
    other way round in more than half of the frames (:func:`~gaitcap.tracking.backward.exchanged_legs`)
    and it fits better: a mirror that came back to the run's own legs is the same hypothesis tracked
    twice, and the better fit of two such draws is not the more accurate one (docs/validation.md).
    The backward pass's ``tracker`` tracks the mirror's forward pass (its random stream goes on).
    """
    n = e - s

    def pose(t: int) -> np.ndarray:  # frame t's pose in the merge
        return chosen[t].q if t in chosen else poses[s + t]

    fit_now = float(np.mean([chosen[t].fit if t in chosen else fit[s + t] for t in range(n)]))
    # the two passes side by side, a core each (a tracker of its own for the backward one)
    backwards = (_new_tracker(cfg, tracker.model, tracker.likelihood, _MIRROR_STREAM + s), spool,
                 tracker.mirrored(pose(n - 1)), s, e)  # fmt: skip
    with ExitStack() as stack:
        future = None
        if _concurrent_kernels("the mirror's passes"):
            pool = stack.enter_context(ThreadPoolExecutor(1, "gaitcap-mirror", partial(numba.set_num_threads, 1)))
            future = pool.submit(_tracked_back, *backwards)
            stack.enter_context(kernel_threads(1))
        tracker.start(tracker.mirrored(pose(0)), fresh=False)
        forward = [tracker.step(Observation.from_arrays(spool.read(t))) for t in range(s, e)]
        back = future.result() if future is not None else _tracked_back(*backwards)
    raw2, poses2, fit2 = raw.copy(), poses.copy(), fit.copy()
    raw2[s:e] = [x.points for x in forward]
    poses2[s:e] = [x.q for x in forward]
    fit2[s:e] = [x.fit for x in forward]
    merged = _merge_run(tracker, spool, raw2, poses2, fit2, back, s, e, cfg, rate_hz)
    mirror = {t: merged.get(t, forward[t]) for t in range(n)}
    fit_mirror = float(np.mean([x.fit for x in mirror.values()]))
    other = float(np.mean(exchanged_legs(np.array([x.points for x in mirror.values()]),
                                         _merged_points(raw[s:e], chosen), tracker.model.point_names)))  # fmt: skip
    kept = other > 0.5 and fit_mirror > fit_now
    log.info("frames %d-%d: no camera views the walk obliquely; tracked again from the legs' mirror, the run fits "
             "%.4f against %.4f, its legs the other way round in %.0f %% of the frames: %s", s, e - 1, fit_mirror,
             fit_now, 100 * other, "kept" if kept else "not kept")  # fmt: skip
    if not kept:
        return chosen, None
    return mirror, (f"frames {s}-{e - 1}: no camera views the walk obliquely, so the run was also tracked from its "
                    f"legs' mirror, which fits the silhouettes better over the run ({fit_mirror:.4f} against "
                    f"{fit_now:.4f}) and was kept (backward.mirror_run)")  # fmt: skip


def _merged_points(forward: np.ndarray, chosen: dict) -> np.ndarray:
    """A run's points (T, P, 3): the forward pass's ``forward``, with ``chosen``'s estimates where it has one."""
    points = forward.copy()
    for i, b in chosen.items():
        points[i] = b.points
    return points


def _finish_points(raw: np.ndarray, quality: np.ndarray, rate_hz: float, cfg: TrackingConfig) -> tuple[np.ndarray, str]:
    """Flagged frames -> NaN, then the optional zero-lag low-pass filter (none, with a warning, where its
    cut-off is not below half the frame rate: such videos hold nothing above it to filter)."""
    points = raw.copy()
    points[quality != QUALITY_OK] = np.nan
    cutoff = cfg.smoothing.cutoff_hz
    if cutoff is None:
        return points, "none"
    if cutoff >= rate_hz / 2:
        log.warning("smoothing.cutoff_hz %g Hz is not below half the videos' frame rate (%g fps): the trajectories "
                    "are written unfiltered", cutoff, rate_hz)  # fmt: skip
        return points, "none"
    return lowpass(points, rate_hz, cutoff, cfg.smoothing.order), (
        f"zero-lag Butterworth low-pass, order {cfg.smoothing.order}, cut-off {cutoff} Hz (filtfilt)")


def write_joints_csv(path: Path, traj: Trajectory) -> None:
    """``frame, time_s, <point>_x, <point>_y, <point>_z ...`` in metres, NaN where flagged."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["frame", "time_s"] + [f"{n}_{a}" for n in traj.names for a in "xyz"])
    times = traj.times()
    for t in range(traj.n_frames):
        w.writerow([t, f"{times[t]:.6f}"] + [f"{v:.6f}" if np.isfinite(v) else "NaN" for v in traj.points[t].ravel()])
    write_text_atomic(path, buf.getvalue())
