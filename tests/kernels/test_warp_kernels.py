"""Each kernel against a slow, obvious reference."""

import numpy as np
import pytest
from scipy.ndimage import map_coordinates
from scipy.spatial.transform import Rotation

from aamtrack._kernels.features import gradient_features
from aamtrack.landmark_cascade import quantise_rows
from aamtrack._kernels.warp import (_cascade, _compose, _normalize, _prior_cost, _project, _residual,
                                   _residual_batch, _search, _warp)
from aamtrack.train.cascade import inverse_compose
from conftest import SEED


def test_project_matches_scipy_rotation():
    rng = np.random.default_rng(SEED)
    shape = rng.normal(size=(20, 3))
    basis = rng.normal(size=(2, 20, 3))
    q = np.r_[0.2, -0.3, 0.4, 50.0, 100.0, 80.0, 0.5, -0.25]
    X = shape + 0.5 * basis[0] - 0.25 * basis[1]
    R = Rotation.from_euler("xyz", q[:3]).as_matrix()  # extrinsic x, then y, then z: Rz @ Ry @ Rx
    ref = np.column_stack([50 * (X @ R.T)[:, 0] + 100, -50 * (X @ R.T)[:, 1] + 80])
    out = np.empty((20, 2))
    _project(shape, basis, q, out)
    assert np.abs(out - ref).max() < 1e-9  # exact up to rounding


def test_warp_matches_map_coordinates():
    rng = np.random.default_rng(SEED)
    image = rng.uniform(0, 255, (60, 80)).astype(np.float32)
    verts = np.array([[10.0, 5.0], [70.0, 12.0], [30.0, 50.0], [65.5, 55.25]])
    vid = rng.integers(0, 4, (500, 3)).astype(np.int32)
    bary = rng.dirichlet([1, 1, 1], 500).astype(np.float32)
    out = np.empty(1000, np.float32)
    image2 = np.stack([image, 255 - 2 * image])  # two channels, sampled at the same positions
    for scale, shift in ((1.0, 0.0), (0.5, 0.0), (0.5, -0.25)):
        _warp(image2, verts, scale, shift, vid, bary, out)
        pos = scale * np.einsum("pk,pkd->pd", bary.astype(float), verts[vid]) + shift
        for ch in range(2):
            ref = map_coordinates(image2[ch].astype(float), [pos[:, 1], pos[:, 0]], order=1)
            assert np.abs(out[ch * 500:(ch + 1) * 500] - ref).max() < 1e-3  # bilinear, float32, channel-major


def test_warp_clamps_outside_samples():
    image = np.arange(12, dtype=np.float32).reshape(3, 4)
    verts = np.array([[-5.0, -5.0], [10.0, 10.0]])
    vid = np.array([[0, 0, 0], [1, 1, 1]], np.int32)
    bary = np.array([[1, 0, 0], [1, 0, 0]], np.float32)
    out = np.empty(2, np.float32)
    assert _warp(image[None], verts, 1.0, 0.0, vid, bary, out) == 2
    assert out.tolist() == [0.0, 11.0]  # nearest corners


def _slow_warp_exact(image, verts, scale, shift, vid, bary):
    """``_warp`` one pixel at a time in Python, in the kernel's float64 expressions and float32 differences."""
    C, H, W = image.shape
    N = len(vid)
    out = np.empty(C * N, np.float32)
    n_out = 0
    for p in range(N):
        w = [float(b) for b in bary[p]]
        x = scale * (w[0] * verts[vid[p, 0], 0] + w[1] * verts[vid[p, 1], 0] + w[2] * verts[vid[p, 2], 0]) + shift
        y = scale * (w[0] * verts[vid[p, 0], 1] + w[1] * verts[vid[p, 1], 1] + w[2] * verts[vid[p, 2], 1]) + shift
        if x < 0.0 or y < 0.0 or x > W - 1 or y > H - 1:
            n_out += 1
            x = min(max(x, 0.0), W - 1.0)
            y = min(max(y, 0.0), H - 1.0)
        x0 = min(int(x), W - 2)
        y0 = min(int(y), H - 2)
        fx = x - x0
        fy = y - y0
        for ch in range(C):
            im = image[ch]
            top = float(im[y0, x0]) + fx * float(im[y0, x0 + 1] - im[y0, x0])  # float32 difference, float64 rest
            bot = float(im[y0 + 1, x0]) + fx * float(im[y0 + 1, x0 + 1] - im[y0 + 1, x0])
            out[ch * N + p] = top + fy * (bot - top)
    return out, n_out


def test_warp_is_bit_identical_to_the_pixel_by_pixel_loop():
    rng = np.random.default_rng(SEED)
    image = rng.uniform(-3, 3, (2, 37, 53)).astype(np.float32)
    verts = rng.uniform(-8, 60, (12, 2))  # some samples fall outside the image (clamped)
    vid = rng.integers(0, 12, (401, 3)).astype(np.int32)
    bary = rng.dirichlet([1, 1, 1], 401).astype(np.float32)
    out = np.empty(802, np.float32)
    for scale, shift in ((1.0, 0.0), (0.5, -0.25)):
        n_out = _warp(image, verts, scale, shift, vid, bary, out)
        ref, ref_out = _slow_warp_exact(image, verts, scale, shift, vid, bary)
        assert n_out == ref_out and (scale != 1.0 or n_out > 0)
        assert np.array_equal(out, ref)  # the same expressions: the same bits


def test_normalize():
    tex = np.random.default_rng(SEED).normal(5, 3, 400).astype(np.float32)
    _normalize(tex)
    assert abs(tex.mean()) < 1e-5 and abs(tex.std() - 1) < 1e-4


def test_compose_moves_in_the_face_frame():
    q = np.r_[0.0, 0.0, np.pi / 2, 10.0, 100.0, 100.0]
    free = np.arange(6)
    out = np.empty(6)
    inf = np.full(6, np.inf)
    _compose(q, free, np.r_[0, 0, 0, np.log(2.0), 1.0, 0.0], 1.0, -inf, inf, out)
    # one model unit along the face's x axis, rolled by 90 degrees: straight up in the image (y down)
    assert np.allclose(out[4:6], [100.0, 90.0]) and out[3] == pytest.approx(20.0)
    _compose(q, free, np.r_[0, 0, 0, 0, 1.0, 0.0], 0.5, -inf, inf, out)
    assert np.allclose(out[4:6], [100.0, 95.0])  # half a step


def test_compose_clips_to_bounds():
    q = np.r_[0, 0, 0, 10.0, 0, 0, 0.9]
    out = np.empty(7)
    lo, hi = np.full(7, -np.inf), np.full(7, np.inf)
    hi[6] = 1.0
    _compose(q, np.array([6]), np.array([0.5]), 1.0, lo, hi, out)
    assert out[6] == 1.0


def _slow_gradient_features(gray, soft, eps):
    """Sobel / 8 with edge replication, then g / (|g| + soft mean|g| + eps): the obvious numpy version."""
    g = np.pad(gray.astype(float), 1, mode="edge")
    H, W = gray.shape
    sl = lambda dy, dx: g[1 + dy:1 + dy + H, 1 + dx:1 + dx + W]  # noqa: E731
    gx = (sl(-1, 1) - sl(-1, -1) + 2 * (sl(0, 1) - sl(0, -1)) + sl(1, 1) - sl(1, -1)) / 8.0
    gy = (sl(1, -1) - sl(-1, -1) + 2 * (sl(1, 0) - sl(-1, 0)) + sl(1, 1) - sl(-1, 1)) / 8.0
    # the kernel takes one-sided differences at the border (half the span): match it there
    gx[:, 0] *= 2
    gx[:, -1] *= 2
    gy[0, :] *= 2
    gy[-1, :] *= 2
    mag = np.hypot(gx, gy)
    d = mag + soft * mag.mean() + eps
    return np.stack([gx / d, gy / d])


def test_gradient_features_match_reference():
    gray = np.random.default_rng(SEED).uniform(0, 255, (30, 41)).astype(np.float32)
    for soft, eps in ((0.0, 1.0), (1.0, 1.0), (2.0, 0.0)):
        ref = _slow_gradient_features(gray, soft, eps)
        assert np.abs(gradient_features(gray, soft=soft, eps=eps) - ref).max() < 1e-5  # float32


def test_gradient_features_of_flat_and_affine_images():
    flat = np.full((20, 20), 77.0, np.float32)
    assert np.abs(gradient_features(flat)).max() == 0.0  # no gradient, no orientation
    gray = np.random.default_rng(SEED).uniform(0, 255, (20, 20)).astype(np.float32)
    a = gradient_features(gray, soft=1.0, eps=0.0)
    b = gradient_features(3.0 * gray + 40.0, soft=1.0, eps=0.0)
    assert np.abs(a - b).max() < 1e-5  # invariant to gain and offset of the grey levels


def _toy_problem(rng, n_ch=2):
    """A random mesh over an image, the texture of one parameter vector as the mean: (arrays for the kernels)."""
    image = rng.uniform(-1, 1, (n_ch, 80, 90)).astype(np.float32)
    shape3d = np.array([[-1.0, 1.0, 0.0], [1.0, 1.0, 0.0], [1.0, -1.0, 0.0], [-1.0, -1.0, 0.0]])
    basis = rng.normal(0, 0.1, (1, 4, 3))
    vid = np.array([[0, 1, 2]] * 150 + [[0, 2, 3]] * 150, np.int32)
    bary = rng.dirichlet([2, 2, 2], 300).astype(np.float32)
    q = np.r_[0.0, 0.0, 0.2, 20.0, 45.0, 40.0, 0.3]
    return image, shape3d, basis, vid, bary, q


def _slow_residual(image, shape3d, basis, q, mean, app, vid, bary, mode):
    """The residual in numpy: texture pixels whose sample falls outside the image take the mean's value."""
    verts = np.empty((len(shape3d), 2))
    _project(shape3d, basis, q, verts)
    pos = np.einsum("pk,pkd->pd", bary.astype(float), verts[vid])
    tex = np.concatenate([map_coordinates(ch.astype(float), [pos[:, 1], pos[:, 0]], order=1, mode="nearest")
                          for ch in image])
    N = len(vid)
    if mode == 0:
        tex = (tex - tex.mean()) / tex.std()
    else:
        c, s = np.cos(q[2]), np.sin(q[2])
        gx, gy = tex[:N].copy(), tex[N:].copy()
        tex = np.r_[c * gx - s * gy, s * gx + c * gy]
    H, W = image.shape[1:]
    out = (pos[:, 0] < 0) | (pos[:, 1] < 0) | (pos[:, 0] > W - 1) | (pos[:, 1] > H - 1)
    tex = np.where(np.tile(out, len(image)), mean, tex)
    e = tex - mean
    e = e - app @ (app.T @ e)
    return e, float(e @ e / len(e))


@pytest.mark.parametrize("mode,n_ch", [(0, 1), (1, 2)])
def test_residual_matches_reference(mode, n_ch):
    rng = np.random.default_rng(SEED)
    image, shape3d, basis, vid, bary, q = _toy_problem(rng, n_ch)
    D = n_ch * len(vid)
    mean = rng.normal(0, 1, D).astype(np.float32)
    app = np.linalg.qr(rng.normal(0, 1, (D, 3)))[0].astype(np.float32)
    e = np.empty(D)
    err = _residual(image, 1.0, 0.0, shape3d, basis, q, mean, app, vid, bary, mode, np.empty((4, 2)),
                    np.empty(D, np.float32), np.empty(3), e)
    e_ref, err_ref = _slow_residual(image, shape3d, basis, q, mean.astype(float), app.astype(float), vid, bary, mode)
    assert np.abs(e - e_ref).max() < 1e-4 and err == pytest.approx(err_ref, rel=1e-4)  # float32 textures
    e2 = np.empty(D)
    _residual(image, 1.0, 0.0, shape3d, basis, q, mean, app, vid, bary, mode, np.empty((4, 2)), np.empty(D, np.float32),
              np.empty(3), e2, True)
    assert np.array_equal(e, e2)  # the toy face lies inside the image: nothing to fill, with or without
    E = np.empty((2, D), np.float32)
    _residual_batch(image, 1.0, 0.0, shape3d, basis, np.stack([q, q]), mean, app, vid, bary, mode, E)
    assert np.abs(E - e_ref).max() < 1e-4  # the batch is the same residual, row by row


@pytest.mark.parametrize("mode,n_ch", [(0, 1), (1, 2)])
def test_residual_leaves_out_the_samples_outside_the_image(mode, n_ch):
    """A face partly out of the frame: texture pixels whose sample falls outside the image take the mean texture's
    value (no residual there) instead of the border's value smeared over them; the rest as before."""
    rng = np.random.default_rng(SEED)
    image, shape3d, basis, vid, bary, q = _toy_problem(rng, n_ch)
    q[4] = 8.0  # the mesh (about 40 px wide) about its centre at x = 8: a third of it left of the image
    D = n_ch * len(vid)
    mean = rng.normal(0, 1, D).astype(np.float32)
    app = np.linalg.qr(rng.normal(0, 1, (D, 3)))[0].astype(np.float32)
    verts, tex, e = np.empty((4, 2)), np.empty(D, np.float32), np.empty(D)
    err = _residual(image, 1.0, 0.0, shape3d, basis, q, mean, app, vid, bary, mode, verts, tex, np.empty(3), e, True)
    pos = np.einsum("pk,pkd->pd", bary.astype(float), verts[vid])
    out = np.tile(pos[:, 0] < 0, n_ch)
    assert 0.2 < out.mean() < 0.5  # the premise: a good part of the texture lies outside
    assert np.array_equal(tex[out], mean[out])  # those pixels read as the mean texture
    e_border = np.empty(D)
    _residual(image, 1.0, 0.0, shape3d, basis, q, mean, app, vid, bary, mode, verts, tex, np.empty(3), e_border, False)
    assert not np.array_equal(tex[out], mean[out]) and np.abs(e_border - e).max() > 0.1  # ``fill`` off: the border
    _residual(image, 1.0, 0.0, shape3d, basis, q, mean, app, vid, bary, mode, verts, tex, np.empty(3), e, True)
    e_ref, err_ref = _slow_residual(image, shape3d, basis, q, mean.astype(float), app.astype(float), vid, bary, mode)
    assert np.abs(e - e_ref).max() < 1e-4 and err == pytest.approx(err_ref, rel=1e-4)  # float32 textures


@pytest.mark.parametrize("m", [0, 3, 8, 9])
def test_residual_projection_sums_in_the_order_of_the_pixels(m):
    """The appearance coefficients (four pixels per pass over the m sums) and the residual are bit for bit the
    plain loops: each coefficient summed pixel by pixel in float64, then e - app c, coefficient by coefficient."""
    rng = np.random.default_rng(SEED)
    image, shape3d, basis, vid, bary, q = _toy_problem(rng, 2)
    vid, bary = vid[:299], bary[:299]  # D = 598: not a whole number of fours
    D = 2 * len(vid)
    mean = rng.normal(0, 1, D).astype(np.float32)
    app = np.linalg.qr(rng.normal(0, 1, (D, max(m, 1))))[0][:, :m].astype(np.float32).copy()
    tex = np.empty(D, np.float32)
    coef = np.empty(m)
    e = np.empty(D)
    err = _residual(image, 1.0, 0.0, shape3d, basis, q, mean, app, vid, bary, 1, np.empty((4, 2)), tex, coef, e)
    e0 = [float(t - u) for t, u in zip(tex, mean, strict=True)]  # float32 difference
    ref = []
    for j in range(m):
        acc = 0.0
        for p in range(D):
            acc += float(app[p, j]) * e0[p]
        ref.append(acc)
    assert coef.tolist() == ref
    e_ref = []
    for p in range(D):
        acc = e0[p]
        for j in range(m):
            acc -= float(app[p, j]) * ref[j]
        e_ref.append(acc)
    assert e.tolist() == e_ref
    err_ref = 0.0
    for v in e_ref:
        err_ref += v * v
    assert err == err_ref / D


def test_prior_cost():
    q = np.r_[0.1, 0.2, 0.3, 4.0, 5.0, 6.0, 0.5, -2.0]
    assert _prior_cost(q, np.array([2, 6, 7]), np.array([0.0, 3.0, 0.5])) == pytest.approx(3 * 0.25 + 0.5 * 4.0)


def test_inverse_compose_undoes_compose():
    rng = np.random.default_rng(SEED)
    free = np.arange(8)
    inf = np.full(8, np.inf)
    for _ in range(20):
        q = np.r_[rng.normal(0, 0.3, 3), rng.uniform(5, 50), rng.uniform(0, 300, 2), rng.normal(0, 1, 2)]
        delta = rng.normal(0, 0.2, 8)
        out = np.empty(8)
        _compose(q, free, delta, 1.0, -inf, inf, out)
        assert np.abs(inverse_compose(q, out, free)[0] - delta).max() < 1e-9  # exact up to rounding


def test_cascade_applies_each_stage_once():
    """With R = 0 every stage moves p by its bias alone: the cascade composes the stages in order."""
    rng = np.random.default_rng(SEED)
    image, shape3d, basis, vid, bary, q = _toy_problem(rng)
    D = 2 * len(vid)
    free = np.array([4, 5, 6])
    R = np.zeros((3, 3, D), np.float32)
    b = np.array([[0.1, 0.0, 0.05], [0.0, -0.2, 0.05], [0.1, 0.1, 0.0]])
    p = q.copy()
    lo, hi = np.full(7, -np.inf), np.full(7, np.inf)
    _cascade(image, 1.0, 0.0, shape3d, basis, p, free, lo, hi, *quantise_rows(R), b, np.zeros(D, np.float32),
             np.zeros((D, 0), np.float32), vid, bary, 1, np.empty((4, 2)), np.empty(D, np.float32), np.empty(0),
             np.empty(D), np.empty(3))
    ref = q.copy()
    for s in range(3):
        _compose(ref.copy(), free, b[s], 1.0, lo, hi, ref)
    assert np.abs(p - ref).max() < 1e-12


def test_cascade_stage_is_the_matrix_product_of_its_residual():
    """One stage, delta = R e + b with e the residual at the start, against numpy's float64 product of the
    unquantised R: the int16 matrices and float32 sums move delta by about 1e-5 of its size."""
    rng = np.random.default_rng(SEED + 5)
    image, shape3d, basis, vid, bary, q = _toy_problem(rng)
    D = 2 * len(vid)
    free = np.array([4, 5, 6])
    R = rng.normal(0, 2e-3, (1, 3, D)).astype(np.float32)
    b = np.array([[0.01, -0.02, 0.0]])
    mean = rng.normal(0, 1, D).astype(np.float32)
    app = np.zeros((D, 0), np.float32)
    lo, hi = np.full(7, -np.inf), np.full(7, np.inf)
    scratch = (np.empty((4, 2)), np.empty(D, np.float32), np.empty(0), np.empty(D))
    _residual(image, 1.0, 0.0, shape3d, basis, q, mean, app, vid, bary, 1, *scratch)
    e = scratch[3].copy()
    delta = R[0].astype(np.float64) @ e + b[0]
    assert np.abs(delta).max() > 0.01  # the product moves the parameters
    want = np.empty(7)
    _compose(q, free, delta, 1.0, lo, hi, want)
    p = q.copy()
    _cascade(image, 1.0, 0.0, shape3d, basis, p, free, lo, hi, *quantise_rows(R), b, mean, app, vid, bary, 1,
             *scratch, np.empty(3))
    assert np.abs(p - want).max() < 1e-4 * np.abs(want - q).max()  # of the move: int16 weights, float32 sums


def test_search_reaches_a_known_minimum():
    """The Jacobian search from a start moved along one parameter, with U the exact inverse of a numerical
    gradient of the toy residual, returns to the parameters whose texture is the mean."""
    rng = np.random.default_rng(SEED)
    image, shape3d, basis, vid, bary, q = _toy_problem(rng, 1)
    import cv2

    image = cv2.GaussianBlur(image[0], (0, 0), 4.0)[None]  # smooth, so the linearisation holds
    D = len(vid)
    tex = np.empty(D, np.float32)
    e = np.empty(D)
    no_app = np.zeros((D, 0), np.float32)
    args = (np.empty((4, 2)), tex, np.empty(0), e)
    _residual(image, 1.0, 0.0, shape3d, basis, q, np.zeros(D, np.float32), no_app, vid, bary, 0, *args)
    mean = tex.copy()
    free = np.array([4, 5])
    G = np.empty((D, 2))
    for a in range(len(free)):
        qp = q.copy()
        _compose(q, free, np.eye(2)[a] * 0.01, 1.0, np.full(7, -np.inf), np.full(7, np.inf), qp)
        _residual(image, 1.0, 0.0, shape3d, basis, qp, mean, no_app, vid, bary, 0, *args)
        G[:, a] = e / 0.01
    U = (-np.linalg.pinv(G)).astype(np.float32)
    start = q.copy()
    start[4] += 0.6  # pixels
    lo, hi = np.full(7, -np.inf), np.full(7, np.inf)
    _search(image, 1.0, 0.0, shape3d, basis, start, free, lo, hi, U, np.zeros((2, 2)), np.zeros(2), mean, no_app, vid,
            bary, 0, 30, 1e-6, 4, np.full(2, 1e-6))
    assert np.abs(start[4:6] - q[4:6]).max() < 0.05  # back to the true translation within 1/20 pixel


def test_cascade_leaves_pinned_parameters():
    rng = np.random.default_rng(SEED)
    image, shape3d, basis, vid, bary, q = _toy_problem(rng)
    D = 2 * len(vid)
    free = np.array([4, 5, 6])
    R = rng.normal(0, 1e-3, (2, 3, D)).astype(np.float32)
    b = np.full((2, 3), 0.05)
    lo, hi = np.full(7, -np.inf), np.full(7, np.inf)
    lo[6] = hi[6] = q[6]  # the coefficient is held
    p = q.copy()
    _cascade(image, 1.0, 0.0, shape3d, basis, p, free, lo, hi, *quantise_rows(R), b, np.zeros(D, np.float32),
             np.zeros((D, 0), np.float32), vid, bary, 1, np.empty((4, 2)), np.empty(D, np.float32), np.empty(0), np.empty(D), np.empty(3))
    assert p[6] == q[6] and not np.allclose(p[4:6], q[4:6])  # held stays, the rest moved


def test_accumulate_gradient_matches_a_loop_of_residuals():
    """G += sum_d d (e(q0 (+) d) - e(q0)) / sum_d d^2, per free parameter, against the same sum written out."""
    from aamtrack._kernels.warp import _accumulate_gradient

    rng = np.random.default_rng(SEED)
    image, shape3d, basis, vid, bary, q = _toy_problem(rng)
    D = 2 * len(vid)
    mean = rng.normal(0, 1, D).astype(np.float32)
    app = np.linalg.qr(rng.normal(0, 1, (D, 2)))[0].astype(np.float32)
    free = np.array([2, 4, 6])
    steps = np.array([[0.02, -0.02, 0.05, -0.05], [0.1, -0.1, 0.3, -0.3], [0.05, -0.05, 0.2, -0.2]])
    G = np.zeros((D, 3))
    e0 = np.empty(D)
    _accumulate_gradient(image, 1.0, 0.0, shape3d, basis, q, free, steps, mean, app, vid, bary, 1, G, e0)
    scratch = (np.empty((4, 2)), np.empty(D, np.float32), np.empty(2))
    base = np.empty(D)
    _residual(image, 1.0, 0.0, shape3d, basis, q, mean, app, vid, bary, 1, *scratch, base)
    inf = np.full(7, np.inf)
    for a in range(3):
        ref = np.zeros(D)
        for d in steps[a]:
            qd, e = np.empty(7), np.empty(D)
            _compose(q, free, np.eye(3)[a] * d, 1.0, -inf, inf, qd)
            _residual(image, 1.0, 0.0, shape3d, basis, qd, mean, app, vid, bary, 1, *scratch, e)
            ref += d * (e - base) / (steps[a] ** 2).sum()
        assert np.abs(G[:, a] - ref).max() < 1e-9
    assert np.abs(e0 - base).max() < 1e-12


@pytest.mark.parametrize("r", [0.5, 0.3, 0.17])
def test_levels_half_pixel_mapping(r):
    """A level resampled by r (halvings, then one resize) holds the source at x = (x' + 0.5) / r - 0.5, i.e. frame
    pixel x at x' = r x + ``imaging.level_shift(r)``, and the warp sampling the level at (r, level_shift(r)) reads
    the frame at x. On a linear ramp away from the border: exact at r = 0.5 (measured 0), within a tenth of a
    level pixel at other ratios (INTER_AREA's weights at non-integer ratios; measured 0.05 at r = 0.3, 0.08 at
    r = 0.17)."""
    from aamtrack.imaging import Features, Levels, level_shift

    yy, xx = np.mgrid[0:240, 0:320].astype(np.float32)
    ramp = 0.3 * xx + 0.7 * yy + 10.0
    level = Levels(ramp, Features("intensity", lcn_sigma=0.0)).get(r)[0]
    h, w = level.shape
    ys, xs = np.mgrid[3:h - 3, 3:w - 3]
    src_x = (xs + 0.5) / r - 0.5
    src_y = (ys + 0.5) / r - 0.5
    grey_err = np.abs(level[3:h - 3, 3:w - 3] - (0.3 * src_x + 0.7 * src_y + 10.0)).max()
    level_px = grey_err / np.hypot(0.3, 0.7) * r  # the ramp's grey error as a position error in level pixels
    assert level_px < (1e-3 if r == 0.5 else 0.1)
    # the warp at (r, level_shift(r)) reads the frame's own values at frame pixels, through the level
    rng = np.random.default_rng(SEED)
    verts = rng.uniform(40, 200, (50, 2))
    vid = np.repeat(np.arange(50, dtype=np.int32)[:, None], 3, 1)
    bary = np.tile(np.array([1, 0, 0], np.float32), (50, 1))
    out = np.empty(50, np.float32)
    _warp(level[None], verts, r, level_shift(r), vid, bary, out)
    truth = 0.3 * verts[:, 0] + 0.7 * verts[:, 1] + 10.0
    assert np.abs(out - truth).max() / np.hypot(0.3, 0.7) < (1e-3 if r == 0.5 else 0.1) / r  # in frame pixels
