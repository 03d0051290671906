"""The marker mapping schema: how each gaitcap point is built from a marker set.

A mapping is a YAML file (``configs/mappings/<name>.yaml``) that only *declares* rules; the
maths lives in :mod:`gaitcap.markers.jointcentres`. Each definition is one rule::

    virtual:                 # helper points, evaluated first, in order (any names)
      mid_asis: {mean: [LASI, RASI]}
    points:                  # output points: names from gaitcap.trajectory.POINT_NAMES, in order
      hip_l: {harrington: {side: left, lasi: LASI, rasi: RASI, lpsi: LPSI, rpsi: RPSI}}
      knee_l: {marker: [LKJC, LFEO]}          # first one present in the file

A rule refers to markers of the file or to helper/output points defined *above* it.
Rules: ``marker``, ``mean``, ``harrington``, ``cluster``, ``sole``, ``shift``, ``lerp`` (see the
classes below), and ``first``: a list of rules, the first one whose markers are all present is
used (so one mapping covers a marker set's variants: SACR or LPSI/RPSI, with or without heels,
the lab's own joint centres when the file has them); in the frames where it gives nothing (its
markers have a gap there), the next usable one fills in::

    hip_l:
      first:
        - marker: LHJC                                     # the lab's own hip centre
        - harrington: {side: left, lasi: LASI, rasi: RASI, lpsi: LPSI, rpsi: RPSI}
        - harrington: {side: left, lasi: LASI, rasi: RASI, sacral: SACR}

``segments`` lists groups of markers on one rigid body (``pelvis: [LASI, RASI, LPSI, RPSI,
SACR]``) whose gaps are filled from each other before the rules run (see
:func:`gaitcap.markers.jointcentres.fill_segment_gaps`).

``floor_contacts`` names, per foot, a marker that often drops out at push-off (the toe, hidden by
the other foot) and a marker near that foot's ankle: a gap that opens while the toe is on the
floor is held there while the ankle can still reach it, and the frame it no longer can is the
toe's lift-off (see :func:`gaitcap.markers.jointcentres.hold_floor_contacts`).

Output points listed under ``optional`` are left out when their markers are missing (arms of a
full-body set in a lower-body file); every other output point is required for the mapping to fit.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Literal

from pydantic import Field, PrivateAttr, field_validator, model_validator

from gaitcap.config import CONFIG_DIR, Strict, load_yaml_model
from gaitcap.errors import ConfigError
from gaitcap.trajectory import POINT_NAMES

MAPPINGS_DIR = CONFIG_DIR / "mappings"


MAX_OFFSET_M = 0.3  # no offset between markers and joint centres of one body segment is longer
MAX_FRACTION = 2.0  # a fraction of a distance on the body: 0.33, not 33 (%)


def _metres(value: float | None, limit: float = MAX_OFFSET_M) -> float | None:
    """An offset of a rule, in metres: one over ``limit`` (longer than any such offset on a body
    segment) is refused, naming millimetres when it is one (57 for 0.057)."""
    if value is not None and abs(value) > limit:
        hint = f": millimetres? {value:g} mm is {value / 1000:g} m" if abs(value) / 1000 <= limit else ""
        raise ValueError(f"{value:g} m is longer than this offset can be (at most {limit:g} m); "
                         f"distances are in metres{hint}")  # fmt: skip
    return value


def _fraction(value: float | None) -> float | None:
    """A fraction of a distance (0.33): a percentage (33) is refused, naming it."""
    if value is not None and abs(value) > MAX_FRACTION:
        raise ValueError(f"fraction {value:g} is not a fraction of a distance (at most {MAX_FRACTION:g}); "
                         f"a percentage? {value:g} % is {value / 100:g}")  # fmt: skip
    return value


class HarringtonRule(Strict):
    """Hip joint centre from the pelvis markers, Harrington et al. 2007 (J Biomech 40:595).

    Give both PSIS markers (``lpsi``, ``rpsi``) or one ``sacral`` marker standing for mid-PSIS.
    """

    side: Literal["left", "right"]
    lasi: str
    rasi: str
    lpsi: str | None = None
    rpsi: str | None = None
    sacral: str | None = None

    @model_validator(mode="after")
    def _psis_or_sacral(self) -> HarringtonRule:
        pair = self.lpsi is not None and self.rpsi is not None
        if pair == (self.sacral is not None) or (self.lpsi is None) != (self.rpsi is None):
            raise ValueError("give either both lpsi and rpsi, or sacral")
        return self

    def references(self) -> list[str]:
        return [n for n in (self.lasi, self.rasi, self.lpsi, self.rpsi, self.sacral) if n is not None]


class ClusterRule(Strict):
    """A point defined in a static trial, carried by a rigid marker cluster into the motion trial.

    In the static trial the point is the mean of ``static_mean`` (e.g. the two epicondyles) and
    is expressed relative to ``markers`` (>= 3, non-collinear); in each motion frame the
    cluster's least-squares rigid motion (Kabsch) from the static pose moves it.
    """

    markers: list[str] = Field(min_length=3)
    static_mean: list[str] = Field(min_length=1)

    def references(self) -> list[str]:
        return list(self.markers)


class SoleRule(Strict):
    """A foot marker brought down to the sole along the foot's own vertical.

    down = world down made orthogonal to the foot's long axis (``heel`` -> ``toe``), so the
    shift follows the foot when it pitches; distance = the marker's height above the floor
    (z = 0) during foot-flat, estimated as the ``percentile`` of its height over the trial
    (or fixed by ``height_m``).
    """

    point: str
    heel: str
    toe: str
    percentile: float = Field(default=5.0, ge=0.0, le=50.0)
    height_m: float | None = Field(default=None, ge=0.0)

    @field_validator("height_m")
    @classmethod
    def _in_metres(cls, value: float | None) -> float | None:
        return _metres(value, 0.2)

    def references(self) -> list[str]:
        return [self.point, self.heel, self.toe]


class ShiftRule(Strict):
    """``point`` moved by a distance along a direction defined by two points.

    direction = unit vector ``direction[0] -> direction[1]``, made orthogonal to the axis
    ``orthogonal_to[0] -> orthogonal_to[1]`` when given; distance = ``distance_m``, or
    ``fraction`` x |``fraction_of[0]`` - ``fraction_of[1]``| (per frame).
    """

    point: str
    direction: tuple[str, str]
    orthogonal_to: tuple[str, str] | None = None
    distance_m: float | None = None
    fraction: float | None = None
    fraction_of: tuple[str, str] | None = None

    _in_metres = field_validator("distance_m")(_metres)
    _a_fraction = field_validator("fraction")(_fraction)

    @model_validator(mode="after")
    def _one_distance(self) -> ShiftRule:
        relative = self.fraction is not None and self.fraction_of is not None
        if (self.fraction is None) != (self.fraction_of is None):
            raise ValueError("fraction and fraction_of go together")
        if relative == (self.distance_m is not None):
            raise ValueError("give either distance_m, or fraction with fraction_of")
        return self

    def references(self) -> list[str]:
        out = [self.point, *self.direction]
        out += list(self.orthogonal_to or ()) + list(self.fraction_of or ())
        return out


class LerpRule(Strict):
    """The point ``fraction`` of the way from ``start`` to ``end`` (0 -> start, 1 -> end)."""

    start: str
    end: str
    fraction: float

    _a_fraction = field_validator("fraction")(_fraction)

    def references(self) -> list[str]:
        return [self.start, self.end]


class ChordRule(Strict):
    """A joint centre from a lateral marker, a wand marker and the proximal joint centre
    (Plug-in-Gait's chord function, Davis et al. 1991, Hum Mov Sci 10:575-587).

    The centre J lies ``distance_m`` from ``marker`` (half the joint width plus the marker
    radius), in the plane of ``proximal``, ``wand`` and ``marker``, on the side away from the
    wand, with J - marker perpendicular to proximal - J (J on the circle of diameter
    marker-proximal). Knee: proximal = hip centre, wand = THI, marker = KNE; ankle: proximal =
    knee centre, wand = TIB, marker = ANK.

    With ``width`` (a Plug-in-Gait measurement such as ``LKneeWidth``) the distance is the
    subject's own when the file carries it (C3D PROCESSING, mm): width / 2 + the marker radius
    (PROCESSING ``MarkerDiameter`` / 2, else ``marker_radius_m``); ``distance_m`` (a typical
    width) otherwise.
    """

    proximal: str
    wand: str
    marker: str
    distance_m: float = Field(gt=0.0)
    width: str | None = None
    marker_radius_m: float = Field(default=0.007, ge=0.0, le=0.03)

    @field_validator("distance_m")
    @classmethod
    def _in_metres(cls, value: float) -> float:
        return _metres(value, 0.2)  # type: ignore[return-value]

    def references(self) -> list[str]:
        return [self.proximal, self.wand, self.marker]


RULE_KINDS: tuple[str, ...] = ("marker", "mean", "harrington", "cluster", "sole", "shift", "lerp", "chord", "first")


class Rule(Strict):
    """One definition: exactly one of the rule keys.

    ``marker``: an existing (possibly virtual) point of the file; a list means the first one
    present. ``mean``: the mean of several points (NaN if any is missing). ``first``: the first
    of several rules whose references are all present.
    """

    marker: str | list[str] | None = None
    mean: list[str] | None = Field(default=None, min_length=1)
    harrington: HarringtonRule | None = None
    cluster: ClusterRule | None = None
    sole: SoleRule | None = None
    shift: ShiftRule | None = None
    lerp: LerpRule | None = None
    chord: ChordRule | None = None
    first: list[Rule] | None = Field(default=None, min_length=1)

    @model_validator(mode="after")
    def _exactly_one(self) -> Rule:
        given = [k for k in RULE_KINDS if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueError(f"give exactly one rule among {', '.join(RULE_KINDS)} (got {given or 'none'})")
        return self

    @property
    def kind(self) -> str:
        return next(k for k in RULE_KINDS if getattr(self, k) is not None)

    def alternatives(self) -> list[list[str]]:
        """Referenced names, each as a list of alternatives (one of them must exist)."""
        if self.marker is not None:
            return [[self.marker] if isinstance(self.marker, str) else list(self.marker)]
        if self.mean is not None:
            return [[n] for n in self.mean]
        if self.first is not None:
            return [alts for rule in self.first for alts in rule.alternatives()]
        body = getattr(self, self.kind)
        return [[n] for n in body.references()]

    def missing(self, have: set[str], unresolved: dict[str, list[str]] | None = None) -> list[str]:
        """References not in ``have`` (alternatives as ``a|b``); [] when the rule can be evaluated.

        ``unresolved`` (helper point -> the markers it misses) counts a helper's markers in place
        of the helper. For ``first``: [] if any alternative can be evaluated, else the gaps of
        the alternative missing the fewest markers (of equal ones the last: the first alternatives are usually a
        lab's own joint centres, the last the markers a set needs at least).
        """
        if self.first is not None:
            gaps = [_expand(rule.missing(have, unresolved), unresolved or {}) for rule in self.first]
            return [] if any(not g for g in gaps) else min(reversed(gaps), key=len)
        return ["|".join(alts) for alts in self.alternatives() if not any(a in have for a in alts)]

    def chosen(self, have: set[str]) -> Rule:
        """The rule evaluated given the names in ``have``: the first usable alternative of ``first``."""
        return self.usable(have)[0]

    def usable(self, have: set[str]) -> list[Rule]:
        """The alternatives that can be evaluated given ``have``, in order (``[self]`` for a rule
        other than ``first``; ``[first[0]]`` when none can). Frames where one gives NaN take the
        next one's value (:func:`gaitcap.markers.jointcentres.apply_mapping`)."""
        if self.first is None:
            return [self]
        out = [r for rule in self.first if not rule.missing(have) for r in rule.usable(have)]
        return out or [self.first[0]]

    def describe(self, have: set[str]) -> str:
        """One line: the rule kind used and the names it reads, e.g. ``harrington(LASI, RASI, SACR)``,
        then the rules that fill its gaps (``marker(LFEP), gaps: harrington(LASI, RASI, SACR)``)."""
        texts = []
        for rule in self.usable(have):
            names = [next((a for a in alts if a in have), alts[0]) for alts in rule.alternatives()]
            texts.append(f"{rule.kind}({', '.join(dict.fromkeys(names))})")
        return texts[0] + (f", gaps: {', '.join(texts[1:])}" if len(texts) > 1 else "")


class GrfSpec(Strict):
    """Gait events from a force-plate table next to the motion file (OpenSim .mot)."""

    file_suffix: str = "_grf.mot"
    right: str = Field(description="column prefix of the right foot's force, e.g. ground_force_v")
    left: str
    threshold_n: float = Field(default=20.0, gt=0.0)


class FloorContact(Strict):
    """A foot marker held on the floor through a gap while the foot can still stand on it.

    See :func:`gaitcap.markers.jointcentres.hold_floor_contacts`.
    """

    marker: str | list[str] = Field(
        description="the foot's marker nearest the ground at push-off (toe, metatarsal head); a list: the first present"
    )
    reach: str | list[str] = Field(
        description="a marker near the same foot's ankle (the lateral malleolus); a list: the first present"
    )
    max_height_m: float = Field(
        default=0.03, gt=0.0, le=0.2,
        description="the marker was on the floor: at most this far above its foot-flat height (m)",
    )
    max_speed_m_s: float = Field(
        default=0.3, gt=0.0, le=2.0, description="and moved at most this fast when it was last seen (m/s)"
    )
    tolerance_m: float = Field(
        default=0.003, ge=0.0, le=0.05,
        description="slack on the foot's length (marker jitter, m) before the toe counts as lifted",
    )

    def present(self, have: Iterable[str]) -> tuple[str, str] | None:
        """The (marker, reach) names found among ``have``, or None when either is missing."""
        names = set(have)

        def first(spellings: str | list[str]) -> str | None:
            return next((n for n in ([spellings] if isinstance(spellings, str) else spellings) if n in names), None)

        marker, reach = first(self.marker), first(self.reach)
        return (marker, reach) if marker and reach else None


class Mapping(Strict):
    """A marker set -> gaitcap points mapping (see the module docstring).

    ``segments`` name groups of markers fixed to one rigid body that rotates little over a gap
    (the pelvis, the head): a marker's gaps are filled from the others of its group before the
    rules are evaluated (:func:`gaitcap.markers.jointcentres.fill_segment_gaps`).
    """

    name: str
    description: str = ""
    up_axis: Literal["x", "y", "z"] | None = None
    static_trial: str | None = Field(default=None, description="glob of the static trial beside the motion file")
    grf: GrfSpec | None = None
    virtual: dict[str, Rule] = Field(default_factory=dict)
    points: dict[str, Rule]
    optional: list[str] = Field(
        default_factory=list, description="output points left out when their markers are missing"
    )
    segments: dict[str, list[str]] = Field(
        default_factory=dict, description="markers of one rigid body, filling each other's gaps"
    )
    floor_contacts: dict[Literal["left", "right"], FloorContact] = Field(
        default_factory=dict, description="per foot, a marker lost while on the floor and held there while in reach"
    )
    _path: str | None = PrivateAttr(default=None)

    @property
    def label(self) -> str:
        """``mapping 'name'``, with the YAML file it was read from (``mapping 'my_lab' (my_lab.yaml)``)."""
        return f"mapping {self.name!r}" + (f" ({self._path})" if self._path else "")

    @model_validator(mode="after")
    def _segments(self) -> Mapping:
        small = [k for k, v in self.segments.items() if len(set(v)) < 2]
        if small:
            raise ValueError(f"segment(s) {small}: a segment needs at least two markers")
        return self

    @model_validator(mode="after")
    def _names_and_order(self) -> Mapping:
        unknown = [n for n in self.points if n not in POINT_NAMES]
        if unknown:
            raise ValueError(f"unknown output point(s) {unknown}; valid: {', '.join(POINT_NAMES)}")
        stray = [n for n in self.optional if n not in self.points]
        if stray:
            raise ValueError(f"optional point(s) {stray} are not defined under points")
        clash = sorted(set(self.virtual) & set(self.points))
        if clash:
            raise ValueError(f"names defined both as virtual and output points: {clash}")
        order = list(self.virtual) + list(self.points)
        for i, (name, rule) in enumerate(self.definitions()):
            for alts in rule.alternatives():
                for ref in alts:
                    if ref == name or ref in order[i + 1 :]:
                        raise ValueError(f"{name}: refers to {ref!r}, which is defined later (or is itself)")
        return self

    def definitions(self) -> Iterator[tuple[str, Rule]]:
        """(name, rule) in evaluation order: virtual points first, then output points."""
        yield from self.virtual.items()
        yield from self.points.items()

    def defined_names(self) -> set[str]:
        return set(self.virtual) | set(self.points)

    def needs_static(self) -> bool:
        return any(rule.cluster is not None for _, rule in self.definitions())

    def resolve(self, available: Iterable[str]) -> Resolution:
        """Which definitions can be evaluated from the ``available`` marker names, in order."""
        have = set(available)
        unresolved: dict[str, list[str]] = {}
        for name, rule in self.definitions():
            gaps = rule.missing(have, unresolved)
            if gaps:
                unresolved[name] = _expand(gaps, unresolved)
            else:
                have.add(name)
        return Resolution(self, have, unresolved)

    def static_requirements(self) -> list[str]:
        """Markers the static trial must hold (cluster markers and the defined points)."""
        out: list[str] = []
        for _, rule in self.definitions():
            if rule.cluster is not None:
                out += [m for m in rule.cluster.markers + rule.cluster.static_mean if m not in out]
        return out

    def missing_markers(self, available: Iterable[str]) -> list[str]:
        """Markers missing for the required output points (alternatives shown as ``a|b``)."""
        return self.resolve(available).missing_required()


def _closest(name: str, names: list[str]) -> list[str]:
    """The names most like ``name`` (a typo's likely intent; several when equally close), or []."""
    scores = {n: difflib.SequenceMatcher(None, name.lower(), n.lower()).ratio() for n in names if n != name}
    best = max(scores.values(), default=0.0)
    return [n for n, v in scores.items() if v == best][:3] if best >= 0.7 else []


def _all_references(rule: Rule) -> list[str]:
    """Every name a rule refers to, alternatives joined by ``|`` (all alternatives of ``first``)."""
    return ["|".join(alts) for alts in rule.alternatives()] + [a for alts in rule.alternatives() for a in alts]


def _expand(gaps: list[str], unresolved: dict[str, list[str]]) -> list[str]:
    """Gaps with each unresolved helper point replaced by the markers it misses."""
    out: list[str] = []
    for gap in gaps:
        for g in unresolved.get(gap, [gap]):
            if g not in out:
                out.append(g)
    return out


@dataclass(frozen=True)
class Resolution:
    """A mapping checked against a marker set (:meth:`Mapping.resolve`).

    Attributes:
        mapping: the mapping.
        have: marker names plus the definitions that can be evaluated.
        unresolved: definition name -> the markers it misses.
    """

    mapping: Mapping
    have: set[str]
    unresolved: dict[str, list[str]] = field(default_factory=dict)

    def missing_required(self) -> list[str]:
        """Markers missing for required output points, without repeats."""
        names = [n for n in self.mapping.points if n in self.unresolved and n not in self.mapping.optional]
        return _expand(names, self.unresolved)

    def explain_missing(self, available: Iterable[str]) -> str:
        """The markers missing for required output points, each with the definitions whose rules
        name it, the output points it leaves out and, for a likely typo, the closest name among
        ``available`` markers and the mapping's own points: ``L_KNE_LAT (named by kjc_l; needed
        for knee_l, ankle_l; did you mean 'L_KNEE_LAT'?)``."""
        names = sorted(set(available) | self.mapping.defined_names())
        required = [n for n in self.mapping.points if n in self.unresolved and n not in self.mapping.optional]
        parts = []
        for gap in self.missing_required():
            naming = [d for d, rule in self.mapping.definitions() if gap in _all_references(rule)]
            needed = [p for p in required if gap in self.unresolved[p]]
            close = [m for alt in gap.split("|") for m in _closest(alt, names)]
            notes = [f"named by {', '.join(naming)}"] if naming else []
            notes += [f"needed for {', '.join(needed)}"] if needed and needed != naming else []
            notes += [f"did you mean {' or '.join(repr(c) for c in dict.fromkeys(close))}?"] if close else []
            parts.append(gap + (f" ({'; '.join(notes)})" if notes else ""))
        return ", ".join(parts)

    @property
    def fits(self) -> bool:
        return not self.missing_required()

    def output_points(self) -> list[str]:
        """Output points that can be evaluated, in :data:`POINT_NAMES` order."""
        return [n for n in POINT_NAMES if n in self.mapping.points and n in self.have]

    def describe(self, name: str) -> str:
        """How one definition is computed, or what it misses."""
        if name in self.unresolved:
            return "missing " + ", ".join(self.unresolved[name])
        rule = dict(self.mapping.definitions())[name]
        return rule.describe(self.have)


def load_mapping(name_or_path: str | Path) -> Mapping:
    """A shipped mapping by name (``plugin_gait``) or a mapping YAML file by path (validated:
    unknown keys, unknown points and rules referring to later names are errors naming the file)."""
    path = Path(name_or_path)
    if path.suffix.lower() not in (".yaml", ".yml"):
        path = MAPPINGS_DIR / f"{name_or_path}.yaml"
        if not path.is_file():
            known = ", ".join(shipped_mapping_names())
            raise ConfigError(f"unknown mapping {name_or_path!r} (shipped mappings: {known})")
    mapping = load_yaml_model(Mapping, path)
    mapping._path = str(name_or_path) if Path(name_or_path).suffix.lower() in (".yaml", ".yml") else None
    return mapping


def shipped_mapping_names() -> list[str]:
    """Names of the mappings shipped in ``configs/mappings``."""
    return sorted(p.stem for p in MAPPINGS_DIR.glob("*.yaml"))
