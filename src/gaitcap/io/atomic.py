"""Atomic file output: write to a temporary name beside the target, then rename.

A run killed in the middle never leaves a truncated file under the final name.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import tempfile
from collections.abc import Iterable, Iterator
from pathlib import Path

from gaitcap.errors import OutputError


def _umask() -> int:
    umask = os.umask(0)
    os.umask(umask)
    return umask


def default_file_mode() -> int:
    """The mode a new file gets under the current umask (temporary files are created 0600)."""
    return 0o666 & ~_umask()


def default_dir_mode() -> int:
    """The mode a new folder gets under the current umask (temporary folders are created 0700)."""
    return 0o777 & ~_umask()


#: the free space (bytes) a run leaves on the disk it writes to: below it, it stops with an error rather
#: than fill the disk, since the HDF5 library cannot close a file cleanly once a write has failed
#: (h5py issue 914: the process crashes)
MIN_FREE_BYTES = 32_000_000


def check_free_space(folder: str | Path, min_bytes: int = MIN_FREE_BYTES) -> None:
    """Raise :class:`OutputError` when the disk holding ``folder`` (or, before it is made, its nearest
    existing parent) has less than ``min_bytes`` free: called before a run's work, before a stream's
    file is opened and as each frame is written (a disk whose space cannot be read is not checked)."""
    existing = next((p for p in (Path(folder), *Path(folder).parents) if p.exists()), None)
    try:
        free = shutil.disk_usage(existing if existing is not None else ".").free
    except OSError:
        return
    if free < min_bytes:
        raise OutputError(f"{folder}: {free / 1e6:.1f} MB free on its disk, under the {min_bytes / 1e6:.0f} MB a run "
                          "keeps: stopped before the disk is full (an HDF5 file cannot be closed cleanly on a full "
                          "disk); free some space and run again")  # fmt: skip


def refuse_existing(path: str | Path, force: bool) -> None:
    """Raise :class:`OutputError` when ``path`` exists and ``force`` is not given (called before the work, so
    that nothing is computed and then refused)."""
    if Path(path).exists() and not force:
        raise OutputError(f"{path}: exists already (use --force to overwrite)")


def file_in_the_way(folder: str | Path) -> Path | None:
    """The file (not a folder) at ``folder`` or at one of its parents, which keeps ``folder`` from being
    a folder; None when there is none."""
    folder = Path(folder)
    return next((p for p in (folder, *folder.parents) if p.exists() and not p.is_dir()), None)


def unwritable(target: str | Path, error: OSError) -> OutputError:
    """The error to raise when nothing can be created beside ``target`` (``error``): naming the file that
    stands where one of its folders must be, else the reason."""
    blocker = file_in_the_way(Path(target).parent)
    if blocker is not None:
        return OutputError(f"{blocker}: is a file, not a folder: cannot write {target} under it")
    return OutputError(f"{target}: cannot write here ({error.strerror})")


def check_output_folder(folder: str | Path) -> None:
    """Raise :class:`OutputError` when a file stands where the output folder ``folder`` (or one of its
    parents) must be (called before the work, so that nothing is computed and then refused)."""
    blocker = file_in_the_way(folder)
    if blocker is not None:
        raise OutputError(f"{blocker}: is a file, not a folder; give an output folder{_under(blocker, folder)}")


def _under(blocker: Path, folder: str | Path) -> str:
    return "" if blocker == Path(folder) else f" (for {folder})"


def remove_replaced(paths: Iterable[Path]) -> None:
    """Remove an earlier run's outputs (files or folders) that a new run replaces.

    Raises:
        OutputError: naming the first that cannot be removed.
    """
    for path in paths:
        try:
            if path.is_dir():
                shutil.rmtree(path)
            else:
                path.unlink()
        except OSError as e:
            raise OutputError(f"{path}: cannot remove the replaced run's {path.name} ({e.strerror})") from e


def remove_stale_parts(folder: str | Path) -> None:
    """Remove the temporary files that :func:`atomic_path` left in ``folder`` when a run was killed
    (``.<name>.*.part*``); a missing folder has none."""
    for stale in Path(folder).glob(".*.part*"):
        stale.unlink(missing_ok=True)


@contextlib.contextmanager
def atomic_path(target: str | Path, suffix: str | None = None) -> Iterator[Path]:
    """Yield a temporary path in ``target``'s folder; on success rename it to ``target``.

    On any exception the temporary file is removed and ``target`` is left untouched.
    """
    target = Path(target)
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(
            prefix=f".{target.name}.", suffix=suffix or (target.suffix + ".part"), dir=target.parent
        )
    except OSError as e:
        raise unwritable(target, e) from e
    os.close(fd)
    tmp_path = Path(tmp)
    try:
        yield tmp_path
        if tmp_path.exists():
            os.chmod(tmp_path, default_file_mode())
        os.replace(tmp_path, target)
    except OSError as e:
        tmp_path.unlink(missing_ok=True)
        raise OutputError(f"{target}: write failed ({e.strerror})") from e
    except BaseException:
        tmp_path.unlink(missing_ok=True)
        raise


def write_text_atomic(target: str | Path, text: str) -> None:
    """Write ``text`` to ``target`` atomically (UTF-8)."""
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")


def write_bytes_atomic(target: str | Path, data: bytes) -> None:
    """Write ``data`` to ``target`` atomically."""
    with atomic_path(target) as tmp:
        tmp.write_bytes(data)
