from __future__ import annotations

import itertools
import logging

import cv2
import numpy as np
import pytest
from silhouette_scene import grey_body_rig, iou, sway_in_place, walk_across

from gaitcap.config import model_from_mapping
from gaitcap.errors import ConfigError, InputError
from gaitcap.silhouette import SilhouetteConfig, SilhouetteExtractor
from gaitcap.silhouette.background import _channel_mean, _median, global_gain, global_gains
from gaitcap.silhouette.extract import BORDER, EMPTY, NO_BACKGROUND, TOO_LARGE, _label_type
from gaitcap.camera import Camera
from gaitcap.silhouette.floor import (FloorShadowCheck, _floor_map_rows, _floor_points_rows, floor_map, floor_points,
                                      floor_rows, head_top)  # fmt: skip
from gaitcap.silhouette.joint import JointExtractor, floor_check


@pytest.fixture(scope="module")
def scene():
    # dark trousers on a grey textured floor next to a soft cast shadow, noise, 8% drift
    return walk_across(200, 150, 40, seed=3)


def _mean_iou(extractor, scene, min_area=300):
    ious = []
    for k, (mask, _) in enumerate(extractor.extract(scene.frames)):
        if scene.masks[k].sum() >= min_area:
            ious.append(iou(mask, scene.masks[k]))
    return float(np.mean(ious))


def _config(**sections) -> SilhouetteConfig:
    return model_from_mapping(SilhouetteConfig, sections, "test")


def test_shipped_yaml_equals_schema_defaults():
    assert SilhouetteConfig.load() == SilhouetteConfig()


def test_config_rejects_unknown_key_with_suggestion():
    with pytest.raises(ConfigError, match=r"shadow\.min_ration: unknown key \(did you mean 'min_ratio'\?\)"):
        _config(shadow={"min_ration": 0.4})


def test_config_rejects_inverted_shadow_ratios():
    with pytest.raises(ConfigError, match="min_ratio"):
        _config(shadow={"min_ratio": 0.9, "max_ratio": 0.5})


def test_masks_match_truth_with_plate(scene):
    ex = SilhouetteExtractor(SilhouetteConfig())
    report = ex.fit_background(plate=scene.plate, samples=scene.frames[::4])
    assert report.source == "plate" and report.usable
    # 0.932 with one hard threshold; the hysteresis adds a pixel-wide ring of penumbra at the feet
    assert _mean_iou(ex, scene) >= 0.92


def test_masks_match_truth_with_background_from_video(scene):
    ex = SilhouetteExtractor(SilhouetteConfig())
    report = ex.fit_background(samples=scene.frames[::2])
    assert report.source == "video" and report.usable
    assert _mean_iou(ex, scene) >= 0.93


def test_shadow_suppression_removes_the_shadow_not_the_trousers(scene):
    with_shadow = SilhouetteExtractor(SilhouetteConfig())
    without = SilhouetteExtractor(_config(shadow={"enabled": False}))
    for ex in (with_shadow, without):
        ex.fit_background(plate=scene.plate)
    k = 20
    on, q_on = with_shadow.process(scene.frames[k])
    off, q_off = without.process(scene.frames[k])
    truth = scene.masks[k].astype(bool)
    trousers = truth & (scene.frames[k].mean(axis=2) < 70)  # the dark legs
    assert trousers.sum() > 200
    assert on[trousers].mean() >= 0.95  # dark trousers kept although darker than the floor
    assert off[~truth].sum() > 3 * max(on[~truth].sum(), 1)  # the shadow is what "off" adds
    assert q_on.shadow_fraction > 0 and q_off.shadow_fraction == 0
    assert iou(on, truth) > iou(off, truth) + 0.1


def test_empty_scene_is_flagged_empty(scene):
    ex = SilhouetteExtractor(SilhouetteConfig())
    ex.fit_background(plate=scene.plate)
    rng = np.random.default_rng(1)
    frame = np.clip(scene.plate + rng.normal(0, 3, scene.plate.shape), 0, 255).astype(np.uint8)
    mask, q = ex.process(frame)
    assert mask.sum() == 0 and q.flags & EMPTY and q.bbox is None


def test_figure_at_the_edge_is_flagged_border(scene):
    ex = SilhouetteExtractor(SilhouetteConfig())
    ex.fit_background(plate=scene.plate)
    flags = [q.flags for _, q in ex.extract(scene.frames)]
    truth = scene.masks
    at_edge = [k for k in range(len(truth)) if truth[k].sum() > 100 and (truth[k][:, 0].any() or truth[k][:, -1].any())]
    inside = [k for k in range(len(truth)) if truth[k].sum() > 100 and not (truth[k][:, :3].any() or truth[k][:, -3:].any())]
    assert len(at_edge) >= 2 and len(inside) >= 10
    assert all(flags[k] & BORDER for k in at_edge)
    assert not any(flags[k] & BORDER for k in inside)


def test_lighting_jump_compensated_or_flagged(scene):
    jump = np.clip(scene.frames[20].astype(np.float32) * 1.35, 0, 255).astype(np.uint8)
    ex = SilhouetteExtractor(SilhouetteConfig())
    ex.fit_background(plate=scene.plate)
    mask, q = ex.process(jump)
    # the wall clipped at 255 cannot be compensated: a patch at the head stays foreground (0.86 with
    # one hard threshold, 0.82 with the hysteresis, which grows that patch by a ring of weak pixels)
    assert not q.flags & TOO_LARGE and iou(mask, scene.masks[20]) > 0.8
    naive = SilhouetteExtractor(_config(background={"gain_compensation": False}))
    naive.fit_background(plate=scene.plate)
    _, q = naive.process(jump)
    assert q.flags & TOO_LARGE


def test_no_usable_background_when_subject_never_leaves(caplog):
    sway = sway_in_place(200, 150, 40, seed=5)
    ex = SilhouetteExtractor(SilhouetteConfig())
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        report = ex.fit_background(samples=sway.frames)
    assert not report.usable
    assert "no usable background" in caplog.text
    _, q = ex.process(sway.frames[0])
    assert q.flags & NO_BACKGROUND


def test_usable_background_on_a_walk_across(scene, caplog):
    ex = SilhouetteExtractor(SilhouetteConfig())
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        report = ex.fit_background(samples=scene.frames)
    assert report.usable and report.ambiguous_fraction < 0.02
    assert "no usable background" not in caplog.text


def test_frames_and_backgrounds_of_the_wrong_shape_are_named_by_their_shape():
    """A grey (H, W) frame of the background's size was refused with "frame 0 is 64x48, the background is
    64x48", and one (H, W, 3) image given as ``samples`` with the shape its rows took after working on them,
    (48, 64, 8): each is named by the shape given now."""
    ex = SilhouetteExtractor(SilhouetteConfig.load(), name="cam0")
    plate = np.full((48, 64, 3), 120, np.uint8)
    with pytest.raises(InputError, match=r"cam0: expected sampled frames of shape \(N, H, W, 3\) \(BGR\), got \(48, 64, 3\)"):
        ex.fit_background(samples=plate)
    with pytest.raises(InputError, match=r"cam0: expected a background plate of shape \(H, W, 3\) \(BGR\), got \(48, 64\)"):
        ex.fit_background(plate=plate[..., 0])
    ex.fit_background(plate=plate)
    with pytest.raises(InputError, match=r"cam0: frame 0 has shape \(48, 64\), expected \(H, W, 3\) \(BGR\)"):
        ex.process(plate[..., 0])
    with pytest.raises(InputError, match="cam0: frame 0 is 64x40, the background is 64x48"):
        ex.process(plate[:40])
    mask, _ = ex.process(plate)
    assert mask.shape == (48, 64) and not mask.any()


def test_small_holes_filled_large_gaps_kept():
    plate = np.full((120, 160, 3), 128, np.uint8)
    frame = plate.copy()
    frame[20:100, 40:120] = 30  # a dark block ...
    frame[55:59, 60:64] = 128  # ... with a 4x4 hole (0.25% of the block)
    frame[30:90, 95:110] = 128  # ... and a large notch-like hole (14%)
    ex = SilhouetteExtractor(SilhouetteConfig())
    ex.fit_background(plate=plate)
    mask, _ = ex.process(frame)
    assert mask[56, 61] == 1
    assert mask[60, 102] == 0


def test_extract_is_lazy(scene):
    ex = SilhouetteExtractor(SilhouetteConfig())
    ex.fit_background(plate=scene.plate)
    endless = itertools.cycle(scene.frames[:3])  # never ends: extract must not collect it
    out = list(itertools.islice(ex.extract(endless), 5))
    assert [q.index for _, q in out] == [0, 1, 2, 3, 4]
    assert out[0][0].shape == scene.frames[0].shape[:2] and out[0][0].dtype == np.uint8


def test_working_scale_returns_full_size_masks():
    scene = walk_across(320, 240, 24, seed=4)
    ex = SilhouetteExtractor(_config(scale=0.5))
    ex.fit_background(plate=scene.plate, samples=scene.frames[::4])
    assert ex.background.shape == (120, 160, 3)
    assert _mean_iou(ex, scene, min_area=800) >= 0.85


def test_errors_name_the_camera(scene):
    ex = SilhouetteExtractor(SilhouetteConfig(), name="camX")
    with pytest.raises(InputError, match="camX.*fit_background"):
        ex.process(scene.frames[0])
    with pytest.raises(InputError, match="camX: no background plate"):
        ex.fit_background()
    ex.fit_background(plate=scene.plate)
    with pytest.raises(InputError, match="camX: frame 0 is 100x75"):
        ex.process(scene.frames[0][::2, ::2])
    with pytest.raises(InputError, match="plate is 200x150 but the video is 100x75"):
        ex.fit_background(plate=scene.plate, samples=scene.frames[:5, ::2, ::2])


def test_plate_with_a_subject_who_never_leaves_the_spot():
    """Walking in place: the subject is in every sampled frame. The noise estimated from those
    samples must not swallow the subject (the per-pixel sigma is capped)."""
    from silhouette_scene import sway_in_place

    scene = sway_in_place(seed=3)
    ex = SilhouetteExtractor(SilhouetteConfig(), name="cam")
    ex.fit_background(plate=scene.plate, samples=scene.frames[::3])
    ious = [iou(ex.process(f)[0], m) for f, m in zip(scene.frames, scene.masks)]
    assert np.mean(ious) > 0.85, np.mean(ious)


def test_a_plate_of_another_scene_is_unusable_and_said(embedded_session, caplog):
    """A plate that is not this camera's scene (the other camera's here; another session's: the masks were
    fragments, reported usable) is told by the median of the sampled frames; the subject walking across
    its own plate's scene, or on the spot, moves that median little."""
    from gaitcap.session import Session
    from gaitcap.video import sample_frames

    ses = Session.open(embedded_session.session)
    plates = {cam: cv2.imread(str(path)) for cam, path in ses.backgrounds.items()}
    samples = sample_frames(ses.videos["cam1"], 31)
    own = SilhouetteExtractor(SilhouetteConfig(), name="cam1")
    own.fit_background(plate=plates["cam1"], samples=samples)
    assert own.report.usable
    swayed = sway_in_place(seed=3)
    on_the_spot = SilhouetteExtractor(SilhouetteConfig(), name="cam")
    on_the_spot.fit_background(plate=swayed.plate, samples=swayed.frames[::3])
    assert on_the_spot.report.usable
    swapped = SilhouetteExtractor(SilhouetteConfig(), name="cam1")
    with caplog.at_level(logging.WARNING, logger="gaitcap"):
        swapped.fit_background(plate=plates["cam2"], samples=samples)
    assert not swapped.report.usable and "cam1: the plate does not match the video" in caplog.text
    assert swapped.process(samples[0])[1].flags & NO_BACKGROUND  # every frame flagged, as without a background


def _rig_masks(rig, config: SilhouetteConfig, calibrated: bool = True) -> list[np.ndarray]:
    extractors = []
    for cam, plate in zip(rig.cameras, rig.plates):
        ex = SilhouetteExtractor(config, name=cam.name)
        ex.fit_background(plate=plate, samples=np.stack([plate] * 5))
        extractors.append(ex)
    joint = JointExtractor(extractors, rig.cameras if calibrated else None)
    return [mask for mask, _ in joint.process(rig.frames)]


def test_floor_check_keeps_a_grey_body_over_a_grey_wall_and_removes_the_floor_shadow():
    rig = grey_body_rig(seed=5)
    checked = _rig_masks(rig, SilhouetteConfig())
    alone = _rig_masks(rig, SilhouetteConfig(), calibrated=False)
    for c in range(2):
        truth = rig.masks[c].astype(bool)
        # alone, the darker grey body over the lighter grey wall passes the photometric shadow test
        assert checked[c][truth].mean() > 0.9 > 0.6 > alone[c][truth].mean()
        # the floor shadow, darkened in both views, stays out
        assert checked[c][rig.shadows[c].astype(bool)].mean() < 0.05
        assert iou(checked[c], rig.masks[c]) > 0.85


def test_floor_check_without_the_other_camera_keeps_the_photometric_shadow():
    rig = grey_body_rig(seed=6)
    rig.cameras, rig.plates, rig.frames = rig.cameras[:1], rig.plates[:1], rig.frames[:1]
    (mask,) = _rig_masks(rig, SilhouetteConfig())
    # nobody confirms the floor shadow, so it stays a shadow; the body above the horizon is kept
    assert mask[rig.shadows[0].astype(bool)].mean() < 0.05
    top = np.flatnonzero(rig.masks[0].any(axis=1))[0]
    assert mask[top + 3][rig.masks[0][top + 3].astype(bool)].mean() > 0.9


def test_a_head_cut_off_at_a_thin_neck_is_kept_a_far_speck_is_not():
    plate = np.full((120, 160, 3), 128, np.uint8)
    frame = plate.copy()
    frame[40:110, 60:100] = 30  # the body (2800 px)
    frame[30:40, 79] = 30  # a 1-pixel neck, removed by the opening
    cv2.circle(frame, (79, 24), 6, (30, 30, 30), -1)  # the head (about 4 % of the body)
    frame[10:16, 140:146] = 30  # a speck away from the body (36 px)
    ex = SilhouetteExtractor(SilhouetteConfig())
    ex.fit_background(plate=plate)
    mask, q = ex.process(frame)
    assert mask[24, 79] == 1 and mask[70, 80] == 1
    assert mask[12, 142] == 0
    assert q.components == 2


def test_a_foot_below_a_trunk_whose_legs_were_lost_is_kept_specks_beside_or_far_below_are_not():
    plate = np.full((240, 200, 3), 128, np.uint8)
    frame = plate.copy()
    frame[20:100, 80:120] = 30  # head and trunk (3200 px): the legs, the floor's colour, were not found
    frame[150:160, 95:115] = 30  # a shoe (200 px), 50 rows (0.63 box heights) below the trunk
    frame[60:70, 170:180] = 30  # a speck beside the body, beyond the margin (100 px)
    frame[225:235, 95:105] = 30  # a speck 1.6 box heights below the trunk (100 px)
    for below, shoe in ((0.0, 0), (1.0, 1)):
        ex = SilhouetteExtractor(_config(cleanup={"keep_below": below}))
        ex.fit_background(plate=plate)
        mask, q = ex.process(frame)
        assert mask[60, 100] == 1 and mask[155, 105] == shoe
        assert mask[65, 175] == 0 and mask[230, 100] == 0
        assert q.components == 1 + shoe


def test_a_small_foot_cut_off_at_the_ankle_is_kept_a_small_shadow_piece_beside_it_is_not():
    plate = np.full((240, 200, 3), 128, np.uint8)
    frame = plate.copy()
    frame[20:100, 80:120] = 30  # head and trunk (3200 px)
    frame[100:160, 100:108] = 30  # a leg down to the ankle (row 160)
    frame[170:174, 100:105] = 30  # its foot (20 px), 10 rows below: the ankle taken for shadow
    frame[170:174, 120:125] = 30  # a piece of cast shadow (20 px) beside the foot: nothing above it
    ex = SilhouetteExtractor(SilhouetteConfig())
    ex.fit_background(plate=plate)
    min_area = ex.config.cleanup.min_component_fraction * 240 * 200
    assert 20 < min_area  # both too small to be kept on their area alone
    mask, q = ex.process(frame)
    assert mask[60, 100] == 1 and mask[130, 104] == 1
    assert mask[172, 102] == 1  # the foot, under the leg it was cut from
    assert mask[172, 122] == 0  # the shadow piece: no body over or under it
    assert q.components == 2
    line = plate.copy()
    line[20:100, 80:120] = 30  # the same trunk and leg, no foot ...
    line[100:160, 100:108] = 30
    line[170:173, 107:114] = 30  # ... and a thin line of shadow (21 px) reaching under the leg by one column of 7
    mask, q = ex.process(line)
    assert mask[171, 110] == 0 and q.components == 1


def test_the_floor_row_keeps_a_foot_whose_leg_was_lost_and_drops_a_shadow_piece_below_found_feet():
    plate = np.full((240, 200, 3), 128, np.uint8)
    lost = plate.copy()
    lost[20:100, 70:130] = 30  # head and trunk (4800 px): the legs were not found
    lost[150:160, 95:115] = 30  # a shoe 50 rows below the trunk, on the floor (row 160)
    lost[160:180, 100:120] = 30  # its cast shadow on the floor, joined to it (with the shoe, 600 px: no main part)
    found = plate.copy()
    found[20:160, 80:120] = 30  # the whole body down to the feet on the floor (row 160)
    found[185:195, 70:90] = 30  # a piece of its cast shadow that the shadow test missed, 25 rows below
    ex = SilhouetteExtractor(SilhouetteConfig())
    ex.fit_background(plate=plate)
    mask, _ = ex.finish(ex.observe(lost), np.zeros((240, 200), bool), floor_row=160.0)
    assert mask[155, 105] == 1 and mask[165, 110] == 1  # the foot, and the floor row's slack (8 % of 140 rows)
    assert not mask[175:].any()  # past it, the shadow joined to the foot is cut off
    mask, q = ex.finish(ex.observe(found), np.zeros((240, 200), bool), floor_row=160.0)
    assert mask[190, 80] == 0 and q.components == 1
    mask, q = ex.finish(ex.observe(found), np.zeros((240, 200), bool))  # no floor row: one box height
    assert mask[190, 80] == 1 and q.components == 2


def _person_masks(cams, at, height=1.7, radius=0.2):
    """Full-size masks of an upright cylinder (a person) standing at floor point ``at`` (x, y)."""
    t = np.linspace(0, 2 * np.pi, 24, endpoint=False)
    ring = np.stack([at[0] + radius * np.cos(t), at[1] + radius * np.sin(t)], axis=1)
    pts = np.concatenate([np.c_[ring, np.zeros(len(t))], np.c_[ring, np.full(len(t), height)]])
    masks = []
    for cam in cams:
        px = cam.project(pts)
        m = np.zeros(cam.size[::-1], np.uint8)
        cv2.fillConvexPoly(m, cv2.convexHull(np.round(px).astype(np.int32)), 1)
        masks.append(m)
    return masks


def test_floor_rows_put_the_floor_beneath_the_person_where_each_camera_sees_it():
    cams = [Camera.look_at(name, pos, (0.0, 0.0, 0.9), size=(320, 240), focal_px=260.0, dist=(-0.1, 0.02, 0, 0))
            for name, pos in (("side", (0.0, -4.0, 1.2)), ("front", (4.0, 0.5, 1.5)), ("oblique", (-3.0, -3.0, 2.0)))]
    at = (0.3, -0.2)
    rows = floor_rows(cams, _person_masks(cams, at))
    truth = [cam.project(np.array([[*at, 0.0]]))[0, 1] for cam in cams]
    assert all(r is not None for r in rows)
    assert np.max(np.abs(np.array(rows) - truth)) < 0.03 * 240  # the head's top is the cylinder's rim
    masks = _person_masks(cams, at)
    assert floor_rows(cams[:1], masks[:1]) == [None]  # one camera cannot triangulate
    masks[1][:] = 0
    masks[2][:5] = 1  # the top at the image's edge: the head is cut off there
    assert floor_rows(cams, masks) == [None, None, None]
    assert head_top(np.zeros((10, 10), np.uint8)) is None


def test_joint_extractor_follows_the_floor_beneath_the_person_from_frame_to_frame():
    cams = [Camera.look_at(name, pos, (0.0, 0.0, 0.9), size=(320, 240), focal_px=260.0)
            for name, pos in (("side", (0.0, -4.0, 1.2)), ("front", (4.0, 0.5, 1.5)))]
    at = (0.3, -0.2)
    plates = [np.full((240, 320, 3), 128, np.uint8) for _ in cams]
    frames = [np.where(m[..., None] > 0, np.uint8(40), p) for m, p in zip(_person_masks(cams, at), plates)]
    extractors = []
    for plate in plates:
        ex = SilhouetteExtractor(_config(shadow={"enabled": False}))
        ex.fit_background(plate=plate)
        extractors.append(ex)
    joint = JointExtractor(extractors, cams)
    assert joint._floor_rows == [None, None]  # nothing seen yet
    joint.process(frames)
    truth = [cam.project(np.array([[*at, 0.0]]))[0, 1] for cam in cams]
    assert np.max(np.abs(np.array(joint._floor_rows) - truth)) < 0.03 * 240
    assert np.hypot(*(joint._top[:2] - at)) < 0.1  # the person's floor point, for shadow.floor_footprint
    alone = JointExtractor(extractors[:1], None)  # no calibration: no floor row
    alone.process(frames[:1])
    assert alone._floor_rows == [None]


def test_floor_map_sends_a_floor_point_to_where_the_other_camera_sees_it():
    cams = [
        Camera.look_at(name, (x, -3.0, 1.4), (0.0, 0.0, 0.5), size=(160, 120), focal_px=120.0, dist=(-0.2, 0.05, 0, 0))
        for name, x in (("a", -2.0), ("b", 1.5))
    ]
    points = floor_points(cams[0], (80, 60))  # half scale
    # a pixel of the top row sees the wall region above the horizon: no floor point
    assert np.isnan(points[0, 40]).all() and np.isfinite(points[59, 40]).all()
    mapped = floor_map(points, cams[1], (80, 60))
    for world in ([0.3, 0.2, 0.0], [-0.5, -1.0, 0.0]):
        u, v = (cams[0].project(np.array(world)) + 0.5) / 2 - 0.5  # camera a, working scale
        i, j = int(round(v)), int(round(u))
        expected = (cams[1].project(points[i, j]) + 0.5) / 2 - 0.5
        np.testing.assert_allclose(mapped[i, j], expected, atol=1e-3)
        back = (cams[0].project(points[i, j]) + 0.5) / 2 - 0.5  # the floor point is on the pixel's ray
        np.testing.assert_allclose(back, [j, i], atol=1e-3)
        assert abs(points[i, j][2]) < 1e-9 and np.hypot(*(points[i, j][:2] - world[:2])) < 0.15  # near the point


def _noisy(image: np.ndarray, sigma: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.clip(image + rng.normal(0, sigma, image.shape), 0, 255).astype(np.uint8)


def _low_contrast_legs() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A plate, a frame and its true mask: a confident torso on low-contrast legs (12 grey levels,
    below the 18 of ``min_diff``) and an unconnected blob of the same low contrast."""
    plate = np.full((120, 160, 3), 120.0)
    frame = plate.copy()
    truth = np.zeros((120, 160), bool)
    frame[20:60, 60:100] = 40  # torso
    frame[60:110, 64:96] = 132  # legs, 12 grey levels brighter than the floor
    frame[80:100, 130:150] = 132  # a blob as faint, away from the body
    truth[20:110, 60:100] = True
    truth[60:110, 96:100] = truth[60:110, 60:64] = False
    return _noisy(plate, 1.5, 1), _noisy(frame, 1.5, 2), truth


def test_hysteresis_keeps_faint_legs_joined_to_the_body_not_a_faint_blob_away_from_it():
    plate, frame, truth = _low_contrast_legs()
    results = {}
    for h in (1.0, 0.5):
        ex = SilhouetteExtractor(_config(foreground={"hysteresis": h}))
        ex.fit_background(plate=plate)
        results[h] = ex.process(frame)[0]
    assert iou(results[1.0], truth) < 0.6  # one hard threshold: the torso only
    assert iou(results[0.5], truth) > 0.95
    assert results[0.5][90, 140] == 0


def test_texture_cue_finds_a_smooth_leg_over_a_carpet_of_its_colour():
    rng = np.random.default_rng(5)
    carpet = 120 + rng.normal(0, 12, (120, 160, 1)).repeat(3, axis=2)  # grain of one pixel
    plate = np.clip(carpet, 0, 255).astype(np.uint8)
    frame = plate.copy()
    frame[20:60, 60:100] = 30  # a dark torso
    frame[60:110, 66:94] = 120  # a smooth leg of the carpet's mean colour
    leg = np.s_[65:105, 70:90]
    masks = {}
    for ncc in (-1.0, 0.4):
        ex = SilhouetteExtractor(_config(foreground={"texture_ncc": ncc}))
        ex.fit_background(plate=plate)
        masks[ncc] = ex.process(frame)[0]
    assert masks[-1.0][leg].mean() < 0.5
    assert masks[0.4][leg].mean() > 0.95
    assert masks[0.4][:, 110:].sum() == 0  # the untouched carpet stays background


def test_soft_silhouette_is_sure_on_the_body_doubtful_on_faint_parts_and_zero_outside():
    plate, frame, truth = _low_contrast_legs()
    ex = SilhouetteExtractor(SilhouetteConfig())
    ex.fit_background(plate=plate)
    mask, soft, _ = ex.finish_soft(ex.observe(frame), np.zeros((120, 160), bool))
    assert soft.dtype == np.float32 and soft.shape == mask.shape
    m = ex.config.foreground.soft_min
    assert np.all(soft[mask == 0] == 0) and np.all((soft[mask == 1] >= m) & (soft[mask == 1] <= 1))
    assert np.median(soft[30:50, 70:90]) == 1.0  # the torso
    assert m <= np.median(soft[70:100, 70:90]) < 1 - 0.2 * (1 - m)  # the faint legs: doubtful


def test_doubt_outside_the_mask_is_at_most_half_never_on_shadow_nor_far_from_the_body():
    """``foreground.doubt_min`` (the run ``lost_legs`` tracks again): outside the mask, a pixel no
    shadow whose difference reaches doubt_min x threshold scores up to 0.5, up to the weak level;
    inside the mask nothing changes; far from the body, on shadow, and on the plain floor: 0."""
    plate, frame, _ = _low_contrast_legs()
    frame[110:116, 64:96] += 7  # the feet under the legs: 7 grey levels, under the weak level (9 of 18)
    frame[5:11, 5:25] += 7  # as faint, far above and beside the body
    shadow = np.zeros((120, 160), bool)
    shadow[110:116, 80:96] = True  # the right half of the feet taken for a shadow
    outs = {}
    for doubt_min in (0.3, 1.0):
        ex = SilhouetteExtractor(_config(foreground={"soft_min": 1.0, "doubt_min": doubt_min}))
        ex.fit_background(plate=plate)
        outs[doubt_min] = ex.finish_soft(ex.observe(frame), shadow)
    (mask, soft, _), (mask_off, soft_off, _) = outs[0.3], outs[1.0]
    assert np.array_equal(mask, mask_off)  # the masks do not depend on the doubt
    assert np.all(soft[mask == 1] == 1.0) and np.array_equal(soft[mask == 1], soft_off[mask == 1])
    outside = soft[mask == 0]
    assert outside.min() >= 0.0 and outside.max() <= 0.5
    assert np.all(soft_off[mask == 0] == 0)  # doubt_min at or above the weak level: no doubt
    feet = soft[111:115, 66:78]
    assert (mask[111:115, 66:78] == 0).all() and 0.05 < np.median(feet) <= 0.5  # doubtful, not sure
    assert np.all(soft[110:116, 80:96][mask[110:116, 80:96] == 0] == 0)  # shadow: no doubt
    assert np.all(soft[5:11, 5:25] == 0)  # as faint, but far from the body's box
    assert np.median(soft[mask == 0]) == 0.0  # the plain floor: noise under doubt_min x threshold


def test_joint_soft_silhouettes_agree_with_the_masks():
    rig = grey_body_rig(seed=5)
    extractors = []
    for cam, plate in zip(rig.cameras, rig.plates):
        ex = SilhouetteExtractor(SilhouetteConfig(), name=cam.name)
        ex.fit_background(plate=plate, samples=np.stack([plate] * 5))
        extractors.append(ex)
    hard = JointExtractor(extractors, rig.cameras).process(rig.frames)
    soft = JointExtractor(extractors, rig.cameras).process_soft(rig.frames)
    for (mask, _), (mask_s, s, _) in zip(hard, soft):
        assert np.array_equal(mask, mask_s)
        assert np.all(s[mask == 0] == 0) and s[mask == 1].min() >= extractors[0].config.foreground.soft_min
        assert s.max() == 1.0


def _colour_only_leg(ring: bool) -> tuple[np.ndarray, np.ndarray, tuple[slice, slice]]:
    """A plate (a teal floor), a frame and the leg's box: a dark torso on a leg of the floor's
    brightness but another colour (plain RMS difference 12.9 grey levels, below ``min_diff`` 18; all of
    it a change of colour), with, if ``ring``, a one-pixel ring of half that colour change around the
    leg (how video's half-resolution colour bleeds past an outline)."""
    plate = np.full((120, 160, 3), (100.0, 100.0, 70.0))  # BGR
    frame = plate.copy()
    frame[20:60, 60:100] = 30  # torso
    if ring:
        frame[59:111, 65:95] = plate[0, 0] + 0.5 * np.array([-8.0, -6.0, 20.0])
    frame[60:110, 66:94] = plate[0, 0] + np.array([-8.0, -6.0, 20.0])  # grey-violet leg: D orthogonal to B
    return _noisy(plate, 1.0, 1), _noisy(frame, 1.0, 2), np.s_[60:110, 66:94]


def test_colour_weight_finds_a_leg_that_differs_from_the_floor_in_colour_not_brightness():
    plate, frame, leg = _colour_only_leg(ring=False)
    masks = {}
    for w in (1.0, 2.0):
        ex = SilhouetteExtractor(_config(foreground={"chroma_weight": w, "hysteresis": 1.0}))
        ex.fit_background(plate=plate)
        masks[w] = ex.process(frame)[0]
    inside = np.s_[leg[0].start + 1 : leg[0].stop - 1, leg[1].start + 1 : leg[1].stop - 1]
    assert masks[1.0][leg].mean() < 0.1  # plain RMS: below the threshold
    assert masks[2.0][inside].mean() > 0.95  # (its outermost ring is trimmed: chroma_edge)
    assert masks[2.0][:, 110:].sum() == 0 and masks[2.0][:15].sum() == 0  # the floor stays background


def test_outline_rings_follow_the_brightness_not_the_bleeding_colour():
    plate, frame, leg = _colour_only_leg(ring=True)
    masks = {}
    for rings in (0, 1):
        ex = SilhouetteExtractor(_config(foreground={"chroma_edge": rings}))
        ex.fit_background(plate=plate)
        masks[rings] = ex.process(frame)[0]
    side = np.s_[70:100, 65]  # the bleeding ring left of the leg
    assert masks[0][side].mean() > 0.9 and masks[1][side].mean() < 0.1
    assert masks[1][leg].mean() > 0.95  # the leg itself stays whole


def test_a_deep_shadow_is_removed_where_another_camera_confirms_it_on_the_floor():
    rig = grey_body_rig(seed=7, shadow_depth=0.3)  # one strong light: the shadow has 30 % of the floor's light
    deep = _rig_masks(rig, SilhouetteConfig())
    shallow_only = _rig_masks(rig, _config(shadow={"floor_min_ratio": 0.45}))
    alone = _rig_masks(rig, SilhouetteConfig(), calibrated=False)
    for c in range(2):
        shadow, truth = rig.shadows[c].astype(bool), rig.masks[c].astype(bool)
        assert deep[c][shadow].mean() < 0.05 and deep[c][truth].mean() > 0.9
        assert shallow_only[c][shadow].mean() > 0.5  # too dark for the photometric test
        assert alone[c][shadow].mean() > 0.5  # one camera cannot tell it from dark clothes


@pytest.mark.parametrize("shape", [(1,), (2,), (7,), (8,), (31, 5, 4), (30, 6, 3, 3)])
def test_median_equals_numpys_bit_for_bit(shape):
    rng = np.random.default_rng(len(shape) * 10 + shape[0])
    x = (rng.random(shape) * 300).astype(np.float32)
    x[..., 0] = np.round(x[..., 0])  # ties
    for axis in [None, *range(x.ndim)]:
        want, got = np.asarray(np.median(x, axis=axis)), np.asarray(_median(x, axis=axis))
        assert got.dtype == want.dtype and got.tobytes() == want.tobytes()
    if shape[-1] == 3:
        assert _channel_mean(x).tobytes() == x.mean(axis=-1).tobytes()


def test_the_gains_of_many_frames_at_once_equal_each_frames_gain():
    rng = np.random.default_rng(3)
    plate = rng.integers(0, 256, (48, 64, 3)).astype(np.float32)
    plate[:, :20, 2] = 5  # too dark in one channel there: skipped
    frames = np.clip(plate[None] * rng.uniform(0.7, 1.3, (6, 1, 1, 3)) + rng.normal(0, 4, (6, 48, 64, 3)), 0, 255)
    frames = frames.astype(np.uint8)
    each = np.stack([global_gain(f, plate) for f in frames])
    assert global_gains(frames, plate).tobytes() == each.tobytes()
    assert global_gains(frames[:, :8, :8], plate[:8, :8]).tolist() == [[1.0] * 3] * 6  # too few pixels: 1


def test_the_floor_geometry_in_blocks_of_rows_equals_the_whole_image():
    cams = [Camera.look_at(name, (x, -3.0, 1.4), (0.0, 0.0, 0.5), size=(160, 130), focal_px=120.0,
                           dist=(-0.2, 0.05, 0, 0)) for name, x in (("a", -2.0), ("b", 1.5))]  # fmt: skip
    size = (160, 130)  # more rows than one block, not a multiple of it
    points = floor_points(cams[0], size)
    whole = _floor_points_rows(cams[0], size, 0, size[1])
    assert np.array_equal(points, whole, equal_nan=True) and np.isnan(points).any() and np.isfinite(points).any()
    assert np.array_equal(floor_map(points, cams[1], size), _floor_map_rows(whole, cams[1], size))


def test_a_floor_check_built_ahead_is_the_joint_extractors_own_and_must_fit_its_sizes():
    cams = [Camera.look_at(name, pos, (0.0, 0.0, 0.9), size=(160, 120), focal_px=130.0)
            for name, pos in (("side", (0.0, -4.0, 1.2)), ("front", (4.0, 0.5, 1.5)))]  # fmt: skip
    config = SilhouetteConfig()
    extractors = []
    for _ in cams:
        ex = SilhouetteExtractor(config)
        ex.fit_background(plate=np.full((120, 160, 3), 128, np.uint8))
        extractors.append(ex)
    ahead = floor_check(cams, config)
    own = JointExtractor(extractors, cams).floor
    for a, b in zip(ahead.near + ahead.seen + ahead.on_floor, own.near + own.seen + own.on_floor):
        assert np.array_equal(a, b)
    assert JointExtractor(extractors, cams, floor=ahead).floor is ahead
    with pytest.raises(ValueError, match="image sizes"):
        JointExtractor(extractors, cams, floor=floor_check(cams, _config(scale=0.5)))
    assert floor_check(cams, _config(shadow={"floor_check": False})) is None


def test_the_16_bit_labels_give_way_to_32_bits_when_they_could_overflow():
    sparse = np.zeros((300, 400), np.uint8)
    sparse[::2, ::2] = 1  # 30000 isolated pixels: 30000 components
    assert _label_type(sparse) == cv2.CV_16U
    dense = np.zeros((600, 600), np.uint8)
    dense[::2, ::2] = 1  # 90000 components: more than 16 bits can number
    assert _label_type(dense) == cv2.CV_32S
    n, labels = cv2.connectedComponents(dense, connectivity=8, ltype=_label_type(dense))
    assert n == 90001 and labels.max() == 90000


def _two_floor_views(footprint: bool = False, tolerance: int = 1,
                     ratio_window: int = 1) -> tuple[FloorShadowCheck, list[np.ndarray]]:  # fmt: skip
    """Two cameras on either side of a floor (160x120); per camera, the (h, w, 3) floor point of
    every pixel."""
    cams = [Camera.look_at(name, (x, -3.0, 1.4), (0.0, 0.0, 0.0), size=(160, 120), focal_px=200.0)
            for name, x in (("a", -2.0), ("b", 2.0))]  # fmt: skip
    check = FloorShadowCheck(cams, [c.size for c in cams], tolerance=tolerance, footprint=footprint,
                             ratio_window=ratio_window)  # fmt: skip
    return check, [floor_points(c, c.size) for c in cams]


def _patch(points: np.ndarray, x0: float, x1: float, y0: float = -0.5, y1: float = 0.5) -> np.ndarray:
    """(h, w) bool: the pixels whose floor point lies in x0 <= x < x1, y0 < y < y1 (metres)."""
    x, y = points[..., 0], points[..., 1]
    with np.errstate(invalid="ignore"):
        return (x >= x0) & (x < x1) & (y > y0) & (y < y1)


def test_another_camera_confirms_a_shadow_only_at_the_same_darkening_ratio():
    """A shadow (x in [-0.9, -0.1)) dims the floor by the same ratio in both views; a shoe on the
    floor (x in [0.1, 0.9)) is darker than the floor in both, but by different ratios (two sides,
    two shadings). Both are shadow candidates to each camera alone; the ratio keeps only the shadow,
    any darkening (the former rule) keeps both."""
    check, points = _two_floor_views()
    shadow = [_patch(p, -0.9, -0.1) for p in points]
    shoe = [_patch(p, 0.1, 0.9) for p in points]
    candidates = [s | o for s, o in zip(shadow, shoe)]
    ratio = []
    for s, o, shoe_ratio in zip(shadow, shoe, (0.55, 0.3)):
        r = np.zeros(s.shape, np.float32)
        r[s] = np.log(0.6)
        r[o] = np.log(shoe_ratio)
        ratio.append(r)
    no_body = [np.zeros_like(c) for c in candidates]
    kept = check.relabel(candidates, candidates, None, ratio, no_body, ratio_tolerance=0.15)
    old = check.relabel(candidates, candidates)
    for c in range(2):
        inner_shadow = cv2.erode(shadow[c].view(np.uint8), np.ones((5, 5), np.uint8)) > 0
        inner_shoe = cv2.erode(shoe[c].view(np.uint8), np.ones((5, 5), np.uint8)) > 0
        assert inner_shadow.sum() > 50 and inner_shoe.sum() > 50
        assert kept[c][inner_shadow].all() and not kept[c][inner_shoe].any()
        assert old[c][inner_shadow].all() and old[c][inner_shoe].all()


def test_the_ratio_is_matched_within_the_ratio_window_only():
    """A shoe (x in [-0.1, 0.7)) stands right beside its shadow (x in [-0.9, -0.1)). The shoe's
    ratios differ between the views, so only the shadow's ratio, found within the ratio window of a
    shoe pixel's floor point, confirms that pixel: a band of the shoe along the shadow, as wide as
    the window. The shadow stays a shadow with any window."""
    _, points = _two_floor_views()
    shadow = [_patch(p, -0.9, -0.1) for p in points]
    shoe = [_patch(p, -0.1, 0.7) for p in points]
    candidates = [s | o for s, o in zip(shadow, shoe)]
    ratio = [np.where(s, np.log(0.6), np.where(o, np.log(r), 0)).astype(np.float32)
             for s, o, r in zip(shadow, shoe, (0.55, 0.3))]  # fmt: skip
    no_body = [np.zeros_like(c) for c in candidates]
    inner_shadow = cv2.erode(shadow[0].view(np.uint8), np.ones((5, 5), np.uint8)) > 0
    kept_shoe = []
    for window in (0, 1, 3):
        check, _ = _two_floor_views(tolerance=3, ratio_window=window)
        kept = check.relabel(candidates, candidates, None, ratio, no_body, ratio_tolerance=0.15)
        assert kept[0][inner_shadow].all()
        kept_shoe.append(int(np.count_nonzero(kept[0] & shoe[0])))
    rows = int(np.count_nonzero(np.any(shoe[0], axis=1)))  # the shoe's height in camera a's image
    assert kept_shoe[0] <= rows  # the border column at most
    assert kept_shoe[0] < kept_shoe[1] < kept_shoe[2]
    assert kept_shoe[2] < 0.5 * np.count_nonzero(shoe[0])  # a band, not the shoe


def test_a_camera_that_sees_the_person_in_front_of_the_floor_point_still_confirms():
    """Camera b sees its body (no shadow candidate) over the shadow's floor points, with another
    ratio: it cannot see the floor there, so it confirms as before instead of refuting."""
    check, points = _two_floor_views()
    shadow = [_patch(p, -0.9, -0.1) for p in points]
    ratio = [np.where(shadow[0], np.log(0.6), 0).astype(np.float32), np.where(shadow[1], np.log(0.2), 0).astype(np.float32)]
    body = [np.zeros_like(shadow[0]), shadow[1]]  # b: the person stands there, darker than a shadow
    candidates = [shadow[0], np.zeros_like(shadow[1])]
    darkening = [shadow[0], shadow[1]]
    inner = cv2.erode(shadow[0].view(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert check.relabel(candidates, darkening, None, ratio, body)[0][inner].all()
    refuted = check.relabel(candidates, darkening, None, ratio, [np.zeros_like(b) for b in body])[0]
    assert not refuted[inner].any()  # without the body: b sees the floor at another ratio


def test_a_third_camera_that_sees_the_floor_point_lit_refutes_the_shadow():
    """Cameras a and b see a patch of floor darkened by the same ratio (a shadow to both); a third
    camera c sees that floor lit (no darkening, nobody in front): a shadow darkens the floor in every
    view, so the patch is no shadow. With c's view blocked by the person it cannot tell, and a and b
    decide as two cameras do; without c, the two cameras' result is unchanged."""
    cams = [Camera.look_at(name, pos, (0.0, 0.0, 0.0), size=(160, 120), focal_px=200.0)
            for name, pos in (("a", (-2.0, -3.0, 1.4)), ("b", (2.0, -3.0, 1.4)), ("c", (0.0, 3.0, 1.4)))]  # fmt: skip
    points = [floor_points(c, c.size) for c in cams]
    patch = [_patch(p, -0.4, 0.4, -0.3, 0.3) for p in points]
    ratio = [np.where(m, np.log(0.6), 0).astype(np.float32) for m in patch]
    candidates = [patch[0], patch[1], np.zeros_like(patch[2])]
    darkening = [patch[0], patch[1], np.zeros_like(patch[2])]  # c: the floor as bright as its plate
    none = [np.zeros_like(m) for m in patch]
    inner = cv2.erode(patch[0].view(np.uint8), np.ones((5, 5), np.uint8)) > 0
    assert inner.sum() > 50
    three = FloorShadowCheck(cams, [c.size for c in cams], tolerance=1)
    two = FloorShadowCheck(cams[:2], [c.size for c in cams[:2]], tolerance=1)
    assert two.relabel(candidates[:2], darkening[:2], None, ratio[:2], none[:2])[0][inner].all()
    assert not three.relabel(candidates, darkening, None, ratio, none)[0][inner].any()
    blocked = [none[0], none[1], patch[2]]  # c sees the person in front of the floor point
    assert three.relabel(candidates, darkening, None, ratio, blocked)[0][inner].all()


def test_an_unconfirmed_shadow_stays_one_only_where_confirmed_shadows_fell_around_the_person():
    """The person stands at the origin; both cameras confirm a shadow cast towards +x, frame after
    frame. Camera a alone then sees two more candidates, where b cannot look: one further along the
    shadow's direction (its far end) stays a shadow, one in another direction (a leg of the floor's
    colour, back-projected far behind the person) goes back to the person. Before enough confirmed
    shadow has been seen, and without the person's position, one camera's decision stands. A check
    made without the footprint keeps no floor points and refuses a position."""
    plain, _ = _two_floor_views()
    assert plain.floor_xy is None
    check, points = _two_floor_views(footprint=True)
    cast = [_patch(p, 0.4, 1.2) & check.seen[i] for i, p in enumerate(points)]
    along = _patch(points[0], 1.3, 1.7, 0.0, 0.5) & ~check.seen[0]  # unseen by b, the shadow's way
    elsewhere = _patch(points[0], -1.7, -1.0, -2.0, -0.5) & ~check.seen[0]  # unseen by b, the other way
    assert along.sum() > 10 and elsewhere.sum() > 10 and cast[0].sum() > 100
    candidates = [cast[0] | along | elsewhere, cast[1]]
    darkening = [c.copy() for c in cast]
    centre = np.zeros(2)
    first = check.relabel(candidates, darkening, centre=centre)
    assert first[0][along].all() and first[0][elsewhere].all()  # nothing learnt yet: a's decision stands
    for _ in range(8):
        kept = check.relabel(candidates, darkening, centre=centre)
    assert check.support.sum() > 2000
    assert kept[0][cast[0]].all() and kept[1][cast[1]].all()
    assert kept[0][along].all()
    assert not kept[0][elsewhere].any()
    # the person's position unknown: nothing is judged by where the shadows fell
    assert check.relabel(candidates, darkening)[0][elsewhere].all()
    with pytest.raises(ValueError, match="footprint=True"):
        plain.relabel(candidates, darkening, centre=centre)


def _covered_rectangle(x0: float, x1: float, y0: float, y1: float, size=(80, 60), up: int = 10) -> np.ndarray:
    """(h, w) float32: the fraction of each pixel a rectangle (pixel units, sub-pixel edges) covers."""
    h, w = size[1], size[0]
    fine = np.zeros((h * up, w * up), np.float32)
    fine[round(y0 * up) : round(y1 * up), round(x0 * up) : round(x1 * up)] = 1.0
    return cv2.resize(fine, (w, h), interpolation=cv2.INTER_AREA)


def test_matte_outline_keeps_the_pixels_the_person_covers_at_least_half():
    from gaitcap.silhouette.extract import matte_outline

    cover = _covered_rectangle(20.7, 41.3, 10.2, 50.6)  # edge pixels covered 0.3, 0.3, 0.8, 0.6
    background = np.full((*cover.shape, 3), (90.0, 110.0, 100.0), np.float32)
    person = np.array([200.0, 60.0, 150.0], np.float32)
    image = background + cover[..., None] * (person - background)
    halo = cover > 0.05  # a threshold on the difference: every pixel the person touches
    mask = matte_outline(image, background, np.where(halo, 255, 0).astype(np.uint8), np.zeros(halo.shape, bool), 18.0)
    assert np.array_equal(mask > 0, cover >= 0.5)
    thin = np.where(cover >= 0.5, 255, 0).astype(np.uint8)  # a mask one ring too thin gets its ring back
    again = matte_outline(image, background, cv2.erode(thin, np.ones((3, 3), np.uint8)), np.zeros(halo.shape, bool), 18.0)
    assert np.array_equal(again > 0, cover >= 0.5)


def test_matte_outline_leaves_low_contrast_and_shadow_pixels_as_they_were():
    from gaitcap.silhouette.extract import matte_outline

    cover = _covered_rectangle(20.7, 41.3, 10.2, 50.6)
    background = np.full((*cover.shape, 3), 100.0, np.float32)
    halo = np.where(cover > 0.05, 255, 0).astype(np.uint8)
    faint = background + cover[..., None] * 12.0  # person within 12 grey levels of the background
    assert np.array_equal(matte_outline(faint, background, halo, np.zeros(cover.shape, bool), 18.0), halo)
    image = background + cover[..., None] * 100.0
    inside = np.where(cover >= 0.99, 255, 0).astype(np.uint8)  # the mask lost its outline ...
    shadow = np.zeros(cover.shape, bool)
    shadow[:, :31] = True  # ... and its left half's outline is a cast shadow: not added back
    out = matte_outline(image, background, inside, shadow, 18.0) > 0
    assert np.array_equal(out[:, 31:], (cover >= 0.5)[:, 31:])
    assert np.array_equal(out[:, :31], (inside > 0)[:, :31])


def test_the_extractor_mattes_a_blurred_outline_to_the_covered_half():
    cover = _covered_rectangle(60.4, 100.3, 20.8, 110.5, size=(160, 140))
    plate = np.full((*cover.shape, 3), (70, 90, 80), np.uint8)
    frame = (plate + cover[..., None] * (np.array([190.0, 170.0, 60.0]) - plate)).round().astype(np.uint8)
    truth = cover >= 0.5
    scores = {}
    for matte in (False, True):
        ex = SilhouetteExtractor(_config(cleanup={"matte_outline": matte}))
        ex.fit_background(plate=plate)
        scores[matte] = iou(ex.process(frame)[0], truth)
    assert scores[True] > 0.99 and scores[True] > scores[False]
