"""Gait cycles from events, and time normalisation of per-frame curves over 0-100 % of a cycle.

A gait cycle (stride) of one side runs from a foot strike of that side to its next foot strike. It is
complete when exactly one foot off of the same side lies inside it; the contralateral foot off and
foot strike inside it (if both were detected) give the double and single support phases:

    FS_i ---- FO_c ---------- FS_c ---- FO_i ------------ FS_i'
    |  double  |   single support  | double |     swing      |
    |  support |   (ipsilateral)   | support|  (ipsilateral) |

The feet alternate: a cycle holds exactly one strike of the other foot (while one foot swings,
the other one carries the body, and it must land in turn before the first one lifts off again).
A span with two (a strike of this foot missed) or none (a strike of the other foot missed, or a
spurious one of this foot) is not a complete cycle: its timing is not that of one stride.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from gaitcap.trajectory import GaitEvent, Side

#: number of samples of a time-normalised cycle: 0, 1, ..., 100 %
N_CYCLE_POINTS = 101


def other_side(side: Side) -> Side:
    return "right" if side == "left" else "left"


@dataclass(frozen=True)
class GaitCycle:
    """One complete stride of one side; times in seconds on the trajectory's axis.

    Attributes:
        side: the side whose foot strikes open and close the cycle.
        start_s, end_s: the two foot strikes.
        foot_off_s: the ipsilateral foot off (end of stance).
        contra_off_s, contra_strike_s: contralateral foot off and foot strike inside the cycle
            (NaN if not detected).
    """

    side: Side
    start_s: float
    end_s: float
    foot_off_s: float
    contra_off_s: float = float("nan")
    contra_strike_s: float = float("nan")

    @property
    def duration_s(self) -> float:
        return self.end_s - self.start_s

    def pct(self, t: float) -> float:
        """Time ``t`` as a percentage of this cycle."""
        return 100.0 * (t - self.start_s) / self.duration_s


def _times(events: Sequence[GaitEvent], side: Side, kind: str) -> np.ndarray:
    return np.array(sorted(e.time_s for e in events if e.side == side and e.event == kind))


def find_cycles(events: Sequence[GaitEvent], side: Side) -> list[GaitCycle]:
    """The complete gait cycles of ``side``, in time order: exactly one foot off of ``side`` and
    one strike of the other foot inside (see the module docstring)."""
    strikes = _times(events, side, "foot_strike")
    offs = _times(events, side, "foot_off")
    c_offs = _times(events, other_side(side), "foot_off")
    c_strikes = _times(events, other_side(side), "foot_strike")
    cycles = []
    for a, b in zip(strikes[:-1], strikes[1:], strict=True):
        inside = offs[(offs > a) & (offs < b)]
        if len(inside) != 1 or np.count_nonzero((c_strikes > a) & (c_strikes < b)) != 1:
            continue
        co = c_offs[(c_offs > a) & (c_offs < inside[0])]
        cs = c_strikes[(c_strikes > a) & (c_strikes < inside[0])]
        co_t = float(co[0]) if len(co) == 1 else float("nan")
        cs_t = float(cs[0]) if len(cs) == 1 and (not np.isfinite(co_t) or cs[0] > co_t) else float("nan")
        cycles.append(GaitCycle(side, float(a), float(b), float(inside[0]), co_t, cs_t))
    return cycles


def normalise_cycle(values: np.ndarray, times: np.ndarray, cycle: GaitCycle, max_gap_pct: float = 10.0) -> np.ndarray:
    """Resample a per-frame signal onto 0..100 % of one cycle (101 points), linear in time.

    Args:
        values: shape (T,) or (T, K); NaN where missing.
        times: frame times, shape (T,).
        cycle: the cycle.
        max_gap_pct: output samples inside a gap of missing data longer than this (in % of the
            cycle) are NaN; shorter gaps are interpolated.

    Returns:
        Shape (101,) or (101, K).
    """
    values = np.asarray(values, dtype=np.float64)
    flat = values.reshape(len(values), -1)
    t_new = cycle.start_s + np.linspace(0.0, 1.0, N_CYCLE_POINTS) * cycle.duration_s
    out = np.full((N_CYCLE_POINTS, flat.shape[1]), np.nan)
    max_gap = max_gap_pct / 100.0 * cycle.duration_s
    slack = 0.5 * (times[1] - times[0]) if len(times) > 1 else 0.0  # half a frame at either end
    for j in range(flat.shape[1]):
        ok = np.isfinite(flat[:, j])
        t_ok = times[ok]
        if len(t_ok) < 2 or t_ok[0] > t_new[0] + slack or t_ok[-1] < t_new[-1] - slack:
            continue  # the cycle is not covered by data
        v = np.interp(t_new, t_ok, flat[ok, j])
        k = np.clip(np.searchsorted(t_ok, t_new), 1, len(t_ok) - 1)
        gap = t_ok[k] - t_ok[k - 1]
        v[gap > max_gap + 1e-9] = np.nan
        out[:, j] = v
    return out.reshape((N_CYCLE_POINTS,) + values.shape[1:])
