"""Spatio-temporal gait parameters per stride, per side and overall (mean, SD, count).

Definitions (``d`` the walking direction, ``n`` the horizontal left axis, times from the events):

- stride time: between two consecutive foot strikes of one side (a complete cycle, see
  :mod:`gaitcap.gait.cycles`); step time of side X: from the contralateral foot strike to the next
  foot strike of X.
- stance / swing: ipsilateral foot strike -> foot off, foot off -> next foot strike, in % of the
  cycle. Double support: (contralateral foot off - foot strike) + (foot off - contralateral foot
  strike), in %. Single support (ipsilateral): contralateral foot off -> contralateral foot strike.
- stride length: ground-frame displacement of the heel along ``d`` between the two foot strikes of
  the cycle. The ground frame moves with the belt: ``x_g(t) = x(t) - v_belt t``. Overground
  ``v_belt = 0``; for a walk-in-place / treadmill trial ``v_belt`` is the velocity along ``d`` of
  the stance foot in single support (see :func:`belt_velocity`).
- step length of side X: ``(heel_X - heel_contra) . d`` at the foot strike of X; step width:
  ``|(heel_X - heel_contra) . n|`` at the same instant.
- walking speed: stride length / stride time per stride; cadence: 60 / step time per step.
- symmetry index (Robinson et al. 1987): ``SI = 100 (L - R) / (0.5 (L + R))``, 0 = symmetric.

Each summary value ``k`` comes with ``k_sd`` (sample SD, ddof = 1; NaN for one value) and ``k_n``.

Never absurd: a per-step or per-stride value outside its plausible range
(:class:`gaitcap.gait.options.PlausibleRanges`) is withheld (NaN, ``null`` in parameters.json, left
out of the summaries) and named in ``implausible`` with the reason; the status is then
``"implausible"``, never ``"ok"``. A trajectory without one complete cycle on either side gives
``status = "not_enough_steps"`` with the reason, never zeros; the step-level parameters (step
length, time and width, cadence) of the steps it has are still reported.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from gaitcap.gait.cycles import GaitCycle, find_cycles, other_side
from gaitcap.gait.events import WalkingDirection, heel_track, toe_track
from gaitcap.gait.options import PlausibleRanges
from gaitcap.trajectory import SIDES, GaitEvent, Side, Trajectory

log = logging.getLogger("gaitcap.gait.parameters")

STATUS_OK = "ok"
STATUS_NOT_ENOUGH_STEPS = "not_enough_steps"
STATUS_IMPLAUSIBLE = "implausible"

#: per-side summary keys and their units
SIDE_KEYS: dict[str, str] = {
    "stride_length_m": "m",
    "step_length_m": "m",
    "step_width_m": "m",
    "stride_time_s": "s",
    "step_time_s": "s",
    "cadence_steps_per_min": "steps/min",
    "speed_m_s": "m/s",
    "stance_pct": "%",
    "swing_pct": "%",
    "single_support_pct": "%",
    "double_support_pct": "%",
}
#: overall summary keys (both sides pooled)
OVERALL_KEYS: dict[str, str] = {
    "cadence_steps_per_min": "steps/min",
    "speed_m_s": "m/s",
    "stride_length_m": "m",
    "step_length_m": "m",
    "step_width_m": "m",
    "stride_time_s": "s",
    "step_time_s": "s",
    "stance_pct": "%",
    "swing_pct": "%",
    "single_support_pct": "%",
    "double_support_pct": "%",
}
#: the keys measured per step (the others per stride, i.e. per complete cycle)
STEP_KEYS = ("step_length_m", "step_time_s", "step_width_m", "cadence_steps_per_min")
SYMMETRY_KEYS = ("step_length_m", "step_time_s", "stride_time_s", "stance_pct", "swing_pct", "single_support_pct")


@dataclass(frozen=True)
class Stride:
    """Per-stride values of one cycle (NaN where an input was missing)."""

    side: Side
    cycle: GaitCycle
    stride_time_s: float
    stride_length_m: float
    speed_m_s: float
    stance_pct: float
    swing_pct: float
    single_support_pct: float
    double_support_pct: float


@dataclass(frozen=True)
class Step:
    """One step, ending at the foot strike of ``side``."""

    side: Side
    time_s: float
    step_time_s: float
    step_length_m: float
    step_width_m: float

    @property
    def cadence_steps_per_min(self) -> float:
        return 60.0 / self.step_time_s


@dataclass
class GaitParameters:
    """The result of :func:`compute_parameters`; :meth:`to_dict` is ``parameters.json``."""

    status: str
    reason: str
    overall: dict[str, float]
    sides: dict[str, dict[str, float]]
    symmetry: dict[str, float]
    strides: list[Stride] = field(default_factory=list)
    steps: list[Step] = field(default_factory=list)
    info: dict[str, Any] = field(default_factory=dict)
    implausible: dict[str, str] = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == STATUS_OK

    def to_dict(self) -> dict[str, Any]:
        def clean(d: dict[str, Any]) -> dict[str, Any]:
            return {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}

        return {
            "status": self.status,
            "reason": self.reason,
            "overall": clean(self.overall),
            "left": clean(self.sides["left"]),
            "right": clean(self.sides["right"]),
            "symmetry_index_pct": clean(self.symmetry),
            "implausible": dict(self.implausible),
            "info": self.info,
        }


def _summary(values: Sequence[float]) -> tuple[float, float, int]:
    v = np.asarray([x for x in values if math.isfinite(x)], dtype=np.float64)
    if len(v) == 0:
        return math.nan, math.nan, 0
    return float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else math.nan, len(v)


def _put(out: dict[str, float], key: str, values: Sequence[float]) -> None:
    mean, sd, n = _summary(values)
    out[key], out[f"{key}_sd"], out[f"{key}_n"] = mean, sd, n


def _at(track: np.ndarray, times: np.ndarray, t: float) -> np.ndarray:
    """Linear interpolation of a (T, 3) track at time ``t`` (NaN if a neighbour is missing)."""
    i = int(np.clip(np.searchsorted(times, t) - 1, 0, len(times) - 2))
    w = (t - times[i]) / (times[i + 1] - times[i])
    return (1 - w) * track[i] + w * track[i + 1]


def _single_support(c: GaitCycle) -> tuple[float, float]:
    """Start and end time (s) of the ipsilateral single support of a cycle: contralateral foot off
    -> contralateral foot strike; where those were not detected, the same phase of a typical cycle
    (10-50 % of the cycle with 60 % stance, Perry & Burnfield 2010), i.e. 1/6 to 5/6 of stance."""
    stance = c.foot_off_s - c.start_s
    if np.isfinite(c.contra_off_s) and np.isfinite(c.contra_strike_s) and c.contra_off_s < c.contra_strike_s:
        return c.contra_off_s, c.contra_strike_s
    return c.start_s + stance / 6.0, c.start_s + 5.0 * stance / 6.0


def belt_velocity(traj: Trajectory, direction: WalkingDirection, cycles: Sequence[GaitCycle]) -> float:
    """Ground (belt) velocity along the walking direction, m/s: 0 overground.

    For an in-place trial: the least-squares slope of the stance foot's position along ``d``
    (mid-point of heel and toe) against time during single support, one slope common to all
    cycles and one intercept per cycle:

        v_belt = sum_c sum_t (t - t_c)(x - x_c) / sum_c sum_t (t - t_c)^2

    (``t_c``, ``x_c`` the means over cycle c's single support). In single support the stance foot
    alone carries the body and cannot slide, so it moves with the belt. Late in single support the
    heel rises and the foot rolls about the forefoot (the heel moves forward and up, the toe
    centre, a few cm above the contact, a little forward): on the truth of the OpenSim walk the
    heel's slope over single support is 0.5 % below the foot-flat velocity (20-50 % of stance),
    the toe's 0.5 % above, the heel-toe mid-point's within 0.1 %. A slope over the whole single
    support (~0.4 s) averages out the frame-to-frame jitter of tracked joint centres. The former
    estimate, the median of central-difference velocities over 20-50 % of stance (5-6 samples per
    cycle at 25 fps), followed that jitter: on 31 tracked runs (several tracker settings) of the
    synthetic OpenSim walk-in-place, it missed the same estimate on the truth by -0.032 +/- 0.044
    m/s (max 0.107), this one by -0.016 +/- 0.023 m/s (max 0.073), and the stride length error
    went from 6.1 to 3.7 cm RMS (30 runs, a failed one left out). On the truth itself both agree
    with the foot-flat velocity: -1.146 m/s at 60 Hz and 25 fps (the former -1.145 and -1.141).
    """
    if not direction.in_place:
        return 0.0
    times = traj.times()
    num = den = 0.0
    for c in cycles:
        t0, t1 = _single_support(c)
        foot = 0.5 * (heel_track(traj, c.side) + toe_track(traj, c.side)) @ direction.forward
        sel = (times >= t0) & (times <= t1) & np.isfinite(foot)
        if sel.sum() < 3:
            continue
        t, x = times[sel] - times[sel].mean(), foot[sel] - foot[sel].mean()
        num += float(t @ x)
        den += float(t @ t)
    return num / den if den > 0 else 0.0


def _strides(traj: Trajectory, direction: WalkingDirection, cycles: Sequence[GaitCycle], v_belt: float) -> list[Stride]:
    times = traj.times()
    out = []
    for c in cycles:
        heel = heel_track(traj, c.side)
        T = c.duration_s
        disp = (_at(heel, times, c.end_s) - _at(heel, times, c.start_s)) @ direction.forward
        length = float(disp - v_belt * T)
        stance = c.pct(c.foot_off_s)
        ds = c.pct(c.contra_off_s) + (stance - c.pct(c.contra_strike_s))
        ss = c.pct(c.contra_strike_s) - c.pct(c.contra_off_s)
        out.append(Stride(c.side, c, T, length, length / T, stance, 100.0 - stance, ss, ds))
    return out


def _steps(traj: Trajectory, direction: WalkingDirection, events: Sequence[GaitEvent], max_step_s: float) -> list[Step]:
    """Steps: each foot strike preceded (within ``max_step_s``) by a contralateral strike, with no
    other strike in between."""
    times = traj.times()
    strikes = sorted((e for e in events if e.event == "foot_strike"), key=lambda e: e.time_s)
    out = []
    for prev, cur in zip(strikes[:-1], strikes[1:], strict=True):
        if prev.side == cur.side or cur.time_s - prev.time_s > max_step_s:
            continue
        rel = _at(heel_track(traj, cur.side), times, cur.time_s) - _at(heel_track(traj, other_side(cur.side)), times, cur.time_s)
        out.append(
            Step(cur.side, cur.time_s, cur.time_s - prev.time_s, float(rel @ direction.forward), float(abs(rel @ direction.left)))
        )
    return out


def _withhold(items: Sequence[Stride] | Sequence[Step], ranges: dict[str, tuple[float, float]],
              keys: Sequence[str], what: str) -> tuple[list[Any], dict[str, str]]:
    """``items`` with every value outside its range set to NaN, and per parameter the reason.

    A step's cadence is ``60 / step time``: withholding one withholds the other.
    """
    out: list[Any] = []
    bad: dict[str, list[tuple[Side, float, float]]] = {}
    for it in items:
        nan_fields: dict[str, float] = {}
        for key in keys:
            v = float(getattr(it, key))
            lo, hi = ranges[key]
            if math.isfinite(v) and not lo <= v <= hi:
                bad.setdefault(key, []).append((it.side, _item_time(it), v))
                nan_fields["step_time_s" if key == "cadence_steps_per_min" else key] = math.nan
        out.append(replace(it, **nan_fields) if nan_fields else it)
    reasons = {}
    for key, vals in bad.items():
        lo, hi = ranges[key]
        unit = SIDE_KEYS[key]
        reasons[key] = f"{len(vals)} of {len(items)} {what} outside the plausible {lo:g} to {hi:g} {unit}, withheld"
        log.warning("implausible %s withheld: %s", key,
                    ", ".join(f"{v:.4g} {unit} ({side} at {t:.3f} s)" for side, t, v in vals))  # fmt: skip
    return out, reasons


#: a median stride (or step) longer than this (m) is no walk in metres: points given in millimetres
MILLIMETRES_M = 50.0


def _millimetres_hint(lengths: Sequence[float]) -> str:
    """A reason naming the likely cause when the strides' (or steps') median length, ``lengths`` in the
    trajectory's unit, is beyond any walk in metres; empty otherwise."""
    ok = [abs(v) for v in lengths if math.isfinite(v)]
    median = float(np.median(ok)) if ok else math.nan
    if not median > MILLIMETRES_M:
        return ""
    return (f"the strides measure {median:.4g} m: the points are likely in millimetres, and "
            "gaitcap reads metres (divide them by 1000)")


def _item_time(it: Stride | Step) -> float:
    return it.time_s if isinstance(it, Step) else it.cycle.start_s


def _symmetry(left: float, right: float) -> float:
    den = 0.5 * (left + right)
    return 100.0 * (left - right) / den if math.isfinite(den) and den != 0 else math.nan


def compute_parameters(
    traj: Trajectory, events: Sequence[GaitEvent], direction: WalkingDirection, ranges: PlausibleRanges | None = None,
    *, passes: Sequence[tuple[Trajectory, Sequence[GaitEvent], WalkingDirection]] | None = None,
) -> GaitParameters:  # fmt: skip
    """Spatio-temporal parameters from a trajectory and its events (see the module docstring).

    Args:
        ranges: the plausible range of each parameter (default :class:`PlausibleRanges`).
        passes: a clip walked up and down a walkway, pass by pass (:mod:`gaitcap.gait.analysis`):
            each pass's trajectory (its frames alone: :func:`gaitcap.gait.analysis.within`), events
            and walking direction; its cycles, strides and steps are its own, and they are summarised
            together (``events`` and ``direction`` then only name the whole clip's events and the
            first pass's direction in ``info``).

    Returns:
        :class:`GaitParameters`; ``status == "not_enough_steps"`` (with the reason, the step-level
        values and NaN for the stride-level ones) when neither side has one complete gait cycle;
        ``"implausible"`` when values were withheld (``implausible`` names them and why).
    """
    bounds = (ranges or PlausibleRanges()).bounds()
    parts = list(passes) if passes is not None else [(traj, events, direction)]
    per_pass = [{s: find_cycles(ev, s) for s in SIDES} for _, ev, _ in parts]
    cycles = {s: [c for pc in per_pass for c in pc[s]] for s in SIDES}
    info: dict[str, Any] = {
        "n_frames": traj.n_frames,
        "rate_hz": traj.rate_hz,
        "n_events": len(events),
        "walking_direction": [round(float(x), 6) for x in direction.forward],
        "direction_method": direction.method,
        "in_place": direction.in_place,
        "event_method": "Zeni et al. 2008 (heel/toe relative to pelvis along the walking direction)",
    }
    if len(parts) > 1:
        info["walking_directions"] = [[round(float(x), 6) for x in d.forward] for _, _, d in parts]
    strides: list[Stride] = []
    for (part, _, d), pc in zip(parts, per_pass, strict=True):
        pass_cycles = pc["left"] + pc["right"]
        v_belt = belt_velocity(part, d, pass_cycles)
        info.setdefault("belt_velocity_m_s", v_belt)  # the first pass's (a walk that turns travels: 0)
        strides += _strides(part, d, pass_cycles, v_belt)
    median_stride = float(np.median([s.stride_time_s for s in strides])) if strides else math.nan
    max_step_s = 0.75 * median_stride if math.isfinite(median_stride) else bounds["step_time_s"][1]
    steps = [st for part, ev, d in parts for st in _steps(part, d, ev, max_step_s=max_step_s)]
    units_hint = _millimetres_hint([s.stride_length_m for s in strides] or [s.step_length_m for s in steps])
    strides, implausible = _withhold(strides, bounds, [k for k in SIDE_KEYS if k not in STEP_KEYS], "strides")
    steps, bad_steps = _withhold(steps, bounds, STEP_KEYS, "steps")
    implausible.update(bad_steps)
    sides: dict[str, dict[str, float]] = {}
    for side in SIDES:
        st = [s for s in strides if s.side == side]
        sp = [s for s in steps if s.side == side]
        d: dict[str, float] = {}
        for key in SIDE_KEYS:
            if key in STEP_KEYS:
                _put(d, key, [getattr(s, key) for s in sp])
            else:
                _put(d, key, [getattr(s, key) for s in st])
        d["n_strides"] = len(st)
        d["n_steps"] = len(sp)
        sides[side] = d
    overall: dict[str, float] = {}
    for key in OVERALL_KEYS:
        src = steps if key in STEP_KEYS else strides
        _put(overall, key, [getattr(s, key) for s in src])
    overall["n_strides"] = len(strides)
    overall["n_steps"] = len(steps)
    symmetry = {k: _symmetry(sides["left"][k], sides["right"][k]) for k in SYMMETRY_KEYS}
    status, reasons = STATUS_OK, []
    if not strides:
        status = STATUS_NOT_ENOUGH_STEPS
        reasons.append(_no_cycle_reason(traj, events, len(steps)))
    elif not all(cycles[s] for s in SIDES):
        reasons.append("only the " + next(s for s in SIDES if cycles[s]) + " side has a complete gait cycle")
    if implausible:
        status = STATUS_IMPLAUSIBLE if status == STATUS_OK else status
        reasons.append("implausible values withheld: " + "; ".join(f"{k}: {r}" for k, r in implausible.items()))
    if units_hint:
        reasons.append(units_hint)
        log.warning("%s", units_hint)
    params = GaitParameters(status, "; ".join(reasons), overall, sides, symmetry, strides, steps, info, implausible)
    return params


def _count(n: int, noun: str) -> str:
    return f"{n} {noun}{'' if n == 1 else 's'}"


def _no_cycle_reason(traj: Trajectory, events: Sequence[GaitEvent], n_steps: int) -> str:
    n_fs = sum(e.event == "foot_strike" for e in events)
    n_fo = len(events) - n_fs
    reason = (
        f"not enough steps: no complete gait cycle (found {_count(n_fs, 'foot strike')} and "
        f"{_count(n_fo, 'foot off')} in "
        f"{traj.n_frames / traj.rate_hz:.2f} s; a cycle needs two foot strikes of one foot with its foot off and "
        "one strike of the other foot between)"
    )
    missing = int(np.sum(~np.isfinite(traj.points).any(axis=(1, 2)))) if traj.n_frames else 0
    if missing:  # a tracking run's flagged frames: no event is found in them
        reason += f"; {missing} of the {traj.n_frames} frames have no position (flagged by the tracker or missing)"
    if n_steps:
        reason += (
            f"; step length, step time, step width and cadence are from {n_steps} step{'s' if n_steps > 1 else ''}; "
            "stride length, stride time, speed, stance, swing and support phases need a complete cycle"
        )
    return reason
