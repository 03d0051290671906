"""Marker-based motion: from C3D/TRC marker trajectories to gaitcap joint centres.

- :mod:`gaitcap.markers.axes`: the up-axis rotations (file frame -> gaitcap z-up frame).
- :mod:`gaitcap.markers.mapping`: the declarative mapping schema (YAML) marker -> joint centre.
- :mod:`gaitcap.markers.jointcentres`: the rules' maths (Harrington HJC, rigid clusters, ...).
- :mod:`gaitcap.markers.events`: gait events from force-plate data.
- :mod:`gaitcap.markers.motion`: ``read_markers`` and ``read_motion``, the public entry points.
"""
