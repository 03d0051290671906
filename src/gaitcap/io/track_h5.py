"""Streaming writer of the tracker's ``trajectories.h5`` (same layout as gaitcap.io.trajectories_h5).

Rows are appended frame by frame to resizable datasets in a temporary file beside the target,
so memory does not grow with the video; :meth:`TrackWriter.finish` writes the last datasets and
renames the file into place. A run killed before that leaves no ``trajectories.h5``.

Layout: ``/points`` (T, P, 3) metres, NaN where flagged (filtered when smoothing is on), attrs
``names``, ``rate_hz``, ``t0_s``; ``/points_unfiltered`` (T, P, 3) the tracker's raw estimate,
never NaN; ``/times`` (T,); ``/uncertainty`` (T, P) metres, calibrated after tracking
(gaitcap.quality; the particles' spread when none is given); ``/spread`` (T, P) metres, the weighted
spread of the tracker's particles; ``/quality`` (T,) uint8 (0 ok,
1 poor fit, 2 subject out of view, 3 not initialised); ``/poses`` (T, D) attr ``dof_names``;
``/likelihood`` (T,); ``/fit`` (T,); root attrs ``gaitcap_version``, ``config`` (YAML),
``tracker``, ``height_m``, ``height_source``, ``filter``.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from gaitcap import __version__
from gaitcap.errors import OutputError
from gaitcap.io.atomic import atomic_path

QUALITY_OK, QUALITY_POOR_FIT, QUALITY_OUT_OF_VIEW, QUALITY_NOT_INITIALISED = 0, 1, 2, 3
QUALITY_NAMES = {QUALITY_OK: "ok", QUALITY_POOR_FIT: "poor_fit", QUALITY_OUT_OF_VIEW: "out_of_view",
                 QUALITY_NOT_INITIALISED: "not_initialised"}  # fmt: skip


class TrackWriter:
    """Append per-frame results; ``finish`` completes and renames the file."""

    def __init__(self, path: str | Path, names: tuple[str, ...], dof_names: tuple[str, ...], rate_hz: float,
                 attrs: dict[str, Any]) -> None:  # fmt: skip
        self.path = Path(path)
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
        self.names, self.rate_hz, self.n = names, rate_hz, 0
        f.attrs["gaitcap_version"] = __version__
        for k, v in attrs.items():
            f.attrs[k] = v

    def append(self, points: np.ndarray, uncertainty: np.ndarray, pose: np.ndarray, likelihood: float, fit: float,
               quality: int) -> None:  # fmt: skip
        """One frame: points (P, 3), uncertainty (P,) (the particles' spread), pose (D,)."""
        i = self.n
        for key, value in (("points_unfiltered", points), ("spread", uncertainty), ("poses", pose),
                           ("likelihood", likelihood), ("fit", fit), ("quality", quality)):  # fmt: skip
            ds = self._ds[key]
            ds.resize(i + 1, axis=0)
            ds[i] = value
        self.n += 1

    def read_back(self) -> tuple[np.ndarray, np.ndarray]:
        """(points_unfiltered (T, P, 3), quality (T,)) written so far."""
        return self._ds["points_unfiltered"][()], self._ds["quality"][()]

    def read_fit(self) -> np.ndarray:
        """The fit (T,) written so far."""
        return self._ds["fit"][()]

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
        f.close()
        self._stack.close()

    def abort(self, exc: BaseException) -> None:
        with contextlib.suppress(Exception):
            self._f.close()
        self._stack.__exit__(type(exc), exc, exc.__traceback__)
