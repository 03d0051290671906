"""C3D motion files (read only), through ezc3d.

What is read:

- marker points (POINT channels that are not model outputs: labels listed in POINT:ANGLES,
  FORCES, MOMENTS, POWERS, REACTIONS are left out; virtual points such as Vicon's KJC/AJC or
  PELO/LFEO are kept), converted to metres from POINT:UNITS, in the file's axes;
- time: ``t0_s = first_frame / rate`` where ``first_frame`` is ezc3d's 0-based header value
  (the C3D header stores it 1-based: a Vicon file with header frame 153 starts at 1.52 s at
  100 Hz), so frame i is at ``t0_s + i / rate``, the axis C3D EVENT:TIMES use;
- events from the EVENT group: contexts Left/Right, labels Foot Strike/Foot Off (a subject
  prefix such as ``A22:Foot Strike`` is ignored);
- subject height from PROCESSING:Height (``meta["height_m"]``), and Plug-in-Gait's knee and ankle
  widths and marker diameter (LKneeWidth, RKneeWidth, LAnkleWidth, RAnkleWidth, MarkerDiameter,
  mm: ``meta["anthropometry_mm"]``, those present);
- the file's up axis from POINT:Y_SCREEN (``meta["up_axis"]``, e.g. ``"+Z"`` -> ``"z"``);
- model angles (POINT:ANGLES channels, degrees) through :func:`read_c3d_angles`.

Force plates (FORCE_PLATFORM group, through ezc3d's ``extract_forceplat_data``) are read by
:func:`read_c3d_plates`: vertical force and centre of pressure in the lab frame. Other analog
channels (EMG) are never read.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from gaitcap.errors import InputError
from gaitcap.markers.axes import metres_per_unit
from gaitcap.trajectory import GaitEvent, Trajectory

log = logging.getLogger("gaitcap.io.c3d")

#: POINT sub-groups whose labels are model outputs, not positions.
NON_POSITION_GROUPS: tuple[str, ...] = ("ANGLES", "FORCES", "MOMENTS", "POWERS", "REACTIONS", "SCALARS")

_EVENT_KINDS = {"foot strike": "foot_strike", "foot off": "foot_off"}
_EVENT_SIDES = {"left": "left", "right": "right"}


@dataclass(frozen=True)
class AngleSeries:
    """Model angles stored in a C3D file.

    Attributes:
        names: channel labels, length A (e.g. ``LKneeAngles``).
        values: degrees, shape (T, A, 3); NaN where missing.
        rate_hz, t0_s: the same time axis as the file's markers.
    """

    names: tuple[str, ...]
    values: np.ndarray
    rate_hz: float
    t0_s: float

    def get(self, name: str) -> np.ndarray:
        """One channel, shape (T, 3)."""
        try:
            return self.values[:, self.names.index(name)]
        except ValueError:
            raise InputError(f"no angle channel {name!r} (channels: {', '.join(self.names)})") from None


@dataclass(frozen=True)
class ForcePlate:
    """One force plate of a C3D file, on the analog time axis.

    Attributes:
        force: ground reaction force on the subject, N, shape (N, 3), the file's axes.
        cop: centre of pressure, metres, shape (N, 3), the file's axes (NaN when unloaded).
        rate_hz: analog rate; t0_s: time of the first sample (the points' first frame).
    """

    force: np.ndarray
    cop: np.ndarray
    rate_hz: float
    t0_s: float

    def times(self) -> np.ndarray:
        return self.t0_s + np.arange(self.force.shape[0]) / self.rate_hz


def _open(path: Path, plates: bool = False) -> Any:
    import ezc3d

    if not path.is_file():
        raise InputError(f"{path}: C3D file not found")
    try:
        return ezc3d.c3d(str(path), extract_forceplat_data=plates)
    except Exception as e:  # ezc3d raises plain RuntimeError/IOError
        raise InputError(f"{path}: cannot read C3D file ({e})") from e


def _param(c3d: Any, group: str, name: str, default: Any = None) -> Any:
    try:
        return c3d["parameters"][group][name]["value"]
    except KeyError:
        return default


def _strings(values: Any) -> list[str]:
    return [str(v).strip() for v in (values if values is not None else [])]


def _time_axis(c3d: Any) -> tuple[float, float]:
    rate = float(c3d["header"]["points"]["frame_rate"])
    if not rate > 0:
        raise InputError("C3D header point rate is not positive")
    return rate, float(c3d["header"]["points"]["first_frame"]) / rate


def _points(c3d: Any, labels: list[str], keep: list[int]) -> np.ndarray:
    """POINT data of the kept channels, shape (T, len(keep), 3), NaN where the residual is < 0."""
    data = np.asarray(c3d["data"]["points"], dtype=np.float64)[:3, keep, :]
    residuals = np.asarray(c3d["data"]["meta_points"]["residuals"])[0, keep, :]
    data[:, residuals < 0] = np.nan
    return np.transpose(data, (2, 1, 0))


def _events(c3d: Any, source: Path) -> tuple[GaitEvent, ...]:
    labels = _strings(_param(c3d, "EVENT", "LABELS"))
    contexts = _strings(_param(c3d, "EVENT", "CONTEXTS"))
    times = _param(c3d, "EVENT", "TIMES")
    if not labels or times is None:
        return ()
    times = np.asarray(times, dtype=np.float64).reshape(2, -1)
    seconds = 60.0 * times[0] + times[1]  # row 0 minutes, row 1 seconds; float32 in the file
    out = []
    for label, context, t in zip(labels, contexts, seconds, strict=False):
        kind = _EVENT_KINDS.get(_unprefixed(label).lower().replace("_", " "))
        side = _EVENT_SIDES.get(_unprefixed(context).lower())
        if kind is None or side is None:
            log.debug("%s: event %s/%s at %.3f s ignored", source, context, label, t)
            continue
        out.append(GaitEvent(round(float(t), 6), side, kind, source="c3d"))  # type: ignore[arg-type]
    return tuple(sorted(out))


def _unprefixed(text: str) -> str:
    """``"A22:Foot Strike"`` -> ``"Foot Strike"`` (some systems prefix event labels with the subject)."""
    return text.rsplit(":", 1)[-1].strip()


def _height_m(c3d: Any) -> float | None:
    value = _param(c3d, "PROCESSING", "Height")
    if value is None or len(np.atleast_1d(value)) == 0:
        return None
    h = float(np.atleast_1d(value)[0])
    if not h > 0:
        return None
    return h / 1000.0 if h > 3.0 else h  # Vicon stores millimetres; a value above 3 cannot be metres


#: Plug-in-Gait subject measurements read from PROCESSING (millimetres) and their plausible range
ANTHROPOMETRY_MM: dict[str, tuple[float, float]] = {
    "LKneeWidth": (40.0, 250.0), "RKneeWidth": (40.0, 250.0),
    "LAnkleWidth": (30.0, 200.0), "RAnkleWidth": (30.0, 200.0),
    "MarkerDiameter": (3.0, 40.0),
}  # fmt: skip


def _anthropometry_mm(c3d: Any, source: Path) -> dict[str, float]:
    """The subject's Plug-in-Gait measurements in PROCESSING (mm), those present and plausible."""
    out: dict[str, float] = {}
    for key, (low, high) in ANTHROPOMETRY_MM.items():
        value = np.atleast_1d(_param(c3d, "PROCESSING", key, []))
        if value.size == 0 or not np.isfinite(float(value[0])) or float(value[0]) == 0.0:
            continue
        if low <= float(value[0]) <= high:
            out[key] = float(value[0])
        else:
            log.warning("%s: PROCESSING:%s = %g is not a plausible width in mm (%g-%g); not used",
                        source, key, float(value[0]), low, high)  # fmt: skip
    return out


def _up_axis(c3d: Any) -> str | None:
    screen = _strings(_param(c3d, "POINT", "Y_SCREEN"))
    if screen and screen[0].upper() in ("+X", "+Y", "+Z"):
        return screen[0][1].lower()
    return None


def _non_position_labels(c3d: Any) -> set[str]:
    out: set[str] = set()
    for group in NON_POSITION_GROUPS:
        out.update(_strings(_param(c3d, "POINT", group)))
    return out


def read_c3d_markers(path: str | Path) -> Trajectory:
    """Read the marker (position) points of a C3D file, metres, file axes.

    Returns a :class:`Trajectory` whose names are the marker labels (model angle/force/moment/
    power channels left out), with the file's events and ``meta`` keys ``source``, ``format``,
    ``units``, ``up_axis`` (from POINT:Y_SCREEN, or None), ``height_m`` (or None) and
    ``anthropometry_mm`` (PROCESSING's knee/ankle widths and marker diameter present, mm).
    """
    path = Path(path)
    c3d = _open(path)
    labels = _strings(_param(c3d, "POINT", "LABELS"))
    n_channels = np.asarray(c3d["data"]["points"]).shape[1]
    if len(labels) < n_channels:  # more than 255 points: labels continue in LABELS2, LABELS3...
        for k in range(2, 10):
            labels += _strings(_param(c3d, "POINT", f"LABELS{k}"))
    labels = labels[:n_channels]
    skip = _non_position_labels(c3d)
    keep = [i for i, n in enumerate(labels) if n not in skip]
    units = (_strings(_param(c3d, "POINT", "UNITS")) or ["mm"])[0]
    scale = metres_per_unit(units, str(path))
    rate, t0 = _time_axis(c3d)
    meta = {"source": str(path), "format": "c3d", "units": units, "up_axis": _up_axis(c3d),
            "height_m": _height_m(c3d), "anthropometry_mm": _anthropometry_mm(c3d, path)}  # fmt: skip
    return Trajectory(
        names=tuple(labels[i] for i in keep),
        points=_points(c3d, labels, keep) * scale,
        rate_hz=rate,
        t0_s=t0,
        events=_events(c3d, path),
        meta=meta,
    )


def read_c3d_angles(path: str | Path) -> AngleSeries:
    """Read the model angle channels (POINT:ANGLES, degrees) of a C3D file, e.g. Plug-in-Gait's."""
    path = Path(path)
    c3d = _open(path)
    labels = _strings(_param(c3d, "POINT", "LABELS"))
    angle_names = set(_strings(_param(c3d, "POINT", "ANGLES")))
    keep = [i for i, n in enumerate(labels) if n in angle_names]
    rate, t0 = _time_axis(c3d)
    names = tuple(_unprefixed(labels[i]) for i in keep)  # "A22:LKneeAngles" -> "LKneeAngles"
    return AngleSeries(names, _points(c3d, labels, keep), rate, t0)


def read_c3d_plates(path: str | Path) -> list[ForcePlate]:
    """The force plates of a C3D file ([] when it has none or they cannot be read)."""
    path = Path(path)
    try:
        c3d = _open(path, plates=True)
    except InputError as e:
        log.info("%s: force plates not read (%s)", path, e)
        return []
    _, t0 = _time_axis(c3d)
    rate = float(c3d["header"]["analogs"]["frame_rate"])
    out = []
    for plate in c3d["data"].get("platform", []):
        scale = metres_per_unit(str(plate.get("unit_position", "mm")), str(path))
        force = np.asarray(plate["force"], dtype=np.float64).T
        cop = np.asarray(plate["center_of_pressure"], dtype=np.float64).T * scale
        out.append(ForcePlate(force, cop, rate, t0))
    return out
