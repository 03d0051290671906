"""pyproject.toml and the README's quick start agree on the Pythons gaitcap supports."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_the_pythons_named_agree():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    floor = re.fullmatch(r">=\s*3\.(\d+)", project["requires-python"])
    assert floor, project["requires-python"]
    named = sorted(int(c.rsplit(".", 1)[1]) for c in project["classifiers"]
                   if re.fullmatch(r"Programming Language :: Python :: 3\.\d+", c))  # fmt: skip
    assert named and named[0] == int(floor[1]), (named, project["requires-python"])
    assert named == list(range(named[0], named[-1] + 1))  # no gap
    heading = next(line for line in (ROOT / "README.md").read_text().splitlines() if line.startswith("## Quick start"))
    assert f"Python >= 3.{named[0]}" in heading
    assert ", ".join(f"3.{n}" for n in named[:-1]) + f" and 3.{named[-1]}" in heading


def test_the_licence_is_an_spdx_expression_with_a_setuptools_that_reads_it():
    # the table form license = {text = "MIT"}: the wheel's build (setuptools 84) warned "`project.license`
    # as a TOML table is deprecated ... By 2027-Feb-18, you need to update your project ... or your
    # builds will no longer be supported" (seen with pip install -v; pip hides it otherwise)
    data = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert data["project"]["license"] == "MIT"
    floor = next(re.fullmatch(r"setuptools>=(\d+)(\.\d+)*", r) for r in data["build-system"]["requires"]
                 if r.startswith("setuptools"))  # fmt: skip
    assert floor and int(floor[1]) >= 77  # the first to read an SPDX expression
    assert not any(c.startswith("License ::") for c in data["project"].get("classifiers", []))  # refused beside it
