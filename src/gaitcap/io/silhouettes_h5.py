"""Read and write ``silhouettes.h5``: masks and per-frame quality, streamed frame by frame.

Layout (the same mask convention as ``truth.h5`` of ``gaitcap synth``; the readers also take a
truth folder's ``masks.h5``, whose (T, H, W) datasets are at the root, one per camera)::

    /masks/<camera>            uint8 (T, H, W) 0/1, gzip, one chunk per frame
                               attrs: fps, video, background_source, background_usable,
                               background_message, ambiguous_fraction
    /quality/<camera>/fraction          float32 (T,)  foreground pixels / image pixels
    /quality/<camera>/shadow_fraction   float32 (T,)
    /quality/<camera>/components        int16 (T,)
    /quality/<camera>/flags             uint8 (T,)    bit field, see attrs flag_<name>
    /quality/<camera>/bbox              int32 (T, 4)  x, y, w, h; -1 when empty
    /background/<camera>       uint8 (h, w, 3) BGR, the initial background (working scale)
    attrs: config (YAML text), flag_empty, flag_border, flag_too_large, flag_no_background

The file is written under a temporary name and renamed when closed without error.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from types import TracebackType
from typing import Any

import h5py
import numpy as np

from gaitcap.errors import InputError, OutputError
from gaitcap.io.atomic import atomic_path, check_free_space

#: the file name of the silhouettes in an output folder (``gaitcap silhouettes``, ``gaitcap track --save-masks``)
SILHOUETTES_FILE = "silhouettes.h5"

_QUALITY = {
    "fraction": (np.float32, ()),
    "shadow_fraction": (np.float32, ()),
    "components": (np.int16, ()),
    "flags": (np.uint8, ()),
    "bbox": (np.int32, (4,)),
}


class SilhouetteWriter:
    """Stream masks and quality rows of several cameras into one HDF5 file (atomically).

    Use as a context manager; call :meth:`add_camera` once per camera, then :meth:`append`
    once per frame.
    """

    def __init__(self, path: str | Path, attrs: dict[str, Any] | None = None) -> None:
        self.path = Path(path)
        check_free_space(self.path.parent)
        self._stack = contextlib.ExitStack()
        tmp = self._stack.enter_context(atomic_path(self.path))
        try:
            self._h5 = h5py.File(tmp, "w")
        except OSError as e:
            self._stack.close()
            raise OutputError(f"{self.path}: cannot create HDF5 file ({e})") from e
        for key, value in (attrs or {}).items():
            self._h5.attrs[key] = value
        self._count: dict[str, int] = {}

    def __enter__(self) -> SilhouetteWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._h5.close()
        # the atomic_path context renames on success and removes the temporary file on error
        self._stack.__exit__(exc_type, exc, tb)

    def add_camera(self, camera: str, width: int, height: int, background: np.ndarray | None, attrs: dict[str, Any]) -> None:
        """Create the datasets of ``camera`` (frames of ``width`` x ``height``)."""
        masks = self._h5.create_dataset(
            f"masks/{camera}", shape=(0, height, width), maxshape=(None, height, width), dtype=np.uint8,
            chunks=(1, height, width), compression="gzip", compression_opts=1,
        )
        for key, value in attrs.items():
            masks.attrs[key] = value
        for name, (dtype, tail) in _QUALITY.items():
            self._h5.create_dataset(
                f"quality/{camera}/{name}", shape=(0, *tail), maxshape=(None, *tail), dtype=dtype,
                chunks=(1024, *tail),
            )
        if background is not None:
            self._h5.create_dataset(f"background/{camera}", data=background, compression="gzip")
        self._count[camera] = 0

    def append(self, camera: str, mask: np.ndarray, quality: dict[str, Any]) -> None:
        """Add one frame: ``mask`` (H, W) uint8 0/1 and its quality values (keys of the layout)."""
        check_free_space(self.path.parent)
        t = self._count[camera]
        ds = self._h5[f"masks/{camera}"]
        ds.resize(t + 1, axis=0)
        ds[t] = mask
        for name in _QUALITY:
            q = self._h5[f"quality/{camera}/{name}"]
            q.resize(t + 1, axis=0)
            q[t] = quality[name]
        self._count[camera] = t + 1

    def set_attrs(self, camera: str, attrs: dict[str, Any]) -> None:
        for key, value in attrs.items():
            self._h5[f"masks/{camera}"].attrs[key] = value


def _open(path: str | Path) -> h5py.File:
    try:
        return h5py.File(path, "r")
    except (OSError, FileNotFoundError) as e:
        raise InputError(f"{path}: cannot open as HDF5 ({e})") from e


def _mask_group(path: str | Path, f: h5py.File) -> h5py.Group:
    """Where the masks are: the ``/masks`` group, or the root when it holds (T, H, W) datasets of 0/1
    (a truth folder's ``masks.h5``: one uint8 dataset per camera; not a trajectories.h5's points)."""
    if "masks" in f and isinstance(f["masks"], h5py.Group):
        return f["masks"]
    if any(_is_masks(d) for d in f.values()):
        return f
    raise InputError(f"{path}: no masks (neither a /masks group nor (frames, H, W) uint8 datasets at the root)")


def _is_masks(item: h5py.Group | h5py.Dataset) -> bool:
    """A (frames, H, W) dataset of integers or booleans."""
    return isinstance(item, h5py.Dataset) and item.ndim == 3 and item.dtype.kind in "uib"


def _mask_dataset(path: str | Path, f: h5py.File, camera: str) -> h5py.Dataset:
    group = _mask_group(path, f)
    if camera not in group or not isinstance(group[camera], h5py.Dataset):
        raise InputError(f"{path}: no masks for camera {camera!r} (have: {', '.join(group.keys())})")
    ds = group[camera]
    if ds.ndim != 3:
        raise InputError(f"{path}: masks of camera {camera!r} must be (frames, H, W), got shape {ds.shape}")
    return ds


def read_cameras(path: str | Path) -> list[str]:
    """Names of the cameras stored in a silhouettes (or truth) HDF5 file."""
    with _open(path) as f:
        group = _mask_group(path, f)
        return [k for k, v in group.items() if _is_masks(v)]


def read_masks(path: str | Path, camera: str, frames: slice | None = None) -> np.ndarray:
    """Masks of ``camera``: (T, H, W) uint8 0/1 (or the ``frames`` slice of them)."""
    with _open(path) as f:
        return _mask_dataset(path, f, camera)[frames if frames is not None else slice(None)]


def read_mask_shape(path: str | Path, camera: str) -> tuple[int, int, int]:
    """(T, H, W) of ``camera``'s masks, without reading them."""
    with _open(path) as f:
        return tuple(_mask_dataset(path, f, camera).shape)  # type: ignore[return-value]


def read_quality(path: str | Path, camera: str) -> dict[str, np.ndarray]:
    """Quality arrays of ``camera`` (keys: fraction, shadow_fraction, components, flags, bbox)."""
    with _open(path) as f:
        key = f"quality/{camera}"
        if key not in f:
            raise InputError(f"{path}: no quality records for camera {camera!r}")
        return {name: f[key][name][()] for name in f[key]}


def read_mask_attrs(path: str | Path, camera: str) -> dict[str, Any]:
    """The attributes stored with a camera's masks (background provenance, fps, video).

    Raises:
        InputError: the file cannot be opened or holds no masks of ``camera`` (named).
    """
    with _open(path) as f:
        return dict(_mask_dataset(path, f, camera).attrs)
