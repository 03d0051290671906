"""Settings of the gait analysis: one schema, defaults here only."""

from __future__ import annotations

from pydantic import Field

from gaitcap.config import Strict


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
        strike_window_s: the foot-strike refinement looks this far after the anchor.
        off_window_s: the foot-off refinement looks this far after (and half as far before) it.
    """

    lowpass_hz: float = Field(6.0, ge=0.0)
    max_gap_s: float = Field(0.1, ge=0.0)
    min_prominence: float = Field(0.25, gt=0.0, lt=1.0)
    min_event_interval_s: float = Field(0.35, gt=0.0)
    edge_rhythm_tolerance: float = Field(0.25, gt=0.0)
    treadmill_speed_ratio: float = Field(0.15, gt=0.0, lt=1.0)
    refine: bool = True
    refine_min_rate_hz: float = Field(50.0, ge=0.0)
    strike_window_s: float = Field(0.12, gt=0.0)
    off_window_s: float = Field(0.1, gt=0.0)
