"""How plausible 68 points are as a face: a point distribution model of the labelled shapes (Cootes et al., "Active
shape models", 1995), used to refuse fits that no labelled face resembles.

The landmark cascade and the validators judge a fit by what the image looks like around it; neither asks whether
the 68 points still make a face. A hand over the mouth pulls the mouth and chin up to the occluder's edge (cap12
with a skin-coloured ellipse over the mouth, shipped 3D model: the jaw 0.16 and the mouth 0.13 outer eye-corner
distances off, reported tracked at confidence 0.98), a face turned past about 70 degrees of yaw keeps a mesh
stuck at 45 (renders of a textured face: NME 0.12-0.17 at confidence 0.5-0.9), and a camera jump can leave a fit
half on the new place: in each the points form a shape the labelled faces do not.

``score`` is that distance: the points are taken into the model's frame by the least-squares similarity
(``mesh.landmarks.similarity_fit``), and their departure x from the mean is split into the modes' coefficients b
and the rest r:
score = sqrt((sum b_k^2 / lambda_k + |r|^2 / rho) / 136), lambda_k the modes' variances and rho the mean
variance of the directions left out, all over the training labels (so the labels themselves score about 1). The
tracker's fits are smoother than hand labels (the cascade's regressions shrink towards the usual shape) and score
lower: helen_test's 327 fits 0.52 median and 0.98 at most, cap12's 1337 tracked frames 0.76 at most, the
robustness suite's video variants 0.94 at most (measured 2026-11-29, shipped 3D model; see
``TrackerConfig.max_shape_score``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..kernels import shape_prior_score


@dataclass(frozen=True)
class ShapePrior:
    """mean (68, 2) float64: the labelled shapes' mean in the model frame (centred, outer eye corners 1 apart,
    level); modes (k, 136) float64, orthonormal rows over (x_0, y_0, x_1, ...); variances (k,) float64: the labels'
    variance along each mode; residual_variance: their mean variance along the directions the modes leave out."""

    mean: np.ndarray
    modes: np.ndarray
    variances: np.ndarray
    residual_variance: float

    @property
    def n_modes(self) -> int:
        return len(self.variances)

    def score(self, points: np.ndarray) -> float:
        """How far the shape of points (68, 2) (any pixels, any size and roll) lies from the labelled faces' (module
        docstring): about 1 for a typical label, lower for the tracker's usual fits; inf for non-finite points or
        points all in one place. One compiled call (``kernels.shape_prior_score``, about 4 us with its checks;
        numpy took 37)."""
        return shape_prior_score(points, self.mean, self.modes, self.variances, self.residual_variance)


__all__ = ["ShapePrior"]
