"""Deformation of 3D space by radial basis functions with an affine part, fitted to key point displacements.

``D(x) = sum_k w_k phi(|x - c_k|) + A^T [1, x]``: the weights ``w`` and the affine part ``A`` solve the usual
saddle-point system ``[[Phi + s I, P], [P^T, 0]] [W; A] = [Y; 0]`` so that D maps every centre ``c_k`` to its target
``y_k`` (exactly when the smoothing ``s`` is 0) and reproduces any affine map exactly. Kernels:

- ``"thin_plate"``: ``phi(r) = r``, the biharmonic (thin-plate) kernel of 3D; scale-free.
- ``"cubic"``: ``phi(r) = r^3``.
- ``"gaussian"``: ``phi(r) = exp(-(r / scale)^2)``.

Akagi et al. follow Sumner et al. 2007 (embedded deformation); embedded deformation itself is not implemented here.
Because D is linear in the targets, :func:`rbf_operator` gives the matrix that maps targets to deformed points, so
fixed centres can be fitted once and applied to many frames.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

KERNELS = ("thin_plate", "cubic", "gaussian")
_CHUNK = 2048  # rows of the evaluation matrix formed at once (bounds memory to _CHUNK * n_centres)


def _phi(r: np.ndarray, kernel: str, scale: float) -> np.ndarray:
    if kernel == "thin_plate":
        return r
    if kernel == "cubic":
        return r * r * r
    if kernel == "gaussian":
        return np.exp(-((r / scale) ** 2))
    raise ValueError(f"unknown RBF kernel {kernel!r}; expected one of {KERNELS}")


def _distances(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None, :] - 2.0 * a @ b.T
    return np.sqrt(np.maximum(d2, 0.0))


def _poly(points: np.ndarray, centre: np.ndarray, size: float) -> np.ndarray:
    return np.hstack([np.ones((len(points), 1)), (points - centre) / size])


@dataclass(frozen=True)
class RbfSystem:
    """A factored RBF system for fixed centres; fit many targets with :meth:`solve`.

    centres : (n_centres, 3) float64; kernel, scale, smoothing as in :func:`fit_rbf`.
    origin, size : normalisation of the affine part (for conditioning only).
    lu : LU factors of the (n_centres + 4)^2 system matrix.
    """

    centres: np.ndarray
    kernel: str
    scale: float
    smoothing: float
    origin: np.ndarray
    size: float
    lu: tuple

    def solve(self, targets: np.ndarray) -> np.ndarray:
        """Coefficients ``(n_centres + 4, n_cols)`` for targets ``(n_centres, n_cols)`` (e.g. 3 per frame)."""
        rhs = np.zeros((len(self.centres) + 4, targets.shape[1]))
        rhs[: len(self.centres)] = targets
        return scipy.linalg.lu_solve(self.lu, rhs)

    def basis(self, points: np.ndarray) -> np.ndarray:
        """``[Phi(points, centres), P(points)]`` : (n_points, n_centres + 4) float64."""
        points = np.asarray(points, dtype=np.float64)
        r = _distances(points, self.centres)
        return np.hstack([_phi(r, self.kernel, self.scale), _poly(points, self.origin, self.size)])

    def evaluate(self, points: np.ndarray, coefs: np.ndarray) -> np.ndarray:
        """``basis(points) @ coefs`` in row chunks : (n_points, n_cols) float64."""
        points = np.asarray(points, dtype=np.float64)
        out = np.empty((len(points), coefs.shape[1]))
        for start in range(0, len(points), _CHUNK):
            out[start : start + _CHUNK] = self.basis(points[start : start + _CHUNK]) @ coefs
        return out

    def operator(self, points: np.ndarray) -> np.ndarray:
        """(n_points, n_centres) float64 matrix L with ``D(points) = L @ targets`` for any targets."""
        eye = np.eye(len(self.centres))
        return self.evaluate(points, self.solve(eye))


def rbf_system(
    centres: np.ndarray, *, kernel: str = "thin_plate", scale: float | None = None, smoothing: float = 0.0
) -> RbfSystem:
    """Factor the RBF system for fixed centres.

    centres : (n_centres, 3) distinct points (at least 4, not all in one plane, for the affine part).
    scale : Gaussian width; default the mean distance from a centre to its nearest other centre times 3.
    smoothing : added to the diagonal of Phi (0 interpolates exactly; larger values give a smoother D).
    """
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    if centres.ndim != 2 or centres.shape[1] != 3 or len(centres) < 4:
        raise ValueError(f"centres must be (n >= 4, 3), got {centres.shape}")
    if kernel not in KERNELS:
        raise ValueError(f"unknown RBF kernel {kernel!r}; expected one of {KERNELS}")
    origin = centres.mean(0)
    size = float(np.sqrt(((centres - origin) ** 2).sum(1).mean())) or 1.0
    r = _distances(centres, centres)
    if scale is None:
        np.fill_diagonal(r, np.inf)
        scale = 3.0 * float(r.min(1).mean())
        np.fill_diagonal(r, 0.0)
    n = len(centres)
    system = np.zeros((n + 4, n + 4))
    system[:n, :n] = _phi(r, kernel, scale) + smoothing * np.eye(n)
    poly = _poly(centres, origin, size)
    system[:n, n:] = poly
    system[n:, :n] = poly.T
    lu = scipy.linalg.lu_factor(system, check_finite=False)
    return RbfSystem(centres, kernel, float(scale), float(smoothing), origin, size, lu)


@dataclass(frozen=True)
class RbfDeformation:
    """A fitted deformation D of 3D space; ``D.apply(points)`` maps (n, 3) points.

    system : the factored :class:`RbfSystem` of the centres.
    coefs : (n_centres + 4, 3) float64 -- RBF weights then the affine part.
    """

    system: RbfSystem
    coefs: np.ndarray

    def apply(self, points: np.ndarray) -> np.ndarray:
        """Deformed points : (n, 3) float64."""
        return self.system.evaluate(points, self.coefs)

    @property
    def linear(self) -> np.ndarray:
        """(3, 3) float64: the linear part of the affine term, ``D(x) ~ x @ linear + ...`` far from the centres."""
        return self.coefs[-3:] / self.system.size


def fit_rbf(
    centres: np.ndarray,
    targets: np.ndarray,
    *,
    kernel: str = "thin_plate",
    scale: float | None = None,
    smoothing: float = 0.0,
) -> RbfDeformation:
    """Fit D with ``D(centres[k]) = targets[k]``.

    centres, targets : (n_centres, 3) key point positions before and after the deformation.
    kernel : one of ``KERNELS``; scale : Gaussian width (see :func:`rbf_system`); smoothing : 0 interpolates.
    """
    targets = np.asarray(targets, dtype=np.float64)
    system = rbf_system(centres, kernel=kernel, scale=scale, smoothing=smoothing)
    if targets.shape != system.centres.shape:
        raise ValueError(f"targets {targets.shape} do not match centres {system.centres.shape}")
    return RbfDeformation(system, system.solve(targets))
