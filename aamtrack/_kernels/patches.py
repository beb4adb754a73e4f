"""Compiled local descriptors at landmarks: a histogram of gradient orientations (HOG/SIFT-like) of a square patch
around each point, sampled on a grid in the face's own frame (rotated and scaled with it), so the descriptor of a
landmark does not change when the face turns in the image plane or changes size (Xiong & De la Torre 2013,
supervised descent, regress on SIFT at the landmarks; here a lighter HOG made in one pass).

Per point: (cells * cell + 2)^2 bilinear samples of the grey image; central differences inside; each interior
sample adds its gradient magnitude to the two orientation bins (of ``bins`` over 360 degrees) nearest its angle,
in its cell; the point's cells * cells * bins histogram is L2-normalised (with a floor, so a flat patch stays
near zero), clipped at 0.2 and scaled back to its norm before clipping (SIFT's step against single strong edges).

Grey levels rather than the search's own gradient feature image (edge-structure orientations, blurred): read from
that, the same cascade measured worse on helen_test (mean NME 0.0492 against 0.0455, prototype, 4 stages).
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._flags import NJIT

CLIP = 0.2
EDGE = 0.01  # level pixels: a grid read without clamping keeps this far inside the image (float32 samples)


@numba.njit(**NJIT)
def _bilinear(img, x, y):
    H, W = img.shape
    if x < 0.0:
        x = 0.0
    elif x > W - 1.0:
        x = W - 1.0
    if y < 0.0:
        y = 0.0
    elif y > H - 1.0:
        y = H - 1.0
    x0 = min(int(x), W - 2) if W > 1 else 0
    y0 = min(int(y), H - 2) if H > 1 else 0
    fx = x - x0
    fy = y - y0
    x1 = min(x0 + 1, W - 1)
    y1 = min(y0 + 1, H - 1)
    top = img[y0, x0] + fx * (img[y0, x1] - img[y0, x0])
    bot = img[y1, x0] + fx * (img[y1, x1] - img[y1, x0])
    return top + fy * (bot - top)


@numba.njit(**NJIT)
def _atan2(y, x):
    """atan2 to about 1e-5 radians (tested): reduction to an angle in [0, pi/4] and an odd polynomial of degree
    11 for atan there; enough for soft binning, and cheaper than libm's exact atan2. Written with selects
    only (no branches), so a loop over samples calling it is vectorised; atan2(0, 0) = 0. Its constants are
    float32, so float32 arguments are worked in float32 throughout (twice the lanes of float64)."""
    f = np.float32
    ax = abs(x)
    ay = abs(y)
    swap = ay > ax
    num = ax if swap else ay
    den = ay if swap else ax
    t = num / den if den > f(0.0) else num * f(0.0)
    t2 = t * t
    a = t * (f(0.99997726) + t2 * (f(-0.33262347) + t2 * (f(0.19354346) + t2 * (f(-0.11643287) + t2 * (
        f(0.05265332) - t2 * f(0.01172120))))))
    a = f(0.5 * math.pi) - a if swap else a
    a = f(math.pi) - a if x < f(0.0) else a
    return -a if y < f(0.0) else a


@numba.njit(**NJIT)
def _descriptors(img, pts, scale, shift, a00, a01, a10, a11, cells, cell, bins, floor, out):
    """out (L, cells * cells * bins) float32 <- descriptors of the points pts (L, 2) (frame pixels) on img, a
    level resampled by ``scale`` (frame x at scale * x + shift). A sample at grid offset (du, dv) (in samples,
    grid centred on the point) lies at pts + (a00 du + a01 dv, a10 du + a11 dv) frame pixels.

    Per point, in passes over the patch: the samples; the gradients; magnitudes and orientation bins (one
    branch-free loop, vectorised); each sample's two bins and weights (branch-free, vectorised); the soft votes
    into the cells' histograms (a scatter, scalar); the normalisation. (One fused loop with a branchy atan2 took
    1.6x as long.) Measured 2026-12-01 on a cap12 frame's 68 points (one core, medians of 3,000 interleaved runs):
    92 -> 79 us with float32 sample positions and int32 indices (below) and the squared sums in four running sums,
    -> 69 us with the votes' bins and weights worked out before the scatter rather than in it (a branchy scatter
    loop; four copies of the histogram to break its chains through memory gained nothing, nor did voting
    densely into every bin of every sample, 102 us). The descriptors move by float32 rounding (4.8e-7 at most,
    values up to 0.42)."""
    L = pts.shape[0]
    H, W = img.shape
    flat = img.reshape(-1)  # (img is C-contiguous: ``kernels.landmark_descriptors``, ``landmark_cascade``)
    n = cells * cell
    G = n + 2
    c0 = 0.5 * (G - 1)
    N = G * G
    patch = np.empty(N, np.float32)  # the samples, row by row
    grid = patch.reshape(G, G)  # (the differences read from flat indices measured 20% slower)
    xs = np.empty(N)  # where each sample lies (level pixels), for a grid that crosses the image's border
    ys = np.empty(N)
    fxs = np.empty(N, np.float32)  # a grid inside the image: each sample's bilinear weights and first pixel
    fys = np.empty(N, np.float32)
    ats = np.empty(N, np.int32)
    oxs = np.empty(N, np.float32)  # each sample's row start: its offset from the whole pixel before it
    oys = np.empty(N, np.float32)
    rows = np.empty(N, np.int32)  # and that pixel's flat index
    js = np.empty(N, np.float32)  # each sample's column in the grid
    oxr = np.empty(G, np.float32)  # each row's start
    oyr = np.empty(G, np.float32)
    rowr = np.empty(G, np.int32)
    for k in range(N):
        js[k] = k % G
    gxs = np.empty(n * n, np.float32)
    gys = np.empty(n * n, np.float32)
    mags = np.empty(n * n, np.float32)  # float32 as the samples: the orientation pass vectorises twice as wide
    bs = np.empty(n * n, np.float32)
    base_of = np.empty(n * n, np.int32)  # first bin of each interior sample's cell
    for i in range(n):
        for j in range(n):
            base_of[i * n + j] = ((i // cell) * cells + j // cell) * bins
    per = cells * cells * bins
    i0s = np.empty(n * n, np.int32)
    i1s = np.empty(n * n, np.int32)
    w0s = np.empty(n * n, np.float32)
    w1s = np.empty(n * n, np.float32)
    to_bin = np.float32(bins / (2.0 * math.pi))
    pi = np.float32(math.pi)
    ux, uy, vx, vy = scale * a00, scale * a10, scale * a01, scale * a11  # grid steps in level pixels
    sx = np.float32(ux)
    sy = np.float32(uy)
    W32 = np.int32(W)
    ext_x = c0 * (abs(ux) + abs(vx)) + EDGE
    ext_y = c0 * (abs(uy) + abs(vy)) + EDGE
    for li in range(L):
        cx = scale * pts[li, 0] + shift
        cy = scale * pts[li, 1] + shift
        if cx - ext_x >= 0.0 and cx + ext_x < W - 1.0 and cy - ext_y >= 0.0 and cy + ext_y < H - 1.0:
            # the whole grid is in the image (EDGE inside): no clamping, and the gathers apart from the
            # arithmetic, which vectorises: each row's samples in float32 from the whole pixel before the row's
            # first one (to about 1e-6 px; in float64 with int64 indices, which AVX2 cannot convert in vectors,
            # the samples of 68 points took 43 us against 29), the indices in int32 (``kernels._patch_image``
            # bounds the image's size)
            # (the rows' starts, then copied to their samples, then one loop over the whole grid; 68 points'
            # descriptors, 2026-12-01, Intel Xeon VM, one core, medians of 4,600 interleaved runs on cap12's tracked
            # frames: 81.1 us with a loop over each row's 11 samples, 68.9 with the copies made in that loop, 62.9
            # with the starts first; 69.0 -> 57.5 in a quieter run of the first and last)
            for i in range(G):
                dv = i - c0
                rx = cx + vx * dv - ux * c0
                ry = cy + vy * dv - uy * c0
                bx = math.floor(rx)
                by = math.floor(ry)
                ox = np.float32(rx - bx)
                oy = np.float32(ry - by)
                oxr[i] = ox
                oyr[i] = oy
                rowr[i] = np.int32(by) * W32 + np.int32(bx)
            for i in range(G):
                ox = oxr[i]
                oy = oyr[i]
                row = rowr[i]
                for j in range(G):
                    oxs[i * G + j] = ox
                    oys[i * G + j] = oy
                    rows[i * G + j] = row
            for k in range(N):
                x = oxs[k] + sx * js[k]
                y = oys[k] + sy * js[k]
                xf = np.floor(x)
                yf = np.floor(y)
                fxs[k] = x - xf
                fys[k] = y - yf
                ats[k] = rows[k] + np.int32(yf) * W32 + np.int32(xf)
            for k in range(N):  # (on the flat image: 2-d indexing measured 10% slower)
                at = ats[k]
                fx = fxs[k]
                v00 = flat[at]
                v01 = flat[at + W]
                top = v00 + fx * (flat[at + 1] - v00)
                bot = v01 + fx * (flat[at + W + 1] - v01)
                patch[k] = top + fys[k] * (bot - top)
        else:
            for i in range(G):
                dv = i - c0
                rx = cx + vx * dv - ux * c0
                ry = cy + vy * dv - uy * c0
                for j in range(G):
                    xs[i * G + j] = rx + ux * j
                    ys[i * G + j] = ry + uy * j
            for k in range(N):
                patch[k] = _bilinear(img, xs[k], ys[k])
        for i in range(n):  # central differences at the interior samples
            for j in range(n):
                gxs[i * n + j] = grid[i + 1, j + 2] - grid[i + 1, j]
                gys[i * n + j] = grid[i + 2, j + 1] - grid[i, j + 1]
        for k in range(n * n):
            gx = gxs[k]
            gy = gys[k]
            mags[k] = math.sqrt(gx * gx + gy * gy)
            bs[k] = (_atan2(gy, gx) + pi) * to_bin
        o = out[li]
        for k in range(per):
            o[k] = 0.0
        for k in range(n * n):  # branch-free: each sample's two bins and weights (vectorises)
            bk = bs[k]
            fl = np.floor(bk)
            f = bk - fl
            b0 = np.int32(fl)
            b0 = b0 - np.int32(bins) if b0 >= bins else b0
            b1 = b0 + np.int32(1)
            b1 = np.int32(0) if b1 == bins else b1
            i0s[k] = base_of[k] + b0
            i1s[k] = base_of[k] + b1
            w1s[k] = mags[k] * f
            w0s[k] = mags[k] - w1s[k]
        for k in range(n * n):
            o[i0s[k]] += w0s[k]
            o[i1s[k]] += w1s[k]
        # normalise, clip, and bring back to the norm before clipping (the floor keeps a flat patch's noise
        # small, and clipping must not undo that); sums of squares in four running sums (one waits on each add)
        norm = math.sqrt(_sum_squares(o, per))
        inv = 1.0 / (norm + floor)
        pre = norm * inv
        for k in range(per):
            v = o[k] * inv
            o[k] = CLIP if v > CLIP else v
        ss = _sum_squares(o, per)
        if ss > 0.0:
            inv = pre / math.sqrt(ss)
            for k in range(per):
                o[k] = o[k] * inv


@numba.njit(**NJIT)
def _sum_squares(o, n):
    """The sum of o[k]^2 (float32 squares) over k < n in float64, as four running sums added at the end."""
    s0 = 0.0
    s1 = 0.0
    s2 = 0.0
    s3 = 0.0
    n4 = n - n % 4
    for k in range(0, n4, 4):
        s0 += o[k] * o[k]
        s1 += o[k + 1] * o[k + 1]
        s2 += o[k + 2] * o[k + 2]
        s3 += o[k + 3] * o[k + 3]
    for k in range(n4, n):
        s0 += o[k] * o[k]
    return (s0 + s1) + (s2 + s3)


@numba.njit(**NJIT)
def _similarity(pts, ref, n2):
    """(a, c, mx, my): (a, c) of the least-squares similarity [[a, c], [-c, a]] taking the centred reference ref
    (L, 2) (squared norm n2) to pts (L, 2) about pts' centroid (mx, my) (``landmark_cascade.similarity_to`` in
    closed form)."""
    L = pts.shape[0]
    mx = 0.0
    my = 0.0
    for li in range(L):
        mx += pts[li, 0]
        my += pts[li, 1]
    mx /= L
    my /= L
    a = 0.0
    c = 0.0
    for li in range(L):
        dx = pts[li, 0] - mx
        dy = pts[li, 1] - my
        a += ref[li, 0] * dx + ref[li, 1] * dy
        c += ref[li, 0] * dy - ref[li, 1] * dx
    return a / n2, c / n2, mx, my


@numba.njit(**NJIT)
def _squared_norm(ref):
    n2 = 0.0
    for li in range(ref.shape[0]):
        n2 += ref[li, 0] * ref[li, 0] + ref[li, 1] * ref[li, 1]
    return n2


@numba.njit(**NJIT)
def _qmatvec(Q, s, z, acc, out):
    """out (m,) float64 <- diag(s) Q^T z, the product of a matrix stored transposed and quantised
    (``landmark_cascade.quantise_rows``): Q (n, m) int16, s (m,) float32 each output's scale, z (n,) float32;
    acc (m,) float32 scratch. Four rows of Q at a time into float32 sums (each output's terms in the order of n,
    in fours), the inner loop across the m outputs, so it vectorises without reassociating anything."""
    n, m = Q.shape
    acc[:] = 0.0
    n4 = n - n % 4
    for j in range(0, n4, 4):
        z0 = z[j]
        z1 = z[j + 1]
        z2 = z[j + 2]
        z3 = z[j + 3]
        q0 = Q[j]
        q1 = Q[j + 1]
        q2 = Q[j + 2]
        q3 = Q[j + 3]
        for i in range(m):
            acc[i] += (np.float32(q0[i]) * z0 + np.float32(q1[i]) * z1) + (np.float32(q2[i]) * z2
                                                                           + np.float32(q3[i]) * z3)
    for j in range(n4, n):
        zj = z[j]
        qj = Q[j]
        for i in range(m):
            acc[i] += np.float32(qj[i]) * zj
    for i in range(m):
        out[i] = acc[i] * s[i]


@numba.njit(**NJIT)
def _expand(Ut, t, out):
    """out (m,) float64 <- U t, U stored transposed: Ut (r, m) float32, t (r,) float64 (one column of U at a time
    across the m outputs: vectorises, each output summed in the order of r)."""
    r, m = Ut.shape
    out[:] = 0.0
    for j in range(r):
        tj = t[j]
        u = Ut[j]
        for i in range(m):
            out[i] += u[i] * tj


@numba.njit(**NJIT)
def _landmark_cascade(img, scale, shift, pts, ref, halves, basis_mean, basis, Q, Qs, Ut, b, S, shape_from, repeats,
                      cells, cell, bins, floor, feat, shape, prior, blank=False):
    """The whole landmark cascade on pts (L, 2) float64 (frame pixels, moved in place): per stage k, the similarity
    M = [[a, c], [-c, a]] taking the centred reference ref (L, 2) to pts (least squares), the descriptors
    (``_descriptors``, into feat (L, cells * cells * bins) float32) on a grid of step 2 halves[k] / (cells * cell +
    1) reference units, each point's descriptor projected on the stage's basis (z = (feat - basis_mean[k]) basis[k],
    (L, d); with ``blank``, 0 for a point whose patch lies outside img, ``_blank_outside``), and pts += (R[k] z +
    S[k] s + b[k]) @ M per point, R[k] of rank r as U[k] W[k] (``landmark_cascade.factorise``): W[k] (r, 68 d) as
    int16, transposed, with per-row scales (Q (K, 68 d, r), Qs (K, r), ``_qmatvec``), U[k] (2 L, r) transposed, Ut
    (K, r, 2 L) float32 (``_expand``), where the stages from ``shape_from`` on read the points' own shape in the
    reference frame (s = (pts - centroid) M^-1 - ref, into shape (2 L,) float32; S[k] is zero before). prior (L, 2)
    float64 <- the sum of the (S[k] s) @ M moves. The last stage runs ``repeats`` more times, each on the points as
    the one before left them. Returns the last stage's z (what the landmark validator weighs: the face around each
    point just before the last, smallest update)."""
    L = pts.shape[0]
    side = cells * cell
    n2 = _squared_norm(ref)
    z = np.zeros((L, basis.shape[2]), np.float32)
    d = np.empty(2 * L)
    t = np.empty(Ut.shape[1])
    acc = np.empty(Ut.shape[1], np.float32)
    prior[:] = 0.0
    n = halves.shape[0]
    for it in range(n + repeats if n > 0 else 0):
        k = min(it, n - 1)
        a, c, mx, my = _similarity(pts, ref, n2)
        step = 2.0 * halves[k] / (side + 1)
        _descriptors(img, pts, scale, shift, step * a, -step * c, step * c, step * a, cells, cell, bins, floor,
                     feat)
        z = np.dot(feat - basis_mean[k], basis[k])
        if blank:
            _blank_outside(img, scale, shift, pts, halves[k] * math.sqrt(a * a + c * c) * scale, z)
        _qmatvec(Q[k], Qs[k], z.reshape(-1), acc, t)
        _expand(Ut[k], t, d)
        if k >= shape_from and _shape_in_frame(pts, ref, a, c, mx, my, shape):
            ds = np.dot(S[k], shape)
            d += ds
            for li in range(L):
                prior[li, 0] += ds[2 * li] * a - ds[2 * li + 1] * c
                prior[li, 1] += ds[2 * li] * c + ds[2 * li + 1] * a
        for li in range(L):
            ux = d[2 * li] + b[k, 2 * li]
            uy = d[2 * li + 1] + b[k, 2 * li + 1]
            pts[li, 0] += ux * a - uy * c
            pts[li, 1] += ux * c + uy * a
    return z


@numba.njit(**NJIT)
def _blank_outside(img, scale, shift, pts, reach, z):
    """z[l] <- 0 (the stage's mean descriptor) for every point l of pts (L, 2) (frame pixels) whose patch lies
    wholly outside img, the level resampled by ``scale`` (frame x at scale * x + shift): its centre more than
    ``reach`` level pixels (the patch's half side) past an edge. A patch the image does not have (a face partly out
    of the frame) says nothing, rather than what ``_descriptors`` reads of the border smeared over it.
    Measured 2026-12-02 (cap12 moved so up to 40% of the face's width lies past the frame's side edge, 3D, /tmp
    script): NME over the visible points of the frames 60-70% inside 0.0678 -> 0.0431 (with ``warp._fill_outside``);
    a point blanked as soon as its centre leaves the image did better there (0.0389) but cost the robustness suite's
    ``close_up`` (brows and chin on the frame's edges, their patches half inside) 0.0212 -> 0.0297."""
    H, W = img.shape
    for li in range(pts.shape[0]):
        x = scale * pts[li, 0] + shift
        y = scale * pts[li, 1] + shift
        if x < -reach or y < -reach or x > W - 1 + reach or y > H - 1 + reach:
            z[li, :] = 0.0


@numba.njit(**NJIT)
def _shape_in_frame(pts, ref, a, c, mx, my, out):
    """out (2 L,) float32 <- (pts - (mx, my)) M^-1 - ref, M = [[a, c], [-c, a]] and (mx, my) the centroid
    (``_similarity``): the points' shape in the reference frame, as its departure from the reference (x_0, y_0,
    x_1, ...). Returns False (out untouched) for a degenerate M."""
    det = a * a + c * c
    if not det > 0.0:
        return False
    for li in range(pts.shape[0]):
        dx = pts[li, 0] - mx
        dy = pts[li, 1] - my
        out[2 * li] = (dx * a + dy * c) / det - ref[li, 0]
        out[2 * li + 1] = (dy * a - dx * c) / det - ref[li, 1]
    return True


@numba.njit(**NJIT)
def _training_rows(img, scale, shift, X, truth, ref, half, cells, cell, bins, floor, with_shape, F, Y, frames, S):
    """The landmark cascade's training rows of the starts X (m, L, 2) (frame pixels) of one image, whose labels are
    truth (L, 2): per start, the similarity M = [[a, c], [-c, a]] taking the centred reference ref (L, 2) to it
    (``_similarity``), into frames[m] (2, 2); its descriptors on a grid of step 2 half / (cells * cell + 1)
    reference units (``_descriptors``) into F[m] (L, cells * cells * bins) float32; the displacement to the labels
    in the reference frame, (truth - X[m]) M^-1, into Y[m] (2 L,) (x_0, y_0, x_1, ...); and with ``with_shape``
    the start's own shape (``_shape_in_frame``) into S[m] (2 L,) float32. What ``train.landmarks`` did per start
    in numpy (``similarity_to``, ``descriptors``, ``shape_features``), the same to rounding."""
    L = X.shape[1]
    n2 = _squared_norm(ref)
    step = 2.0 * half / (cells * cell + 1)
    for m in range(X.shape[0]):
        pts = X[m]
        a, c, mx, my = _similarity(pts, ref, n2)
        _descriptors(img, pts, scale, shift, step * a, -step * c, step * c, step * a, cells, cell, bins, floor, F[m])
        det = a * a + c * c
        for li in range(L):
            dx = truth[li, 0] - pts[li, 0]
            dy = truth[li, 1] - pts[li, 1]
            Y[m, 2 * li] = (dx * a + dy * c) / det
            Y[m, 2 * li + 1] = (dy * a - dx * c) / det
        frames[m, 0, 0] = a
        frames[m, 0, 1] = c
        frames[m, 1, 0] = -c
        frames[m, 1, 1] = a
        if with_shape:
            _shape_in_frame(pts, ref, a, c, mx, my, S[m])
