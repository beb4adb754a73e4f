"""Compiled statistics of the face's box in a grey level: how soft it looks (``_sharpness``) and what its contrast
over the image's noise is read from (``_noise_and_deviation``: the median absolute Laplacian and the
standard deviation), which pick the landmark cascade and validator for every fit (``aamtrack.landmark_cascade``),
and a noise estimate that reads less of a small face's detail (``_fine_noise``: Immerkaer's mask), which decides
whether the cascade reads a noisy face smoothed.
In numpy and OpenCV calls each took 0.09-0.15 ms of a tracked frame's ~2.5 ms, most of it per-call overhead on
boxes of a few thousand pixels; here each is one compiled call.

The box: the points pts (L, 2) (frame pixels) mapped into the level resampled by ``scale``
(x -> scale (x + 0.5) - 0.5), its floor and ceiling (+1), grown by ``pad`` pixels and cut to the image.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ._flags import NJIT


@numba.njit(**NJIT)
def _face_box(H, W, scale, pts, pad, min_side, box):
    """box (4,) int64 <- (x0, y0, x1, y1) of the points in an image of H x W (see the module docstring).
    Returns False when a point is not finite or a side is under ``min_side``."""
    lo_x = math.inf
    lo_y = math.inf
    hi_x = -math.inf
    hi_y = -math.inf
    for i in range(pts.shape[0]):
        x = scale * (pts[i, 0] + 0.5) - 0.5
        y = scale * (pts[i, 1] + 0.5) - 0.5
        if not (math.isfinite(x) and math.isfinite(y)):
            return False
        lo_x = min(lo_x, x)
        lo_y = min(lo_y, y)
        hi_x = max(hi_x, x)
        hi_y = max(hi_y, y)
    if pts.shape[0] == 0:
        return False
    x0 = max(int(math.floor(lo_x)) - pad, 0)
    y0 = max(int(math.floor(lo_y)) - pad, 0)
    x1 = min(int(math.ceil(hi_x)) + 1 + pad, W)
    y1 = min(int(math.ceil(hi_y)) + 1 + pad, H)
    if x1 - x0 < min_side or y1 - y0 < min_side:
        return False
    box[0] = x0
    box[1] = y0
    box[2] = x1
    box[3] = y1
    return True


@numba.njit(**NJIT)
def _blur(src, k, out, row, acc):
    """out (h, w) float32 <- src (h, w) float32 convolved with the odd symmetric kernel k (n,) float32 along both
    axes, borders replicated (OpenCV's ``GaussianBlur`` with ``BORDER_REPLICATE``, to float32 rounding). row
    (w + n - 1,) and acc (w,) float32: scratch. The vertical pass first, into out, then the horizontal one row
    by row; each inner loop runs along x into acc, which aliases nothing, so it vectorises (summing into a row of
    out directly took 2-3x as long)."""
    h, w = src.shape
    n = k.shape[0]
    r = n // 2
    for y in range(h):
        for x in range(w):
            acc[x] = 0.0
        for t in range(n):
            yy = min(max(y + t - r, 0), h - 1)
            kt = k[t]
            for x in range(w):
                acc[x] += kt * src[yy, x]
        for x in range(w):
            out[y, x] = acc[x]
    for y in range(h):
        for x in range(w):
            row[x + r] = out[y, x]
        for x in range(r):
            row[x] = out[y, 0]
            row[w + r + x] = out[y, w - 1]
        for x in range(w):
            acc[x] = 0.0
        for t in range(n):
            kt = k[t]
            for x in range(w):
                acc[x] += kt * row[x + t]
        for x in range(w):
            out[y, x] = acc[x]


@numba.njit(**NJIT)
def _energy(img, m):
    """Sum of squared differences of neighbours along x and y (float64) inside img less an ``m``-pixel margin:
    in eight running sums (one sum is a chain of dependent adds, which does not vectorise)."""
    h, w = img.shape
    acc = np.zeros(8)
    for y in range(m, h - m):
        r = img[y]
        n = w - m - 1 - m
        n8 = n - n % 8
        for x in range(m, m + n8, 8):
            for j in range(8):
                d = float(r[x + j + 1] - r[x + j])
                acc[j] += d * d
        for x in range(m + n8, w - m - 1):
            d = float(r[x + 1] - r[x])
            acc[0] += d * d
    for y in range(m, h - m - 1):
        r0 = img[y]
        r1 = img[y + 1]
        n = w - 2 * m
        n8 = n - n % 8
        for x in range(m, m + n8, 8):
            for j in range(8):
                d = float(r1[x + j] - r0[x + j])
                acc[j] += d * d
        for x in range(m + n8, w - m):
            d = float(r1[x] - r0[x])
            acc[0] += d * d
    return acc.sum()


@numba.njit(**NJIT)
def _halve(img, x0, y0, w, h):
    """(round(h / 2), round(w / 2)) float32: the box (x0, y0, w, h) of img resampled by 1/2 as OpenCV's
    ``cv2.resize(box, None, fx=0.5, fy=0.5, interpolation=cv2.INTER_AREA)`` resamples it (its fast path for a whole
    factor, sizes rounded half to even): 2 x 2 means, and where an odd side rounds up, a last column or row of the
    means of the pixels left (2, or 1 in the corner). The same values to float32 rounding (sums in another order)."""
    ho = int(np.rint(0.5 * h))
    wo = int(np.rint(0.5 * w))
    hf = h // 2
    wf = w // 2
    out = np.empty((ho, wo), np.float32)
    quarter = np.float32(0.25)
    half = np.float32(0.5)
    for y in range(hf):
        r0 = img[y0 + 2 * y]
        r1 = img[y0 + 2 * y + 1]
        for x in range(wf):
            c = x0 + 2 * x
            out[y, x] = ((r0[c] + r0[c + 1]) + (r1[c] + r1[c + 1])) * quarter
        if wo > wf:  # the last source column alone
            c = x0 + w - 1
            out[y, wf] = (r0[c] + r1[c]) * half
    if ho > hf:  # the last source row alone
        r = img[y0 + h - 1]
        for x in range(wf):
            c = x0 + 2 * x
            out[hf, x] = (r[c] + r[c + 1]) * half
        if wo > wf:
            out[hf, wf] = r[x0 + w - 1]
    return out


@numba.njit(**NJIT)
def _sharpness(img, scale, pts, pad, k1, k2):
    """The gradient energy of the face's box (grown by ``pad``, an even number of pixels) halved (``_halve``) and
    blurred by k2 after k1 over that of it blurred by k1, inside a margin of pad / 2 half-size pixels
    (``landmark_cascade.sharpness``). 0 for a flat box or one under 2 pad + 4 pixels a side."""
    H, W = img.shape
    box = np.empty(4, np.int64)
    if not _face_box(H, W, scale, pts, pad, 2 * pad + 4, box):
        return 0.0
    half = _halve(img, box[0], box[1], box[2] - box[0], box[3] - box[1])
    h, w = half.shape
    row = np.empty(w + max(k1.shape[0], k2.shape[0]), np.float32)
    acc = np.empty(w, np.float32)
    a = np.empty((h, w), np.float32)
    _blur(half, k1, a, row, acc)
    _blur(a, k2, half, row, acc)  # b, into half's memory
    m = pad // 2
    e = _energy(a, m)
    return _energy(half, m) / e if e > 1e-6 else 0.0


@numba.njit(**NJIT)
def _bins(v, m, lo, c, B, out):
    """out[:m] <- the bin of each value of v[:m]: for c == 0 by its float32 bit pattern shifted right 20 (the
    exponent and the mantissa's top three bits: bins an eighth of an octave wide, in order for values >= 0, and
    no pass over the values for their range), else linearly, min(int((x - lo) c), B - 1)."""
    if c == 0.0:
        bits = v.view(np.int32)
        for i in range(m):
            out[i] = min(max(bits[i] >> 20, 0), B - 1)
    else:
        for i in range(m):
            out[i] = min(int((float(v[i]) - lo) * c), B - 1)


@numba.njit(**NJIT)
def _middle(v):
    """np.median of v (n >= 1,) float32 (values >= 0, finite), bit for bit (for even n the two middle values' mean
    in float32), in linear passes: the values' bins (``_bins``: first by their bit pattern, then linearly between
    the survivors' min and max) are counted to find the bins of the middle ranks, the values there are gathered
    to the front of v (branch-free), and again until at most 48 are left, which are sorted; two middle ranks in
    two bins are the first bin's largest value and the second's smallest. (A value's bin is monotonic in the
    value, so the ranks stay where counted.) v is overwritten.
    On the 17k absolute Laplacians of the face boxes of a tracked video, each box once (a loop over one box many
    times trains the branch predictor and misleads): 21-26 us against 110 for numpy's partition (the median this
    replaced)."""
    n = v.shape[0]
    r1 = n // 2
    r0 = r1 if n % 2 else r1 - 1
    m = n
    B = 2048
    counts = np.empty(B, np.int64)
    idx = np.empty(n, np.int32)
    lo = 0.0
    c = 0.0
    first = True
    while True:
        if not first:
            vlo = v[0]
            vhi = v[0]
            for i in range(1, m):
                vlo = min(vlo, v[i])
                vhi = max(vhi, v[i])
            if m <= 48 or not vhi > vlo:
                break
            lo = float(vlo)
            c = (B - 1) / (float(vhi) - lo)
        first = False
        _bins(v, m, lo, c, B, idx)
        counts[:] = 0
        for i in range(m):
            counts[idx[i]] += 1
        cum = 0
        b0 = -1
        b1 = B - 1
        before = 0
        for j in range(B):
            if b0 < 0 and cum + counts[j] > r0:
                b0 = j
                before = cum
            if cum + counts[j] > r1:
                b1 = j
                break
            cum += counts[j]
        if b0 != b1:  # the two middle ranks in two bins: the last of b0's values and the first of b1's
            a = -np.float32(np.inf)
            b = np.float32(np.inf)
            for i in range(m):
                if idx[i] == b0:
                    a = max(a, v[i])
                elif idx[i] == b1:
                    b = min(b, v[i])
            return (a + b) / np.float32(2.0)
        k = 0
        for i in range(m):  # branch-free: which values stay is unpredictable
            j = idx[i]
            v[k] = v[i]
            k += j == b0
        m = k  # (a linear round always leaves some out: its min and max have bins 0 and B - 1)
        r0 -= before
        r1 -= before
    s = np.sort(v[:m])
    if n % 2:
        return s[r0]
    return (s[r0] + s[r1]) / np.float32(2.0)


@numba.njit(**NJIT)
def _noise_and_deviation(img, scale, pts):
    """What ``landmark_cascade.signal_to_noise`` reads of the face's box (no pad): (the median of the |4-neighbour
    Laplacian| of the box's inner pixels, float32, each formed as numpy forms 4 c - up - down - left - right, the
    median as np.median takes it (``_middle``); the box's standard deviation, float64 from the sums of values and
    squares, as OpenCV's ``meanStdDev``). (0, -1) for a box under 8 pixels a side or off the image."""
    H, W = img.shape
    box = np.empty(4, np.int64)
    if not _face_box(H, W, scale, pts, 0, 8, box):
        return np.float32(0.0), -1.0
    x0, y0, x1, y1 = box[0], box[1], box[2], box[3]
    h = y1 - y0
    w = x1 - x0
    lap = np.empty((h - 2) * (w - 2), np.float32)
    four = np.float32(4.0)
    for y in range(1, h - 1):
        up = img[y0 + y - 1, x0:x1]
        mid = img[y0 + y, x0:x1]
        down = img[y0 + y + 1, x0:x1]
        o = lap[(y - 1) * (w - 2):y * (w - 2)]
        for x in range(1, w - 1):
            o[x - 1] = abs((((four * mid[x] - up[x]) - down[x]) - mid[x - 1]) - mid[x + 1])
    s = np.zeros(8)  # eight running sums each (see ``_energy``): s[j] adds the values at x = j, j + 8, ... of each
    ss = np.zeros(8)  # row in turn, then s[0] the row's last w % 8 (the squares in float32: numba's float() of a
    # float32 stays float32)
    # The lanes' loop vectorises when its count is not a constant (numba leaves SLP vectorisation off, and a loop
    # of 8 is unrolled to scalar code) and it reads slices by the loop index alone (a sum of indices may be
    # negative, so numba's wraparound makes it a gather); four values of each lane per pass, each added in turn.
    # Measured 2026-12-01 (Intel Xeon VM, one core, the boxes of cap12's tracked frames, medians): the sums
    # 17.2 -> 10.4 us, the same bits.
    L = min(8, w)  # = 8: the box is at least 8 wide
    w8 = w - w % L
    w32 = w8 - w8 % (4 * L)
    for y in range(y0, y1):
        r = img[y]
        for x in range(x0, x0 + w32, 4 * L):
            a0 = r[x:x + L]
            a1 = r[x + L:x + 2 * L]
            a2 = r[x + 2 * L:x + 3 * L]
            a3 = r[x + 3 * L:x + 4 * L]
            for j in range(L):
                v0 = float(a0[j])
                v1 = float(a1[j])
                v2 = float(a2[j])
                v3 = float(a3[j])
                s[j] = (((s[j] + v0) + v1) + v2) + v3
                ss[j] = (((ss[j] + v0 * v0) + v1 * v1) + v2 * v2) + v3 * v3
        for x in range(x0 + w32, x0 + w8, L):
            a0 = r[x:x + L]
            for j in range(L):
                v = float(a0[j])
                s[j] += v
                ss[j] += v * v
        for x in range(x0 + w8, x1):
            v = float(r[x])
            s[0] += v
            ss[0] += v * v
    cnt = h * w
    mean = s.sum() / cnt
    ss = ss.sum()
    return _middle(lap), math.sqrt(max(ss / cnt - mean * mean, 0.0))


@numba.njit(**NJIT)
def _fine_noise(img, scale, pts):
    """The median of |Immerkaer's mask response| over the face's box's inner pixels (no pad), float32: the mask
    [[1, -2, 1], [-2, 4, -2], [1, -2, 1]] (the 4-neighbour Laplacian's difference with the diagonal one), formed
    as (4 e - 2 (b + d + f + h)) + (a + c + g + i) for the 3 x 3 neighbourhood a..i, the median as np.median takes
    it (``_middle``). -1 for a box under 8 pixels a side or off the image (``landmark_cascade.fine_noise_sd``)."""
    H, W = img.shape
    box = np.empty(4, np.int64)
    if not _face_box(H, W, scale, pts, 0, 8, box):
        return np.float32(-1.0)
    x0, y0, x1, y1 = box[0], box[1], box[2], box[3]
    h = y1 - y0
    w = x1 - x0
    out = np.empty((h - 2) * (w - 2), np.float32)
    two = np.float32(2.0)
    four = np.float32(4.0)
    for y in range(1, h - 1):
        up = img[y0 + y - 1, x0:x1]
        mid = img[y0 + y, x0:x1]
        down = img[y0 + y + 1, x0:x1]
        o = out[(y - 1) * (w - 2):y * (w - 2)]
        for x in range(1, w - 1):
            edges = (up[x] + down[x]) + (mid[x - 1] + mid[x + 1])
            corners = (up[x - 1] + up[x + 1]) + (down[x - 1] + down[x + 1])
            o[x - 1] = abs((four * mid[x] - two * edges) + corners)
    return _middle(out)
