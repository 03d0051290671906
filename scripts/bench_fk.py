"""Forward-kinematics throughput: time to pose N particles (points and capsules).

    python scripts/bench_fk.py [--n 10000] [--repeat 20]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "src"))  # this checkout's gaitcap, not an installed one

from gaitcap.body import load_body_model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--n", type=int, nargs="+", default=[1000, 10000])
    ap.add_argument("--repeat", type=int, default=20)
    args = ap.parse_args()
    model = load_body_model(height_m=1.75)
    rng = np.random.default_rng(0)
    print("| poses | forward (points) ms | capsules ms | poses per second (points) |")
    print("|---|---|---|---|")
    for n in args.n:
        lo = np.where(np.isfinite(model.lower), model.lower, -1.0)
        hi = np.where(np.isfinite(model.upper), model.upper, 1.0)
        q = rng.uniform(lo, hi, size=(n, model.n_dofs))
        model.forward(q[:10])
        times_p, times_c = [], []
        for _ in range(args.repeat):
            t = time.perf_counter()
            model.forward(q)
            times_p.append(time.perf_counter() - t)
            t = time.perf_counter()
            model.capsules(q)
            times_c.append(time.perf_counter() - t)
        p, c = 1000 * np.median(times_p), 1000 * np.median(times_c)
        print(f"| {n} | {p:.1f} | {c:.1f} | {n / (p / 1000):,.0f} |")


if __name__ == "__main__":
    main()
