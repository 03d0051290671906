"""The body model a tracking run used, rebuilt from what its ``trajectories.h5`` records.

A run records the subject's height (root attribute ``height_m``) and the per-segment proportions
its shape calibration gave the model (``body_scales``, ``body_shifts``:
:func:`gaitcap.io.track_h5.proportions_attrs`), so the model it tracked can be rebuilt exactly:
``gaitcap report`` draws it over the frames, and ``gaitcap track --body`` tracks another clip of
the same subject with it instead of calibrating the shape again.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from gaitcap.body.model import BodyModel, load_body_model
from gaitcap.errors import GaitcapError

if TYPE_CHECKING:
    from gaitcap.io.track_h5 import TrackRecord


def recorded_model(record: TrackRecord) -> tuple[BodyModel | None, str]:
    """The body model the run of ``record`` tracked (its height and recorded proportions), or None
    and why not, in a sentence: the run does not record the height, or not the proportions its
    shape calibration gave (runs before they were recorded), the model cannot be rebuilt from them,
    or its degrees of freedom changed since the run."""
    attrs, shape = record.attrs, str(record.attrs.get("shape", "off"))
    proportions = record.proportions()
    if "height_m" not in attrs:
        return None, "the run does not record the subject's height"
    if proportions is None and not (shape == "off" or shape.startswith("skipped")):
        return None, ("the run does not record the proportions its shape calibration gave the body model "
                      "(it predates their recording)")  # fmt: skip
    scales, shifts = proportions if proportions is not None else (None, None)
    try:
        model = load_body_model(height_m=float(attrs["height_m"]), scales=scales, shifts=shifts)
    except GaitcapError as e:
        return None, f"the body model cannot be rebuilt ({e})"
    if model.dof_names != record.dof_names:
        return None, "the body model's degrees of freedom changed since this run"
    return model, ""
