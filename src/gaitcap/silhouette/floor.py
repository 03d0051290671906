"""Cast shadows checked with the calibration: a shadow lies on the floor and every camera sees it.

The photometric shadow test of :mod:`gaitcap.silhouette.extract` (darker, same chromaticity, same
texture) cannot tell grey clothes over a grey floor or wall from a shadow. With calibrated
cameras two geometric facts can:

* a cast shadow lies on the floor plane z = 0, so a pixel whose ray does not meet the floor in
  front of the camera (above the horizon) is not a floor shadow;
* a floor shadow belongs to the floor: every camera that sees its floor point sees it darkened.
  A point of the body above the floor, back-projected to z = 0 through camera i, lands on a
  floor point that camera j sees elsewhere than the body (parallax), as plain floor.

So a shadow candidate of camera i stays a shadow only where its ray meets the floor, at least one
other camera that sees that floor point finds it darkened (foreground or darker than its background)
by the same brightness ratio, or cannot see it behind the person (its foreground there is no shadow
candidate), and no other camera sees that floor point lit (not darkened within the tolerance, nobody
in front): with three or four cameras, one that sees the person's foot where another's shadow
candidate is (the foot is on the floor) no longer confirms it alone when a third sees plain floor
there. The ratio is the check that tells an object on the floor from a shadow:

* a shadow darkens a matte floor by the same factor for every camera (it is the light that
  changes, not the surface: brightness / background brightness does not depend on the view);
* a shoe or a foot on the floor is seen from two sides, shaded differently, against two patches
  of floor: a dark shoe on a lilac floor, grey shoes on a grey floor, shoes the mat's colour are
  all darker than the floor "like a shadow", at the same floor points in both views, but their
  ratios differ (on the suite's sessions: |log ratio difference| median 0.25-0.44 on such feet,
  0.02-0.03 on the true shadows; docs/validation.md). The other camera's ratio is looked up at the
  floor point and its neighbours within ``shadow.floor_ratio_window`` (1 pixel): the shoe's own
  shadow lies right beside it, so a wider window finds the shadow's ratio there and confirms the
  shoe after all.

Where no other camera sees the point, camera i's photometric decision stands, except
for candidates darker than the photometric test accepts alone (``shadow.floor_min_ratio``), which
need that confirmation, and, when the person's floor position is known (``shadow.floor_footprint``),
except where no confirmed shadow has fallen: the confirmed shadows' floor points are counted by
direction and distance from the person over the walk (one lamp casts the shadow the same way all
through it), and an unconfirmed candidate stays a shadow only in a direction where they fell and
not much farther (:meth:`FloorShadowCheck._footprint`). A leg of the floor's colour, back-projected
to the floor through one camera, lands metres behind the person, often outside the other camera's
view: on the suite's sessions (every sixth frame) such pixels lay 1.9-3.1 m (median) from the
person, the confirmed shadows 0.35-0.87 m (docs/validation.md).

With several cameras, a shadow must also lie near the capture area (the floor two cameras see,
grown by ``reach``): a pixel of a wall, back-projected to the floor, lands behind the wall,
outside the view of the other cameras, where no shadow of the person can be seen.

The floor point of every working-scale pixel of camera i, projected into camera j, is computed
once per rig (:class:`FloorShadowCheck`); each frame then costs one ``cv2.remap`` per camera pair.
"""

from __future__ import annotations

from collections.abc import Sequence

import cv2
import numpy as np

from gaitcap.camera import Camera, dlt_point

# a floor point farther than this from camera i is too near the horizon to be looked up
_MAX_FLOOR_DISTANCE_M = 50.0


def _work_to_full(size_work: tuple[int, int], size_full: tuple[int, int]) -> tuple[float, float]:
    """Per-axis factors full / working pixel size."""
    return size_full[0] / size_work[0], size_full[1] / size_work[1]


#: image rows computed at a time by :func:`floor_points` and :func:`floor_map` (each point's result
#: is its own: the same values in blocks, a tenth of the temporary memory of a whole 640x480 image)
_BLOCK_ROWS = 48


def floor_points(camera: Camera, size_work: tuple[int, int]) -> np.ndarray:
    """Where each working-scale pixel's ray meets the floor z = 0.

    Args:
        camera: the calibrated camera (world z up, floor z = 0).
        size_work: (w, h) of the working-scale image.

    Returns:
        (h, w, 3) world points in metres, NaN where the ray does not meet the floor in front of
        the camera (at or above the horizon) or meets it farther than 50 m.
    """
    w, h = size_work
    out = np.empty((h, w, 3))
    for r0 in range(0, h, _BLOCK_ROWS):
        out[r0 : r0 + _BLOCK_ROWS] = _floor_points_rows(camera, size_work, r0, min(h, r0 + _BLOCK_ROWS))
    return out


def _floor_points_rows(camera: Camera, size_work: tuple[int, int], r0: int, r1: int) -> np.ndarray:
    """:func:`floor_points` of the working-scale rows ``r0:r1``: (r1 - r0, w, 3)."""
    w = size_work[0]
    fx, fy = _work_to_full(size_work, camera.size)
    u, v = np.meshgrid((np.arange(w) + 0.5) * fx - 0.5, (np.arange(r0, r1) + 0.5) * fy - 0.5)
    ideal = camera.undistort_pixels(np.stack([u.ravel(), v.ravel()], axis=1))
    K = camera.matrix
    y = (ideal[:, 1] - K[1, 2]) / K[1, 1]
    x = (ideal[:, 0] - K[0, 2] - K[0, 1] * y) / K[0, 0]
    rays = np.einsum("nj,jk->nk", np.stack([x, y, np.ones_like(x)], axis=1), camera.R)  # world directions R^T d
    c = camera.center
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -c[2] / rays[:, 2]
    points = c + t[:, None] * rays
    far = np.linalg.norm(points - c, axis=1) > _MAX_FLOOR_DISTANCE_M
    points[~(t > 0) | far] = np.nan
    return points.reshape(r1 - r0, w, 3)


def floor_map(points: np.ndarray, other: Camera, other_work: tuple[int, int]) -> np.ndarray:
    """Working-scale pixel coordinates in camera ``other`` of floor points, for ``cv2.remap``.

    Args:
        points: (h, w, 3) floor points (NaN: none), from :func:`floor_points`.
        other: the camera looking at them.
        other_work: (w, h) of that camera's working-scale image.

    Returns:
        (h, w, 2) float32 coordinates; (-1, -1) (outside the image) where the point is NaN,
        behind the camera or outside its view.
    """
    h, w = points.shape[:2]
    out = np.empty((h, w, 2), np.float32)
    for r0 in range(0, h, _BLOCK_ROWS):
        out[r0 : r0 + _BLOCK_ROWS] = _floor_map_rows(points[r0 : r0 + _BLOCK_ROWS], other, other_work)
    return out


def _floor_map_rows(points: np.ndarray, other: Camera, other_work: tuple[int, int]) -> np.ndarray:
    """:func:`floor_map` of a block of rows of floor points (r, w, 3) -> (r, w, 2) float32."""
    flat = points.reshape(-1, 3)
    full = other.project(flat)
    # the polynomial distortion folds back far outside the view: check the ideal projection too
    inside = other.in_image(full) & other.in_image(other.project(flat, distort=False), margin=-0.25 * max(other.size))
    fx, fy = _work_to_full(other_work, other.size)
    out = np.stack([(full[:, 0] + 0.5) / fx - 0.5, (full[:, 1] + 0.5) / fy - 0.5], axis=1)
    out[~inside] = -1.0
    return out.reshape(points.shape[:2] + (2,)).astype(np.float32)


_GRID_M = 0.05  # cell of the floor grid that measures the distance to the capture area

_SUPPORT_BINS = 36  # directions on the floor around the person (FloorShadowCheck.support)
_SUPPORT_NEAR_M = 0.3  # within this distance of the person every direction supports a shadow
_SUPPORT_MIN = 0.005  # a direction supports a shadow from this fraction of all confirmed shadow pixels
_SUPPORT_STEP_M = 0.1  # distance bins of the support, metres
_SUPPORT_FAR_M = 10.0  # the last distance bin holds everything farther
_SUPPORT_SLACK_M = 0.5  # an unconfirmed shadow reaches this far past the confirmed ones in its direction
_SUPPORT_READY = 2000.0  # confirmed shadow pixels needed before unconfirmed ones are judged by it


def _near_shared_floor(points: Sequence[np.ndarray], seen: Sequence[np.ndarray], reach: float) -> list[np.ndarray]:
    """Per camera, (h_i, w_i) bool: the pixel's floor point lies within ``reach`` metres of a floor
    point that two cameras see. With one camera (nothing shared) every floor point counts as near.

    The shared floor is rasterised on a 5 cm grid and measured with a distance transform (each
    camera's points a block of rows at a time: the temporary memory stays small).
    """
    shared = [p[..., :2][s] for p, s in zip(points, seen)]  # (n_i, 2) each
    if not any(len(xy) for xy in shared):
        return [np.isfinite(p[..., 0]) for p in points]
    lo = np.min([xy.min(axis=0) for xy in shared if len(xy)], axis=0) - reach - _GRID_M
    hi = np.max([xy.max(axis=0) for xy in shared if len(xy)], axis=0) + reach + _GRID_M
    shape = tuple(np.ceil((hi - lo) / _GRID_M).astype(int)[::-1])  # (rows: y, cols: x)
    free = np.full(shape, 255, np.uint8)
    for xy in shared:
        cells = ((xy - lo) / _GRID_M).astype(int)
        free[cells[:, 1], cells[:, 0]] = 0
    del shared
    dist = cv2.distanceTransform(free, cv2.DIST_L2, 5) * _GRID_M
    near = []
    for p in points:
        out = np.empty(p.shape[:2], bool)
        for r0 in range(0, p.shape[0], _BLOCK_ROWS):
            xy = p[r0 : r0 + _BLOCK_ROWS, :, :2]
            ok = np.isfinite(xy[..., 0])
            idx = np.where(ok[..., None], (xy - lo) / _GRID_M, -1).astype(int)
            inside = ok & (idx[..., 0] >= 0) & (idx[..., 0] < shape[1]) & (idx[..., 1] >= 0) & (idx[..., 1] < shape[0])
            d = np.full(ok.shape, np.inf, np.float32)
            d[inside] = dist[idx[..., 1][inside], idx[..., 0][inside]]
            out[r0 : r0 + _BLOCK_ROWS] = d <= reach
        near.append(out)
    return near


class FloorShadowCheck:
    """The floor geometry of a rig, to re-label shadow candidates frame by frame.

    Args:
        cameras: the calibrated cameras, in the order of the frames given to :meth:`relabel`.
        work_sizes: (w, h) of each camera's working-scale image.
        tolerance: pixels (working scale) by which another camera's darkening is grown before it
            is looked up (calibration error, soft shadow edges).
        reach: metres; with several cameras, a shadow lies within this distance of the floor that
            two cameras see (the capture area, where the person walks).
        footprint: whether :meth:`relabel` may be given the person's floor point (``centre``:
            ``shadow.floor_footprint``); only then is each pixel's floor point kept (about 5 MB per
            640x480 camera).
        ratio_window: pixels (working scale) around the floor point within which another camera's
            log ratio may match the candidate's (:meth:`relabel`'s ``log_ratio``). Narrower than
            ``tolerance``, the darkening's slack: a shoe stands on the floor beside its own shadow,
            and a window that wide finds the shadow's ratio next to the shoe's floor points and
            confirms the shoe as shadow.
    """

    def __init__(self, cameras: Sequence[Camera], work_sizes: Sequence[tuple[int, int]], tolerance: int = 2,
                 reach: float = 1.0, footprint: bool = False, ratio_window: int = 1) -> None:  # fmt: skip
        if len(cameras) != len(work_sizes):
            raise ValueError(f"{len(cameras)} cameras but {len(work_sizes)} working sizes")
        points = [floor_points(cam, size) for cam, size in zip(cameras, work_sizes)]
        #: (h_i, w_i, 2) each pixel's floor point (x, y), NaN off the floor (for ``centre`` in :meth:`relabel`);
        #: None without ``footprint``
        self.floor_xy = [np.ascontiguousarray(p[..., :2]) for p in points] if footprint else None
        self.on_floor = [np.isfinite(p[..., 0]) for p in points]  # (h_i, w_i) bool each
        #: where the confirmed shadows fell around the person (pixels per direction bin and distance bin)
        self.support = np.zeros((_SUPPORT_BINS, int(_SUPPORT_FAR_M / _SUPPORT_STEP_M)), np.float64)
        self.maps: list[list[tuple[int, np.ndarray]]] = []  # camera i -> [(j, (h_i, w_i, 2) map)]
        self.seen: list[np.ndarray] = []  # (h_i, w_i) bool: another camera sees the floor point
        for i, p in enumerate(points):
            maps = [(j, floor_map(p, cam, work_sizes[j])) for j, cam in enumerate(cameras) if j != i]
            self.maps.append(maps)
            seen = np.zeros(p.shape[:2], bool)
            for _, m in maps:
                seen |= m[..., 0] >= 0
            self.seen.append(seen)
        self.near = _near_shared_floor(points, self.seen, reach)
        self._grow, self._ratio_grow = (cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1,) * 2) if r > 0 else None
                                        for r in (tolerance, ratio_window))

    def relabel(self, shadows: Sequence[np.ndarray], darkening: Sequence[np.ndarray],
                deep: Sequence[np.ndarray] | None = None, log_ratio: Sequence[np.ndarray] | None = None,
                body: Sequence[np.ndarray] | None = None, ratio_tolerance: float = 0.15,
                centre: np.ndarray | None = None) -> list[np.ndarray]:  # fmt: skip
        """The shadow maps kept by the floor test, one per camera.

        Args:
            shadows: (h_i, w_i) bool per camera, the photometric shadow candidates.
            darkening: (h_i, w_i) bool per camera, foreground or darker than the background.
            deep: (h_i, w_i) bool per camera, candidates too dark for the photometric test alone
                (dark clothes look the same to one camera), or None.
            log_ratio: (h_i, w_i) float32 per camera, log of the frame's brightness over the
                background's, or None (any darkening confirms). Given, another camera confirms a
                candidate where it finds the floor point darkened with a log ratio (any within the
                ratio window) within ``ratio_tolerance`` of the candidate's, or where it sees
                ``body`` there.
            body: (h_i, w_i) bool per camera, its foreground that is no shadow candidate (the
                person in front of the floor point: the camera cannot tell), with ``log_ratio``.
            centre: (2,) the floor point (x, y) beneath the person, metres, or None: with it, a
                candidate that no other camera sees stays a shadow only where the confirmed
                shadows have fallen around the person (:meth:`_footprint`; a check made with
                ``footprint``).

        Returns:
            (h_i, w_i) bool per camera: candidates on the floor near the capture area that another
            camera seeing the floor point also finds darkened and none sees lit, or that no other
            camera sees; deep candidates only where another camera confirms them and none sees the
            floor point lit. With two cameras "and none sees lit" changes nothing (the other camera
            either confirms or sees the floor lit).
        """
        dark = [d.view(np.uint8) for d in darkening]
        if self._grow is not None:
            dark = [cv2.dilate(d, self._grow) for d in dark]
        if log_ratio is not None:  # the range of each camera's log ratio over the ratio window
            low = [cv2.erode(r, self._ratio_grow) if self._ratio_grow is not None else r for r in log_ratio]
            high = [cv2.dilate(r, self._ratio_grow) if self._ratio_grow is not None else r for r in log_ratio]
        out = []
        for i, shadow in enumerate(shadows):
            kept = np.zeros_like(shadow)
            deep_i = deep[i] if deep is not None else np.zeros_like(shadow)
            x, y, w, h = cv2.boundingRect((shadow | deep_i).view(np.uint8))  # only where there are candidates
            if w and h:
                box = np.s_[y : y + h, x : x + w]
                confirmed = np.zeros((h, w), np.uint8)
                refuted = np.zeros((h, w), np.uint8)
                for j, m in self.maps[i]:
                    dark_j = cv2.remap(dark[j], m[box], None, cv2.INTER_NEAREST,
                                       borderMode=cv2.BORDER_CONSTANT, borderValue=0)  # fmt: skip
                    seen_j = dark_j.copy()
                    if log_ratio is not None:
                        seen_j &= self._same_ratio(log_ratio[i][box], low[j], high[j], m[box], ratio_tolerance)
                        if body is not None:
                            seen_j |= cv2.remap(body[j].view(np.uint8), m[box], None, cv2.INTER_NEAREST,
                                                borderMode=cv2.BORDER_CONSTANT, borderValue=0)  # fmt: skip
                    confirmed |= seen_j
                    # camera j sees the floor point lit (no darkening within the tolerance, nobody in front)
                    refuted |= (m[box][..., 0] >= 0).view(np.uint8) & (1 - dark_j) & (1 - seen_j)
                floor = self.on_floor[i][box] & self.near[i][box]
                confirmed = (confirmed > 0) & (refuted == 0)
                kept[box] = floor & ((shadow[box] & (confirmed | ~self.seen[i][box])) | (deep_i[box] & confirmed))
            out.append(kept)
        if centre is not None:
            if self.floor_xy is None:
                raise ValueError("relabel: a centre needs a FloorShadowCheck made with footprint=True")
            self._footprint(out, centre)
        return out

    def _bins(self, i: int, where: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Direction bins (n,) int of the floor points of camera ``i``'s pixels ``where`` (h_i, w_i)
        bool seen from the person's floor point ``centre`` (2,), and their distances (n,) metres."""
        off = self.floor_xy[i][where] - centre
        angle = np.arctan2(off[:, 1], off[:, 0])
        b = np.floor((angle + np.pi) / (2 * np.pi) * _SUPPORT_BINS).astype(int) % _SUPPORT_BINS
        return b, np.hypot(off[:, 0], off[:, 1])

    def _footprint(self, kept: list[np.ndarray], centre: np.ndarray) -> None:
        """Learn where the shadows fall, drop the unconfirmed ones that fall elsewhere (in place).

        The shadows that another camera confirmed this frame are added to :attr:`support`, by their
        direction and distance on the floor from the person (``centre``: (2,) metres, the floor point
        beneath them). A shadow that no other camera sees stays one only within
        :data:`_SUPPORT_NEAR_M` of the person or in a direction where confirmed shadows have fallen
        (a direction bin and its neighbours holding :data:`_SUPPORT_MIN` of the support), no farther
        than :data:`_SUPPORT_SLACK_M` past the farthest of them there (their 99th percentile): one
        lamp casts the person's shadow the same way all through a walk, while a leg of the floor's
        colour, back-projected to the floor, lands metres behind the person, where one camera alone
        cannot check it."""
        unseen = []
        n_dist = self.support.shape[1]
        for i, k in enumerate(kept):
            b, d = self._bins(i, k & self.seen[i], centre)
            far = d >= _SUPPORT_NEAR_M
            r = np.minimum((d[far] / _SUPPORT_STEP_M).astype(int), n_dist - 1)
            self.support += np.bincount(b[far] * n_dist + r, minlength=self.support.size).reshape(self.support.shape)
            unseen.append(k & ~self.seen[i])
        total = self.support.sum()
        if total < _SUPPORT_READY:
            return
        wide = self.support + np.roll(self.support, 1, axis=0) + np.roll(self.support, -1, axis=0)
        count = wide.sum(axis=1)
        cum = np.cumsum(wide, axis=1)
        reach = (np.argmax(cum >= 0.99 * count[:, None], axis=1) + 1) * _SUPPORT_STEP_M + _SUPPORT_SLACK_M
        reach[count < _SUPPORT_MIN * total] = 0.0
        for i, (k, u) in enumerate(zip(kept, unseen)):
            if not u.any():
                continue
            b, d = self._bins(i, u, centre)
            k[u] = (d < _SUPPORT_NEAR_M) | (d <= reach[b])

    @staticmethod
    def _same_ratio(mine: np.ndarray, low: np.ndarray, high: np.ndarray, look: np.ndarray, tolerance: float) -> np.ndarray:
        """(h, w) uint8 0/1: the other camera's log ratio range [``low``, ``high``] at the floor
        points ``look`` (h, w, 2) comes within ``tolerance`` of ``mine`` (h, w); 0 outside its view."""
        lo = cv2.remap(low, look, None, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=np.inf)
        hi = cv2.remap(high, look, None, cv2.INTER_NEAREST, borderMode=cv2.BORDER_CONSTANT, borderValue=-np.inf)
        tol = np.float32(tolerance)
        return ((mine >= lo - tol) & (mine <= hi + tol)).view(np.uint8)


#: a triangulated head top outside these heights (metres above the floor) is no person's: no floor row
_HEAD_TOP_M = (0.7, 2.5)


def head_top(mask: np.ndarray, rows: int = 3) -> np.ndarray | None:
    """The top of a mask (H, W) uint8/bool, the person's head: (2,) pixel (x, y), x the mean column of
    its first ``rows`` rows; None when the mask is empty or touches the image's top edge (the head
    cut off: its top is not the head's)."""
    filled = np.flatnonzero(np.any(mask, axis=1))
    if filled.size == 0 or filled[0] == 0:
        return None
    y = int(filled[0])
    cols = np.flatnonzero(np.any(mask[y : y + rows], axis=0))
    return np.array([float(cols.mean()), float(y)])


def person_head_top(cameras: Sequence[Camera], masks: Sequence[np.ndarray]) -> np.ndarray | None:
    """(3,) the person's head top, triangulated from the masks' tops (:func:`head_top`, DLT on
    undistorted pixels, every camera that sees the top); None when fewer than two see it or it is
    no person's head (height outside 0.7-2.5 m)."""
    tops = [head_top(m) for m in masks]
    seen = [i for i, t in enumerate(tops) if t is not None]
    if len(seen) < 2:
        return None
    ideal = [cameras[i].undistort_pixels(tops[i][None])[0] for i in seen]
    top = dlt_point([cameras[i].projection_matrix() for i in seen], ideal)
    if top is None or not _HEAD_TOP_M[0] <= top[2] <= _HEAD_TOP_M[1]:
        return None
    return top


def floor_rows(cameras: Sequence[Camera], masks: Sequence[np.ndarray]) -> list[float | None]:
    """The image row of the floor beneath the person, per camera, from the masks of one frame.

    The masks' tops (:func:`head_top`) are triangulated (:func:`person_head_top`: DLT, undistorted
    pixels, every camera that sees the top); the floor point straight below, (X, Y, 0), is projected
    into each camera (:func:`rows_below`).

    Args:
        cameras: the calibrated cameras (world z up, floor z = 0).
        masks: (H_c, W_c) full-resolution masks, one per camera.

    Returns:
        Per camera, the row (full-resolution pixels) or None.
    """
    return rows_below(cameras, person_head_top(cameras, masks))


def rows_below(cameras: Sequence[Camera], top: np.ndarray | None) -> list[float | None]:
    """Per camera, the image row (full-resolution pixels) of the floor point (X, Y, 0) straight
    below the head top ``top`` (3,): None for every camera when ``top`` is None (fewer than two
    cameras saw it, or it is no person's head), None for a camera that the point is behind."""
    if top is None:
        return [None] * len(cameras)
    foot = np.array([[top[0], top[1], 0.0]])
    rows: list[float | None] = []
    for cam in cameras:
        in_front = cam.to_camera(foot)[0, 2] > 0
        rows.append(float(cam.project(foot)[0, 1]) if in_front else None)
    return rows
