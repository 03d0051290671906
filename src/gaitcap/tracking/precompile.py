"""Compile the numba kernels into numba's on-disk cache before their first use.

``python -m gaitcap.tracking.precompile`` fills the ``__pycache__`` folders next to
:mod:`gaitcap.tracking.raster`, :mod:`gaitcap.tracking.projector`, :mod:`gaitcap.tracking.contact`,
:mod:`gaitcap.tracking.particles` and
:mod:`gaitcap.synth.zbuffer` (``*.nbi`` indexes, ``*.nbc``
object code). The wheel build runs it on the built package (``setup.py``), so that ``pip install .``
installs the cache with the sources and the first run compiles nothing. A cache entry is used only
when everything it is keyed on matches: the source file's content (numba >= 0.68 stamps it with a
sha256 of the file, not its modification time, which pip does not keep), numba's version, the
Python version, the function's bytecode, the argument types and the CPU (name and features: a wheel
built on the machine that runs it). Otherwise numba compiles at first use as before and caches the
result where it can write. When the package's folder is read-only, the folder numba writes to
(``NUMBA_CACHE_DIR``, else its user-wide cache folder under HOME, else a private temporary folder of
the process) is first given a copy of the package's entries (:mod:`gaitcap.jit`), so a read-only
install compiles nothing either when they match.

Imports numpy and numba only (the build environment has nothing else).
"""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Sequence

from gaitcap.synth import zbuffer
from gaitcap.tracking import contact, particles, projector, raster

log = logging.getLogger("gaitcap.precompile")

#: the numbers of views (cameras) compiled ahead: a kernel taking a tuple of views is compiled
#: once per tuple length (about 20 s each); other counts compile at their first use. 4: the
#: four-camera labs (the Qualisys set in ../shared, the suite's 4-camera sessions)
VIEW_COUNTS = (1, 2, 3, 4)


def compile_kernels(view_counts: Sequence[int] = VIEW_COUNTS) -> None:
    """Compile (or load from the cache) every kernel with the argument types the tracker passes."""
    for n in view_counts:
        raster.warm_up(n)
    projector.warm_up()
    contact.warm_up()
    particles.warm_up()
    zbuffer.warm_up()  # the synthetic renderer's (gaitcap synth, gaitcap demo)


def main() -> int:
    logging.basicConfig(level=logging.INFO, format="%(name)s: %(message)s")
    t = time.perf_counter()
    compile_kernels()
    log.info("numba kernels compiled into their cache in %.1f s", time.perf_counter() - t)
    return 0


if __name__ == "__main__":
    sys.exit(main())
