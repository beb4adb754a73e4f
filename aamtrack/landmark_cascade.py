"""The last stage of a fit: supervised descent on local descriptors at the 68 landmarks.

The AAM search (``search``) leaves the landmarks where its shape model and texture residual can take them: on
held-out faces that stops short of the labels (its linear updates underfit, and the model cannot represent every
labelled shape). This stage moves the 68 points themselves, as supervised descent does (Xiong & De la Torre,
CVPR 2013: a cascade of linear regressions from SIFT at the current points to the remaining displacement):

    x <- x + (R_k phi(I, x) + S_k s(x) + b_k) @ M(x),  k = 1..K

phi: the orientation histograms of a patch around each point (``aamtrack._kernels.patches``), sampled in the
face's frame; M(x) = s R: the similarity that takes the reference shape (centred, outer eye corners 1 apart and
level) to the current points, so R_k learns displacements in face units whatever the face's size and roll.
s(x) = (x - centroid) M^-1 - ref: the points' own shape in that frame (``shape_features``), so a stage can also
learn what a shape says of itself (where a jaw lies given the eyes, nose and mouth), which local descriptors
cannot see (S_k is zero for stages learned without it). Stage k+1 is learned on the points as stage k left them
(``aamtrack.train.landmarks``). The patches are read from the
grey image at the finest couple's resolution (the face about ``face_px`` wide), which the search has made.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from .imaging import level_shift
from .kernels import (face_fine_noise, face_noise_and_deviation, face_sharpness, landmark_cascade,
                      landmark_descriptors, landmark_training_rows)
from .mesh.landmarks import similarity_fit


@dataclass(frozen=True)
class DescriptorSpec:
    """Each point's descriptor: ``cells`` x ``cells`` cells of ``cell`` x ``cell`` samples, ``bins`` orientation
    bins over 360 degrees; ``floor`` grey levels of gradient per sample below which a patch counts as flat."""

    cells: int = 3
    cell: int = 3
    bins: int = 8
    floor: float = 1.0

    @property
    def size(self) -> int:
        return self.cells * self.cells * self.bins

    @property
    def side(self) -> int:
        return self.cells * self.cell

    @property
    def patch_floor(self) -> float:
        """``floor`` over a whole patch (the kernel's normalisation floor)."""
        return self.floor * self.side * self.side


def similarity_to(ref: np.ndarray, pts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The least-squares similarity pts ~ ref @ M + t (``mesh.landmarks.similarity_fit``) as (M (2, 2) = s R,
    t (2,))."""
    s, R, t = similarity_fit(ref, pts)
    return s * R, t


def descriptors(spec: DescriptorSpec, image: np.ndarray, scale: float, pts: np.ndarray, half: float, M: np.ndarray,
                out: np.ndarray | None = None, gain: float = 1.0) -> np.ndarray:
    """(68 * spec.size,) float32 descriptors of pts (68, 2) (frame pixels) on ``image``, the grey frame resampled
    by ``scale``, on a patch of half side ``half`` in the face frame M (``similarity_to``), read as if ``image``
    were multiplied by ``gain`` (``descriptor_gain``: the floor divided by it, which is the same and copies
    nothing)."""
    if out is None:
        out = np.empty((len(pts), spec.size), np.float32)
    step = 2.0 * half / (spec.side + 1)
    landmark_descriptors(image, scale, level_shift(scale), pts, step * M, cells=spec.cells, cell=spec.cell,
                         bins=spec.bins, floor=spec.patch_floor / gain, out=out)
    return out.reshape(-1)


def training_rows(spec: DescriptorSpec, image: np.ndarray, scale: float, starts: np.ndarray, truth: np.ndarray,
                  ref: np.ndarray, half: float, *, with_shape: bool) -> tuple:
    """One image's rows for learning a stage, in one compiled call (``kernels.landmark_training_rows``): for starts
    (m, 68, 2) (frame pixels) with labels truth (68, 2), (F (m, 68 * spec.size) float32 descriptors as
    ``descriptors`` reads them in the frame M = ``similarity_to(ref, start)``, Y (m, 136) the displacement to the
    labels (truth - start) M^-1, frames (m, 2, 2) the M, S (m, 136) float32 ``shape_features`` or None)."""
    m = len(starts)
    F = np.empty((m, len(ref), spec.size), np.float32)
    Y = np.empty((m, 2 * len(ref)))
    frames = np.empty((m, 2, 2))
    S = np.empty((m, 2 * len(ref)), np.float32) if with_shape else None
    landmark_training_rows(image, scale, level_shift(scale), starts, truth, ref, half, cells=spec.cells,
                           cell=spec.cell, bins=spec.bins, floor=spec.patch_floor, F=F, Y=Y, frames=frames, S=S)
    return F.reshape(m, -1), Y, frames, S


def shape_features(ref: np.ndarray, pts: np.ndarray, M: np.ndarray) -> np.ndarray:
    """(2 L,) the points pts (L, 2) in the reference frame, as their departure from ref (L, 2): (pts - centroid)
    M^-1 - ref, (x_0, y_0, x_1, ...); M the similarity of ``similarity_to(ref, pts)``."""
    return ((pts - pts.mean(0)) @ np.linalg.inv(M) - ref).reshape(-1)


SHARPNESS_SIGMAS = (1.5, 3.0)  # pixels of the image the cascade reads (the face about its finest couple's width)


def _gaussian(sigma: float) -> np.ndarray:
    """(n,) float32: the kernel OpenCV's ``GaussianBlur`` takes for a float32 image and ``sigma`` (n = round(8 sigma
    + 1), odd)."""
    n = int(round(sigma * 8 + 1)) | 1
    return cv2.getGaussianKernel(n, sigma, cv2.CV_32F).ravel()


_S1, _S2 = SHARPNESS_SIGMAS
_SHARPNESS_PAD = 2 * int(math.ceil(_S2))  # >= 2 sigma, and even: the half-size margin is pad / 2 whole pixels
_SHARPNESS_KERNELS = (_gaussian(0.5 * _S1), _gaussian(0.5 * math.sqrt(_S2 * _S2 - _S1 * _S1)))


def sharpness(image: np.ndarray, scale: float, pts: np.ndarray) -> float:
    """How soft the face looks, 0..1: the gradient energy of the image blurred by ``SHARPNESS_SIGMAS[1]`` pixels
    over that of it blurred by ``SHARPNESS_SIGMAS[0]``, on the box of the points pts (68, 2) (frame pixels) in
    ``image`` (the grey frame resampled by ``scale``: the face at the finest couple's size, so sharp and soft mean
    the same for every face size), computed at half that resolution in one compiled call
    (``kernels.face_sharpness``). Independent of contrast, and of noise: both blurs are wider than a pixel (a
    ratio against the raw image, tried first, called blurred faces with sensor noise sharp). helen_test at that
    resolution (/tmp harness, 2026-11-26): sharp faces 0.35-0.53 (5th-95th percentile), with Gaussian noise of 12
    grey levels 0.34-0.52; blurred by 0.06 eye distances 0.77-0.86, with that noise 0.63-0.80. 0 for a flat box
    or one off the image. What picks the soft landmark cascade (``Model.soft_cascade``)."""
    return face_sharpness(image, scale, pts, _SHARPNESS_PAD, *_SHARPNESS_KERNELS)


#: ``descriptor_gain``: a face whose grey levels' standard deviation on its points' box is under GAIN_TARGET_SD
#: (helen_train's faces at the finest couple's resolution, 5th / 50th / 95th percentile: 25 / 51 / 73) is read as
#: if brightened to it, at most GAIN_MAX times, and never so far that the image's noise (``noise_sd``) passes
#: GAIN_NOISE_CAP grey levels (helen_train: 0.6 / 1.4 / 2.8): the gain may not make a noisy face noisier than
#: the photos the cascade learned from.
GAIN_TARGET_SD = 25.0
GAIN_MAX = 4.0
GAIN_NOISE_CAP = 3.0


def noise_sd(median_laplacian: float) -> float:
    """The image noise's standard deviation from the median absolute Laplacian (``face_noise_and_deviation``) of
    Gaussian noise: the 4-neighbour Laplacian of noise of sd s has sd s sqrt(20), and |N(0, 1)|'s median is
    0.6745."""
    return median_laplacian / (0.6745 * math.sqrt(20.0))


def descriptor_gain(image: np.ndarray, scale: float, pts: np.ndarray) -> float:
    """The gain (>= 1) the landmark cascade reads a low-contrast face's descriptors with (``LandmarkCascade.run``,
    ``GAIN_TARGET_SD``, ``GAIN_MAX``, ``GAIN_NOISE_CAP``), on the box of the points pts (68, 2) (frame pixels)
    in ``image`` (the grey frame resampled by ``scale``); 1 for a box under 8 pixels a side or off the image.

    The descriptors are normalised with a floor (``DescriptorSpec.floor`` grey levels of gradient per sample),
    so that flat patches stay near zero; on a dark or low-contrast face (a stage, an evening webcam) most of the
    face's gradients fall near that floor, every descriptor shrinks, and the cascade's regressors, learned on
    photos of ordinary contrast, move the points by less and by their biases: the jaw, whose edges are the
    weakest, drew up (cap12 under the robustness suite's dark_cast, jaw points' mean offset 0.022 eye distances
    upwards against 0.006 clean). A gain leaves a clear face's descriptors as they were (the floor is a small part
    of their norm) and a noisy face's too (its noise, not the floor, is what the floor was for).
    Run time only, so far: training reads the descriptors as they are (the shipped models were learned so; most
    training photos are above the target, but the validators' dark and flat copies are not: reading them with the
    gain at the next retraining is to do, and changes the synthetic models the tests train)."""
    return _gain(*face_noise_and_deviation(image, scale, pts))


def _gain(median_laplacian: float, sd: float) -> float:
    """``descriptor_gain`` from the box's ``face_noise_and_deviation``."""
    if sd <= 0.0:
        return 1.0
    return max(1.0, min(GAIN_MAX, GAIN_TARGET_SD / sd, GAIN_NOISE_CAP / max(noise_sd(median_laplacian), 1e-6)))


def fine_noise_sd(image: np.ndarray, scale: float, pts: np.ndarray) -> float:
    """The image noise's standard deviation on the box of the points pts (68, 2) (frame pixels) in ``image`` (the
    grey frame resampled by ``scale``), from the median absolute response to Immerkaer's mask (J. Immerkaer, "Fast
    noise variance estimation", CVIU 1996: the difference of two Laplacians, blind to the plane and much of the
    curvature a Laplacian reads; on noise of sd s its response has sd 6 s) (``kernels.face_fine_noise``, one
    compiled call); -1 for a box under 8 pixels a side or off the image. Where ``noise_sd`` reads a small face's
    own detail as noise, this reads less of it: measured on the faces the tracker fitted (/tmp harness,
    2026-11-30, median over frames, the added noise's grey sd in brackets), cap12 clean 0.49 (Laplacian 0.99),
    ``benchmarks/hard_clips.py``'s hard7 (16 px between the eyes, 2.0) 3.5 (5.3), hard5 (22 px, 2.7) 2.7 (3.3),
    the robustness suite's noise (16.7) 16.6 (16.6) and dim_small (5.3) 5.4 (5.3); helen_train's faces at the
    cascade's resolution, 5th / 50th / 95th percentile 0.24 / 0.59 / 1.55 (Laplacian 0.72 / 1.35 / 2.85).
    What decides whether the cascade reads a face smoothed (``descriptor_view``); ``signal_to_noise`` keeps the
    Laplacian's estimate, on which the models' thresholds for dim faces were learned."""
    med = face_fine_noise(image, scale, pts)
    return -1.0 if med < 0 else med / (0.6745 * 6.0)


def descriptor_view(image: np.ndarray, scale: float, pts: np.ndarray) -> tuple[np.ndarray, float]:
    """(the image, gain) the landmark cascade reads the face at the points pts (68, 2) (frame pixels) on, in
    ``image`` (the grey frame resampled by ``scale``): ``image`` and ``descriptor_gain`` for a face whose noise
    (``fine_noise_sd``) is at most ``GAIN_NOISE_CAP`` grey levels; for a noisier one, ``image`` smoothed by the
    Gaussian that takes white noise of that sd down to the cap (sigma = noise / (2 sqrt(pi) cap) pixels: Gaussian
    smoothing divides white noise's sd by 2 sqrt(pi) sigma), read with the gain its smoothed contrast asks for
    (``GAIN_TARGET_SD`` over the smoothed box's sd, at most ``GAIN_MAX``; what noise is left is low-frequency,
    which the descriptors' gradients barely read). Without it a noisy face's descriptors read the noise's
    gradients: on the robustness suite's noise variant (sensor noise of 25 grey levels on each channel) the
    cascade's points were 0.0250 eye distances off against 0.0215 with it (``benchmarks/README.md``,
    "robustness.py"). For the cascade only: the landmark validators, learned on faces as they are, judge the
    points from the unsmoothed image's descriptors (``LandmarkCascade.read``, in ``Searcher.refine_landmarks``):
    fed the smoothed ones, they accepted fits of smoothed noise in noisy stills (two at NME 1.1-1.2). A smoothed
    image is a new array (the level itself is left as it is). The noise decides, never the contrast alone: a dim
    face without noise keeps its detail and gets the gain. Cost: a face whose Laplacian estimate (``noise_sd``,
    which reads at least as much as the fine one but for chance: white noise reads alike in both, detail more in
    the Laplacian) is under the cap pays what ``descriptor_gain`` alone costs; a noisier one the fine estimate
    too (about 45 us) and, if smoothed, its level's blur (about 80 us for a 640 x 480 frame's face; /tmp harness,
    2026-11-30, medians on the sample clip)."""
    med, sd = face_noise_and_deviation(image, scale, pts)
    if noise_sd(med) <= GAIN_NOISE_CAP or (noise := fine_noise_sd(image, scale, pts)) <= GAIN_NOISE_CAP:
        return image, _gain(med, sd)
    sigma = noise / (2.0 * math.sqrt(math.pi) * GAIN_NOISE_CAP)
    smoothed = cv2.GaussianBlur(image, (0, 0), sigma, borderType=cv2.BORDER_REPLICATE)
    sd = face_noise_and_deviation(smoothed, scale, pts)[1]
    return smoothed, max(1.0, min(GAIN_MAX, GAIN_TARGET_SD / max(sd, 1e-6)))


def signal_to_noise(image: np.ndarray, scale: float, pts: np.ndarray) -> float:
    """The face's contrast over the image's noise, on the box of the points pts (68, 2) (frame pixels) in ``image``
    (the grey frame resampled by ``scale``, as ``sharpness`` reads it): the box's standard deviation over
    (0.5 grey levels + the noise's standard deviation, estimated as the median absolute Laplacian / 0.6745 /
    sqrt(20), which edges barely move) (``kernels.face_noise_and_deviation``, one compiled call).
    helen_test at the 3D model's finest couple (5th-95th percentile): clean 13-44, under the robustness suite's
    other variants at least 4.8 (noise of 25 grey levels 4.8-15), made small and dim (dim_small) 1.7-3.7; cap12,
    whose face is smaller in its frame, under noise of 25 grey levels 1.6-1.9. 0 for a box under 8 pixels a side
    or off the image. What picks the model's validator for dim, noisy faces (``Model.validator_for``)."""
    med, sd = face_noise_and_deviation(image, scale, pts)
    if sd < 0:
        return 0.0
    return sd / (noise_sd(med) + 0.5)


def quantise_rows(R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Regressors R (..., m, n) float32 as the compiled cascade reads them: (Q (..., n, m) int16, the transpose
    of R over per-row scales, s (..., m) float32 = each row's largest |weight| / 32767), R ~ s Q^T to within
    half a step of the row's scale (1.5e-5 of its largest weight). Half the bytes: a tracked frame reads every
    stage's regressors (7 MB of float32 for the shipped models), which leave the caches between frames, and
    reading them was most of the stages' products (measured 2026-11-28, 3D, cap12 at 640x480, in place)."""
    R = np.asarray(R, np.float32)
    s = np.abs(R).max(-1) / np.float32(32767.0)
    s = np.where(s > 0, s, np.float32(1.0)).astype(np.float32)
    Q = np.rint(R / s[..., None]).astype(np.int16)
    return np.ascontiguousarray(np.swapaxes(Q, -1, -2)), s


def factorise(R: np.ndarray, rank: int) -> tuple[np.ndarray, np.ndarray]:
    """Regressors R (K, m, n) as their best rank-``rank`` approximations (Frobenius), R_k ~ U_k W_k: (Ut (K, r, m)
    float32, U_k transposed, orthonormal columns: the leading eigenvectors of R_k R_k^T; W (K, r, n) float32 =
    U_k^T R_k), r = min(rank, m) (m when rank <= 0: exact up to rounding). Eigenvectors of the m x m product
    rather than an SVD of R: the same subspace in a tenth of the time (a few ms a stage at load)."""
    R = np.asarray(R, np.float64)
    K, m, _ = R.shape
    r = m if rank <= 0 else min(int(rank), m)
    Ut = np.empty((K, r, m), np.float32)
    W = np.empty((K, r, R.shape[2]), np.float32)
    for k in range(K):
        _, vecs = np.linalg.eigh(R[k] @ R[k].T)
        top = vecs[:, ::-1][:, :r]  # eigh sorts ascending
        Ut[k] = top.T
        W[k] = top.T @ R[k]
    return Ut, W


def project_descriptors(phi: np.ndarray, mean: np.ndarray, basis: np.ndarray) -> np.ndarray:
    """(..., n_points d) each point's descriptor of phi (..., n_points * p) projected on a basis (p, d) about its
    mean (p,). One matrix product over all the points (a stack of small ones per row took three times as long)."""
    z = (phi.reshape(-1, len(mean)) - mean) @ basis
    return z.reshape(*phi.shape[:-1], -1)


def outside(image: np.ndarray, scale: float, pts: np.ndarray, half: float, M: np.ndarray) -> np.ndarray:
    """(n_points,) bool: which points pts (n, 2) (frame pixels) have their patch (half side ``half`` in the face
    frame M, ``similarity_to``) wholly outside ``image``, the frame resampled by ``scale``: their projected
    descriptors are set to 0, the stage's mean, as the compiled cascade does (``_kernels.patches._blank_outside``)."""
    x = scale * np.asarray(pts, np.float64) + level_shift(scale)
    reach = half * float(np.hypot(M[0, 0], M[1, 0])) * scale
    H, W = image.shape[:2]
    return (x[:, 0] < -reach) | (x[:, 1] < -reach) | (x[:, 0] > W - 1 + reach) | (x[:, 1] > H - 1 + reach)


@dataclass(frozen=True)
class LandmarkCascade:
    """ref (68, 2) float64: the reference shape (centred, outer eye corners 1 apart, level). halves (K,): each
    stage's patch half side (outer eye-corner distances). basis_mean (K, spec.size) and basis (K, spec.size, d)
    float32: each stage's principal components of a point's descriptor (the regressors read d numbers per point:
    a quarter to a half of the weights, which are read from memory every frame). regressors (K, 136, 68 d),
    shape_regressors (K, 136, 136) float32 (``shape_features``; zero for a stage that does not read the shape) and
    biases (K, 136) float64: stage k's displacement (x_0, y_0, x_1, ...) in reference units. repeats: how many more
    times the last stage runs, each on the points as the one before left them: a ridge-regressed stage moves the
    points only part of the way (its shrinkage), and the smallest patch's stage applied again goes on towards the
    labels (measured 2026-11-28, shipped models, no retraining: helen_test mean NME 3D 0.0347 -> 0.0341 -> 0.0339
    with 0 / 1 / 2 repeats, cap12 against dlib 0.0305 -> 0.0288 -> 0.0275; 2D with 1: 0.0352 -> 0.0347, 0.0251 ->
    0.0240), where a fifth stage learned on the fourth's output at the same patch measured no better. Not on a dim,
    noisy face (``Searcher.refine_landmarks``): there the repeats follow the noise (robustness, cap12 dim_small
    0.0327 -> 0.0358, 95.3% -> 94.4% tracked).
    rank: the compiled ``run`` applies each stage's regressor as its best rank-``rank`` approximation
    (``factorise``; 0: the full one), made at first use, not stored in the model file (which keeps the full
    regressors). A regressor's 136 outputs move 68 points, which mostly move together: the shipped models keep 99%
    of each regressor's squared norm in 46-68 dimensions. Rank 80 reads 59% of the weights of the full product,
    which a tracked frame reads six times from memory. Measured 2026-11-28 (3D, shipped model, no retraining,
    ``benchmarks/accuracy.py``): helen_test mean NME 0.0339 full / 0.0339 rank 96 / 0.0339 rank 64 / 0.0341 rank
    48 / 0.0349 rank 32, cap12 against dlib 0.0275 / 0.0275 / 0.0276 / 0.0278 / 0.0284; ``benchmarks/hard_clips.py``
    as at full rank from rank 80 up, but at 64 hard2's false detection (frame 215, pre-existing) was followed by
    five wrong frames accepted as dim tracked ones (confidence 0.21-0.35 against 0.09-0.21 at full rank: NME
    0.0399 -> 0.0595). An approximation, not the same result: from the same starts on the sample clip's faces the
    points lie a mean 0.005 outer eye-corner distances (0.3 px) from the full-rank cascade's at rank 80, 0.007 at
    64, 0.012 at 32 (``tests/test_shipped_models.py`` holds it under 0.01)."""

    ref: np.ndarray
    spec: DescriptorSpec
    halves: tuple
    basis_mean: np.ndarray
    basis: np.ndarray
    regressors: np.ndarray
    biases: np.ndarray
    shape_regressors: np.ndarray
    repeats: int = 0
    rank: int = 80

    @property
    def n_stages(self) -> int:
        return len(self.halves)

    @cached_property
    def factors(self) -> tuple[np.ndarray, np.ndarray]:
        """(Ut (K, r, 136), W (K, r, 68 d)) float32: the regressors of rank ``rank`` (``factorise``)."""
        return factorise(self.regressors, self.rank)

    @cached_property
    def applied(self) -> np.ndarray:
        """(K, 136, 68 d) float32: the regressors as ``run`` applies them (of rank ``rank``, before quantising)."""
        Ut, W = self.factors
        return np.matmul(np.swapaxes(Ut, 1, 2).astype(np.float64), W).astype(np.float32)

    @cached_property
    def quantised(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The regressors as the compiled ``run`` reads them: their row factors W quantised (``quantise_rows``)
        and the column factors U transposed (``factors``)."""
        Ut, W = self.factors
        return (*quantise_rows(W), Ut)

    @cached_property
    def shape_from(self) -> int:
        """The first stage that reads the points' shape (``n_stages`` when none does)."""
        used = np.flatnonzero(np.abs(self.shape_regressors).reshape(self.n_stages, -1).max(1) > 0)
        return int(used[0]) if len(used) else self.n_stages

    def apply(self, image: np.ndarray, scale: float, pts: np.ndarray, first: int = 0) -> np.ndarray:
        """(68, 2) the points pts (68, 2) (frame pixels) moved by stages ``first``.. (all by default, the last one
        ``repeats`` more times), on ``image`` (the grey frame resampled by ``scale``); ``run``'s points."""
        return self.run(image, scale, pts, first)[0]

    def run(self, image: np.ndarray, scale: float, pts: np.ndarray, first: int = 0, repeats: int | None = None,
            gain: float = 1.0, blank: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``apply`` in one compiled call (``kernels.landmark_cascade``; ``run_slow`` is the same in numpy steps),
        the last stage ``repeats`` more times (default: the cascade's own ``repeats``), the descriptors read as if
        the image were multiplied by ``gain`` (``descriptor_gain``); ``blank``: a point whose patch lies wholly
        outside the image reads the stage's mean descriptor (``outside``: where the image's edge is the frame's,
        ``Levels.edge``; off by default, as training reads its photos).
        Returns (points (68, 2), z (68 d,) float32, prior (68, 2)): z the last stage's projected descriptors, read
        at the points just before its update (within about 0.01 eye distances of the final ones), what the
        landmark validator weighs (``model.Validator``): what the face looks like around each point, at no extra
        cost; prior the part of the points' move that the stages' shape term made (S_k s(x), in pixels)."""
        sp = self.spec
        x = np.array(pts, dtype=np.float64)
        k = slice(first, None)
        prior = np.empty_like(x)
        Q, s, Ut = self.quantised
        z = landmark_cascade(image, scale, level_shift(scale), x, self.ref, np.asarray(self.halves[k], np.float64),
                             self.basis_mean[k], self.basis[k], Q[k], s[k], Ut[k], self.biases[k],
                             self.shape_regressors[k], max(0, self.shape_from - first), cells=sp.cells,
                             cell=sp.cell, bins=sp.bins, floor=sp.patch_floor / gain,
                             feat=np.empty((len(x), sp.size), np.float32), shape=np.empty(2 * len(x), np.float32),
                             prior=prior, repeats=self.repeats if repeats is None else repeats, blank=blank)
        return x, z.reshape(-1), prior

    def read(self, image: np.ndarray, scale: float, pts: np.ndarray, gain: float = 1.0,
             blank: bool = False) -> np.ndarray:
        """(68 d,) float32: the last stage's projected descriptors at the points pts (68, 2) (frame pixels) on
        ``image`` (the grey frame resampled by ``scale``), read as if it were multiplied by ``gain``: ``run``'s z
        read at given points (``blank`` as ``run``'s)."""
        k = self.n_stages - 1
        M, _ = similarity_to(self.ref, pts)
        z = project_descriptors(descriptors(self.spec, image, scale, pts, self.halves[k], M, gain=gain),
                                self.basis_mean[k], self.basis[k]).reshape(len(pts), -1)
        if blank:
            z[outside(image, scale, pts, self.halves[k], M)] = 0.0
        return z.reshape(-1)

    def apply_slow(self, image: np.ndarray, scale: float, pts: np.ndarray) -> np.ndarray:
        """``apply`` stage by stage in numpy (what training does; the compiled ``apply`` is tested against it)."""
        return self.run_slow(image, scale, pts)[0]

    def run_slow(self, image: np.ndarray, scale: float, pts: np.ndarray,
                 gain: float = 1.0, blank: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``run`` (all stages, the last one ``repeats`` more times) stage by stage in numpy (the regressors of
        rank ``rank``, unquantised)."""
        x = np.array(pts, dtype=np.float64)
        buf = np.empty((len(x), self.spec.size), np.float32)
        prior = np.zeros_like(x)
        z = None
        n = self.n_stages
        for k in [*range(n), *[n - 1] * (self.repeats if n else 0)]:
            half = self.halves[k]
            M, _ = similarity_to(self.ref, x)
            z = project_descriptors(descriptors(self.spec, image, scale, x, half, M, buf, gain), self.basis_mean[k],
                                    self.basis[k])
            if blank:
                z.reshape(len(x), -1)[outside(image, scale, x, half, M)] = 0.0  # (a view: z stays flat)
            ds = (self.shape_regressors[k] @ shape_features(self.ref, x, M)).reshape(-1, 2) @ M
            prior += ds
            x += (self.applied[k] @ z + self.biases[k]).reshape(-1, 2) @ M + ds
        return x, z.reshape(-1), prior
