"""Typed exceptions. Only the CLI turns them into exit codes and messages.

Every message names the culprit: the file, the camera or the configuration key.
"""

from __future__ import annotations


class GaitcapError(Exception):
    """Base class of every error gaitcap raises on purpose."""


class ConfigError(GaitcapError):
    """A configuration file or value is invalid (unknown key, bad type, impossible value)."""


class CalibrationError(GaitcapError):
    """A calibration is missing, malformed, or too poor to use."""


class InputError(GaitcapError):
    """An input file (video, motion, session folder) is missing, unreadable or inconsistent."""


class TrackingError(GaitcapError):
    """Tracking could not proceed (for example the subject is never in view)."""


class OutputError(GaitcapError):
    """An output cannot be written (exists already, read-only location, disk full)."""
