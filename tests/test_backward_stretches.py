"""The backward pass a stretch at a time (gaitcap.pipeline.BackwardAhead) and the spool it reads
from another thread."""

from __future__ import annotations

import sys
import threading

import numpy as np

from gaitcap.io.spool import FrameSpool
from gaitcap.pipeline import BackwardAhead
from gaitcap.tracking.base import Estimate
from gaitcap.tracking.config import load_tracking_config


def test_spool_reads_from_one_thread_while_another_appends() -> None:
    """Each seek and its read or write under one lock: frames read while later ones are appended
    come back bit for bit."""
    rng = np.random.default_rng(5)
    frames = [[rng.random((16, 20), dtype=np.float32)] for _ in range(64)]
    bad: list = []
    reads = 0
    writing = threading.Event()
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # the threads take turns as often as they can: a race shows at once
    with FrameSpool() as spool:
        spool.append(frames[0])

        def reader() -> None:
            nonlocal reads
            r = np.random.default_rng(6)
            while writing.is_set():
                t = int(r.integers(0, len(spool)))
                try:
                    same = np.array_equal(spool.read(t)[0], frames[t % len(frames)][0])
                except Exception as e:  # noqa: BLE001 - a torn read fails to decompress
                    same = False
                    bad.append(repr(e))
                reads += 1
                if not same:
                    bad.append(t)

        writing.set()
        th = threading.Thread(target=reader)
        th.start()
        try:
            for i in range(1, 3000):
                spool.append(frames[i % len(frames)])
        finally:
            writing.clear()
            th.join()
            sys.setswitchinterval(interval)
    assert reads > 100
    assert not bad


class _Model:
    point_names = ("knee_l", "knee_r")

    @staticmethod
    def dof_index(name: str) -> int:
        return {"hip_flexion_l": 0, "hip_flexion_r": 1}[name]


class _Tracker:
    """Records where it was started; each estimate holds (frame, a draw of its own stream, k)."""

    def __init__(self, k: int, starts: list) -> None:
        self.model, self.k, self.rng, self.starts = _Model(), k, np.random.default_rng([0, k]), starts

    def start(self, q0, fresh: bool = True) -> None:
        self.starts.append((self.k, q0.copy()))

    def step(self, obs) -> Estimate:
        t = float(obs.silhouettes[0][0, 0])
        return Estimate(np.array([t, self.rng.random(), self.k]), np.zeros((2, 3)), np.zeros(2), 0.0, 0.8, 1)


def _forward(T: int, untracked: set[int], apart: set[int]) -> list[tuple[int, np.ndarray | None, float]]:
    """A forward pass: frame t's pose (hip flexions 0.6 rad apart on ``apart``, else level; third DOF t)."""
    out = []
    for t in range(T):
        if t in untracked:
            out.append((t, None, np.nan))
        else:
            out.append((t, np.array([0.6 if t in apart else 0.0, 0.0, float(t)]), 0.8))
    return out


def _run(concurrent: bool, stretch: int = 5):
    cfg = load_tracking_config()
    cfg.backward.stretch_frames = stretch
    T, untracked, apart = 30, {12, 13}, {3, 6, 7, 9, 20, 21, 27}
    starts: list = []
    with FrameSpool() as spool:
        with BackwardAhead(lambda k: _Tracker(k, starts), _Model(), spool, cfg, concurrent) as ahead:
            for t, q, fit in _forward(T, untracked, apart):
                spool.append([np.full((2, 2), t, np.float32)])
                ahead.add(t, q, fit)
            runs = ahead.finish()
    return runs, starts


def test_stretches_end_where_the_legs_are_apart_and_tile_each_run() -> None:
    runs, starts = _run(concurrent=False)
    assert sorted(runs) == [(0, 12), (14, 30)]  # the runs of tracked frames, whole
    for (s, e), back in runs.items():
        assert [int(b.q[0]) for b in back] == list(range(s, e))  # every frame once, in order
    # stretches: at least 5 frames, ending on a frame with the legs apart (6; 20 and 27 in the
    # second run), or at the run's end (11, 29)
    k_of = {int(b.q[0]): int(b.q[2]) for back in runs.values() for b in back}
    bounds = {}
    for t, k in sorted(k_of.items()):
        bounds.setdefault(k, [t, t])[1] = t
    assert sorted(bounds.values()) == [[0, 6], [7, 11], [14, 20], [21, 27], [28, 29]]
    # each stretch started from the forward pass's pose at its last frame
    assert sorted((k, int(q[2])) for k, q in starts) == [(0, 6), (1, 11), (2, 20), (3, 27), (4, 29)]


def test_the_stretches_do_not_depend_on_the_threads() -> None:
    """A tracker per stretch, seeded by its place in the clip: the worker beside the forward pass
    and the threads of finish() give what one thread gives, draw for draw."""
    one, _ = _run(concurrent=False)
    many, _ = _run(concurrent=True)
    assert one.keys() == many.keys()
    for key in one:
        assert all(np.array_equal(a.q, b.q) for a, b in zip(one[key], many[key]))


def test_without_stretches_each_run_is_tracked_from_its_last_frame() -> None:
    runs, starts = _run(concurrent=True, stretch=None)
    assert sorted(runs) == [(0, 12), (14, 30)]
    assert sorted(int(q[2]) for _, q in starts) == [11, 29]
