"""``track.json``: the summary of one session's tracking run, and the "finished" test.

A tracking output folder ``OUT`` is *finished* when ``OUT/track.json`` exists and says
``"status": "ok"``; ``track.json`` is written last, so a run killed half-way leaves an unfinished
folder that the next run redoes.

```json
{"status": "ok", "n_frames": 56, "n_flagged": 0, "seconds": 12.3, "gaitcap_version": "0.1.0",
 "session": "sessions/walk01", "message": "",
 "verdict": "doubtful", "verdict_reasons": ["the ankles cross in 14 of 56 frames: a suspected leg swap"],
 "verdict_notes": [],
 "stages_s": {"setup": 0.2, "kernels": 0.1, "first_frames": 1.1, "initialisation": 0.9, "shape_window": 0.8,
              "shape": 3.9, "shape_settle": 1.0, "tracking": 3.6, "writing": 0.3},
 "body": {"height_m": 1.7, "height_source": "session.yaml", "shape": "pelvis_height x0.960, ...",
          "segment_lengths_m": {"thigh": 0.41, "shank": 0.42, "leg": 0.83, ...}}}
```

:class:`TrackSummary` is the contract between ``gaitcap.pipeline.run_track`` (one session) and
``gaitcap.batch`` (many); the pipeline may re-export it. ``verdict`` (``ok``, ``doubtful`` or
``failed``) and ``verdict_reasons`` say whether the result can be trusted (gaitcap.quality);
``verdict_notes`` name what makes an error more likely without being one (a camera layout that
leaves which leg is ahead ambiguous). A run without them (failed before tracking, or written by an
older version) has no verdict.
"""

from __future__ import annotations

import hashlib
import json
import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from gaitcap import __version__
from gaitcap.errors import ConfigError
from gaitcap.io.atomic import write_text_atomic

if TYPE_CHECKING:
    from gaitcap.silhouette.config import SilhouetteConfig
    from gaitcap.tracking.config import TrackingConfig

log = logging.getLogger(__name__)

TRACK_JSON = "track.json"
TRAJECTORIES_H5 = "trajectories.h5"
JOINTS_CSV = "joints.csv"
JOINTS_TRC = "joints.trc"
#: what other commands derive from a tracking run, in its output folder: ``gaitcap eval``'s results and
#: ``gaitcap report``'s folder. A run tracked again there removes them: they describe the run it replaces
EVAL_FILE = "eval.json"
GAIT_DIR = "gait"
STATUS_OK = "ok"
STATUS_FAILED = "failed"
STATUS_SKIPPED = "skipped"
STATUSES = (STATUS_OK, STATUS_FAILED, STATUS_SKIPPED)
#: a run's verdict (gaitcap.quality.judge): the result can be trusted, should be checked, or is wrong
VERDICTS = ("ok", "doubtful", "failed")


@dataclass
class TrackSummary:
    """What one session's tracking run did.

    Attributes:
        session: the session folder.
        out: the output folder.
        status: ``"ok"``, ``"failed"`` or ``"skipped"`` (finished before, not redone).
        n_frames: frames tracked.
        n_flagged: frames flagged as unreliable (NaN in the trajectories).
        seconds: wall-clock time of the run.
        message: the error for a failed run, a note otherwise.
        stages: wall seconds of the run's stages, in their order (``stages_s`` in track.json;
            empty when not measured): see ``gaitcap.pipeline.Stages``.
        verdict: ``"ok"``, ``"doubtful"`` or ``"failed"`` (gaitcap.quality.judge); None: not judged.
        verdict_reasons: short sentences naming what was wrong.
        verdict_notes: short sentences naming what makes an error more likely (not counted in the
            verdict).
        body: the tracked body: height, how it was obtained, the shape calibration's note and the
            model's segment lengths (``gaitcap.body.measures``); empty for a failed run.
        options: the options the run was made with (:func:`run_options`); empty when not recorded.
    """

    session: Path
    out: Path
    status: str
    n_frames: int
    n_flagged: int
    seconds: float
    message: str = ""
    stages: dict[str, float] = field(default_factory=dict)
    verdict: str | None = None
    verdict_reasons: list[str] = field(default_factory=list)
    verdict_notes: list[str] = field(default_factory=list)
    body: dict[str, Any] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """The ``track.json`` document."""
        return {
            "status": self.status,
            "n_frames": int(self.n_frames),
            "n_flagged": int(self.n_flagged),
            "seconds": round(float(self.seconds), 3),
            "gaitcap_version": __version__,
            "session": str(self.session),
            "message": self.message,
            **(self._verdict() if self.verdict else {}),
            **({"stages_s": {k: round(float(v), 3) for k, v in self.stages.items()}} if self.stages else {}),
            **({"body": self.body} if self.body else {}),
            **({"options": self.options} if self.options else {}),
        }

    def _verdict(self) -> dict[str, Any]:
        return {"verdict": self.verdict, "verdict_reasons": list(self.verdict_reasons),
                "verdict_notes": list(self.verdict_notes)}  # fmt: skip


@dataclass(frozen=True)
class Verdict:
    """A run's verdict as ``track.json`` records it (``verdict``, ``verdict_reasons``,
    ``verdict_notes``: what makes an error more likely without being counted as one)."""

    verdict: str
    reasons: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def line(self) -> str:
        """One line for the terminal."""
        return f"verdict: {self.verdict}" + (f" ({'; '.join(self.reasons)})" if self.reasons else "")


def read_verdict(track_json: dict[str, Any] | None) -> Verdict | None:
    """The verdict of a ``track.json`` document, or None when it has none (runs before verdicts)."""
    if not track_json or not track_json.get("verdict"):
        return None
    def sentences(key: str) -> tuple[str, ...]:
        value = track_json.get(key) or []
        return tuple(str(r) for r in ([value] if isinstance(value, str) else value))

    return Verdict(str(track_json.get("verdict")), sentences("verdict_reasons"), sentences("verdict_notes"))


def format_verdict(verdict: str | None, reasons: list[str] | tuple[str, ...] = ()) -> str:
    """One line: ``doubtful: reason; reason`` (``not judged`` without a verdict)."""
    if not verdict:
        return "not judged"
    return verdict + (": " + "; ".join(reasons) if reasons else "")


def run_options(config: str | Path | None = None, tracker: str | None = None, height_m: float | None = None,
                max_frames: int | None = None, body: str | Path | None = None,
                silhouette_config: str | Path | None = None, seed: int | None = None) -> dict[str, Any]:  # fmt: skip
    """:func:`options_record` of ``gaitcap track``'s options, its configurations read as the run reads them.

    Raises:
        ConfigError: a configuration that cannot be read (as the run would).
    """
    return options_record(*run_configs(config, tracker, seed, silhouette_config), height_m, max_frames, body)


def run_configs(config: str | Path | None, tracker: str | None, seed: int | None,
                silhouette_config: str | Path | None) -> tuple[TrackingConfig, SilhouetteConfig]:  # fmt: skip
    """The tracking configuration (``config``, None: the shipped one; ``tracker`` and ``seed`` override its
    own) and the silhouette configuration a run of ``gaitcap track`` reads.

    Raises:
        ConfigError: a configuration that cannot be read, or a ``tracker`` or ``seed`` it does not take.
    """
    from pydantic import ValidationError

    from gaitcap.body.model import load_body_model
    from gaitcap.config import format_validation_error
    from gaitcap.silhouette.config import SilhouetteConfig
    from gaitcap.tracking.config import TrackingConfig, load_tracking_config

    cfg = load_tracking_config(config, model=load_body_model())  # names only: the run's height comes later
    try:  # validated by the schema (assignment)
        if tracker is not None:
            cfg.tracker = tracker  # type: ignore[assignment]
        if seed is not None:
            cfg.seed = seed
    except ConfigError as e:  # the schema's (gaitcap.config.Strict), said of the options
        if not isinstance(e.__cause__, ValidationError):
            raise
        raise ConfigError(format_validation_error(e.__cause__, "the options given", TrackingConfig)) from e.__cause__
    return cfg, SilhouetteConfig.load(silhouette_config)


def options_record(cfg: TrackingConfig, sil_cfg: SilhouetteConfig, height_m: float | None, max_frames: int | None,
                   body: str | Path | None) -> dict[str, Any]:  # fmt: skip
    """What a run records in track.json (``options``), to tell whether a finished run was made with the
    same options: the tracker and its seed, digests of the tracking (``cfg``, as given: before the run adapts
    it) and silhouette configurations (their contents, not their paths), ``--max-frames``, ``--height`` and
    ``--body``."""

    def digest(text: str) -> str:
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    return {"tracker": cfg.tracker, "seed": cfg.seed,
            "tracking_config": digest(cfg.model_dump_json(exclude={"tracker", "seed"})),
            "silhouette_config": digest(sil_cfg.model_dump_json()), "max_frames": max_frames, "height_m": height_m,
            "body": str(Path(body).resolve()) if body is not None else None}  # fmt: skip


#: how :func:`changed_options` names each option
_OPTION_NAMES = {"tracker": "the tracker", "seed": "the seed", "tracking_config": "the tracking configuration",
                 "silhouette_config": "the silhouette configuration", "max_frames": "--max-frames",
                 "height_m": "--height", "body": "--body"}  # fmt: skip


def changed_options(recorded: dict[str, Any] | None, options: dict[str, Any]) -> str:
    """The options (:func:`run_options`) that differ from a finished run's ``recorded`` ones, named with
    both values where they are short ("the tracker ipf (was factored-ipf)"); empty when they agree or
    the run recorded none (runs before they were recorded)."""
    if not recorded:
        return ""

    def shown(key: str, value: Any) -> str:
        return ("all frames" if key == "max_frames" else "not given") if value is None else str(value)

    changed = []
    for key, name in _OPTION_NAMES.items():
        now, before = options.get(key), recorded.get(key)
        if now != before:
            digest = key in ("tracking_config", "silhouette_config")
            changed.append(name if digest else f"{name} {shown(key, now)} (was {shown(key, before)})")
    return "; ".join(changed)


def write_track_json(summary: TrackSummary) -> Path:
    """Write ``summary.out/track.json`` atomically (the last output of a run)."""
    path = Path(summary.out) / TRACK_JSON
    write_text_atomic(path, json.dumps(summary.to_dict(), indent=2) + "\n")
    return path


#: the unreadable track.json files warned about (path, size, modification time): a command reads a
#: run's track.json in several places, and each file is named once
_unreadable: set[tuple[str, int, int]] = set()


def read_track_json(out: str | Path) -> dict[str, Any] | None:
    """The ``track.json`` document of ``out``, or None when absent or unreadable (a warning, once per
    file and version of it in a process: an unreadable record is taken as no finished run)."""
    path = Path(out) / TRACK_JSON
    if not path.is_file():
        return None
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as e:
        try:
            stat = path.stat()
            version = (str(path.resolve()), stat.st_size, stat.st_mtime_ns)
        except OSError:
            version = (str(path), -1, -1)
        if version not in _unreadable:
            _unreadable.add(version)
            log.warning("%s: unreadable (%s): taken as no finished run", path, e)
        return None
    return data if isinstance(data, dict) else None


def run_record(trajectories: str | Path) -> dict[str, Any] | None:
    """The ``track.json`` beside a tracking run's ``trajectories.h5`` (:func:`read_track_json`), or None
    (none there, or ``trajectories`` is another kind of file)."""
    path = Path(trajectories)
    return read_track_json(path.parent) if path.name == TRAJECTORIES_H5 else None


def unfinished(trajectories: str | Path, record: dict[str, Any] | None) -> str | None:
    """A warning for a ``trajectories.h5`` whose folder holds no finished ``track.json`` (``record``, as
    :func:`run_record` read it): a run there did not finish (stopped after writing it, before its
    track.json; a run tracked again removes the earlier run's files first), or the file is not a
    ``gaitcap track`` output; None for a finished run's or another kind of file."""
    path = Path(trajectories)
    if path.name != TRAJECTORIES_H5 or (record is not None and record.get("status") == STATUS_OK):
        return None
    return (f"{path.parent}: no finished {TRACK_JSON} beside {path.name}: a run there did not finish or the file "
            "is not gaitcap track's; it is read as it is")


def is_finished(out: str | Path) -> bool:
    """True when ``out/track.json`` records a successful run."""
    data = read_track_json(out)
    return data is not None and data.get("status") == STATUS_OK
