"""What a marker file holds and how a mapping reads it (``gaitcap markers FILE``)."""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Iterator
from pathlib import Path

from gaitcap.errors import InputError
from gaitcap.markers.mapping import Mapping, Resolution, load_mapping
from gaitcap.markers.motion import find_static_trial, read_motion, read_raw_markers, resolve_shipped
from gaitcap.trajectory import LOWER_LIMB, POINT_NAMES, Trajectory


def explain_point(resolution: Resolution, name: str) -> str:
    """How a point is computed, following helper points: ``marker(hjc_l) <- marker(LFEP)``."""
    text = resolution.describe(name)
    defined = dict(resolution.mapping.definitions())
    seen = {name}
    while name not in resolution.unresolved:
        rule = defined[name].chosen(resolution.have)
        if rule.kind != "marker":
            break
        alts = [rule.marker] if isinstance(rule.marker, str) else list(rule.marker or [])
        name = next((a for a in alts if a in resolution.have), alts[0])
        if name not in defined or name in seen:
            break
        seen.add(name)
        text += " <- " + resolution.describe(name)
    return text


def _used_markers(resolution: Resolution, markers: Trajectory) -> set[str]:
    used: set[str] = set()
    for name, rule in resolution.mapping.definitions():
        if name not in resolution.unresolved:
            for chosen in rule.usable(resolution.have):
                used.update(a for alts in chosen.alternatives() for a in alts if markers.has(a))
    return used


def describe_file(path: str | Path, mapping: Mapping | str | Path | None = None, subject: str | None = None,
                  static: str | Path | None = None) -> str:  # fmt: skip
    """A readable account of a .c3d/.trc file: markers, the fitting mapping and each point's
    source, what is missing (the static trial of a mapping that needs one: ``static``, else the
    one its pattern finds beside the file), and why the other shipped mappings do not fit."""
    raw = read_raw_markers(path, subject)
    lines = [f"{path}: {raw.n_frames} frames at {raw.rate_hz:g} Hz, {len(raw.names)} markers"
             + (f" (subject {raw.meta['subject']})" if raw.meta.get("subject") else "")
             + f", {len(raw.events)} events in the file"]  # fmt: skip
    if raw.meta.get("empty"):
        lines[0] += f"; {len(raw.meta['empty'])} more labels without any sample: {', '.join(raw.meta['empty'])}"
    if mapping is None and raw.names and set(raw.names) <= set(POINT_NAMES):  # as read_motion takes it
        lines.append(f"joint centres of gaitcap's body model ({len(raw.names)} of {len(POINT_NAMES)} points: a "
                     "gaitcap export, e.g. gaitcap report's trajectories.c3d): read as they are, no marker mapping")
        return "\n".join(lines)
    shipped = resolve_shipped(raw.names)
    main = load_mapping(mapping).resolve(raw.names) if isinstance(mapping, (str, Path)) else (
        mapping.resolve(raw.names) if mapping is not None else shipped[0])  # fmt: skip
    state = "fits" if main.fits else f"does NOT fit: missing {main.explain_missing(raw.names)}"
    undefined = [n for n in LOWER_LIMB if n not in main.mapping.points]
    if undefined:
        state = (f"does NOT fit: defines no {', '.join(undefined)} under points (gaitcap report and synth need "
                 f"{', '.join(LOWER_LIMB)})" + ("" if main.fits else f"; missing {main.explain_missing(raw.names)}"))
    static_line = None
    if main.fits and main.mapping.needs_static():
        try:
            pattern = main.mapping.static_trial or "*_static.*"
            found = Path(static) if static is not None else find_static_trial(Path(path), pattern)
            static_line = f"  static trial: {found}"
        except InputError as e:
            state = f"does NOT fit: {str(e).split(': ', 1)[1]}"
    if state == "fits":  # the joint centres computed: a rule that names the other side's marker shows there
        try:
            with _quiet(logging.getLogger("gaitcap.markers")):  # the account is the output, not the reading's log
                joints = read_motion(path, main.mapping, static, subject=subject)
            if not raw.events and joints.events:  # as gaitcap report and synth take them
                lines[0] += f" ({_forces_note(joints.events)})"
        except InputError as e:
            state = f"does NOT fit: {str(e).split(': ', 1)[1]}"
    lines.append(f"mapping {main.mapping.name}: {state}")
    if static_line:
        lines.append(static_line)
    for name in main.mapping.points:
        tag = " (optional)" if name in main.mapping.optional else ""
        lines.append(f"  {name:<11} {explain_point(main, name)}{tag}")
    for segment, names in main.mapping.segments.items():
        present = [n for n in names if raw.has(n)]
        if len(present) > 1:
            lines.append(f"  segment {segment}: {', '.join(present)} fill each other's gaps")
    for side, contact in main.mapping.floor_contacts.items():
        names = contact.present(raw.names)
        if names is not None:
            lines.append(f"  {side} toe {names[0]}: held on the floor through a gap while {names[1]} can reach it")
    unused = [n for n in raw.names if n not in _used_markers(main, raw)]
    if unused:
        lines.append(f"markers not used: {', '.join(unused)}")
    for other in shipped:
        if other.mapping.name != main.mapping.name:
            why = "fits too" if other.fits else f"missing {', '.join(other.missing_required())}"
            lines.append(f"other mapping {other.mapping.name}: {why}")
    return "\n".join(lines)


#: where events that a file's EVENT group lacks come from (GaitEvent.source, gaitcap.markers.events)
_EVENT_SOURCES = {"grf": "the force-plate table beside it", "forceplate": "its force plates"}


def _forces_note(events: list) -> str:
    """What the events a marker file's reading found outside its EVENT group are, and where from."""
    sources = sorted({_EVENT_SOURCES.get(e.source, e.source) for e in events})
    return f"{len(events)} found from {' and '.join(sources)}"


@contextlib.contextmanager
def _quiet(logger: logging.Logger) -> Iterator[None]:
    """``logger``'s information messages left out inside the block (warnings stay)."""
    level = logger.level
    logger.setLevel(max(logging.WARNING, level))
    try:
        yield
    finally:
        logger.setLevel(level)
