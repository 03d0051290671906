"""``calibration.toml``: one table per camera, the Pose2Sim / anipose convention.

```toml
[cam01]
name = "cam01"
size = [640.0, 480.0]                       # [w, h] pixels
matrix = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]
distortions = [k1, k2, p1, p2]              # OpenCV order: 4, 5 (+ k3), 8, 12 or 14 values
rotation = [rx, ry, rz]                     # Rodrigues vector, world -> camera
translation = [tx, ty, tz]                  # world -> camera, metres
fisheye = false

[metadata]                                  # optional, ignored on reading cameras
adjusted = false
error = 0.0
```
World frame: metres, z up, the floor is z = 0.
"""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

import tomli_w

from gaitcap.camera import Camera, CameraRig
from gaitcap.errors import CalibrationError
from gaitcap.io.atomic import write_text_atomic

METADATA_TABLE = "metadata"


def _read_toml(path: Path) -> dict[str, Any]:
    """The TOML document of ``path``; :class:`CalibrationError` naming the file when it cannot be read."""
    try:
        return tomllib.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as e:
        raise CalibrationError(f"{path}: calibration file not found") from e
    except (OSError, UnicodeDecodeError) as e:
        raise CalibrationError(f"{path}: cannot read ({e})") from e
    except tomllib.TOMLDecodeError as e:
        raise CalibrationError(f"{path}: not valid TOML: {e}") from e


def read_calibration(path: str | Path) -> CameraRig:
    """Read ``calibration.toml`` into a :class:`CameraRig` (cameras in file order).

    Raises:
        CalibrationError: a missing or unreadable file, or a malformed camera table (named).
    """
    path = Path(path)
    data = _read_toml(path)
    cams = []
    for key, table in data.items():
        if key == METADATA_TABLE:
            continue
        if not isinstance(table, dict):
            raise CalibrationError(f"{path}: '{key}' should be a table of camera parameters")
        table = dict(table)
        table.setdefault("name", key)
        cams.append(Camera.from_dict(table, source=str(path)))
    if not cams:
        raise CalibrationError(f"{path}: no camera tables found")
    names = [cam.name for cam in cams]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        tables = [key for key in data if key != METADATA_TABLE and str(data[key].get("name", key)) in dup]
        raise CalibrationError(f"{path}: the tables {', '.join(f'[{k}]' for k in tables)} give the same camera name "
                               f"{', '.join(map(repr, dup))}: each camera needs its own (its video's name)")
    return CameraRig(tuple(cams))


def read_calibration_metadata(path: str | Path) -> dict[str, Any]:
    """The optional ``[metadata]`` table (empty when absent).

    Raises:
        CalibrationError: a missing or unreadable file (named), as :func:`read_calibration`.
    """
    data = _read_toml(Path(path))
    meta = data.get(METADATA_TABLE, {})
    return dict(meta) if isinstance(meta, dict) else {}


def calibration_to_toml(rig: CameraRig, metadata: dict[str, Any] | None = None) -> str:
    """Serialise a rig as ``calibration.toml`` text."""
    doc: dict[str, Any] = {cam.name: cam.to_dict() for cam in rig}
    doc[METADATA_TABLE] = {"adjusted": False, "error": 0.0, **(metadata or {})}
    return tomli_w.dumps(doc)


def write_calibration(path: str | Path, rig: CameraRig, metadata: dict[str, Any] | None = None) -> None:
    """Write ``calibration.toml`` atomically."""
    write_text_atomic(path, calibration_to_toml(rig, metadata))
