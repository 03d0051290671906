"""Batch tracking: many sessions, one output folder each, in parallel processes or on Dask.

``run_batch(sessions, out_root)`` tracks each session into ``out_root/<session name>/``:

- a session whose output is finished (``track.json`` with status ``ok``, see
  :mod:`gaitcap.track_summary`) is skipped (status ``"skipped"``) unless ``force``; one finished
  with other options than this batch's (tracker, configurations, ``max_frames``, ``height_m``,
  ``body``: track.json's ``options``) is not redone either, but counted as failed, naming them;
- each session logs to its own ``out_root/<name>/track.log`` (a ``logging.FileHandler`` set up in
  the worker that runs it, appended to on each run, with the traceback of a failure);
- a session that raises anything is recorded as ``"failed"`` with the message, and the other
  sessions go on; the caller (the CLI) turns any failure into a non-zero exit code;
- ``jobs > 1`` runs sessions in a ``ProcessPoolExecutor`` with the ``spawn`` start method (no
  forked copies of OpenCV/numba state); ``scheduler="local"`` (a ``dask.distributed.LocalCluster``
  of ``jobs`` worker processes) or ``scheduler="tcp://HOST:8786"`` (a running Dask scheduler whose
  workers have gaitcap installed and see the same paths) submits the same per-session function with
  ``client.map``. Dask is the optional extra ``gaitcap[distributed]``.

The per-session function (``task``) has the signature of ``gaitcap.pipeline.run_track``:
``task(session, out, *, force, progress, **options) -> TrackSummary``; it must be importable by
name in a worker (a module-level function), which the default :func:`run_track_lazy` is.
"""

from __future__ import annotations

import contextlib
import json
import logging
import multiprocessing
import os
import sys
import threading
import time
import traceback
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gaitcap.errors import ConfigError, GaitcapError, InputError, OutputError
from gaitcap.io.atomic import write_text_atomic
from gaitcap.session import CALIBRATION_FILE
from gaitcap.track_summary import (STATUS_FAILED, STATUS_OK, STATUS_SKIPPED, VERDICTS, TrackSummary, changed_options,
                                   is_finished, read_track_json, run_options)  # fmt: skip

log = logging.getLogger("gaitcap.batch")

LOG_FILE = "track.log"
LOCAL_SCHEDULER = "local"

Task = Callable[..., TrackSummary]


def run_track_lazy(session: Path, out: Path, **kwargs: Any) -> TrackSummary:
    """``gaitcap.pipeline.run_track``, imported when called (so workers import it themselves)."""
    from gaitcap.pipeline import run_track

    return run_track(session, out, **kwargs)


# ------------------------------------------------------------------------------ sessions
def is_session(folder: Path) -> bool:
    """A session folder holds a ``calibration.toml``."""
    return (folder / CALIBRATION_FILE).is_file()


def find_sessions(folder: str | Path) -> list[Path]:
    """The sessions under ``folder``: ``[folder]`` if it is a session itself, else its direct
    sub-folders that hold a ``calibration.toml``, sorted by name.

    Raises:
        InputError: ``folder`` is missing, or holds no session.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError(f"{folder}: folder not found")
    if is_session(folder):
        return [folder]
    sessions = sorted((p for p in folder.iterdir() if p.is_dir() and is_session(p)), key=lambda p: p.name)
    if not sessions:
        raise InputError(f"{folder}: no session found (neither it nor a sub-folder holds a {CALIBRATION_FILE})")
    return sessions


# ------------------------------------------------------------------- one session, logged
@dataclass(frozen=True)
class SessionJob:
    """Everything a worker needs to track one session (picklable)."""

    task: Task
    session: Path
    out: Path
    force: bool
    kwargs: dict[str, Any] = field(default_factory=dict)


@contextlib.contextmanager
def session_log(path: Path) -> Iterator[None]:
    """Copy the ``gaitcap`` log records of the current thread at INFO and above into ``path``.

    The handler is removed on exit; console handlers keep the level they had.

    Raises:
        OutputError: the log file cannot be created.
    """
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        handler = logging.FileHandler(path, mode="a", encoding="utf-8")
    except OSError as e:
        raise OutputError(f"{path}: cannot write the session log ({e.strerror})") from e
    handler.setLevel(logging.INFO)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    thread = threading.get_ident()
    handler.addFilter(lambda record: record.thread == thread)
    logger = logging.getLogger("gaitcap")
    old_level = logger.level
    effective = logger.getEffectiveLevel()
    old_handler_levels = [(h, h.level) for h in logger.handlers]
    if effective > logging.INFO:  # keep the console as quiet as it was
        for h, level in old_handler_levels:
            h.setLevel(max(level, effective))
        logger.setLevel(logging.INFO)
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)
        handler.close()
        logger.setLevel(old_level)
        for h, level in old_handler_levels:
            h.setLevel(level)


def _failed(job: SessionJob, seconds: float, message: str) -> TrackSummary:
    return TrackSummary(job.session, job.out, STATUS_FAILED, 0, 0, seconds, message)


def _message(error: BaseException) -> str:
    text = str(error).strip() or type(error).__name__
    return text if isinstance(error, GaitcapError) else f"{type(error).__name__}: {text}"


def _ensure_worker_console() -> None:
    """In a fresh worker process, show gaitcap warnings on stderr (the parent prints the rest)."""
    logger = logging.getLogger("gaitcap")
    if not logger.handlers:
        console = logging.StreamHandler(sys.stderr)
        console.setLevel(logging.WARNING)
        console.setFormatter(logging.Formatter("%(levelname)s: %(message)s"))
        logger.addHandler(console)
        logger.propagate = False


THREADS_ENV = "GAITCAP_THREADS"


@contextlib.contextmanager
def _shared_cores(n_workers: int) -> Iterator[None]:
    """Workers started inside this block get cores / n_workers compiled-kernel threads each, so
    that n parallel sessions do not oversubscribe the machine (numba defaults to every core)."""
    old = os.environ.get(THREADS_ENV)
    os.environ[THREADS_ENV] = str(max(1, (os.cpu_count() or 1) // max(1, n_workers)))
    try:
        yield
    finally:
        if old is None:
            os.environ.pop(THREADS_ENV, None)
        else:
            os.environ[THREADS_ENV] = old


def _limit_threads() -> None:
    threads = os.environ.get(THREADS_ENV)
    if threads:
        import numba

        numba.set_num_threads(max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS)))


def run_session(job: SessionJob) -> TrackSummary:
    """Run ``job.task`` on one session with its log file; never raises for a failed session.

    Returns:
        The task's summary, or a ``"failed"`` summary holding the error message (the traceback
        goes to ``track.log``).
    """
    _ensure_worker_console()
    _limit_threads()
    start = time.perf_counter()
    try:
        with session_log(job.out / LOG_FILE):
            log.info("tracking %s -> %s", job.session, job.out)
            try:
                summary = job.task(job.session, job.out, force=job.force, **job.kwargs)
            except Exception as e:  # noqa: BLE001 - one failed session must not stop the batch
                log.error("%s: failed: %s", job.session.name, _message(e))
                log.info("traceback:\n%s", "".join(traceback.format_exception(e)).rstrip())
                return _failed(job, time.perf_counter() - start, _message(e))
            log.info("%s: %s (%.1f s)", job.session.name, summary.status, summary.seconds)
            return summary
    except OutputError as e:
        return _failed(job, time.perf_counter() - start, _message(e))


# ---------------------------------------------------------------------------- executors
def _run_in_process(jobs: list[SessionJob]) -> list[TrackSummary]:
    return [run_session(job) for job in jobs]


def _run_in_pool(jobs: list[SessionJob], n_workers: int) -> list[TrackSummary]:
    results: list[TrackSummary | None] = [None] * len(jobs)
    context = multiprocessing.get_context("spawn")
    with _shared_cores(n_workers), ProcessPoolExecutor(max_workers=n_workers, mp_context=context) as pool:
        futures = {pool.submit(run_session, job): i for i, job in enumerate(jobs)}
        for future in as_completed(futures):
            i = futures[future]
            try:
                results[i] = future.result()
            except Exception as e:  # noqa: BLE001 - a crashed worker (killed, out of memory, unpicklable)
                results[i] = _failed(jobs[i], 0.0, f"worker process failed: {_message(e)}")
            _log_done(results[i])  # type: ignore[arg-type]
    return results  # type: ignore[return-value]


def _dask_client(scheduler: str, n_workers: int) -> tuple[Any, Any]:
    """A ``dask.distributed`` client (and the LocalCluster it owns, or None)."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError as e:
        raise ConfigError(
            f"--scheduler {scheduler}: dask.distributed is not installed (pip install 'gaitcap[distributed]')"
        ) from e
    if scheduler == LOCAL_SCHEDULER:
        with _shared_cores(n_workers):
            cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True, dashboard_address=None)
        return Client(cluster), cluster
    try:
        return Client(scheduler, timeout="10s"), None
    except (OSError, TimeoutError, ValueError) as e:
        raise ConfigError(f"--scheduler {scheduler}: cannot connect to the Dask scheduler ({e})") from e


def _run_on_dask(jobs: list[SessionJob], scheduler: str, n_workers: int) -> list[TrackSummary]:
    client, cluster = _dask_client(scheduler, n_workers)
    results: list[TrackSummary] = []
    try:
        futures = client.map(run_session, jobs, pure=False)
        for job, future in zip(jobs, futures, strict=True):
            try:
                summary = future.result()
            except Exception as e:  # noqa: BLE001 - a lost worker or an unpicklable result
                summary = _failed(job, 0.0, f"dask task failed: {_message(e)}")
            _log_done(summary)
            results.append(summary)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return results


def _log_done(summary: TrackSummary) -> None:
    log.info("%s: %s (%.1f s)%s", Path(summary.session).name, summary.status, summary.seconds,
             f": {summary.message}" if summary.status == STATUS_FAILED else "")  # fmt: skip


# ---------------------------------------------------------------------------- the batch
def run_batch(
    sessions: Sequence[str | Path],
    out_root: str | Path,
    *,
    jobs: int = 1,
    force: bool = False,
    scheduler: str | None = None,
    task: Task = run_track_lazy,
    **task_kwargs: Any,
) -> list[TrackSummary]:
    """Track every session into ``out_root/<session name>/`` (see the module docstring).

    Args:
        sessions: session folders (their names must be distinct).
        out_root: parent of the per-session output folders (created).
        jobs: parallel worker processes (1: in this process, one after the other).
        force: redo finished sessions (passed on to ``task``).
        scheduler: None, ``"local"`` or a Dask scheduler address (``"tcp://host:8786"``).
        task: the per-session function (``run_track`` by default).
        task_kwargs: passed to ``task`` (``config``, ``tracker``, ``height_m``...); ``progress``
            defaults to True only when sessions run one after the other in this process.

    Returns:
        One summary per session, in the order of ``sessions``.

    Raises:
        ConfigError: bad ``jobs``, a configuration (or ``tracker``, ``seed``) that cannot be read, Dask
            missing or unreachable.
        InputError: two sessions with the same name.
        OutputError: ``out_root`` cannot be created.
    """
    if jobs < 1:
        raise ConfigError(f"--jobs must be at least 1, got {jobs}")
    paths = [Path(s) for s in sessions]
    names = [p.name for p in paths]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise InputError(f"several sessions are named {', '.join(dup)}: their outputs would collide in {out_root}")
    options = _batch_options(task, task_kwargs)  # a configuration that cannot be read: refused before any session
    out_root = Path(out_root)
    try:
        out_root.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(f"{out_root}: cannot create the output folder ({e.strerror})") from e
    parallel = scheduler is not None or jobs > 1
    task_kwargs.setdefault("progress", not parallel)

    results: dict[int, TrackSummary] = {}
    todo: list[tuple[int, SessionJob]] = []
    for i, session in enumerate(paths):
        out = out_root / session.name
        if not force and is_finished(out):
            before = read_track_json(out) or {}
            frames, flagged = int(before.get("n_frames", 0)), int(before.get("n_flagged", 0))  # the finished run's
            if options is not None and (changed := changed_options(before.get("options"), options)):
                results[i] = TrackSummary(session, out, STATUS_FAILED, frames, flagged, 0.0,
                                          f"finished before with other options ({changed}): use --force to redo it "
                                          "with these")  # fmt: skip
                log.warning("%s: %s", session.name, results[i].message)
                continue
            results[i] = TrackSummary(session, out, STATUS_SKIPPED, frames, flagged, 0.0,
                                      "finished before (use --force to redo)",
                                      verdict=before.get("verdict"), verdict_reasons=before.get("verdict_reasons", []),
                                      verdict_notes=before.get("verdict_notes", []))  # fmt: skip
            log.info("%s: finished before, skipped", session.name)
        else:
            todo.append((i, SessionJob(task, session, out, force, dict(task_kwargs))))
    job_list = [job for _, job in todo]
    log.info("%d sessions to track, %d finished before", len(job_list), len(results))
    if not job_list:
        done: list[TrackSummary] = []
    elif scheduler is not None:
        done = _run_on_dask(job_list, scheduler, jobs)
    elif jobs > 1 and len(job_list) > 1:
        done = _run_in_pool(job_list, min(jobs, len(job_list)))
    else:
        done = _run_in_process(job_list)
    results.update({i: s for (i, _), s in zip(todo, done, strict=True)})
    return [results[i] for i in range(len(paths))]


def _batch_options(task: Task, task_kwargs: dict[str, Any]) -> dict[str, Any] | None:
    """The options of a batch of ``gaitcap track`` (:func:`gaitcap.track_summary.run_options`), which a
    finished run's track.json is compared with; None for another task.

    Raises:
        ConfigError: a configuration that cannot be read (every session's run would fail on it; a batch
            whose sessions all finished before would otherwise skip them all and say nothing).
    """
    if task is not run_track_lazy:
        return None
    names = ("config", "tracker", "height_m", "max_frames", "body", "silhouette_config", "seed")
    return run_options(**{k: task_kwargs[k] for k in names if k in task_kwargs})


def any_failed(summaries: Sequence[TrackSummary]) -> bool:
    """True when at least one session failed, or its run (also one finished before and skipped) has the
    verdict ``failed`` (the CLI exits with a non-zero code)."""
    return any(s.status == STATUS_FAILED or s.verdict == "failed" for s in summaries)


def _note(s: TrackSummary) -> str:
    """The message column: the verdict's reasons when there are some, else the message's first line."""
    if s.verdict_reasons:
        return "; ".join(s.verdict_reasons)
    return s.message.splitlines()[0] if s.message else ""


#: the batch's summary, machine-readable, in its output folder (written last, atomically)
BATCH_JSON = "batch.json"


def write_batch_json(out_root: str | Path, summaries: Sequence[TrackSummary]) -> Path:
    """``out_root/batch.json``: each session's summary (its track.json's fields and ``out``, also for a
    session that failed before writing one) and ``failed``, as the exit code says (:func:`any_failed`)."""
    path = Path(out_root) / BATCH_JSON
    doc = {"sessions": [{**s.to_dict(), "out": str(s.out)} for s in summaries], "failed": any_failed(summaries)}
    write_text_atomic(path, json.dumps(doc, indent=2) + "\n")
    return path


def format_summary(summaries: Sequence[TrackSummary]) -> str:
    """A plain-text table: session, status, verdict, frames, flagged, seconds, message (the verdict's
    reasons when it is not ok, else the run's message); and a total line."""
    header = ("session", "status", "verdict", "frames", "flagged", "seconds", "message")
    rows = [
        (Path(s.session).name, s.status, s.verdict or "-", str(s.n_frames), str(s.n_flagged), f"{s.seconds:.1f}",
         _note(s))
        for s in summaries
    ]  # fmt: skip
    widths = [max(len(r[k]) for r in [header, *rows]) for k in range(len(header) - 1)]
    right = {3, 4, 5}

    def line(r: tuple[str, ...]) -> str:
        cells = [r[k].rjust(widths[k]) if k in right else r[k].ljust(widths[k]) for k in range(len(widths))]
        return ("  ".join(cells) + "  " + r[-1]).rstrip()

    counts = {st: sum(s.status == st for s in summaries) for st in (STATUS_OK, STATUS_FAILED, STATUS_SKIPPED)}
    total = f"{len(summaries)} sessions: " + ", ".join(f"{n} {st}" for st, n in counts.items())
    verdicts = {v: sum(s.verdict == v for s in summaries) for v in VERDICTS}
    if any(verdicts.values()):
        total += "; verdicts: " + ", ".join(f"{n} {v}" for v, n in verdicts.items())
    return "\n".join([line(header), *(line(r) for r in rows), total])
