"""Settings of the gait analysis: one schema, defaults here only."""

from __future__ import annotations

from pydantic import Field, field_validator

from gaitcap.config import Strict

Bounds = tuple[float, float]


class PlausibleRanges(Strict):
    """The plausible range (low, high) of each spatio-temporal parameter of walking, pathological
    gait included; a value outside is withheld and reported as implausible, never written.

    Only the independent ranges are set; the others follow from them (:meth:`bounds`):
    step time = 60 / cadence, stride time = two steps, swing = 100 - stance, ipsilateral single
    support = contralateral swing.

    Attributes:
        cadence_steps_per_min: 30-250: below 30 (a step every 2 s) is standing, not walking;
            above 250 is beyond sprinting cadence.
        stride_length_m: 0-2.5 m: strides of fast walking reach about 1.8 m.
        step_length_m: -0.2-1.5 m: in a step-to gait the landing foot may stay a little behind
            the other one; a step is at most about 60 % of the longest stride.
        step_width_m: 0-0.6 m: about 0.1 m in healthy walking, 0.3-0.4 m in wide-based gait.
        speed_m_s: 0-3 m/s: faster is running.
        stance_pct: 45-90 % of the cycle: walking keeps a foot on the ground (stance above 50 %,
            less within event timing), very slow pathological gait reaches 80-85 %.
        double_support_pct: 0-80 %: both stances minus the cycle (2 x stance - 100 at most).
    """

    cadence_steps_per_min: Bounds = (30.0, 250.0)
    stride_length_m: Bounds = (0.0, 2.5)
    step_length_m: Bounds = (-0.2, 1.5)
    step_width_m: Bounds = (0.0, 0.6)
    speed_m_s: Bounds = (0.0, 3.0)
    stance_pct: Bounds = (45.0, 90.0)
    double_support_pct: Bounds = (0.0, 80.0)

    @field_validator("*")
    @classmethod
    def _ordered(cls, v: Bounds) -> Bounds:
        if not v[0] < v[1]:
            raise ValueError(f"the low end must be below the high end, got {list(v)}")
        return v

    @property
    def min_step_s(self) -> float:
        """The shortest plausible step (s): one step at the highest plausible cadence."""
        return 60.0 / self.cadence_steps_per_min[1]

    def bounds(self) -> dict[str, Bounds]:
        """Every parameter's range, the derived ones included (keys of ``SIDE_KEYS``)."""
        c_lo, c_hi = self.cadence_steps_per_min
        st_lo, st_hi = self.stance_pct
        swing = (100.0 - st_hi, 100.0 - st_lo)
        return {
            "cadence_steps_per_min": self.cadence_steps_per_min,
            "step_time_s": (60.0 / c_hi, 60.0 / c_lo),
            "stride_time_s": (120.0 / c_hi, 120.0 / c_lo),
            "stride_length_m": self.stride_length_m,
            "step_length_m": self.step_length_m,
            "step_width_m": self.step_width_m,
            "speed_m_s": self.speed_m_s,
            "stance_pct": self.stance_pct,
            "swing_pct": swing,
            "single_support_pct": swing,
            "double_support_pct": self.double_support_pct,
        }


class GaitOptions(Strict):
    """Options of event detection and parameter computation (YAML key ``gait`` or a file of its own).

    Attributes:
        lowpass_hz: cut-off of the zero-lag Butterworth low-pass applied to the foot and pelvis
            signals before event detection (clamped to 0.4 x the sampling rate); 0 disables it.
        max_gap_s: NaN gaps up to this long are bridged by linear interpolation for event
            detection; longer gaps split the signal and no event is taken at their edges.
        min_prominence: an extremum is an event only if its prominence is at least this fraction
            of the robust range (5-95 %) of the signal.
        min_event_interval_s: two events of the same kind and side are at least this far apart.
        edge_rhythm_tolerance: an extremum next to the start or end of the data (its turn seen on
            one sample only) is an event only if the stance or swing phase it opens or closes lasts
            within this fraction of the same phase elsewhere on that side (see
            :mod:`gaitcap.gait.events`).
        treadmill_speed_ratio: the trial is treated as walking in place (treadmill, progression
            removed) when the pelvis net speed is below this fraction of the swing-foot speed.
        refine: refine the Zeni anchors locally (heel lowest point for foot strikes, toe peak
            forward acceleration for foot offs, see :mod:`gaitcap.gait.events`).
        refine_min_rate_hz: the refinement is applied only to trajectories sampled at least this
            fast (at 25 fps it makes events worse, see :mod:`gaitcap.gait.events`).
        refine_tracked: refine a tracking run's trajectories too (``trajectories.h5``); off, their
            anchors are kept at every rate: the tracked heel's lowest point is no sharp landing (see
            :mod:`gaitcap.gait.events`).
        strike_window_s: the foot-strike refinement looks this far after the anchor.
        off_window_s: the foot-off refinement looks this far after (and half as far before) it.
        window_stride_s: the two windows above are for strides up to this long (s); on a walk whose
            median stride is longer (a slow walker) they widen in proportion (see
            :mod:`gaitcap.gait.events`).
        plausible: the plausible range of each parameter (:class:`PlausibleRanges`); its highest
            cadence also sets the shortest interval between the strikes of the two feet.
    """

    lowpass_hz: float = Field(6.0, ge=0.0)
    max_gap_s: float = Field(0.1, ge=0.0)
    min_prominence: float = Field(0.25, gt=0.0, lt=1.0)
    min_event_interval_s: float = Field(0.35, gt=0.0)
    edge_rhythm_tolerance: float = Field(0.25, gt=0.0)
    treadmill_speed_ratio: float = Field(0.15, gt=0.0, lt=1.0)
    refine: bool = True
    refine_min_rate_hz: float = Field(50.0, ge=0.0)
    refine_tracked: bool = False
    strike_window_s: float = Field(0.12, gt=0.0)
    off_window_s: float = Field(0.1, gt=0.0)
    window_stride_s: float = Field(1.25, gt=0.0)
    plausible: PlausibleRanges = Field(default_factory=PlausibleRanges)
