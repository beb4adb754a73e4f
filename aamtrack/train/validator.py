"""The fit validator: a logistic regression on a few statistics of a finished fit (``aamtrack.model.STAT_NAMES``)
that says how likely the fit sits on a face, learned at training time from

- positives: the training fits the cascade brought close to the labels (NME below ``good_nme``);
- negatives: fits the cascade left far off (NME above ``bad_nme``), fits displaced from the truth by a third to
  two thirds of the face width, rescaled or turned, and fits on non-face images (black, grey, uniform colour,
  noise, blurred noise, smooth ramps).

Its output is the search's confidence: it picks among the fits of several starts.

The landmark validator (``landmark_validator_fit``) gives the confidence reported per frame, and the tracker's
loss test, once the landmark cascade has moved the points: the same statistics plus the cascade's descriptors at
the final points, learned from full fits (search and cascade) of the training photos, some of them degraded
(``degraded``): positives, the fits from their Haar boxes that end near the labels; negatives, those that end
far off, fits from random boxes away from the face (hard negatives: what a false detection or a lost track
converges to), and fits on non-face images. On helen_test with the shipped 3D model (prototype), the four
statistics alone ranked the fits' errors at Spearman -0.57 and accepted a hand in a frame turned by 30 degrees
at 0.90 (NME 1.14); with the descriptors, -0.68 and 0.01.

The validator for dim faces (``Model.dim_validator``) is a second landmark validator learned the same way from
dim copies of the photos (``dim_copy``), its bias lowered (``false_accept_shift``) until it accepts held-out
negatives (``held_out_logits``) no more often than the landmark validator does.
"""

from __future__ import annotations

import numpy as np

from ..imaging import level_shift
from ..model import Validator


def _class_weights(y: np.ndarray) -> np.ndarray:
    """(n,) sample weights of labels y in {0, 1} that make each class weigh n / 2 in all."""
    return np.where(y > 0.5, 0.5 / max(y.mean(), 1e-9), 0.5 / max(1 - y.mean(), 1e-9))


def logistic_fit(X: np.ndarray, y: np.ndarray, names: tuple, *, l2: float = 1e-3, n_iter: int = 50) -> Validator:
    """Logistic regression by Newton's method (IRLS) on standardised features X (n, k), labels y (n,) in {0, 1},
    classes weighted to count equally; a small L2 penalty on the weights (not the bias)."""
    mean = X.mean(0)
    scale = X.std(0) + 1e-9
    Z = np.column_stack([(X - mean) / scale, np.ones(len(X))])
    w = np.zeros(Z.shape[1])
    cw = _class_weights(y)
    reg = np.r_[np.full(Z.shape[1] - 1, l2 * len(X)), 0.0]
    for _ in range(n_iter):
        p = 1.0 / (1.0 + np.exp(-np.clip(Z @ w, -50, 50)))
        g = Z.T @ (cw * (p - y)) + reg * w
        H = (Z * (cw * p * (1 - p))[:, None]).T @ Z + np.diag(reg + 1e-9)
        step = np.linalg.solve(H, g)
        w -= step
        if np.abs(step).max() < 1e-8:
            break
    return Validator(tuple(names), w[:-1], mean, scale, float(w[-1]))


def non_face_images(shape: tuple, rng: np.random.Generator) -> list[np.ndarray]:
    """Grey (H, W) float32 images with no face: black, mid grey, a random uniform level, uniform noise, blurred
    noise, and a smooth ramp."""
    import cv2

    H, W = shape
    yy, xx = np.mgrid[0:H, 0:W].astype(np.float32)
    ang = rng.uniform(0, 2 * np.pi)
    return [np.zeros(shape, np.float32), np.full(shape, 128, np.float32),
            np.full(shape, rng.uniform(0, 255), np.float32),
            rng.uniform(0, 255, shape).astype(np.float32),
            cv2.GaussianBlur(rng.uniform(0, 255, shape).astype(np.float32), (0, 0), rng.uniform(2, 8)),
            (128 + 100 * np.sin(ang) * (xx / W - 0.5) + 100 * np.cos(ang) * (yy / H - 0.5)).astype(np.float32)]


DEGRADATIONS = ("blur", "noise", "dark", "low_contrast")


def blurred_copy(gray: np.ndarray, eye_px: float, eye_range: tuple, rng: np.random.Generator, *,
                 scale: float = 1.0) -> np.ndarray:
    """A Gaussian blur of a grey image, sigma drawn uniformly in ``eye_range`` outer eye-corner distances
    (``eye_px`` pixels, times ``scale`` for an image resized by it), at least 0.3 px: how training makes every
    blurred copy (one draw of ``rng``)."""
    import cv2

    return cv2.GaussianBlur(gray, (0, 0), max(0.3, rng.uniform(*eye_range) * eye_px * scale))


def degraded(gray: np.ndarray, eye_px: float, rng: np.random.Generator) -> np.ndarray:
    """A copy of a grey (H, W) float32 image under one of ``DEGRADATIONS``, drawn at random: Gaussian blur of
    sigma 0.02-0.07 outer eye-corner distances (``eye_px``), Gaussian noise of sigma 5-30 grey levels, a gain of
    0.15-0.5 (dark), or contrast x0.2-0.5 about mid grey. The landmark validator learns what a face looks like
    through them too: learned on sharp photos only, it rejected 126 of 247 good fits of helen_test blurred by
    0.06 eye distances (prototype, 3D model)."""
    kind = DEGRADATIONS[rng.integers(len(DEGRADATIONS))]
    if kind == "blur":
        return blurred_copy(gray, eye_px, (0.02, 0.07), rng)
    if kind == "noise":
        return np.clip(gray + rng.normal(0.0, rng.uniform(5.0, 30.0), gray.shape), 0, 255).astype(np.float32)
    if kind == "dark":
        return (gray * rng.uniform(0.15, 0.5)).astype(np.float32)
    return (128.0 + (gray - 128.0) * rng.uniform(0.2, 0.5)).astype(np.float32)


def _shrunk(gray: np.ndarray, f: float) -> tuple[np.ndarray, np.ndarray]:
    """A grey image resized by about f (area resampling), at least 1x1: ``dim_copy``'s and ``tiny_dim_copy``'s far
    face. Returns (image, (fx, fy)): its size is rounded, so each axis has its own true factor (new size over old),
    which may differ from f by half a pixel over the width; a pixel x of the image lands at fx x + (fx - 1) / 2."""
    import cv2

    h, w = gray.shape
    size = (max(1, round(w * f)), max(1, round(h * f)))
    return cv2.resize(gray, size, interpolation=cv2.INTER_AREA), np.array([size[0] / w, size[1] / h])


def dim_copy(gray: np.ndarray, eye_px: float, rng: np.random.Generator) -> np.ndarray:
    """A copy of a grey (H, W) float32 image as a camera in a dim room makes it, for the validator of dim faces
    (``Model.dim_validator``): half the time the optics first (the face shrunk to 25-60 px between the outer eye
    corners, ``eye_px`` now, blurred there by 0.02-0.07 of that half the time, and enlarged back; or blurred as it
    is), then always the light (a gain of 0.15-0.5, or contrast x0.2-0.5 about mid grey) and the sensor's noise
    (Gaussian, sigma 3-14 grey levels: in a dim image it is most of the signal)."""
    import cv2

    out = gray
    if rng.random() < 0.5:
        f = rng.uniform(25.0, 60.0) / max(eye_px, 1.0)
        if f < 0.9 and rng.random() < 0.7:
            h, w = gray.shape
            small = _shrunk(gray, f)[0]
            if rng.random() < 0.5:
                small = blurred_copy(small, eye_px, (0.02, 0.07), rng, scale=f)
            out = cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)
        else:
            out = blurred_copy(gray, eye_px, (0.02, 0.07), rng)
    if rng.random() < 0.6:
        out = out * rng.uniform(0.15, 0.5)
    else:
        out = 128.0 + (out - 128.0) * rng.uniform(0.2, 0.5)
    return np.clip(out + rng.normal(0.0, rng.uniform(3.0, 14.0), gray.shape), 0, 255).astype(np.float32)


def tiny_dim_copy(gray: np.ndarray, box, points: np.ndarray, eye_px: float, rng: np.random.Generator, *,
                  eye_range: tuple = (10.0, 40.0), min_size: tuple = (240, 320)) -> tuple:
    """A far face in a dim room at its own scale, for the validator of dim faces: (image, box, points), the grey
    (H, W) float32 photo shrunk until its face is ``eye_range`` px between the outer eye corners (``eye_px`` now),
    then made dim at that size (``dim_copy``: its sensor noise as coarse as the face is small), with the photo's
    face box (x, y, w, h) and 68 points (OpenCV's pixels) shrunk with it. Images smaller than ``min_size`` (h, w)
    are padded right and bottom by reflection. ``dim_copy``'s small faces are enlarged back, their noise as fine
    as the photo's."""
    import cv2

    f = rng.uniform(*eye_range) / max(eye_px, 1.0)
    small, fxy = _shrunk(gray, f)
    pad_h, pad_w = max(0, min_size[0] - small.shape[0]), max(0, min_size[1] - small.shape[1])
    if pad_h or pad_w:
        small = cv2.copyMakeBorder(small, 0, pad_h, 0, pad_w, cv2.BORDER_REFLECT_101)
    shift = level_shift(fxy)  # per axis
    sbox = np.r_[np.asarray(box[:2], float) * fxy + shift, np.asarray(box[2:4], float) * fxy]
    return dim_copy(small, eye_px * f, rng), sbox, points * fxy + shift


def noise_frame(shape: tuple, rng: np.random.Generator) -> np.ndarray:
    """A grey (H, W) float32 frame of Gaussian noise, mean 20-160 and sigma 5-40 grey levels, blurred by 0.4-2.5
    px four times in five: texture where Haar's smallest-face searches find "faces" (``aamtrack fit`` fitted 5 of
    100 such stills before the validator of dim faces learned from its fits there)."""
    import cv2

    noise = rng.normal(rng.uniform(20.0, 160.0), rng.uniform(5.0, 40.0), shape)
    if rng.random() < 0.8:
        noise = cv2.GaussianBlur(noise, (0, 0), rng.uniform(0.4, 2.5))
    return np.clip(noise, 0, 255).astype(np.float32)


def textured_noise(shape: tuple, rng: np.random.Generator) -> np.ndarray:
    """A grey (H, W) float32 frame of texture with no face for the landmark validator: Gaussian noise blurred by
    3-8 px (blotches), or, one time in three, a sum of such noise at scales 1 to 32 px each weighted by its scale
    (1/f-like, clouds), stretched to a spread of 5-40 grey levels about a mean of 40-160. Haar finds "faces" in
    most such frames (19 of 20 blotchy 640x480 to 1280x720 frames), and before the landmark validator learned from
    its fits there ``aamtrack fit`` fitted 4 of 20 blotchy stills, judged clear faces (/tmp, 2026-11-30)."""
    import cv2

    if rng.random() < 1 / 3:
        im = np.zeros(shape)
        for s in (1, 2, 4, 8, 16, 32):
            im += s * cv2.GaussianBlur(rng.normal(0.0, 1.0, shape), (0, 0), s)
    else:
        im = cv2.GaussianBlur(rng.normal(0.0, 1.0, shape), (0, 0), rng.uniform(3.0, 8.0))
    im = rng.uniform(40.0, 160.0) + im / max(float(im.std()), 1e-9) * rng.uniform(5.0, 40.0)
    return np.clip(im, 0, 255).astype(np.float32)


def soft_copy(gray: np.ndarray, eye_px: float, rng: np.random.Generator) -> np.ndarray:
    """A blurred copy of a grey (H, W) float32 image for the validator of soft faces (``Model.soft_validator``):
    Gaussian blur of sigma 0.02-0.08 outer eye-corner distances (``eye_px``), the range the soft couples and soft
    landmark cascade learn from, with mild sensor noise (sigma 2-8 grey levels) a third of the time."""
    out = blurred_copy(gray, eye_px, (0.02, 0.08), rng)
    if rng.random() < 0.3:
        out = np.clip(out + rng.normal(0.0, rng.uniform(2.0, 8.0), out.shape), 0, 255)
    return out.astype(np.float32)


def occluded_copy(gray: np.ndarray, eye_px: float, rng: np.random.Generator, *, donors: list | None = None,
                  centre: np.ndarray | None = None) -> np.ndarray:
    """A copy of a grey (H, W) float32 face image with part of the face covered, for the landmark cascade to learn
    to place points it cannot see from the ones it can (robust cascaded regression learns so on COFW). One or two
    occluders, each an ellipse or a turned rectangle with axes 0.2-0.7 outer eye-corner distances (``eye_px``),
    centred anywhere within about a face's extent of ``centre`` (default: the image's centre, where the training
    crops have their faces); filled with a patch of a random image of ``donors`` (another face, hair or
    background), or a flat grey level with a gradient and noise (a hand, a sleeve, a microphone); edges
    anti-aliased. Made generic on purpose: no particular hand or object, nothing of the occlusion benchmark's."""
    import cv2

    h, w = gray.shape
    c = np.array([w / 2.0, h / 2.0]) if centre is None else np.asarray(centre, float)
    out = gray.astype(np.float32).copy()
    for _ in range(1 + int(rng.random() < 0.25)):
        mask = np.zeros((h, w), np.uint8)
        at = c + rng.uniform([-0.9, -0.8], [0.9, 1.2]) * eye_px  # x across the face, y from the brows to the chin
        axes = rng.uniform(0.2, 0.7, 2) * eye_px
        angle = rng.uniform(0.0, 180.0)
        if rng.random() < 0.6:
            cv2.ellipse(mask, (int(round(at[0])), int(round(at[1]))), (max(1, int(round(axes[0]))),
                        max(1, int(round(axes[1])))), angle, 0, 360, 255, -1)
        else:
            box = cv2.boxPoints(((float(at[0]), float(at[1])), (float(2 * axes[0]), float(2 * axes[1])), angle))
            cv2.fillConvexPoly(mask, np.round(box).astype(np.int32), 255)
        soft = cv2.GaussianBlur(mask.astype(np.float32) / 255.0, (0, 0), 1.0)
        if donors and rng.random() < 0.5:
            d = donors[rng.integers(len(donors))]
            dy, dx = rng.integers(0, max(1, d.shape[0] - h + 1)), rng.integers(0, max(1, d.shape[1] - w + 1))
            fill = cv2.resize(np.asarray(d, np.float32), (w, h)) if d.shape != (h, w) else d[dy:dy + h, dx:dx + w]
            fill = np.roll(fill, (int(rng.integers(-h // 3, h // 3)), int(rng.integers(-w // 3, w // 3))), (0, 1))
        else:
            yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
            g = rng.normal(0.0, 0.3, 2) / max(eye_px, 1.0)
            fill = rng.uniform(20.0, 235.0) * (1.0 + g[0] * (xx - at[0]) + g[1] * (yy - at[1]))
            fill = fill + rng.normal(0.0, rng.uniform(1.0, 8.0), (h, w))
        out = out * (1.0 - soft) + np.asarray(fill, np.float32) * soft
    return np.clip(out, 0, 255).astype(np.float32)


def dark_noise_image(shape: tuple, rng: np.random.Generator) -> np.ndarray:
    """A grey (H, W) float32 frame with no face for the validator of dim faces: a dark level (10-40) and sensor
    noise (sigma 3-10), as a camera with the lights out gives."""
    return np.clip(rng.uniform(10, 40) + rng.normal(0.0, rng.uniform(3, 10), shape), 0, 255).astype(np.float32)


def landmark_validator_fit(S: np.ndarray, Z: np.ndarray, y: np.ndarray, names: tuple, *,
                           l2: float = 0.04) -> Validator:
    """The landmark validator (``model.Validator`` with descriptor weights): logistic regression on the fit
    statistics S (n, k) and the descriptors at the final points Z (n, D), both standardised, classes weighted to
    count equally, an L2 penalty ``l2`` (per sample) on every weight but the bias; minimised by L-BFGS (D is
    thousands: Newton's Hessian would be D x D). The descriptors' standardisation is folded into their weights
    and the bias, so the model file keeps one weight per descriptor value."""
    from scipy.optimize import minimize

    mean_s, scale_s = S.mean(0), S.std(0) + 1e-9
    mean_z, scale_z = Z.mean(0), Z.std(0) + 1e-6
    A = np.column_stack([(S - mean_s) / scale_s, (Z - mean_z) / scale_z, np.ones(len(S))])
    cw = _class_weights(y) / len(y)
    reg = np.r_[np.full(A.shape[1] - 1, l2), 0.0]

    def loss(w):
        t = A @ w
        # log(1 + exp(t)) - y t, stably; its gradient (sigmoid(t) - y)
        f = float(cw @ (np.logaddexp(0.0, t) - y * t) + 0.5 * reg @ (w * w))
        g = A.T @ (cw * (0.5 * (1.0 + np.tanh(0.5 * t)) - y)) + reg * w
        return f, g

    w = minimize(loss, np.zeros(A.shape[1]), jac=True, method="L-BFGS-B", options={"maxiter": 500}).x
    k = S.shape[1]
    wz = w[k:-1] / scale_z
    return Validator(tuple(names), w[:k], mean_s, scale_s, float(w[-1] - wz @ mean_z), wz.astype(np.float32))


def held_out_logits(S: np.ndarray, Z: np.ndarray, y: np.ndarray, names: tuple, *, folds: int = 2,
                    l2: float = 0.04) -> np.ndarray:
    """(n,) each sample's logit (``Validator.logit``) from a landmark validator learned on the other folds: the
    samples split in ``folds`` consecutive runs (training adds them photo by photo, so a fold holds other photos).
    A validator's own training samples say little of its errors: the landmark validators accept none of their
    negatives there, and 0.8% / 1.4% of them held out (the shipped 3D model's, the general / the dim one)."""
    n = len(y)
    edges = np.linspace(0, n, folds + 1).astype(int)
    out = np.empty(n)
    for a, b in zip(edges[:-1], edges[1:]):
        rest = np.r_[0:a, b:n]
        v = landmark_validator_fit(S[rest], Z[rest], y[rest], names, l2=l2)
        out[a:b] = [v.logit(s, z) for s, z in zip(S[a:b], Z[a:b])]
    return out


def false_accept_shift(negative_logits: np.ndarray, rate: float) -> float:
    """How far to lower a validator's bias so that at most ``rate`` of these (held-out) negatives keep a logit of
    0 or more (confidence 0.5, the tracker's bar); 0 when no more than that do already."""
    v = np.sort(np.asarray(negative_logits, np.float64))[::-1]
    k = int(np.floor(rate * len(v)))  # the negatives that may stay accepted
    if k >= len(v):
        return 0.0
    return max(float(np.nextafter(v[k], np.inf)), 0.0)  # just above the first one that must not
