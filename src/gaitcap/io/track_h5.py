"""Streaming writer of the tracker's ``trajectories.h5`` (same layout as gaitcap.io.trajectories_h5).

Rows are appended frame by frame to resizable datasets in a temporary file beside the target,
so memory does not grow with the video; :meth:`TrackWriter.finish` writes the last datasets and
renames the file into place. A run killed before that leaves no ``trajectories.h5``.

Layout: ``/points`` (T, P, 3) metres, NaN where flagged (filtered when smoothing is on), attrs
``names``, ``rate_hz``, ``t0_s``; ``/points_unfiltered`` (T, P, 3) the tracker's raw estimate,
NaN in frames without a pose (subject out of view or not found); ``/times`` (T,); ``/uncertainty`` (T, P) metres, calibrated after tracking
(gaitcap.quality; the particles' spread when none is given); ``/spread`` (T, P) metres, the weighted
spread of the tracker's particles; ``/quality`` (T,) uint8 (0 ok,
1 poor fit, 2 subject out of view, 3 not initialised; attr ``codes`` says so); ``/poses`` (T, D) attr ``dof_names``;
``/likelihood`` (T,); ``/fit`` (T,); datasets of lengths and times carry ``units`` (``m``, ``s``;
``/poses`` ``dof_units``: ``m`` or ``rad`` per DOF, when given); root attrs ``gaitcap_version``, ``config`` (YAML),
``tracker``, ``height_m``, ``height_source``, ``session`` (the session folder, absolute), ``shape``
(a note), ``body_scales`` and ``body_shifts`` (JSON ``{segment: [x, y, z]}``: the proportions of the
tracked body model, so that its capsules can be drawn again; absent in runs before they were
recorded), ``filter``, ``skip_frames`` (YAML ``{camera: n}``: the frames skipped at the start of each camera's
video, :func:`skip_frames_attr`; absent in runs before they were recorded).

:func:`read_track_record` reads what the tracker recorded per frame (the report draws and plots it).
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import h5py
import numpy as np
import yaml

from gaitcap import __version__
from gaitcap.errors import InputError, OutputError
from gaitcap.io.atomic import atomic_path, check_free_space
from gaitcap.io.trajectories_h5 import label_units

if TYPE_CHECKING:
    from gaitcap.body.model import BodyModel

QUALITY_OK, QUALITY_POOR_FIT, QUALITY_OUT_OF_VIEW, QUALITY_NOT_INITIALISED = 0, 1, 2, 3
QUALITY_NAMES = {QUALITY_OK: "ok", QUALITY_POOR_FIT: "poor_fit", QUALITY_OUT_OF_VIEW: "out_of_view",
                 QUALITY_NOT_INITIALISED: "not_initialised"}  # fmt: skip
#: ``/quality``'s ``codes`` attribute: the file says what its numbers mean
QUALITY_CODES = ", ".join(f"{code} {name}" for code, name in QUALITY_NAMES.items())


def tracked_frames(quality: np.ndarray) -> np.ndarray:
    """(T,) bool: the frames the tracker estimated (quality ok or poor fit) among ``quality`` (T,)."""
    quality = np.asarray(quality)
    return (quality == QUALITY_OK) | (quality == QUALITY_POOR_FIT)


class TrackWriter:
    """Append per-frame results; ``finish`` completes and renames the file."""

    def __init__(self, path: str | Path, names: tuple[str, ...], dof_names: tuple[str, ...], rate_hz: float,
                 attrs: dict[str, Any], dof_units: tuple[str, ...] | None = None) -> None:  # fmt: skip
        self.path = Path(path)
        check_free_space(self.path.parent)
        self._stack = contextlib.ExitStack()
        tmp = self._stack.enter_context(atomic_path(self.path, suffix=".part.h5"))
        try:
            self._f = h5py.File(tmp, "w")
        except OSError as e:
            self._stack.close()
            raise OutputError(f"{self.path}: cannot write ({e})") from e
        P, D = len(names), len(dof_names)
        f = self._f
        self._ds = {
            "points_unfiltered": f.create_dataset("points_unfiltered", (0, P, 3), maxshape=(None, P, 3), chunks=(64, P, 3), dtype=np.float64),
            "spread": f.create_dataset("spread", (0, P), maxshape=(None, P), chunks=(256, P), dtype=np.float64),
            "poses": f.create_dataset("poses", (0, D), maxshape=(None, D), chunks=(256, D), dtype=np.float64),
            "likelihood": f.create_dataset("likelihood", (0,), maxshape=(None,), chunks=(1024,), dtype=np.float64),
            "fit": f.create_dataset("fit", (0,), maxshape=(None,), chunks=(1024,), dtype=np.float64),
            "quality": f.create_dataset("quality", (0,), maxshape=(None,), chunks=(1024,), dtype=np.uint8),
        }  # fmt: skip
        self._ds["poses"].attrs["dof_names"] = list(dof_names)
        self._ds["quality"].attrs["codes"] = QUALITY_CODES
        if dof_units is not None:
            if len(dof_units) != D:
                raise ValueError(f"dof_units must have {D} entries, got {len(dof_units)}")
            self._ds["poses"].attrs["dof_units"] = list(dof_units)
        self.names, self.rate_hz, self.n = names, rate_hz, 0
        f.attrs["gaitcap_version"] = __version__
        for k, v in attrs.items():
            f.attrs[k] = v

    def append(self, points: np.ndarray, uncertainty: np.ndarray, pose: np.ndarray, likelihood: float, fit: float,
               quality: int) -> None:  # fmt: skip
        """One frame: points (P, 3), uncertainty (P,) (the particles' spread), pose (D,)."""
        check_free_space(self.path.parent)
        i = self.n
        for key in self._ds:
            self._ds[key].resize(i + 1, axis=0)
        self.n += 1
        self.replace(i, points, uncertainty, pose, likelihood, fit, quality)

    def replace(self, i: int, points: np.ndarray, uncertainty: np.ndarray | None, pose: np.ndarray,
                likelihood: float, fit: float, quality: int) -> None:  # fmt: skip
        """Overwrite frame ``i`` (already written) with another estimate, as :meth:`append` takes it
        (``uncertainty`` None: the frame's is kept)."""
        if not 0 <= i < self.n:
            raise IndexError(f"frame {i} not written yet ({self.n} frames)")
        for key, value in (("points_unfiltered", points), ("spread", uncertainty), ("poses", pose),
                           ("likelihood", likelihood), ("fit", fit), ("quality", quality)):  # fmt: skip
            if value is not None:
                self._ds[key][i] = value

    def read_back(self) -> tuple[np.ndarray, np.ndarray]:
        """(points_unfiltered (T, P, 3), quality (T,)) written so far."""
        return self._ds["points_unfiltered"][()], self._ds["quality"][()]

    def read_fit(self) -> np.ndarray:
        """The fit (T,) written so far."""
        return self._ds["fit"][()]

    def read_poses(self) -> np.ndarray:
        """The poses (T, D) written so far."""
        return self._ds["poses"][()]

    def finish(self, points: np.ndarray, filter_note: str, uncertainty: np.ndarray | None = None) -> None:
        """Write ``/points`` (T, P, 3) (flagged frames NaN), ``/times`` and ``/uncertainty`` (T, P)
        (the spread when None), close and rename."""
        f = self._f
        spread = self._ds["spread"][()]
        if uncertainty is not None and np.shape(uncertainty) != spread.shape:
            raise ValueError(f"uncertainty must have shape {spread.shape}, got {np.shape(uncertainty)}")
        f.create_dataset("uncertainty", data=spread if uncertainty is None else np.asarray(uncertainty, np.float64))
        ds = f.create_dataset("points", data=points)
        ds.attrs["names"] = list(self.names)
        ds.attrs["rate_hz"] = self.rate_hz
        ds.attrs["t0_s"] = 0.0
        f.create_dataset("times", data=np.arange(self.n) / self.rate_hz)
        f.attrs["filter"] = filter_note
        label_units(f)
        f.close()
        self._stack.close()

    def abort(self, exc: BaseException) -> None:
        """Close and remove the temporary file, ``exc`` the reason: nothing is written."""
        with contextlib.suppress(Exception):
            self._f.close()
        self._stack.__exit__(type(exc), exc, exc.__traceback__)

    def discard(self) -> None:
        """Close and remove the temporary file of a run that is not kept: nothing is written."""
        self.abort(OutputError(f"{self.path}: the run was not kept"))


def proportions_attrs(model: BodyModel) -> dict[str, str]:
    """The root attributes ``body_scales`` and ``body_shifts`` of ``model`` (JSON)."""
    scales, shifts = model.proportions()
    return {"body_scales": json.dumps(scales), "body_shifts": json.dumps(shifts)}


@dataclass(frozen=True)
class TrackRecord:
    """What the tracker recorded per frame, beside the points (T frames, P points, D DOF).

    Attributes:
        names: point names (P,).
        rate_hz: frame rate.
        points: the tracker's raw estimate (T, P, 3) metres (``/points_unfiltered``; NaN where no
            pose was estimated: subject out of view or not found).
        uncertainty: per-point uncertainty (T, P) metres.
        poses: the body model's pose (T, D); ``dof_names`` (D,).
        fit: silhouette fit (T,), 0..1.
        quality: per-frame flag (T,) uint8, see ``QUALITY_NAMES``.
        attrs: the file's root attributes (config YAML, height_m, session, shape, ...).
    """

    names: tuple[str, ...]
    rate_hz: float
    points: np.ndarray
    uncertainty: np.ndarray
    poses: np.ndarray
    dof_names: tuple[str, ...]
    fit: np.ndarray
    quality: np.ndarray
    attrs: dict[str, Any] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return len(self.fit)

    def proportions(self) -> tuple[dict[str, list[float]], dict[str, list[float]]] | None:
        """The tracked model's (scales, shifts), or None when the run did not record them."""
        if "body_scales" not in self.attrs or "body_shifts" not in self.attrs:
            return None
        return json.loads(self.attrs["body_scales"]), json.loads(self.attrs["body_shifts"])


_RECORD_DATASETS = ("points_unfiltered", "uncertainty", "poses", "fit", "quality")


def _str(v: Any) -> Any:
    return v.decode() if isinstance(v, bytes) else v


def skip_frames_attr(offsets: Mapping[str, int]) -> str:
    """The root attribute ``skip_frames`` of a run's ``offsets`` (camera -> frames skipped at the start of
    its video, every camera): YAML, ``{cam1: 2, cam2: 0}``."""
    return yaml.safe_dump(dict(offsets), default_flow_style=True).strip()


def skip_frames_of(attrs: Mapping[str, Any]) -> dict[str, int] | None:
    """The ``skip_frames`` of a file's root attributes (:func:`skip_frames_attr`), None when the run
    did not record them."""
    recorded = attrs.get("skip_frames")
    if recorded is None:
        return None
    return {str(c): int(n) for c, n in (yaml.safe_load(str(_str(recorded))) or {}).items()}


def read_root_attrs(path: str | Path, *names: str) -> dict[str, Any]:
    """The root attributes ``names`` of an HDF5 file that it holds (bytes decoded); empty when it cannot
    be read (the callers' notes are optional)."""
    try:
        with h5py.File(Path(path), "r") as f:
            values = {n: f.attrs[n] for n in names if n in f.attrs}
    except OSError:
        return {}
    return {n: v.decode("utf-8", "replace") if isinstance(v, bytes) else v for n, v in values.items()}


def read_track_record(path: str | Path) -> TrackRecord | None:
    """The per-frame record of a tracker's ``trajectories.h5``, or None for a file without one
    (a trajectory written by another tool).

    Raises:
        InputError: not a readable HDF5 file, or datasets of inconsistent lengths (named).
    """
    path = Path(path)
    try:
        with h5py.File(path, "r") as f:
            if not all(k in f for k in _RECORD_DATASETS) or "points" not in f:
                return None
            data = {k: f[k][()] for k in _RECORD_DATASETS}
            names = tuple(_str(n) for n in f["points"].attrs["names"])
            rate = float(f["points"].attrs["rate_hz"])
            dofs = tuple(_str(n) for n in f["poses"].attrs.get("dof_names", ()))
            attrs = {k: _str(v) for k, v in f.attrs.items()}
    except OSError as e:
        raise InputError(f"{path}: not a readable HDF5 file ({e})") from e
    lengths = {k: len(v) for k, v in data.items()}
    if len(set(lengths.values())) != 1:
        raise InputError(f"{path}: per-frame datasets of different lengths: {lengths}")
    return TrackRecord(names, rate, data["points_unfiltered"], data["uncertainty"], data["poses"], dofs,
                       data["fit"], data["quality"], attrs)  # fmt: skip
