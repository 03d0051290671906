"""The articulated body model: declaration (YAML), forward kinematics and volumetric shape."""

from gaitcap.body.model import BodyModel, load_body_model

__all__ = ["BodyModel", "load_body_model"]
