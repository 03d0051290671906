"""``truth.h5``: the ground truth of a synthetic session.

Layout (shared with ``trajectories.h5`` for the point data):

- ``/points`` (T, P, 3) float64 metres, attrs ``names``, ``rate_hz``, ``t0_s`` (0: video time)
- ``/times`` (T,) seconds
- ``/poses`` (T, D) float64 (radians, root translation metres), attr ``dof_names``
- ``/raw_points`` (T, K, 3): the marker-derived joint centres the model was fitted to, attr ``names``
- ``/fit_residual_m`` (K,): mean distance between the model and ``raw_points``
- ``/events/time_s``, ``/events/side``, ``/events/event``, ``/events/source``: the recording's events
- ``/masks/<camera>`` (T, H, W) uint8 0/1, gzip, one chunk per frame
- root attributes: ``gaitcap_version``, ``source_motion``, ``source_t0_s``, ``height_m``,
  ``proportions`` (JSON scales and shifts), ``options`` (JSON)
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import h5py
import numpy as np

from gaitcap.errors import InputError
from gaitcap.trajectory import GaitEvent, Trajectory


def write_events(group: h5py.Group, events: tuple[GaitEvent, ...]) -> None:
    """Write events as parallel datasets under ``group``."""
    group.create_dataset("time_s", data=np.array([e.time_s for e in events], dtype=np.float64))
    for key in ("side", "event", "source"):
        group.create_dataset(key, data=np.array([getattr(e, key) for e in events], dtype=h5py.string_dtype()))


def read_events(group: h5py.Group) -> tuple[GaitEvent, ...]:
    times = group["time_s"][()]
    cols = {k: [v.decode() if isinstance(v, bytes) else str(v) for v in group[k][()]] for k in ("side", "event", "source")}
    return tuple(
        GaitEvent(float(t), cols["side"][i], cols["event"][i], cols["source"][i])  # type: ignore[arg-type]
        for i, t in enumerate(times)
    )


@dataclass
class Truth:
    """An opened ``truth.h5`` (masks are read lazily, frame by frame)."""

    path: Path
    trajectory: Trajectory
    poses: np.ndarray
    dof_names: tuple[str, ...]
    cameras: tuple[str, ...]
    attrs: dict

    def mask(self, camera: str, frame: int) -> np.ndarray:
        """Ground-truth silhouette (H, W) uint8 0/1 of ``camera`` at ``frame``."""
        with h5py.File(self.path, "r") as f:
            if camera not in f["masks"]:
                raise InputError(f"{self.path}: no masks for camera {camera!r} (cameras: {', '.join(self.cameras)})")
            return f["masks"][camera][frame]


def read_truth(path: str | Path) -> Truth:
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: truth file not found")
    try:
        with h5py.File(path, "r") as f:
            pts = f["points"]
            traj = Trajectory(
                names=tuple(str(n) for n in pts.attrs["names"]),
                points=pts[()],
                rate_hz=float(pts.attrs["rate_hz"]),
                t0_s=float(pts.attrs.get("t0_s", 0.0)),
                events=read_events(f["events"]) if "events" in f else (),
                meta={"source": str(path)},
            )
            attrs = {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()}
            for key in ("proportions", "options"):
                if key in attrs:
                    attrs[key] = json.loads(attrs[key])
            return Truth(
                path=path,
                trajectory=traj,
                poses=f["poses"][()],
                dof_names=tuple(str(n) for n in f["poses"].attrs["dof_names"]),
                cameras=tuple(f["masks"].keys()) if "masks" in f else (),
                attrs=attrs,
            )
    except (OSError, KeyError) as e:
        raise InputError(f"{path}: not a gaitcap truth file ({e})") from e
