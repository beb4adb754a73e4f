"""The landmark descriptor kernel against a slow, obvious numpy reference, and the invariances it is built for."""

import numpy as np
import pytest

from aamtrack._kernels.patches import CLIP
from aamtrack.kernels import landmark_descriptors

SEED = 11


def reference_descriptors(image, scale, shift, pts, frame, cells, cell, bins, floor):
    """Per point: sample the grid (scipy-free bilinear, edge-clamped), central differences, magnitude-weighted
    linear orientation binning per cell, normalise with a floor, clip, restore the norm."""
    H, W = image.shape
    G = cells * cell + 2
    c0 = 0.5 * (G - 1)
    out = np.zeros((len(pts), cells * cells * bins))
    dv, du = np.mgrid[0:G, 0:G] - c0
    for li, (px, py) in enumerate(pts):
        off = np.stack([du.ravel(), dv.ravel()], 1) @ frame
        x = np.clip(scale * (px + off[:, 0]) + shift, 0, W - 1)
        y = np.clip(scale * (py + off[:, 1]) + shift, 0, H - 1)
        x0 = np.minimum(np.floor(x).astype(int), W - 2)
        y0 = np.minimum(np.floor(y).astype(int), H - 2)
        fx, fy = x - x0, y - y0
        v = (image[y0, x0] * (1 - fx) * (1 - fy) + image[y0, x0 + 1] * fx * (1 - fy)
             + image[y0 + 1, x0] * (1 - fx) * fy + image[y0 + 1, x0 + 1] * fx * fy).reshape(G, G)
        gx = v[1:-1, 2:] - v[1:-1, :-2]
        gy = v[2:, 1:-1] - v[:-2, 1:-1]
        mag = np.hypot(gx, gy)
        b = (np.arctan2(gy, gx) + np.pi) / (2 * np.pi) * bins
        b0 = np.floor(b).astype(int)
        f = b - b0
        h = np.zeros((cells, cells, bins))
        for i in range(G - 2):
            for j in range(G - 2):
                h[i // cell, j // cell, b0[i, j] % bins] += mag[i, j] * (1 - f[i, j])
                h[i // cell, j // cell, (b0[i, j] + 1) % bins] += mag[i, j] * f[i, j]
        h = h.ravel()
        norm = np.linalg.norm(h)
        h = h / (norm + floor)
        pre = np.linalg.norm(h)
        h = np.minimum(h, CLIP)
        if np.linalg.norm(h) > 0:
            h *= pre / np.linalg.norm(h)
        out[li] = h
    return out


def test_descriptors_match_reference():
    rng = np.random.default_rng(SEED)
    image = (rng.random((90, 120)) * 255).astype(np.float32)
    image = (image + np.roll(image, 1, 0) + np.roll(image, 1, 1)) / 3  # some spatial structure
    pts = np.column_stack([rng.uniform(-5, 125, 12), rng.uniform(-5, 95, 12)])  # some patches cross the border
    a = 0.4
    frame = 1.3 * np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])
    out = np.empty((12, 3 * 3 * 8), np.float32)
    landmark_descriptors(image, 0.8, -0.1, pts, frame, cells=3, cell=4, bins=8, floor=20.0, out=out)
    ref = reference_descriptors(image.astype(np.float64), 0.8, -0.1, pts, frame, 3, 4, 8, 20.0)
    assert np.abs(out - ref).max() < 1e-4  # float32 sums of the same terms


def test_flat_patch_gives_small_descriptor_and_edges_a_unit_one():
    img = np.full((60, 60), 100.0, np.float32)
    img[:, 30:] += 0.2  # a faint step: below the floor of 1 grey level per sample
    strong = np.full((60, 60), 50.0, np.float32)
    strong[:, 30:] = 200.0
    out = np.empty((1, 72), np.float32)
    pts = np.array([[30.0, 30.0]])
    kw = dict(cells=3, cell=5, bins=8, floor=225.0)
    landmark_descriptors(img, 1.0, 0.0, pts, np.eye(2), out=out, **kw)
    assert np.linalg.norm(out) < 0.05  # a flat patch stays near zero
    landmark_descriptors(strong, 1.0, 0.0, pts, np.eye(2), out=out, **kw)
    assert np.linalg.norm(out) > 0.85  # a strong edge: norm / (norm + floor), near 1


def test_descriptor_turns_with_its_frame():
    """A patch sampled in a frame turned with the image reads the same descriptor: the rotation invariance the
    landmark cascade relies on (up to resampling)."""
    yy, xx = np.mgrid[0:200, 0:200].astype(np.float64)

    def pattern(x, y):
        return 120 + 60 * np.sin(0.21 * x + 0.05 * y) + 40 * np.cos(0.13 * y - 0.02 * x * y / 50)

    c = np.array([100.0, 100.0])
    a = np.radians(35)
    R = np.array([[np.cos(a), np.sin(a)], [-np.sin(a), np.cos(a)]])  # row vectors: u @ R turns u by a
    # image2(x) = image1(R^-1 (x - c) + c): image1 turned by a about c
    d = np.stack([xx.ravel() - c[0], yy.ravel() - c[1]], 1) @ R.T
    img1 = pattern(xx, yy).astype(np.float32)
    img2 = pattern(d[:, 0] + c[0], d[:, 1] + c[1]).reshape(200, 200).astype(np.float32)
    p1 = np.array([[110.0, 95.0]])
    p2 = (p1 - c) @ R + c
    kw = dict(cells=3, cell=5, bins=8, floor=10.0)
    o1, o2 = np.empty((1, 72), np.float32), np.empty((1, 72), np.float32)
    landmark_descriptors(img1, 1.0, 0.0, p1, np.eye(2), out=o1, **kw)
    landmark_descriptors(img2, 1.0, 0.0, p2, R, out=o2, **kw)
    other = np.empty((1, 72), np.float32)
    landmark_descriptors(img2, 1.0, 0.0, p2, np.eye(2), out=other, **kw)
    assert np.abs(o1 - o2).max() < 0.05  # same patch in its turned frame: equal up to interpolation
    assert np.abs(o1 - other).max() > 0.2  # read in the image's axes instead: different


def test_fast_atan2_is_close_to_math_atan2():
    from aamtrack._kernels.patches import _atan2

    rng = np.random.default_rng(SEED + 2)
    for y, x in rng.normal(size=(2000, 2)) * np.array([1.0, 3.0]):
        assert abs(_atan2(y, x) - np.arctan2(y, x)) < 2e-5
    assert _atan2(0.0, 0.0) == 0.0 and abs(_atan2(0.0, -1.0) - np.pi) < 1e-6


def test_quantised_regressors_and_their_product():
    from aamtrack._kernels.patches import _qmatvec
    from aamtrack.landmark_cascade import quantise_rows

    rng = np.random.default_rng(SEED)
    R = (rng.normal(0, 1, (2, 136, 1633)) * rng.uniform(1e-4, 1.0, (2, 136, 1))).astype(np.float32)
    R[1, 7] = 0.0  # a row of zeros keeps a usable scale
    Q, s = quantise_rows(R)
    assert Q.dtype == np.int16 and Q.shape == (2, 1633, 136) and s.shape == (2, 136)
    back = np.swapaxes(Q, -1, -2) * s[..., None].astype(np.float64)
    assert np.all(np.abs(back - R) <= 0.51 * s[..., None])  # half a step of the row's scale (R / s in float32)
    assert np.abs(back - R).max() <= np.abs(R).max() / 32767  # 1.5e-5 of the largest weight at most
    z = rng.normal(0, 1, 1633).astype(np.float32)  # an odd length: the remainder after the blocks of four
    for k in range(2):
        out = np.empty(136)
        _qmatvec(Q[k], s[k], z, np.full(136, 7.0, np.float32), out)  # scratch with old sums in it: cleared
        want = back[k] @ z.astype(np.float64)
        assert np.abs(out - want).max() < 1e-5 * np.abs(back[k]).sum(1).max()  # float32 sums
        assert np.abs(out - R[k].astype(np.float64) @ z).max() < 1e-3 * np.abs(R[k] @ z).max()  # ~ the float product


def test_low_rank_regressors_are_the_best_approximation_and_the_kernel_expands_them():
    from aamtrack._kernels.patches import _expand
    from aamtrack.landmark_cascade import factorise

    rng = np.random.default_rng(SEED + 3)
    A = rng.normal(0, 1, (2, 136, 20)) @ rng.normal(0, 1, (2, 20, 900))  # rank 20 exactly
    Ut, W = factorise(A, 20)
    assert Ut.shape == (2, 20, 136) and W.shape == (2, 20, 900) and Ut.dtype == W.dtype == np.float32
    back = np.swapaxes(Ut, 1, 2).astype(np.float64) @ W
    assert np.abs(back - A).max() < 1e-5 * np.abs(A).max()  # float32 factors of a rank-20 matrix: exact
    assert np.allclose(Ut[0] @ Ut[0].T, np.eye(20), atol=1e-6)  # orthonormal columns
    R = rng.normal(0, 1, (1, 136, 700)) * np.linspace(2.0, 0.01, 136)[None, :, None]
    for rank in (8, 64):
        Ut, W = factorise(R, rank)
        approx = Ut[0].T.astype(np.float64) @ W[0]
        U, s, Vt = np.linalg.svd(R[0], full_matrices=False)
        best = (U[:, :rank] * s[:rank]) @ Vt[:rank]  # Eckart-Young: the truncated SVD is the best of its rank
        assert np.abs(approx - best).max() < 1e-5 * np.abs(best).max()
        assert np.linalg.norm(R[0] - approx) > 0.01 * np.linalg.norm(R[0])  # and it did leave something out
    Ut, W = factorise(R, 0)  # 0: full rank, the matrix itself
    assert Ut.shape[1] == 136 and np.abs(Ut[0].T.astype(np.float64) @ W[0] - R[0]).max() < 1e-5 * np.abs(R).max()
    t = rng.normal(0, 1, 64)
    out = np.full(136, 3.0)  # old values: cleared
    Ut, _ = factorise(R, 64)
    _expand(Ut[0], t, out)
    assert np.abs(out - Ut[0].T.astype(np.float64) @ t).max() < 1e-12 * np.abs(Ut[0]).sum(0).max() * np.abs(t).max()


def test_training_rows_match_the_per_start_numpy_reading():
    """The cascade's training rows of one image in one compiled call against the obvious per-start numpy:
    ``similarity_to``, ``descriptors``, (truth - start) M^-1 and ``shape_features``."""
    from aamtrack.landmark_cascade import DescriptorSpec, descriptors, shape_features, similarity_to, training_rows

    rng = np.random.default_rng(SEED)
    image = (rng.random((120, 140)) * 255).astype(np.float32)
    image = (image + np.roll(image, 1, 0) + np.roll(image, 1, 1)) / 3
    ref = rng.normal(0.0, 0.4, (68, 2))
    ref -= ref.mean(0)
    truth = ref @ (30 * np.array([[np.cos(0.2), np.sin(0.2)], [-np.sin(0.2), np.cos(0.2)]])) + [70, 60]
    starts = truth + rng.normal(0.0, 2.0, (5, 68, 2))  # some near the border: clamped samples too
    spec = DescriptorSpec()
    F, Y, frames, S = training_rows(spec, image, 0.9, starts, truth, ref, 0.22, with_shape=True)
    _, Y2, _, S2 = training_rows(spec, image, 0.9, starts, truth, ref, 0.22, with_shape=False)
    assert S2 is None and np.array_equal(Y, Y2)
    for m, X in enumerate(starts):
        M, _ = similarity_to(ref, X)
        assert np.abs(frames[m] - M).max() < 1e-12
        assert np.abs(F[m] - descriptors(spec, image, 0.9, X, 0.22, M)).max() < 1e-5  # float32 descriptors
        assert np.abs(Y[m] - ((truth - X) @ np.linalg.inv(M)).ravel()).max() < 1e-10
        assert np.abs(S[m] - shape_features(ref, X, M)).max() < 1e-6  # float32


def test_grids_along_the_image_border_match_the_reference():
    """Grids that end just inside the last pixel (read without clamping, in float32) or just past it (clamped),
    on every side: the same descriptors as the reference, and nothing read outside the image."""
    rng = np.random.default_rng(SEED + 1)
    image = (rng.random((40, 50)) * 255).astype(np.float32)
    frame = 0.9 * np.eye(2)
    half = 0.5 * (3 * 3 + 1) * 0.9  # the grid's half extent (pixels) at scale 1: c0 steps of 0.9
    pts = []
    for gap in (0.02, 0.005, 0.0, -0.005):  # how far inside the border the grid's last samples lie
        pts += [[half + gap, 20.0], [49.0 - half - gap, 20.0], [25.0, half + gap], [25.0, 39.0 - half - gap]]
    pts = np.asarray(pts)
    out = np.empty((len(pts), 72), np.float32)
    landmark_descriptors(image, 1.0, 0.0, pts, frame, cells=3, cell=3, bins=8, floor=1.0, out=out)
    ref = reference_descriptors(image.astype(np.float64), 1.0, 0.0, pts, frame, 3, 3, 8, 1.0)
    assert np.abs(out - ref).max() < 1e-4  # float32 sums of the same terms


def test_an_image_too_large_for_int32_pixel_indices_is_refused():
    huge = np.broadcast_to(np.float32(0.0), (50_000, 50_000))  # (no memory behind it: refused before a copy)
    with pytest.raises(ValueError, match="too large"):
        landmark_descriptors(huge, 1.0, 0.0, np.zeros((1, 2)), np.eye(2), cells=3, cell=3, bins=8, floor=1.0,
                             out=np.empty((1, 72), np.float32))
