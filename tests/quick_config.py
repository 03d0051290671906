"""A tracking configuration for quick runs in tests: the shipped tracking.yaml with the shape
calibration off and 40/80 particles."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from gaitcap.config import default_config_path


def quick_tracking(folder: Path, **sections: dict[str, Any]) -> Path:
    """Write ``folder/tracking.yaml``: the shipped configuration, shape calibration off, 40 particles a
    node and 80 at the root, and each of ``sections`` (``verdict={"min_leg_support": 1.0}``) updated."""
    data = yaml.safe_load(default_config_path("tracking.yaml").read_text())
    data["shape"]["enabled"] = False
    data["factored_ipf"].update(particles=40, root_particles=80)
    for name, values in sections.items():
        data[name].update(values)
    path = folder / "tracking.yaml"
    path.write_text(yaml.safe_dump(data))
    return path
