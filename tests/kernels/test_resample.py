"""The compiled area resampling gives OpenCV's INTER_AREA result bit for bit (the tracker's levels depend on it)."""

import cv2
import numpy as np
import pytest

from aamtrack.imaging import resize_area

SEED = 20261121


def test_resize_area_matches_opencv_bit_for_bit():
    rng = np.random.default_rng(SEED)
    for _ in range(200):
        H, W = rng.integers(2, 300, 2)
        k = float(rng.uniform(0.5, 1.0))
        img = (rng.random((H, W)) * 255).astype(np.float32)
        if rng.random() < 0.3:
            img = np.round(img)  # grey levels, as the tracker's crops are
        want = cv2.resize(img, None, fx=k, fy=k, interpolation=cv2.INTER_AREA)
        got = resize_area(img, k)
        assert got.shape == want.shape and np.array_equal(got, want), (H, W, k)


@pytest.mark.parametrize("k", [0.5, 1 / 1.5, 0.75, 0.995, 0.999, 1.0, 0.3])
def test_resize_area_edges_and_fallbacks(k):
    """Exact halving, whole-number scales and factors outside (0.5, 1) go to OpenCV, a size that stays is copied
    (0.999 of 97 x 131), the rest goes to the kernel."""
    img = np.random.default_rng(SEED).random((97, 131)).astype(np.float32) * 255
    want = cv2.resize(img, None, fx=k, fy=k, interpolation=cv2.INTER_AREA)
    assert np.array_equal(resize_area(img, k), want)


def test_crop_gray32_is_the_crop_s_grey_image():
    """``crop_gray32`` (colour crops copied into one block before the conversion) gives the bits of
    ``to_gray32`` of the crop, for BGR, BGRA and grey frames, wide and narrow crops, at the frame's edges."""
    from aamtrack.imaging import crop_gray32, to_gray32

    rng = np.random.default_rng(SEED)
    frame = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    for image in (frame, cv2.cvtColor(frame, cv2.COLOR_BGR2BGRA), cv2.cvtColor(frame, cv2.COLOR_BGR2GRAY)):
        for x0, y0, x1, y1 in ((0, 0, 160, 120), (30, 10, 150, 100), (100, 50, 130, 70), (0, 60, 60, 120)):
            got = crop_gray32(image, x0, y0, x1, y1)
            assert got.dtype == np.float32 and got.flags.c_contiguous
            assert np.array_equal(got, to_gray32(image[y0:y1, x0:x1])), (image.shape, x0, y0, x1, y1)


def test_unsharp_restores_a_blurred_edge_and_keeps_the_image_type():
    from aamtrack.imaging import unsharp

    edge = np.zeros((40, 80), np.float32)
    edge[:, 40:] = 200.0
    blurred = cv2.GaussianBlur(edge, (0, 0), 3.0)
    slope = lambda im: float(np.abs(np.diff(im[20].astype(np.float64))).max())  # noqa: E731
    sharp = unsharp(blurred, 3.0, 2.0)
    assert sharp.dtype == np.float32 and sharp.shape == blurred.shape
    ref = blurred + 2.0 * (blurred - cv2.GaussianBlur(blurred, (0, 0), 3.0))  # the formula, written out
    assert np.allclose(sharp, ref, atol=1e-4)
    assert slope(sharp) > 1.5 * slope(blurred)  # the edge is steeper again
    colour = np.repeat(np.clip(1.2 * blurred + 5, 0, 255).astype(np.uint8)[..., None], 3, axis=2)  # 5..245
    out = unsharp(colour, 3.0, 2.0)
    assert out.dtype == np.uint8 and out.shape == colour.shape
    assert out.min() == 0 and out.max() == 255  # overshoot either side of the edge clipped, not wrapped
    assert np.array_equal(out[..., 0], out[..., 2])  # channels alike in, alike out
