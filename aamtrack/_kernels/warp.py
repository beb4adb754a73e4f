"""Compiled kernels of the active search: projection of the face model, piecewise-affine warp to the
shape-free texture map, photometric normalisation, residual, parameter update and the search loop.

Conventions shared by every kernel (and documented once here):

- ``q`` is the full parameter vector ``[rx, ry, rz, s, tx, ty, c_0 .. c_{k-1}]``: Euler angles (radians,
  R = Rz @ Ry @ Rx), scale s (pixels per model unit in the frame), translation (pixels), deformation
  coefficients c (animation units for the 3D model, PCA coefficients for the 2D model).
- The model frame has x right, y up, z towards the viewer; the image has y down, so
  ``u = s * (R X)_x + tx`` and ``v = -s * (R X)_y + ty``.
- The search updates only ``q[free]``. An update ``delta`` (one value per free parameter) is composed in the
  face's own frame, so one learned update matrix serves every position, size and roll of the face: angles
  and coefficients add, the scale multiplies by ``exp(delta)``, and the translation moves by ``delta`` model
  units along the face's (rolled) axes. Training perturbs with the same ``_compose`` the search applies.
- An image resampled by a factor ``scale`` is sampled at ``scale * x + shift``: frame pixel x maps to that
  pixel of the resampled image (``shift`` = 0.5 scale - 0.5 for cv2.resize's half-pixel convention, 0 for
  cv2.pyrDown octaves; see ``aamtrack.imaging.level_shift``).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._flags import NJIT
from .patches import _qmatvec


@numba.njit(**NJIT)
def _rotation(rx, ry, rz, R):
    """R = Rz @ Ry @ Rx written into R (3, 3)."""
    cx, sx = math.cos(rx), math.sin(rx)
    cy, sy = math.cos(ry), math.sin(ry)
    cz, sz = math.cos(rz), math.sin(rz)
    R[0, 0] = cz * cy
    R[0, 1] = cz * sy * sx - sz * cx
    R[0, 2] = cz * sy * cx + sz * sx
    R[1, 0] = sz * cy
    R[1, 1] = sz * sy * sx + cz * cx
    R[1, 2] = sz * sy * cx - cz * sx
    R[2, 0] = -sy
    R[2, 1] = cy * sx
    R[2, 2] = cy * cx


@numba.njit(**NJIT)
def _project(shape3d, basis, q, out):
    """Vertices in image pixels (of the frame).

    shape3d (n, 3) float64: the person's neutral shape (M + S sigma); basis (k, n, 3) float64;
    q (6 + k,) float64; out (n, 2) float64.
    """
    R = np.empty((3, 3))
    _rotation(q[0], q[1], q[2], R)
    s, tx, ty = q[3], q[4], q[5]
    n = shape3d.shape[0]
    k = basis.shape[0]
    for i in range(n):
        x = shape3d[i, 0]
        y = shape3d[i, 1]
        z = shape3d[i, 2]
        for j in range(k):
            c = q[6 + j]
            if c != 0.0:
                x += c * basis[j, i, 0]
                y += c * basis[j, i, 1]
                z += c * basis[j, i, 2]
        out[i, 0] = s * (R[0, 0] * x + R[0, 1] * y + R[0, 2] * z) + tx
        out[i, 1] = -s * (R[1, 0] * x + R[1, 1] * y + R[1, 2] * z) + ty


@numba.njit(inline="always", **NJIT)
def _sample_at(verts, scale, shift, pix_vid, pix_bary, p):
    """Where texture pixel p samples an image resampled by ``scale`` (``_warp``): (x, y) in its pixels."""
    a, b, c = pix_vid[p, 0], pix_vid[p, 1], pix_vid[p, 2]
    wa, wb, wc = pix_bary[p, 0], pix_bary[p, 1], pix_bary[p, 2]
    x = scale * (wa * verts[a, 0] + wb * verts[b, 0] + wc * verts[c, 0]) + shift
    y = scale * (wa * verts[a, 1] + wb * verts[b, 1] + wc * verts[c, 1]) + shift
    return x, y


@numba.njit(**NJIT)
def _warp(image, verts, scale, shift, pix_vid, pix_bary, out):
    """Piecewise-affine warp with bilinear sampling: texture pixel p of channel ch takes the value of image
    channel ch at ``scale * sum_k pix_bary[p, k] * verts[pix_vid[p, k]] + shift``.

    image (C, H, W) float32 (H, W >= 2), C-contiguous; verts (n, 2) float64 frame pixels; scale, shift = the image's
    resampling (``aamtrack.imaging.level_shift``); pix_vid (N, 3) int32; pix_bary (N, 3) float32; out (C * N,)
    float32, channel-major (``out[ch * N + p]``). Samples outside the image take the nearest border value.
    Returns the number of texture pixels whose sample fell outside the image.

    In two passes: every pixel's sample position (its first pixel's flat index and the bilinear weights, float64),
    then per channel the gathers and the interpolation along the flat image. Measured 2026-12-01 (Intel Xeon VM, one
    core, 2 x 1930 pixels of cap12's tracked frames at 640x480, each frame's level once in turn, medians): 45.5 ->
    25.0 us against one pass doing both per pixel (the same expressions, so the same values bit for bit). Its
    scratch (3 N) is allocated here: handed in, it measured the same (24.95 against 25.05 us).
    """
    C, H, W = image.shape
    N = pix_vid.shape[0]
    flat = image.reshape(-1)
    at = np.empty(N, np.int64)
    fxs = np.empty(N)
    fys = np.empty(N)
    n_out = 0
    for p in range(N):
        x, y = _sample_at(verts, scale, shift, pix_vid, pix_bary, p)
        if x < 0.0 or y < 0.0 or x > W - 1 or y > H - 1:
            n_out += 1
            x = min(max(x, 0.0), W - 1.0)
            y = min(max(y, 0.0), H - 1.0)
        x0 = min(int(x), W - 2)
        y0 = min(int(y), H - 2)
        fxs[p] = x - x0
        fys[p] = y - y0
        at[p] = y0 * W + x0
    for ch in range(C):
        o = ch * H * W
        for p in range(N):
            k = at[p] + o
            fx = fxs[p]
            v00 = flat[k]
            v10 = flat[k + W]
            top = v00 + fx * (flat[k + 1] - v00)
            bot = v10 + fx * (flat[k + W + 1] - v10)
            out[ch * N + p] = top + fys[p] * (bot - top)
    return n_out


@numba.njit(**NJIT)
def _normalize(tex):
    """In place: zero mean, unit standard deviation (photometric normalisation). tex (N,) float32."""
    n = tex.shape[0]
    m = 0.0
    for p in range(n):
        m += tex[p]
    m /= n
    v = 0.0
    for p in range(n):
        d = tex[p] - m
        v += d * d
    sd = math.sqrt(v / n)
    inv = 1.0 / sd if sd > 1e-6 else 0.0
    for p in range(n):
        tex[p] = (tex[p] - m) * inv


@numba.njit(**NJIT)
def _finish_texture(tex, n_pixels, mode, rz):
    """In place, what makes a warped texture comparable with the mean texture. mode 0 (grey levels): zero mean,
    unit standard deviation. mode 1 (gradient vectors, channels gx, gy): each vector turned from image axes into
    the face's own axes (x along the face, y down the face) by the in-plane angle rz."""
    if mode == 0:
        _normalize(tex)
    else:
        c = math.cos(rz)
        s = math.sin(rz)
        for p in range(n_pixels):
            gx = tex[p]
            gy = tex[n_pixels + p]
            tex[p] = c * gx - s * gy
            tex[n_pixels + p] = s * gx + c * gy


@numba.njit(**NJIT)
def _texture(image, scale, shift, shape3d, basis, q, pix_vid, pix_bary, mode, verts, tex):
    """tex (C * N,) float32 <- the finished texture of image (C, H, W) under q (see ``_warp``,
    ``_finish_texture``). Scratch: verts (n, 2) float64. Returns how many texture pixels' samples fell outside the
    image (``_warp``)."""
    _project(shape3d, basis, q, verts)
    n_out = _warp(image, verts, scale, shift, pix_vid, pix_bary, tex)
    _finish_texture(tex, pix_vid.shape[0], mode, q[2])
    return n_out


@numba.njit(**NJIT)
def _fill_outside(image, verts, scale, shift, pix_vid, pix_bary, mean, tex):
    """tex (C * N,) <- the mean texture's value at every texture pixel whose sample falls outside the image (C, H,
    W) under verts (``_warp``'s test): a sample the image does not have leaves no residual (``_residual``)."""
    C, H, W = image.shape
    N = pix_vid.shape[0]
    for p in range(N):
        x, y = _sample_at(verts, scale, shift, pix_vid, pix_bary, p)
        if x < 0.0 or y < 0.0 or x > W - 1 or y > H - 1:
            for ch in range(C):
                tex[ch * N + p] = mean[ch * N + p]


@numba.njit(**NJIT)
def _residual(image, scale, shift, shape3d, basis, q, mean, app, pix_vid, pix_bary, mode, verts, tex, coef, e,
              fill=False):
    """e = P (T(q) - I_m) with T(q) the finished texture (``_texture``) and P the projection off the appearance
    basis ``app`` (D, m) float32 (orthonormal columns; m may be 0), D = C * N. Returns |e|^2 / D. With ``fill``,
    texture pixels whose sample falls outside the image take the mean texture's value (``_fill_outside``): where
    the image's edge is the frame's (a face partly out of the frame), the border smeared over them would pull the
    search towards it. Without it (a crop inside the frame, whose edges are not the picture's, and training,
    as the shipped models learned) they read the border as ``_warp`` samples it.
    Scratch: verts (n, 2) float64, tex (D,) float32, coef (m,) float64.

    The coefficients c = app^T (T - I_m) in one pass over the texture, four of its pixels at a time into all m sums
    (a loop across the m, which vectorises, as ``patches._qmatvec``), each sum in the order of the pixels as before,
    so bit for bit the same. Measured 2026-12-01 (Intel Xeon VM, one core, cap12's tracked frames at 640x480,
    D = 3860, m = 8, medians): the projection after the warp 33.4 -> 23.6 us against passes over the texture for four
    coefficients at a time (four scalar sums in flight; numba does not vectorise such straight-line code).
    """
    if _texture(image, scale, shift, shape3d, basis, q, pix_vid, pix_bary, mode, verts, tex) > 0 and fill:
        _fill_outside(image, verts, scale, shift, pix_vid, pix_bary, mean, tex)
    D = tex.shape[0]
    m = app.shape[1]
    for p in range(D):
        e[p] = tex[p] - mean[p]
    for j in range(m):
        coef[j] = 0.0
    D4 = D - D % 4
    for p in range(0, D4, 4):  # four terms of every sum per pass of a loop across the m coefficients, which
        e0 = e[p]  # vectorises; each sum still adds its terms one by one in the order of p
        e1 = e[p + 1]
        e2 = e[p + 2]
        e3 = e[p + 3]
        r0 = app[p]
        r1 = app[p + 1]
        r2 = app[p + 2]
        r3 = app[p + 3]
        for j in range(m):
            coef[j] = (((coef[j] + r0[j] * e0) + r1[j] * e1) + r2[j] * e2) + r3[j] * e3
    for p in range(D4, D):
        ep = e[p]
        r = app[p]
        for j in range(m):
            coef[j] += r[j] * ep
    err = 0.0
    for p in range(D):
        acc = e[p]
        for j in range(m):
            acc -= app[p, j] * coef[j]
        e[p] = acc
        err += acc * acc
    return err / D


@numba.njit(**NJIT)
def _compose(q, free, delta, step, lo, hi, out):
    """out = q updated by ``step * delta`` in the face's own frame (see module docstring), clipped to [lo, hi]."""
    for i in range(q.shape[0]):
        out[i] = q[i]
    du = 0.0
    dv = 0.0
    for a in range(free.shape[0]):
        j = free[a]
        d = step * delta[a]
        if j == 3:
            out[3] = q[3] * math.exp(d)
        elif j == 4:
            du = d
        elif j == 5:
            dv = d
        else:
            out[j] = q[j] + d
    c = math.cos(q[2])
    s = math.sin(q[2])
    out[4] = q[4] + q[3] * (c * du - s * dv)
    out[5] = q[5] - q[3] * (s * du + c * dv)
    for i in range(q.shape[0]):
        out[i] = min(max(out[i], lo[i]), hi[i])


@numba.njit(**NJIT)
def _prior_cost(q, free, prior):
    """sum_a prior[a] * q[free[a]]^2."""
    acc = 0.0
    for a in range(free.shape[0]):
        if prior[a] != 0.0:
            acc += prior[a] * q[free[a]] * q[free[a]]
    return acc


@numba.njit(**NJIT)
def _search(image, scale, shift, shape3d, basis, q, free, lo, hi, U, prior_step, prior, mean, app, pix_vid, pix_bary,
            mode, max_iter, tol, n_steps, delta_tol, fill=False):
    """Active search on one couple: repeat warp, residual, delta = U e - prior_step q[free], try the steps
    1, 1/2, ... (``n_steps`` of them) of delta and keep the first that lowers the cost; stop when none does,
    when the cost falls by less than ``tol`` (relative), or after ``max_iter`` iterations. Updates q in place.

    The cost is the mean squared residual plus a Gaussian prior on the coefficients,
    ``(|e|^2 + sum_a prior[a] q[free[a]]^2) / N``; U = -(G^T G + diag(prior))^-1 G^T and
    prior_step = (G^T G + diag(prior))^-1 diag(prior) make delta its Gauss-Newton step (prior is 0 for
    the pose). U (n_free, N) float32, prior_step (n_free, n_free) float64, prior (n_free,) float64.
    The search also stops, without trying it, when every |delta[a]| is below delta_tol[a] (n_free,).
    ``fill``: as ``_residual``'s. Returns (iterations, final cost).
    """
    n = shape3d.shape[0]
    N = mean.shape[0]
    verts = np.empty((n, 2))
    tex = np.empty(N, dtype=np.float32)
    coef = np.empty(app.shape[1])
    e = np.empty(N)
    e_try = np.empty(N)
    q_try = np.empty_like(q)
    delta = np.empty(free.shape[0])
    err = _residual(image, scale, shift, shape3d, basis, q, mean, app, pix_vid, pix_bary, mode, verts, tex, coef, e,
                    fill)
    err += _prior_cost(q, free, prior) / N
    it = 0
    while it < max_iter:
        it += 1
        for a in range(free.shape[0]):
            acc = 0.0
            for p in range(N):
                acc += U[a, p] * e[p]
            for b in range(free.shape[0]):
                acc -= prior_step[a, b] * q[free[b]]
            delta[a] = acc
        small = True
        for a in range(free.shape[0]):
            if abs(delta[a]) >= delta_tol[a]:
                small = False
                break
        if small:
            break
        step = 1.0
        accepted = False
        err_try = err
        for _ in range(n_steps):
            _compose(q, free, delta, step, lo, hi, q_try)
            err_try = _residual(image, scale, shift, shape3d, basis, q_try, mean, app, pix_vid, pix_bary, mode,
                                verts, tex, coef, e_try, fill) + _prior_cost(q_try, free, prior) / N
            if err_try < err:
                accepted = True
                break
            step *= 0.5
        if not accepted:
            break
        gain = (err - err_try) / max(err, 1e-12)
        for i in range(q.shape[0]):
            q[i] = q_try[i]
        for p in range(N):
            e[p] = e_try[p]
        err = err_try
        if gain < tol:
            break
    return it, err


@numba.njit(**NJIT)
def _accumulate_gradient(image, scale, shift, shape3d, basis, q0, free, steps, mean, app, pix_vid, pix_bary, mode,
                         G, e0):
    """Add to G (N, n_free) the least-squares slopes of the residual along each free parameter of one
    training image: G[:, a] += sum_d d (e(q0 + d e_a) - e(q0)) / sum_d d^2 over the perturbations
    ``steps[a]`` (n_free, n_steps), each composed with ``_compose``. Also writes e(q0) into e0.
    """
    n = shape3d.shape[0]
    N = mean.shape[0]
    verts = np.empty((n, 2))
    tex = np.empty(N, dtype=np.float32)
    coef = np.empty(app.shape[1])
    e = np.empty(N)
    q = np.empty_like(q0)
    delta = np.zeros(free.shape[0])
    no_lo = np.full(q0.shape[0], -np.inf)
    no_hi = np.full(q0.shape[0], np.inf)
    _residual(image, scale, shift, shape3d, basis, q0, mean, app, pix_vid, pix_bary, mode, verts, tex, coef, e0,
              False)
    for a in range(free.shape[0]):
        denom = 0.0
        for k in range(steps.shape[1]):
            d = steps[a, k]
            denom += d * d
        for k in range(steps.shape[1]):
            d = steps[a, k]
            delta[a] = d
            _compose(q0, free, delta, 1.0, no_lo, no_hi, q)
            _residual(image, scale, shift, shape3d, basis, q, mean, app, pix_vid, pix_bary, mode, verts, tex, coef, e,
                      False)
            for p in range(N):
                G[p, a] += d * (e[p] - e0[p]) / denom
        delta[a] = 0.0



@numba.njit(**NJIT)
def _cascade(image, scale, shift, shape3d, basis, q, free, lo, hi, Q, Qs, b, mean, app, pix_vid, pix_bary, mode,
             verts, tex, coef, e, delta, fill=False):
    """Learned update cascade on one couple (supervised descent): for each stage s, e = residual(q),
    delta = R[s] e + b[s], q <- q composed with delta (``_compose``, clipped to [lo, hi]). Updates q in place.

    Parameters whose bounds are equal (pinned) are not updated (delta 0). R[s] as int16, transposed, with
    per-row scales (``landmark_cascade.quantise_rows``: Q (n_stages, D, n_free) int16, Qs (n_stages, n_free)
    float32; ``patches._qmatvec`` on e in float32), b (n_stages, n_free) float64. Scratch: verts (n, 2) float64,
    tex (D,) float32, coef (m,) float64, e (D,) float64, delta (n_free,) float64. ``fill``: as ``_residual``'s.
    Returns |e|^2 / D of the last stage's residual (before its update).
    """
    q_new = np.empty_like(q)
    n_free = free.shape[0]
    D = e.shape[0]
    e32 = np.empty(D, np.float32)
    acc = np.empty(n_free, np.float32)
    prod = np.empty(n_free)
    err = 0.0
    for s in range(Q.shape[0]):
        err = _residual(image, scale, shift, shape3d, basis, q, mean, app, pix_vid, pix_bary, mode, verts, tex, coef, e,
                        fill)
        for p in range(D):
            e32[p] = e[p]
        _qmatvec(Q[s], Qs[s], e32, acc, prod)
        for a in range(n_free):
            delta[a] = prod[a] + b[s, a] if lo[free[a]] != hi[free[a]] else 0.0
        _compose(q, free, delta, 1.0, lo, hi, q_new)
        for i in range(q.shape[0]):
            q[i] = q_new[i]
    return err


@numba.njit(**NJIT)
def _residual_batch(image, scale, shift, shape3d, basis, Q, mean, app, pix_vid, pix_bary, mode, E):
    """E[i] = the projected residual of image at Q[i] (``_residual``), for Q (M, n_q) float64; E (M, D) float32.
    Training's bulk evaluation of many perturbed starts on one image."""
    D = mean.shape[0]
    verts = np.empty((shape3d.shape[0], 2))
    tex = np.empty(D, dtype=np.float32)
    coef = np.empty(app.shape[1])
    e = np.empty(D)
    for i in range(Q.shape[0]):
        _residual(image, scale, shift, shape3d, basis, Q[i], mean, app, pix_vid, pix_bary, mode, verts, tex, coef, e,
                  False)
        for p in range(D):
            E[i, p] = e[p]
