"""The synthetic renderer's own person and the per-seed variety of sessions."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
import yaml

from gaitcap.data import embedded_walk
from gaitcap.synth.mannequin import Build, Mannequin, Outfit
from gaitcap.synth.session import SynthOptions, scale_walk, synthesize
from gaitcap.synth.variety import _grey_distance, draw_look
from gaitcap.synth.zbuffer import draw_mesh, fill_triangles
from gaitcap.trajectory import POINT_NAMES, Trajectory

SYNTH = Path(__file__).resolve().parents[1] / "src" / "gaitcap" / "synth"
APPEARANCE_MODULES = ("mannequin.py", "render.py", "zbuffer.py", "variety.py", "scene.py")


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            names.add(node.module)
    return names


def test_the_renderer_never_imports_the_trackers_body_or_tracking():
    for name in APPEARANCE_MODULES:
        imported = _imports(SYNTH / name)
        bad = {m for m in imported if m.startswith(("gaitcap.body", "gaitcap.tracking"))}
        assert not bad, f"{name} imports {bad}"
        assert imported, name  # the check parsed something


def test_a_seed_draws_the_same_look_and_two_seeds_differ():
    a, b = draw_look(0, 1.6), draw_look(1, 1.6)
    assert draw_look(0, 1.6) == a
    assert a.outfit != b.outfit and a.room != b.room and a.lighting != b.lighting and a.cameras != b.cameras
    assert a.build != b.build


def test_varieties_cover_the_ranges_the_suite_needs():
    looks = [draw_look(s, 1.1 + 0.8 * (s % 5) / 4, n_cameras=(2, 3, 4)[s % 3]) for s in range(80)]
    outfits = [lk.outfit for lk in looks]
    assert {o.lower for o in outfits} == {"trousers", "shorts", "skirt"}
    assert {o.hair_style for o in outfits} == {"none", "short", "long"}
    assert min(o.sleeves for o in outfits) < 0.4 and max(o.sleeves for o in outfits) == 1.0
    greys = [sum(o.skin) / 3 for o in outfits]
    assert min(greys) < 80 and max(greys) > 170  # dark to light skin
    for lk in looks:
        plan = lk.cameras
        assert all(3.0 <= d <= 6.0 for d in plan.distances_m)
        assert all(0.8 <= h <= 2.0 for h in plan.heights_m)
    assert {len(lk.cameras.azimuths_deg) for lk in looks} == {2, 3, 4}
    # some garments within 20 grey levels of the floor or wall behind them
    near = 0
    for lk in looks:
        grounds = [lk.room.floor_color, lk.room.wall_color] + ([lk.room.mat_color] if lk.room.mat_color else [])
        near += any(_grey_distance(g, c) <= 20 for g in grounds for c in (lk.outfit.top, lk.outfit.bottom))
    assert 0.1 < near / len(looks) < 0.8
    assert {lk.room.floor_kind for lk in looks} == {"tiles", "wood", "carpet", "lino"}


def test_children_have_relatively_larger_heads():
    child = draw_look(5, 1.1).build
    adult = draw_look(5, 1.8).build
    assert child.head[2] > 1.2 * adult.head[2]


def test_zbuffer_keeps_the_nearest_surface_whatever_the_order():
    px = np.array([[10.0, 10], [50, 10], [10, 50], [10, 10], [50, 10], [10, 50]])
    tris = np.array([[0, 1, 2], [3, 4, 5]])
    colors = np.array([[255.0, 0, 0], [0, 255, 0]], np.float32)
    for near_first in (True, False):
        depth = np.array([1.0] * 3 + [2.0] * 3) if near_first else np.array([2.0] * 3 + [1.0] * 3)
        img = np.zeros((64, 64, 3), np.float32)
        cover = draw_mesh(img, px, depth, np.ones(6), tris, colors)
        expected = colors[0] if near_first else colors[1]
        np.testing.assert_allclose(img[20, 20], expected)
        # a closed right triangle of legs 40 px holds area + boundary / 2 + 1 lattice points (Pick)
        assert cover.sum() == 800 + 120 / 2 + 1
    assert img[60, 60].sum() == 0


def test_fill_triangles_is_the_union():
    px = np.array([[0.0, 0], [20, 0], [0, 20], [20, 20]])
    grid = fill_triangles((30, 30), px, np.array([[0, 1, 2], [1, 3, 2]]))
    assert grid[:21, :21].sum() == pytest.approx(441, abs=2)
    assert grid.max() == 1.0 and grid[25:, 25:].sum() == 0


def _standing(height: float) -> np.ndarray:
    h = height
    z = {"pelvis": 0.53, "hip": 0.53, "knee": 0.285, "ankle": 0.039, "heel": 0.005, "toe": 0.01, "thorax": 0.63,
         "neck": 0.82, "head": 0.93, "shoulder": 0.82, "elbow": 0.63, "wrist": 0.49}  # fmt: skip
    pts = []
    for name in POINT_NAMES:
        base = name.rsplit("_", 1)[0]
        y = {"_l": 1.0, "_r": -1.0}.get(name[-2:], 0.0) if name[-2:] in ("_l", "_r") else 0.0
        width = 0.13 if base in ("shoulder", "elbow", "wrist") else 0.05
        x = {"heel": -0.03, "toe": 0.12}.get(base, 0.0)
        pts.append([x * h, y * width * h, z[base] * h])
    return np.array(pts)


def test_mannequin_mesh_is_finite_and_varies_with_the_build():
    pts = _standing(1.7)
    slim = Mannequin(Build(1.7).scaled(0.85, ("thigh", "calf")), Outfit(lower="shorts", legs_cover=0.3))
    heavy = Mannequin(Build(1.7).scaled(1.25, ("thigh", "calf")), Outfit(lower="shorts", legs_cover=0.3))
    vs, ns = slim.mesh(pts)
    vh, _ = heavy.mesh(pts)
    assert vs.shape == (slim.n_vertices, 3) and np.isfinite(vs).all()
    np.testing.assert_allclose(np.linalg.norm(ns, axis=1), 1.0, atol=1e-6)
    assert slim.triangles.max() < slim.n_vertices
    # the heavier build's legs reach further out sideways at knee height
    at_knee = lambda v: np.abs(v[(np.abs(v[:, 2] - 0.4 * 1.7) < 0.05) & (np.abs(v[:, 1]) < 0.18), 1]).max()  # noqa: E731
    assert at_knee(vh) > at_knee(vs)
    with pytest.raises(ValueError, match="finite"):
        slim.mesh(np.full_like(pts, np.nan))


def test_bare_shins_are_skin_and_trousers_cover_them():
    shorts = Mannequin(Build(1.7), Outfit(lower="shorts", legs_cover=0.3, skin=(1.0, 2.0, 3.0)))
    trousers = Mannequin(Build(1.7), Outfit(lower="trousers", skin=(1.0, 2.0, 3.0)))
    def skin_share(m: Mannequin) -> float:  # noqa: E306
        return float(np.all(m.colors == np.float32([1, 2, 3]), axis=1).mean())
    assert skin_share(shorts) > skin_share(trousers) + 0.05


def test_scale_walk_makes_a_child_of_the_same_walk():
    pts = np.stack([_standing(1.7)] * 3)
    traj = Trajectory(POINT_NAMES, pts, 25.0, meta={"height_m": 1.7})
    child = scale_walk(traj, 1.1, 1.7)
    assert child.meta["height_m"] == 1.1
    leg = lambda t: np.linalg.norm(t.point("hip_l") - t.point("ankle_l"), axis=1)  # noqa: E731
    np.testing.assert_allclose(leg(child), leg(traj) * 1.1 / 1.7)
    assert np.nanmin(child.points[..., 2]) >= 0


def test_synth_subject_height_and_look_reach_the_session(tmp_path):
    res = synthesize(embedded_walk(), tmp_path / "child", SynthOptions(size=(160, 120), seed=4, subject_height_m=1.2),
                     progress=False)  # fmt: skip
    info = yaml.safe_load((res.session / "session.yaml").read_text())
    assert info["subject"]["height_m"] == pytest.approx(1.2, abs=1e-3)
    assert res.look == draw_look(4, res.truth.meta["height_m"], 2)
    hip_z = np.nanmedian(res.truth.point("hip_l")[:, 2])
    assert 0.45 < hip_z / 1.2 < 0.55
