"""Face shape models behind one interface: parameters q -> 2D vertex positions in an image.

Both models are written as a 3D linear shape ``X = base + sum_j c_j basis_j`` seen by a weak-perspective
pose (see ``aamtrack._kernels.warp`` for the parameter vector q and the axis conventions):

- 3D (Candide-3): base = M + S sigma (sigma, the person's shape units, is fitted per person and then held),
  basis = the animation units A used for tracking; the pose has 3 rotations, scale and 2D translation.
- 2D (68 points): base = the Procrustes mean shape with z = 0, basis = PCA modes; the pose is a similarity
  (roll, scale, translation), so rx and ry stay 0 and are not searched.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from ..kernels import project, rotation
from .landmarks import similarity_fit

POSE_NAMES = ("rx", "ry", "rz", "scale", "tx", "ty")
EYE_CORNERS_MM = 89.0  # outer eye-corner distance of the average face the 3D landmarks are scaled to (ICT's neutral)
N_POSE = 6


@dataclass(frozen=True)
class ShapeModel:
    """A linear face shape with a weak-perspective pose.

    kind : "3d" or "2d"
    mean : (n_vertices, 3) float64 -- M
    shape_units : (n_shape, n_vertices, 3) float64 -- S (empty for 2D)
    basis : (n_coef, n_vertices, 3) float64 -- A (3D animation units) or PCA modes (2D)
    triangles : (n_triangles, 3) int32
    landmark_map : (68, n_vertices) float64 -- iBUG-68 landmarks as linear combinations of vertices
    shape_names, coef_names : tuple of str
    coef_lo, coef_hi : (n_coef,) float64 -- bounds of the coefficients
    shape_sd : (n_shape,) float64 -- prior spread of sigma (regularisation of the shape fit)
    """

    kind: str
    mean: np.ndarray
    shape_units: np.ndarray
    basis: np.ndarray
    triangles: np.ndarray
    landmark_map: np.ndarray
    shape_names: tuple
    coef_names: tuple
    coef_lo: np.ndarray
    coef_hi: np.ndarray
    shape_sd: np.ndarray

    @property
    def n_vertices(self) -> int:
        return self.mean.shape[0]

    @property
    def n_coef(self) -> int:
        return self.basis.shape[0]

    @property
    def n_shape(self) -> int:
        return self.shape_units.shape[0]

    @property
    def n_q(self) -> int:
        return N_POSE + self.n_coef

    @property
    def free(self) -> np.ndarray:
        """(n_free,) int64 indices of q that the search updates."""
        pose = [0, 1, 2, 3, 4, 5] if self.kind == "3d" else [2, 3, 4, 5]
        return np.array(pose + list(range(N_POSE, self.n_q)), dtype=np.int64)

    @property
    def param_names(self) -> tuple:
        return POSE_NAMES + tuple(self.coef_names)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo, hi) of q, each (n_q,) float64: free pose, bounded coefficients; 2D keeps rx = ry = 0."""
        lo = np.full(self.n_q, -np.inf)
        hi = np.full(self.n_q, np.inf)
        lo[3] = 1e-6
        lo[N_POSE:] = self.coef_lo
        hi[N_POSE:] = self.coef_hi
        if self.kind == "2d":
            lo[:2] = hi[:2] = 0.0
        return lo, hi

    def neutral(self, shape_params: np.ndarray | None = None) -> np.ndarray:
        """(n_vertices, 3) float64: M + S sigma."""
        if shape_params is None or self.n_shape == 0:
            return self.mean.copy()
        return self.mean + np.tensordot(np.asarray(shape_params, float), self.shape_units, axes=1)

    def shape3d(self, q: np.ndarray, shape_params: np.ndarray | None = None) -> np.ndarray:
        """(n_vertices, 3) float64: the deformed shape in the model frame, pose removed."""
        return self.neutral(shape_params) + np.tensordot(np.asarray(q[N_POSE:], float), self.basis, axes=1)

    def project(self, q: np.ndarray, shape_params: np.ndarray | None = None) -> np.ndarray:
        """(n_vertices, 2) float64 image pixels."""
        return project(self.neutral(shape_params), self.basis, q, np.empty((self.n_vertices, 2)))

    def landmarks(self, q: np.ndarray, shape_params: np.ndarray | None = None) -> np.ndarray:
        """(68, 2) float64 iBUG-68 landmarks in image pixels."""
        return self.landmark_map @ self.project(q, shape_params)

    def landmarks3d(self, q: np.ndarray, shape_params: np.ndarray | None = None) -> np.ndarray:
        """(68, 3) float64 iBUG-68 landmarks in the model frame (pose removed), in model units: L (M + S sigma +
        A alpha) as L M + (L S) sigma + (L A) alpha (``landmark_arrays``; the tracker makes this for every frame,
        and the 68 points are a fraction of the mesh)."""
        LM, LS, LA = self.landmark_arrays
        n = len(LM)
        out = LM.reshape(-1) + np.asarray(q[N_POSE:], float) @ LA.reshape(len(LA), -1)  # (tensordot: 2x the time)
        if shape_params is not None and self.n_shape > 0:
            out += np.asarray(shape_params, float) @ LS.reshape(len(LS), -1)
        return out.reshape(n, 3)

    @cached_property
    def landmark_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(L M (68, 3), L S (n_shape, 68, 3), L A (n_coef, 68, 3)) float64: the landmark map L applied to the mean,
        the shape units and the coefficients' basis (animation units or PCA modes), once per model."""
        L = self.landmark_map
        return L @ self.mean, np.einsum("lv,kvd->kld", L, self.shape_units), np.einsum("lv,kvd->kld", L, self.basis)

    def mm_per_unit(self) -> float:
        """Millimetres per model unit: the mean face's outer eye corners (iBUG 36, 45) put ``EYE_CORNERS_MM`` apart.
        An assumed size (weak perspective cannot see the face's real size): a person with wider-set eyes is
        reported as a larger face, not as wider-set eyes."""
        lm = self.landmark_map @ self.mean
        return EYE_CORNERS_MM / float(np.linalg.norm(lm[45] - lm[36]))

    def spreads(self) -> np.ndarray:
        """(n_q + n_shape,) float64 prior spread of each entry of the search vector [q, sigma]: 1 for the pose and
        for 2D PCA coefficients (unit = 1 sd), half the range for animation units, ``shape_sd`` for shape units."""
        out = np.ones(self.n_q + self.n_shape)
        if self.kind == "3d":
            out[N_POSE:self.n_q] = 0.5 * (self.coef_hi - self.coef_lo)
        out[self.n_q:] = self.shape_sd
        return out

    def person_view(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The same model with sigma searched too: (basis (n_coef + n_shape, n, 3), free indices, lo, hi) for
        the extended vector q_ext = [q, sigma], the neutral shape being the mean. Sigma is bounded to
        3 prior spreads."""
        basis = np.ascontiguousarray(np.concatenate([self.basis, self.shape_units]))
        free = np.r_[self.free, N_POSE + self.n_coef + np.arange(self.n_shape)].astype(np.int64)
        lo, hi = self.bounds()
        return basis, free, np.r_[lo, -3 * self.shape_sd], np.r_[hi, 3 * self.shape_sd]

    def frontal_width(self) -> float:
        """Width of the mean shape's 68 landmarks in model units (x extent): the face width that scale s
        multiplies. Vertices beyond the landmarks (a texture band or ring) do not widen it."""
        x = self.landmark_map @ self.mean[:, 0]
        return float(x.max() - x.min())


def initial_pose(sm: ShapeModel, points: np.ndarray, shape_params=None) -> np.ndarray:
    """q with a frontal similarity pose (rx = ry = 0) fitted to the points, coefficients 0."""
    frontal = sm.landmark_map @ sm.neutral(shape_params)
    dst = np.column_stack([points[:, 0], -points[:, 1]])
    s, R, t = similarity_fit(frontal[:, :2], dst)
    q = np.zeros(sm.n_q)
    q[2] = np.arctan2(R[0, 1], R[0, 0])
    q[3] = s
    q[4], q[5] = t[0], -t[1]
    return q


def rotation_matrix(rx: float, ry: float, rz: float) -> np.ndarray:
    """(3, 3) float64 R = Rz @ Ry @ Rx, the model's rotation (the kernels' own)."""
    return rotation(rx, ry, rz)
