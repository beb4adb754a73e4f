"""Checked entry points to the compiled warp and search kernels (``aamtrack._kernels.warp``, whose docstring
states the conventions: parameter vector, axes, resampling ``scale * x + shift``).

A numba kernel compiles one specialisation per argument type: a float64 update matrix or a strided array passed
where a C-contiguous float32 one is expected would silently compile another version (seconds, once per process)
and run it. The rest of the package calls the kernels only through these wrappers: arrays the kernel only reads
are cast to the expected dtype and layout (no copy when they already are, so the hot path pays a few
microseconds per call); arrays it writes into (the search vector, outputs, scratch) must already be right, else
``TypeError`` naming the argument -- a cast copy would swallow the result.
"""

from __future__ import annotations

import numpy as np

from ._kernels import face_stats as _fs
from ._kernels import landmark_fit as _lf
from ._kernels import patches as _p
from ._kernels import shape_score as _ss
from ._kernels import warp as _k

F32, F64, I16, I32, I64 = np.float32, np.float64, np.int16, np.int32, np.int64


def _in(a, dtype, ndim: int, name: str) -> np.ndarray:
    """A read-only argument, cast to a C-contiguous ``dtype`` array of ``ndim`` dimensions."""
    a = np.ascontiguousarray(a, dtype=dtype)
    if a.ndim != ndim:
        raise ValueError(f"{name}: a {ndim}-d array expected, got shape {a.shape}")
    return a


def _out(a, dtype, ndim: int, name: str) -> np.ndarray:
    """An argument the kernel writes into: it must already be a writable C-contiguous ``dtype`` array."""
    if (not isinstance(a, np.ndarray) or a.dtype != dtype or a.ndim != ndim or not a.flags.c_contiguous
            or not a.flags.writeable):
        got = f"{a.dtype} {a.ndim}-d{'' if a.flags.c_contiguous else ' strided'}" if isinstance(a, np.ndarray) \
            else type(a).__name__
        raise TypeError(f"{name}: a writable C-contiguous {ndim}-d {np.dtype(dtype).name} array expected, got {got}")
    return a


def _patch_image(image) -> np.ndarray:
    """The grey image the descriptor kernels read (``_in``), whose pixels they index in int32."""
    shape = np.shape(image)
    if len(shape) == 2 and shape[0] * shape[1] >= 2**31 - 2 * shape[1]:  # (before any copy of it)
        raise ValueError(f"image: {shape[1]}x{shape[0]} is too large for the descriptor kernels")
    return _in(image, F32, 2, "image")


def _model(shape3d, basis, pix_vid, pix_bary):
    return (_in(shape3d, F64, 2, "shape3d"), _in(basis, F64, 3, "basis"), _in(pix_vid, I32, 2, "pix_vid"),
            _in(pix_bary, F32, 2, "pix_bary"))


def rotation(rx: float, ry: float, rz: float) -> np.ndarray:
    """(3, 3) float64 R = Rz @ Ry @ Rx."""
    R = np.empty((3, 3))
    _k._rotation(float(rx), float(ry), float(rz), R)
    return R


def project(shape3d, basis, q, out) -> np.ndarray:
    """out (n, 2) float64 <- the vertices of q in frame pixels. Returns out."""
    _k._project(_in(shape3d, F64, 2, "shape3d"), _in(basis, F64, 3, "basis"), _in(q, F64, 1, "q"),
                _out(out, F64, 2, "out"))
    return out


def normalize(tex) -> None:
    """In place: zero mean, unit standard deviation of tex (N,) float32."""
    _k._normalize(_out(tex, F32, 1, "tex"))


def compose(q, free, delta, step: float, lo, hi, out) -> np.ndarray:
    """out <- q updated by step * delta in the face's frame, clipped to [lo, hi]. Returns out."""
    _k._compose(_in(q, F64, 1, "q"), _in(free, I64, 1, "free"), _in(delta, F64, 1, "delta"), float(step),
                _in(lo, F64, 1, "lo"), _in(hi, F64, 1, "hi"), _out(out, F64, 1, "out"))
    return out


def texture(image, scale: float, shift: float, shape3d, basis, q, pix_vid, pix_bary, mode: int, verts, tex):
    """tex (C * N,) float32 <- the finished texture of the feature image (C, H, W) under q."""
    shape3d, basis, pix_vid, pix_bary = _model(shape3d, basis, pix_vid, pix_bary)
    _k._texture(_in(image, F32, 3, "image"), float(scale), float(shift), shape3d, basis, _in(q, F64, 1, "q"),
                pix_vid, pix_bary, int(mode), _out(verts, F64, 2, "verts"), _out(tex, F32, 1, "tex"))
    return tex


def residual(image, scale: float, shift: float, shape3d, basis, q, mean, app, pix_vid, pix_bary, mode: int,
             verts, tex, coef, e, *, fill: bool = False) -> float:
    """e (D,) float64 <- the projected residual at q; returns |e|^2 / D. verts, tex, coef: scratch. ``fill``:
    samples outside the image read as the mean texture (``_kernels.warp._residual``)."""
    shape3d, basis, pix_vid, pix_bary = _model(shape3d, basis, pix_vid, pix_bary)
    return _k._residual(_in(image, F32, 3, "image"), float(scale), float(shift), shape3d, basis, _in(q, F64, 1, "q"),
                        _in(mean, F32, 1, "mean"), _in(app, F32, 2, "appearance"), pix_vid, pix_bary, int(mode),
                        _out(verts, F64, 2, "verts"), _out(tex, F32, 1, "tex"), _out(coef, F64, 1, "coef"),
                        _out(e, F64, 1, "e"), bool(fill))


def residual_batch(image, scale: float, shift: float, shape3d, basis, Q, mean, app, pix_vid, pix_bary,
                   mode: int, E) -> np.ndarray:
    """E (M, D) float32 <- the projected residual at each row of Q (M, n_q). Returns E."""
    shape3d, basis, pix_vid, pix_bary = _model(shape3d, basis, pix_vid, pix_bary)
    _k._residual_batch(_in(image, F32, 3, "image"), float(scale), float(shift), shape3d, basis, _in(Q, F64, 2, "Q"),
                       _in(mean, F32, 1, "mean"), _in(app, F32, 2, "appearance"), pix_vid, pix_bary, int(mode),
                       _out(E, F32, 2, "E"))
    return E


def cascade(image, scale: float, shift: float, shape3d, basis, q, free, lo, hi, quantised, scales, b, mean, app,
            pix_vid, pix_bary, mode: int, verts, tex, coef, e, delta, *, fill: bool = False) -> float:
    """The learned update cascade on one couple, q (n_q,) float64 updated in place (``_kernels.warp._cascade``),
    its matrices as ``Couple.quantised`` gives them (quantised (n_stages, D, n_free) int16, scales (n_stages,
    n_free) float32). Returns the last stage's mean squared residual."""
    shape3d, basis, pix_vid, pix_bary = _model(shape3d, basis, pix_vid, pix_bary)
    return _k._cascade(_in(image, F32, 3, "image"), float(scale), float(shift), shape3d, basis, _out(q, F64, 1, "q"),
                       _in(free, I64, 1, "free"), _in(lo, F64, 1, "lo"), _in(hi, F64, 1, "hi"),
                       _in(quantised, I16, 3, "quantised"), _in(scales, F32, 2, "scales"),
                       _in(b, F64, 2, "cascade_bias"), _in(mean, F32, 1, "mean"),
                       _in(app, F32, 2, "appearance"), pix_vid, pix_bary, int(mode), _out(verts, F64, 2, "verts"),
                       _out(tex, F32, 1, "tex"), _out(coef, F64, 1, "coef"), _out(e, F64, 1, "e"),
                       _out(delta, F64, 1, "delta"), bool(fill))


def search(image, scale: float, shift: float, shape3d, basis, q, free, lo, hi, U, prior_step, prior, mean, app,
           pix_vid, pix_bary, mode: int, max_iter: int, tol: float, n_steps: int, delta_tol, *,
           fill: bool = False) -> tuple[int, float]:
    """The Jacobian active search on one couple, q updated in place (``_kernels.warp._search``).
    Returns (iterations, final cost)."""
    shape3d, basis, pix_vid, pix_bary = _model(shape3d, basis, pix_vid, pix_bary)
    return _k._search(_in(image, F32, 3, "image"), float(scale), float(shift), shape3d, basis, _out(q, F64, 1, "q"),
                      _in(free, I64, 1, "free"), _in(lo, F64, 1, "lo"), _in(hi, F64, 1, "hi"),
                      _in(U, F32, 2, "update_matrix"), _in(prior_step, F64, 2, "prior_step"),
                      _in(prior, F64, 1, "prior"), _in(mean, F32, 1, "mean"), _in(app, F32, 2, "appearance"),
                      pix_vid, pix_bary, int(mode), int(max_iter), float(tol), int(n_steps),
                      _in(delta_tol, F64, 1, "delta_tol"), bool(fill))


def accumulate_gradient(image, scale: float, shift: float, shape3d, basis, q0, free, steps, mean, app, pix_vid,
                        pix_bary, mode: int, G, e0) -> None:
    """G (D, n_free) float64 += one training image's residual slopes; e0 (D,) <- its residual at q0."""
    shape3d, basis, pix_vid, pix_bary = _model(shape3d, basis, pix_vid, pix_bary)
    _k._accumulate_gradient(_in(image, F32, 3, "image"), float(scale), float(shift), shape3d, basis,
                            _in(q0, F64, 1, "q0"), _in(free, I64, 1, "free"), _in(steps, F64, 2, "steps"),
                            _in(mean, F32, 1, "mean"), _in(app, F32, 2, "appearance"), pix_vid, pix_bary, int(mode),
                            _out(G, F64, 2, "G"), _out(e0, F64, 1, "e0"))


def landmark_descriptors(image, scale: float, shift: float, pts, frame, *, cells: int, cell: int, bins: int,
                         floor: float, out) -> np.ndarray:
    """out (L, cells * cells * bins) float32 <- the orientation histograms of the points pts (L, 2) (frame pixels)
    (``aamtrack._kernels.patches``) on the grey ``image`` (H, W) float32 resampled by ``scale``. ``frame`` (2, 2):
    a grid step (du, dv) lies at (du, dv) @ frame frame pixels."""
    f = np.asarray(frame, dtype=F64)
    _p._descriptors(_patch_image(image), _in(pts, F64, 2, "pts"), float(scale), float(shift), f[0, 0],
                    f[1, 0], f[0, 1], f[1, 1], int(cells), int(cell), int(bins), float(floor),
                    _out(out, F32, 2, "out"))
    return out


def landmark_training_rows(image, scale: float, shift: float, starts, truth, ref, half: float, *, cells: int,
                           cell: int, bins: int, floor: float, F, Y, frames, S=None) -> None:
    """The landmark cascade's training rows of one image's starts (m, L, 2) float64 (frame pixels), labelled truth
    (L, 2) (``aamtrack._kernels.patches._training_rows``), on the grey ``image`` (H, W) float32 resampled by
    ``scale``: F (m, L, cells * cells * bins) float32 <- the descriptors on a patch of half side ``half`` in the
    face frame of the reference shape ref (L, 2) (centred here), Y (m, 2 L) float64 <- the displacement to the
    labels in that frame, frames (m, 2, 2) float64 <- the frames, and S (m, 2 L) float32 <- the starts' own shapes
    (none: not read)."""
    ref = np.asarray(ref, dtype=F64)
    ref = ref - ref.mean(0)
    with_shape = S is not None
    S = _out(S, F32, 2, "S") if with_shape else np.empty((1, 2 * len(ref)), F32)
    _p._training_rows(_patch_image(image), float(scale), float(shift), _in(starts, F64, 3, "starts"),
                      _in(truth, F64, 2, "truth"), _in(ref, F64, 2, "ref"), float(half), int(cells), int(cell),
                      int(bins), float(floor), with_shape, _out(F, F32, 3, "F"), _out(Y, F64, 2, "Y"),
                      _out(frames, F64, 3, "frames"), S)


def landmark_cascade(image, scale: float, shift: float, pts, ref, halves, basis_mean, basis, quantised, scales,
                     expand, biases, shape_regressors, shape_from: int, *, cells: int, cell: int, bins: int,
                     floor: float, feat, shape, prior, repeats: int = 0, blank: bool = False) -> np.ndarray:
    """Run every stage of a landmark cascade (``aamtrack._kernels.patches._landmark_cascade``) on pts (L, 2)
    float64, moved in place, on the grey ``image`` (H, W) float32 resampled by ``scale``, the last stage
    ``repeats`` more times; the stages' regressors of rank r as ``LandmarkCascade.quantised`` gives them (quantised
    (K, 68 d, r) int16 and scales (K, r) float32 of their row factors, expand (K, r, 2 L) float32 the column
    factors transposed); the stages from ``shape_from`` on read the points' shape; feat
    (L, cells * cells * bins) and shape (2 L,) float32 scratch;
    prior (L, 2) float64 <- the shape term's part of the move; ``blank``: a point whose patch lies wholly outside the
    image reads the stage's mean descriptor (``_blank_outside``). Returns (L, d) float32: the last stage's
    projected descriptors."""
    return _p._landmark_cascade(_patch_image(image), float(scale), float(shift), _out(pts, F64, 2, "pts"),
                         _in(ref, F64, 2, "ref"), _in(halves, F64, 1, "halves"), _in(basis_mean, F32, 2, "basis_mean"),
                         _in(basis, F32, 3, "basis"), _in(quantised, I16, 3, "quantised"),
                         _in(scales, F32, 2, "scales"), _in(expand, F32, 3, "expand"),
                         _in(biases, F64, 2, "biases"), _in(shape_regressors, F32, 3, "shape_regressors"),
                         int(shape_from), int(repeats), int(cells), int(cell), int(bins), float(floor),
                         _out(feat, F32, 2, "feat"),
                         _out(shape, F32, 1, "shape"), _out(prior, F64, 2, "prior"), bool(blank))


def landmark_residuals_jacobian(x, free_pose, n_coef: int, fit_sigma: bool, sigma_fixed, LM, LS, LA, points,
                                width: float, lam_c: float, lam_s: float, shape_sd, r, J, *, jacobian: bool = True):
    """Residuals into r and (if ``jacobian``) their Jacobian into J (rows as r, columns as x) of the landmark fit
    (``aamtrack._kernels.landmark_fit._landmark_rj``: unknowns x, the layout of ``mesh.landmark_fit``)."""
    _lf._landmark_rj(_in(x, F64, 1, "x"), _in(free_pose, I64, 1, "free_pose"), int(n_coef), bool(fit_sigma),
                     _in(sigma_fixed, F64, 1, "sigma_fixed"), _in(LM, F64, 2, "LM"), _in(LS, F64, 3, "LS"),
                     _in(LA, F64, 3, "LA"), _in(points, F64, 2, "points"), float(width), float(lam_c), float(lam_s),
                     _in(shape_sd, F64, 1, "shape_sd"), _out(r, F64, 1, "r"), _out(J, F64, 2, "J"), bool(jacobian))


def landmark_gauss_newton_step(x, free_pose, n_coef: int, sigma_fixed, LM, LS, LA, points, width: float,
                               lam_c: float, damping: float, lo, hi, *, fit_sigma: bool = False,
                               lam_s: float = 0.0, shape_sd=None) -> None:
    """x (in place) <- one damped Gauss-Newton step of the landmark fit, sigma held at ``sigma_fixed`` or, with
    ``fit_sigma``, fitted too (x's last entries; prior weight ``lam_s``, scales ``shape_sd``)
    (``aamtrack._kernels.landmark_fit._gauss_newton_step``)."""
    if fit_sigma and (shape_sd is None or len(shape_sd) != len(sigma_fixed)):
        raise ValueError("fit_sigma needs shape_sd, one per shape unit")
    sd = np.ones(len(sigma_fixed)) if shape_sd is None else shape_sd
    _lf._gauss_newton_step(_out(x, F64, 1, "x"), _in(free_pose, I64, 1, "free_pose"), int(n_coef), bool(fit_sigma),
                           _in(sigma_fixed, F64, 1, "sigma_fixed"), _in(LM, F64, 2, "LM"), _in(LS, F64, 3, "LS"),
                           _in(LA, F64, 3, "LA"), _in(points, F64, 2, "points"), float(width), float(lam_c),
                           float(lam_s), _in(sd, F64, 1, "shape_sd"), float(damping), _in(lo, F64, 1, "lo"),
                           _in(hi, F64, 1, "hi"))


def landmark_solve(x, free_pose, n_coef: int, fit_sigma: bool, sigma_fixed, LM, LS, LA, points, width: float,
                   lam_c: float, lam_s: float, shape_sd, lo, hi, *, max_iter: int = 200, ftol: float = 1e-12,
                   xtol: float = 1e-12, gtol: float = 1e-12) -> tuple[float, int]:
    """x (in place) <- the landmark fit's minimum within [lo, hi] from x, by bounded Levenberg-Marquardt
    (``aamtrack._kernels.landmark_fit._solve_lm``). Returns (0.5 |r|^2 there, steps tried)."""
    cost, tried = _lf._solve_lm(_out(x, F64, 1, "x"), _in(free_pose, I64, 1, "free_pose"), int(n_coef),
                                bool(fit_sigma), _in(sigma_fixed, F64, 1, "sigma_fixed"), _in(LM, F64, 2, "LM"),
                                _in(LS, F64, 3, "LS"), _in(LA, F64, 3, "LA"), _in(points, F64, 2, "points"),
                                float(width), float(lam_c), float(lam_s), _in(shape_sd, F64, 1, "shape_sd"),
                                _in(lo, F64, 1, "lo"), _in(hi, F64, 1, "hi"), int(max_iter), float(ftol),
                                float(xtol), float(gtol))
    return float(cost), int(tried)


def face_sharpness(image, scale: float, pts, pad: int, k1, k2) -> float:
    """How soft the face's box in ``image`` looks (``aamtrack._kernels.face_stats._sharpness``): image (H, W)
    float32, the points pts (L, 2) in frame pixels, ``pad`` even, k1 and k2 odd Gaussian kernels (n,) float32."""
    if pad % 2:
        raise ValueError(f"pad: an even number of pixels expected, got {pad}")
    return _fs._sharpness(_in(image, F32, 2, "image"), float(scale), _in(pts, F64, 2, "pts"), int(pad),
                          _in(k1, F32, 1, "k1"), _in(k2, F32, 1, "k2"))


def face_fine_noise(image, scale: float, pts) -> float:
    """The median |Immerkaer mask response| of the face's box's inner pixels, or -1 for a box too small or off the
    image (``aamtrack._kernels.face_stats._fine_noise``): image (H, W) float32, the points pts (L, 2) in frame
    pixels."""
    return float(_fs._fine_noise(_in(image, F32, 2, "image"), float(scale), _in(pts, F64, 2, "pts")))


def face_noise_and_deviation(image, scale: float, pts) -> tuple[float, float]:
    """(median |Laplacian| of the face's box's inner pixels, the box's standard deviation), or (0, -1) for a box
    too small or off the image (``aamtrack._kernels.face_stats._noise_and_deviation``): image (H, W) float32,
    the points pts (L, 2) in frame pixels."""
    med, sd = _fs._noise_and_deviation(_in(image, F32, 2, "image"), float(scale), _in(pts, F64, 2, "pts"))
    return float(med), float(sd)


def shape_prior_score(pts, mean, modes, variances, residual_variance: float) -> float:
    """How far the points pts (L, 2) lie from a shape prior's mean (L, 2) in its modes (K, 2 L) (orthonormal rows)
    of variances (K,) and the residual's variance (``aamtrack._kernels.shape_score._shape_score``; inf for
    non-finite points or points all in one place)."""
    pts = _in(pts, F64, 2, "pts")
    return float(_ss._shape_score(pts, _in(mean, F64, 2, "mean"), _in(modes, F64, 2, "modes"),
                                  _in(variances, F64, 1, "variances"), float(residual_variance),
                                  np.empty(2 * len(pts), F64)))
