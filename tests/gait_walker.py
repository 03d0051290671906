"""A kinematic walker with exactly known gait events and parameters (test helper).

Feet are rigid heel-toe segments: fixed on the floor in stance, moving forward at constant
horizontal speed in swing (raised by a squared half sine, so it lands with zero vertical speed). The pelvis moves at constant speed. Hence
heel - pelvis along the walking direction peaks exactly at foot strike and toe - pelvis has its
minimum exactly at foot off (the Zeni et al. 2008 extrema), and every parameter has a closed form.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gaitcap.trajectory import POINT_NAMES, GaitEvent, Trajectory


@dataclass(frozen=True)
class Walker:
    speed: float = 1.2  # m/s
    stride_time: float = 1.1  # s
    stance: float = 0.62  # fraction of the cycle
    asym: float = 0.0  # left foot strike at (0.5 + asym) of the right cycle
    step_width: float = 0.12  # m between heel lines
    foot_length: float = 0.2  # heel -> toe, m
    first_strike_right: float = 0.23  # s
    heading_deg: float = 30.0  # walking direction in the xy plane
    origin: tuple[float, float] = (1.0, -2.0)
    in_place: bool = False  # treadmill: progression removed, belt at -speed
    rate_hz: float = 100.0
    duration: float = 4.0
    lift: float = 0.08  # m, swing foot clearance

    @property
    def stride_length(self) -> float:
        return self.speed * self.stride_time

    def truth_events(self) -> list[GaitEvent]:
        ev = []
        t_end = self.duration
        for side, offset in (("right", 0.0), ("left", 0.5 + self.asym)):
            t0 = self.first_strike_right + offset * self.stride_time
            for k in range(-3, int(self.duration / self.stride_time) + 3):
                fs = t0 + k * self.stride_time
                fo = fs + self.stance * self.stride_time
                for t, kind in ((fs, "foot_strike"), (fo, "foot_off")):
                    if 0 < t < t_end - 1 / self.rate_hz:
                        ev.append(GaitEvent(t, side, kind, "truth"))  # type: ignore[arg-type]
        return sorted(ev)

    def _foot(self, t: np.ndarray, offset: float) -> tuple[np.ndarray, np.ndarray]:
        """Heel forward position (T,) and height (T,) of a foot with strikes at t0 + k T."""
        T, L = self.stride_time, self.stride_length
        t0 = self.first_strike_right + offset * T
        k = np.floor((t - t0) / T)
        ph = (t - t0) / T - k  # 0 at foot strike
        x_strike = self.speed * (t0 + k * T) + 0.3 * L
        swing = ph >= self.stance
        u = np.where(swing, (ph - self.stance) / (1 - self.stance), 0.0)  # 0..1 through swing
        x = np.where(swing, x_strike + u * L, x_strike)
        z = np.where(swing, self.lift * np.sin(np.pi * u) ** 2, 0.0)  # lands and lifts off gently
        return x, z

    def trajectory(self) -> Trajectory:
        n = int(round(self.duration * self.rate_hz))
        t = np.arange(n) / self.rate_hz
        P = np.full((n, len(POINT_NAMES), 3), np.nan)
        local: dict[str, np.ndarray] = {}
        pel = np.stack([self.speed * t, np.zeros(n), np.full(n, 0.9)], axis=1)
        local["pelvis"] = pel
        local["thorax"] = pel + [0.0, 0.0, 0.45]
        local["neck"] = pel + [0.0, 0.0, 0.6]
        local["head"] = pel + [0.0, 0.0, 0.75]
        for side, offset, lat in (("r", 0.0, -1.0), ("l", 0.5 + self.asym, 1.0)):
            x, z = self._foot(t, offset)
            y = np.full(n, lat * self.step_width / 2)
            heel = np.stack([x, y, z], axis=1)
            local[f"heel_{side}"] = heel
            local[f"toe_{side}"] = heel + [self.foot_length, 0.0, 0.0]
            local[f"ankle_{side}"] = heel + [0.05, 0.0, 0.08]
            hip = pel + [0.0, lat * 0.09, 0.0]
            local[f"hip_{side}"] = hip
            local[f"knee_{side}"] = _knee(hip, local[f"ankle_{side}"], 0.44, 0.44)
        if self.in_place:
            for k in local:
                local[k] = local[k] - np.stack([self.speed * t, np.zeros(n), np.zeros(n)], axis=1)
        c, s = np.cos(np.radians(self.heading_deg)), np.sin(np.radians(self.heading_deg))
        R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
        for name, v in local.items():
            P[:, POINT_NAMES.index(name)] = v @ R.T + [*self.origin, 0.0]
        return Trajectory(POINT_NAMES, P, self.rate_hz)


def _knee(hip: np.ndarray, ankle: np.ndarray, l1: float, l2: float) -> np.ndarray:
    """Knee of a two-link leg bending forward (+x), shapes (T, 3)."""
    d_vec = ankle - hip
    d = np.linalg.norm(d_vec, axis=1, keepdims=True)
    u = d_vec / d
    a = (l1**2 - l2**2 + d**2) / (2 * d)
    h = np.sqrt(np.clip(l1**2 - a**2, 0.0, None))
    fwd = np.array([1.0, 0.0, 0.0]) - u * u[:, :1]  # forward, orthogonal to the leg
    fwd /= np.linalg.norm(fwd, axis=1, keepdims=True)
    return hip + u * np.minimum(a, d) + fwd * h
