"""The compiled face-box statistics (``aamtrack._kernels.face_stats``) against slow references in numpy and OpenCV
(what ``landmark_cascade.sharpness`` and ``signal_to_noise`` were before they were compiled)."""

import math

import cv2
import numpy as np
import pytest

from aamtrack.landmark_cascade import SHARPNESS_SIGMAS, sharpness, signal_to_noise

SEED = 20261127


def _box(shape, scale, pts, pad, min_side):
    q = scale * (np.asarray(pts, np.float64) + 0.5) - 0.5
    lo, hi = np.floor(q.min(0)), np.ceil(q.max(0)) + 1
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
        return None
    h, w = shape
    x0, y0 = max(int(lo[0]) - pad, 0), max(int(lo[1]) - pad, 0)
    x1, y1 = min(int(hi[0]) + pad, w), min(int(hi[1]) + pad, h)
    if x1 - x0 < min_side or y1 - y0 < min_side:
        return None
    return x0, y0, x1, y1


def sharpness_slow(image, scale, pts):
    s1, s2 = SHARPNESS_SIGMAS
    pad = int(math.ceil(2 * s2))
    pad += pad % 2
    box = _box(image.shape, scale, pts, pad, 2 * pad + 4)
    if box is None:
        return 0.0
    x0, y0, x1, y1 = box
    half = cv2.resize(np.ascontiguousarray(image[y0:y1, x0:x1], dtype=np.float32), None, fx=0.5, fy=0.5,
                      interpolation=cv2.INTER_AREA)
    a = cv2.GaussianBlur(half, (0, 0), 0.5 * s1, borderType=cv2.BORDER_REPLICATE)
    b = cv2.GaussianBlur(a, (0, 0), 0.5 * math.sqrt(s2 * s2 - s1 * s1), borderType=cv2.BORDER_REPLICATE)
    m = pad // 2

    def energy(img):
        inner = img[m:img.shape[0] - m, m:img.shape[1] - m].astype(np.float64)
        return float((np.diff(inner, axis=1) ** 2).sum() + (np.diff(inner, axis=0) ** 2).sum())

    e = energy(a)
    return energy(b) / e if e > 1e-6 else 0.0


def _face_crop(image, scale, pts):
    """The face's box (no pad, at least 8 pixels a side) as float32, or None."""
    box = _box(image.shape, scale, pts, 0, 8)
    if box is None:
        return None
    x0, y0, x1, y1 = box
    return np.asarray(image[y0:y1, x0:x1], np.float32)


def signal_to_noise_slow(image, scale, pts):
    c = _face_crop(image, scale, pts)
    if c is None:
        return 0.0
    lap = np.abs(4.0 * c[1:-1, 1:-1] - c[:-2, 1:-1] - c[2:, 1:-1] - c[1:-1, :-2] - c[1:-1, 2:])
    noise = float(np.median(lap)) / (0.6745 * math.sqrt(20.0))
    return float(c.astype(np.float64).std()) / (noise + 0.5)


def fine_noise_slow(image, scale, pts):
    c = _face_crop(image, scale, pts)
    if c is None:
        return -1.0
    e, up, down, left, right = c[1:-1, 1:-1], c[:-2, 1:-1], c[2:, 1:-1], c[1:-1, :-2], c[1:-1, 2:]
    edges = (up + down) + (left + right)
    corners = (c[:-2, :-2] + c[:-2, 2:]) + (c[2:, :-2] + c[2:, 2:])
    resp = (np.float32(4) * e - np.float32(2) * edges) + corners  # the mask [[1, -2, 1], [-2, 4, -2], [1, -2, 1]]
    return float(np.median(np.abs(resp)))


def _cases(n=60):
    """Textured images with a face-sized cloud of points inside, across sizes, scales, odd and even boxes, noise
    and quantised grey levels."""
    rng = np.random.default_rng(SEED)
    for _ in range(n):
        H, W = rng.integers(40, 220, 2)
        img = cv2.GaussianBlur((rng.random((H, W)) * 255).astype(np.float32), (0, 0), float(rng.uniform(0.5, 3)))
        if rng.random() < 0.5:
            img = np.round(img)
        scale = float(rng.choice([1.0, rng.uniform(0.3, 1.0)]))
        centre = rng.uniform(0.3, 0.7, 2) * (W, H) / scale
        pts = centre + rng.normal(0, 1, (68, 2)) * rng.uniform(5, 40) / scale
        yield img, scale, pts


def test_sharpness_matches_its_slow_reference():
    n = 0
    for img, scale, pts in _cases():
        want = sharpness_slow(img, scale, pts)
        got = sharpness(img, scale, pts)
        assert abs(got - want) < 1e-5 * max(1.0, abs(want))  # float32 blurs summed in another order
        n += want > 0
    assert n > 30  # most cases have a box to measure


@pytest.mark.parametrize("which", ["signal_to_noise", "fine_noise"])
def test_median_statistics_match_their_slow_references(which):
    """``signal_to_noise`` (0 without a box) and ``face_fine_noise`` (-1 without one) against numpy: the same
    float32 stencil sums and median."""
    from aamtrack.kernels import face_fine_noise

    fast, slow, boxed = {"signal_to_noise": (signal_to_noise, signal_to_noise_slow, lambda v: v > 0),
                         "fine_noise": (face_fine_noise, fine_noise_slow, lambda v: v >= 0)}[which]
    n = 0
    for img, scale, pts in _cases():
        want = slow(img, scale, pts)
        got = fast(img, scale, pts)
        assert abs(got - want) <= 1e-6 * max(1.0, abs(want))
        n += boxed(want)
    assert n > 30


def test_face_stats_off_the_image_or_not_finite_give_zero():
    from aamtrack.kernels import face_fine_noise

    img = np.full((100, 100), 100.0, np.float32)
    pts = np.full((68, 2), 50.0) + np.random.default_rng(SEED).normal(0, 10, (68, 2))
    assert sharpness(img, 1.0, pts) == 0.0  # flat box
    for bad in (pts + 1000.0, np.where(np.arange(68)[:, None] == 3, np.nan, pts)):
        assert sharpness(img, 1.0, bad) == 0.0
        assert signal_to_noise(img, 1.0, bad) == 0.0
        assert face_fine_noise(img, 1.0, bad) == -1.0


@pytest.mark.parametrize("n", [1, 2, 3, 47, 48, 49, 1000, 17028, 17029])
def test_median_kernel_is_numpys_median(n):
    from aamtrack._kernels.face_stats import _middle

    rng = np.random.default_rng(SEED + n)
    cases = [rng.random(n), np.abs(rng.normal(0, 3, n)), np.abs(np.round(rng.normal(0, 3, n) * 4) / 4),  # ties
             np.abs(rng.standard_cauchy(n)),  # a few values far out: the middle ranks share a bin with many others
             np.where(rng.random(n) < 0.7, 0.0, rng.random(n)),  # most values tied at 0
             np.full(n, 2.5), np.arange(n)[::-1] * 1e-3,
             np.repeat([0.0, 1.0], [n // 2, n - n // 2]),  # the middle ranks at the two ends of the range
             np.r_[np.zeros(n // 2), np.full(n - n // 2, 7.0)][rng.permutation(n)] + (rng.random(n) < 0.01)]
    for v in cases:
        v = v.astype(np.float32)
        assert _middle(v.copy()) == np.median(v)  # exact: the same float32 values and mean


def _deviation_in_eight_lanes(box):
    """The box's standard deviation as ``_noise_and_deviation`` sums it, one value at a time in Python: eight running
    sums (float64) of values and of their squares (squared in float32: numba's ``float()`` of a float32 stays
    float32), lane j taking x = j, j + 8, ... of each row in turn and lane 0 the row's last w % 8; the lanes added
    in order."""
    h, w = box.shape
    s = [0.0] * 8
    ss = [0.0] * 8
    w8 = w - w % 8
    for y in range(h):
        for x in range(w):
            v = box[y, x]
            j = x % 8 if x < w8 else 0
            s[j] += float(v)
            ss[j] += float(v * v)
    tot = 0.0
    tot2 = 0.0
    for j in range(8):
        tot += s[j]
        tot2 += ss[j]
    mean = tot / (h * w)
    return math.sqrt(max(tot2 / (h * w) - mean * mean, 0.0))


@pytest.mark.parametrize("w", [8, 9, 31, 32, 33, 40, 71, 96])
def test_deviation_sums_in_eight_lanes_bit_for_bit(w):
    """The sums (four values of each lane per pass of a vectorised loop over the lanes) add each lane's values one by
    one in the order above: the same bits as the plain loop."""
    from aamtrack._kernels.face_stats import _noise_and_deviation

    rng = np.random.default_rng(SEED)
    img = (rng.random((60, 120)) * 255).astype(np.float32)
    x0, y0, h = 5, 7, 23
    pts = np.array([[x0, y0], [x0 + w - 1, y0 + h - 1], [x0 + 2, y0 + 3]], np.float64)  # the box (x0, y0, w, h)
    _, sd = _noise_and_deviation(img, 1.0, pts)
    assert sd == _deviation_in_eight_lanes(img[y0:y0 + h, x0:x0 + w])
