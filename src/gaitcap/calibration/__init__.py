"""Camera calibration: boards and their detection, intrinsics, extrinsics, file formats.

Declarations (:mod:`boards`) are separate from algorithms (:mod:`intrinsics`, :mod:`extrinsics`)
and from readers/writers (:mod:`formats`). The CLI (``gaitcap calibrate ...``) only wires them.
"""
