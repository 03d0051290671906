"""The shipped configuration files say, beside each key, the range its schema accepts (the README: "Each
key's comment says what it does, its unit and range")."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from pydantic import BaseModel

from gaitcap.body.spec import BodySpec
from gaitcap.config import default_config_path
from gaitcap.silhouette.config import SilhouetteConfig
from gaitcap.tracking.config import TrackingConfig


def _key_lines(path: Path) -> tuple[list[str], dict[str, int]]:
    """The file's lines and {dotted key: line index} of every mapping key."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out: dict[str, int] = {}
    stack: list[tuple[int, str]] = []
    for i, line in enumerate(lines):
        m = re.match(r"^(\s*)([A-Za-z_]\w*):(\s|$)", line)
        if m:
            stack = [(d, k) for d, k in stack if d < len(m[1])] + [(len(m[1]), m[2])]
            out[".".join(k for _, k in stack)] = i
    return lines, out


def _comment_near(lines: list[str], i: int) -> str:
    """The comments of line ``i`` and of the lines around it (a key's comment may run over a few lines,
    or several keys share one)."""
    return " ".join(line.split("#", 1)[1] for line in lines[max(0, i - 2): i + 4] if "#" in line)


def _bounds(model: type[BaseModel], prefix: str = ""):
    """(dotted key, [(ge|gt|le|lt, value)]) of every field with numeric bounds, sub-models walked."""
    for name, f in model.model_fields.items():
        ann = f.annotation
        if isinstance(ann, type) and issubclass(ann, BaseModel):
            yield from _bounds(ann, f"{prefix}{name}.")
            continue
        found = [(a, getattr(m, a)) for m in f.metadata for a in ("ge", "gt", "le", "lt") if getattr(m, a, None) is not None]
        if found:
            yield prefix + name, found


def _spellings(value: float) -> list[str]:
    out = [f"{value:g}"]
    if float(value).is_integer():
        out.append(str(int(value)))
    return out


@pytest.mark.parametrize(("model", "name"), [(TrackingConfig, "tracking.yaml"), (SilhouetteConfig, "silhouette.yaml"),
                                             (BodySpec, "body.yaml")])  # fmt: skip
def test_every_bounded_key_of_a_shipped_config_states_its_range(model, name):
    lines, at = _key_lines(default_config_path(name))
    missing = []
    for key, bounds in _bounds(model):
        assert key in at, f"{name}: {key} is not in the shipped file"
        text = _comment_near(lines, at[key])
        for kind, value in bounds:
            if not any(re.search(r"(?<![\d.])" + re.escape(s) + r"(?![\d])", text) for s in _spellings(value)):
                missing.append(f"{key} ({kind} {value:g})")
    assert not missing, f"{name}: comments without the schema's bound: {', '.join(missing)}"
