"""Key point sampling and refinement for facial tracking (Akagi et al., "A facial tracking and transfer method with a
key point refinement"). The deformation ``D^t`` (an RBF of 3D space, :mod:`.rbf`) maps the neutral face F^0 close
to frame F^t. Starting from the 68 landmarks (given in every frame by a landmark detector), each round:

1. computes ``D^t(F^0)`` for every frame from the current key points;
2. samples candidate key points at random from F^0;
3. keeps those whose motion correlates with the motion of their neighbourhood above the mean; the motion is
   ``D^t(F^0)`` moved along the scans' normals onto the scans (:func:`_observed_motion`), so that motion the
   current key points do not see yet (a cheek puff between landmarks) draws candidates;
4. refines the key points' positions in every frame t by non-rigid GMM registration (:mod:`.gmm`) of the thinned
   F^0 to the scan F^t (the landmarks stay where the detector put them), then moves each key point along the
   scan's normal onto a robust local quadric of the scan where that is well fixed (:func:`_fit_heights`) --
   except where the prior already lies on the scan (``gate``);
   then the normal parts of the key points' offsets from their prior are taken as one smooth field in 3D
   (``field``: :func:`_smooth_offsets`; where neighbouring normals differ, their normal moves give the moves along
   the surface that a single key point's scan cannot); then the key points' offsets from their prior are smoothed over time (``temporal``: the scans sample the
   surface anew in every frame, so their sampling noise is independent between frames, the motion is not);
5. repeats while the error falls by more than ``min_improvement`` (1%).

Step 4 in detail (our choices; the paper names only the registration method). A surface says where the skin is
along its normal, not where it slid along itself. So the registration's steps are point-to-plane (``gmm.pull``:
each moving point moves along its normal only), coarse to fine, first as a smooth field of a few nodes
(``nodes``), then key point by key point, and the key points are pulled (``gmm.anchor``) to a prior that places
them along the surface: a thin-plate RBF through the landmarks and through anchors far from them (beyond
``rigid_beyond`` spacings: the skull, the neck) that follow the head's rigid motion, estimated per frame by robust
point-to-plane ICP of F^0 to the scan (:func:`_rigid_motion`). The prior comes from the landmarks
and the rigid motion only, never from a previous round's registration, so that sliding cannot add up over rounds.
Measured on ICT sequences in benchmarks/refine.py (with and without the registration: ``registration=False``).

Only the landmarks are assumed to correspond between frames: the scans are point clouds (any subset of the face,
any order), and the error that steers the loop is the mean point-to-plane distance from ``D^t(F^0)`` to the
scans, truncated so that template parts a scan does not cover count the same wherever they are, over the template
points each scan covers at the start (so that the parts no scan covers do not dilute the relative gain).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Callable, Sequence

import numpy as np
import scipy.ndimage
import scipy.sparse
import scipy.sparse.linalg
from scipy.spatial import cKDTree

from .gmm import GmmConfig, _farthest_points, register, smooth_basis, thin
from .rbf import rbf_system
from .scan_surface import _fit_heights, _project, _rigid_motion, _Surface

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SamplerConfig:
    """Options of the key point sampler.

    n_candidates : candidates drawn per round; max_rounds : upper bound on rounds;
    min_improvement : stop when the error falls by less than this fraction in a round;
    neighbour_radius : radius of a key point's neighbourhood, in units of the mesh spacing;
    thin_cell : F^0 and the scans are thinned to one point per cube of this side (in units of the mesh spacing)
    before registration, which evens out the point density and bounds the cost;
    kernel, smoothing : of the RBF deformation; gmm : registration options (one scale per entry of ``nodes``);
    nodes : per scale, the number of nodes of the smooth field the free key points move by (0: each moves on its
    own), None: always on their own; whole : register all of F^0 (else only the key points' neighbourhoods);
    rigid_beyond, n_rigid_anchors : the prior is a thin-plate RBF through the landmarks and through this many
    points of F^0 (farthest point sampling) farther than ``rigid_beyond`` (thinned) spacings from every landmark,
    which follow the head's rigid motion; registration : False
    leaves the key points at their prior (an ablation: what the GMM registration adds); project : after the
    registration, move each free key point along the scan's normal onto the scan (:func:`_project`); gate : a free
    key point whose prior lies within this many (thinned) spacings of the scan's tangent plane stays at its prior:
    the scan does not contradict it there, and registration and projection would only add drift along the surface
    (seen on the ears); 0 turns it off. The default, 0.01 (0.05 mm on the ICT benchmark's thinned spacing, about
    twice the quadric fit's own noise at 0.05 mm scan noise), holds about 85% of priors lying exactly on such a scan;
    0.02 held nearly all and, holding them firmly (``field_anchor_gated``), kept the smooth field from moving them
    along the surface with their neighbours: on identity 1 of benchmarks/refine.py, 0.02 / 0.01 / 0.005 gave
    0.280 / 0.277 / 0.276 mm far from the landmarks; 0 fails the synthetic cheek-puff test; temporal : the key points' offsets from their prior (what step 4 adds) are
    smoothed over the frames by a Gaussian of this standard deviation in frames (0: off; needs more than two
    frames): each scan is a new sample of the surface with new noise, the skin's motion is smooth in time;
    field, field_anchor : after the projection and the gate, the free key points' offsets from their prior are
    replaced by one smooth field in 3D that keeps their parts along the scan's normal (:func:`_smooth_offsets`:
    ``field`` weighs its bending energy, 0 turns it off; ``field_anchor`` holds what neither the normals nor the
    smoothness fix at the prior; ``field_anchor_gated`` does so for the key points the gate kept at their prior,
    which the field would otherwise drag along with their neighbours); fit_neighbours, fit_max_sigma : the
    projection moves each free key point onto a robust local quadric of its ``fit_neighbours`` nearest scan points
    (:func:`_fit_heights`), only where the fitted height's standard error is below ``fit_max_sigma`` scan spacings
    (median distance between neighbouring scan points) and the key point is not at the scan's border; the others
    keep their place and give the smooth field no normal part (it moves them with their neighbours); the gate
    then uses the same fit at the prior; fit_neighbours = 0: tangent planes of the nearest scan points instead
    (:func:`_project`, the former way); seed : of the sampling.
    """

    n_candidates: int = 300
    max_rounds: int = 5
    min_improvement: float = 0.01
    neighbour_radius: float = 4.0
    thin_cell: float = 2.75
    kernel: str = "thin_plate"
    smoothing: float = 0.0
    gmm: GmmConfig = field(default_factory=lambda: GmmConfig(scales=(4.0, 2.0, 1.0), anchor=2.0))
    nodes: tuple | None = (12, 48, 0)
    whole: bool = True
    rigid_beyond: float = 8.0
    n_rigid_anchors: int = 150
    registration: bool = True
    project: bool = True
    gate: float = 0.01
    temporal: float = 2.0
    field: float = 0.01
    field_anchor: float = 0.03
    field_anchor_gated: float = 1.0
    fit_neighbours: int = 16
    fit_max_sigma: float = 0.037
    fit_tilt: bool = True
    seed: int = 0


@dataclass(frozen=True)
class KeyPoints:
    """Result of the sampler.

    index : (n_keys,) int64 vertex indices into F^0; the first ``n_fixed`` are the given landmarks.
    positions : (n_frames, n_keys, 3) float64 key point positions in every frame (frame 0: F^0).
    errors : mean distance from D^t(F^0) to the scans (over the template points each scan covers at the start),
    before the first round and after each accepted round.
    n_keys : number of key points after each of those steps.
    """

    index: np.ndarray
    positions: np.ndarray
    n_fixed: int
    errors: tuple = ()
    n_keys: tuple = ()


def mesh_spacing(points: np.ndarray) -> float:
    """Median distance from a point to its nearest neighbour."""
    d, _ = cKDTree(points).query(points, k=2)
    return float(np.median(d[:, 1]))


def motion_correlation(motion: np.ndarray, candidates: np.ndarray, neighbours: Sequence) -> np.ndarray:
    """Mean correlation coefficient between each candidate's motion and its neighbours' motions.

    motion : (n_frames, n_points, 3) displacements from F^0; candidates : (n_cand,) point indices;
    neighbours : for each candidate, an index array of its neighbouring points (the candidate itself is skipped).
    Returns (n_cand,) float64 in [-1, 1]; 0 where a candidate or all its neighbours do not move.
    """
    traj = np.asarray(motion, dtype=np.float64).transpose(1, 0, 2).reshape(motion.shape[1], -1)
    traj = traj - traj.mean(1, keepdims=True)
    norm = np.linalg.norm(traj, axis=1)
    scale = max(float(norm.max()), 1e-300)
    z = np.where(norm[:, None] > 1e-9 * scale, traj / np.maximum(norm, 1e-300)[:, None], 0.0)
    out = np.zeros(len(candidates))
    for i, (c, nb) in enumerate(zip(candidates, neighbours, strict=True)):
        nb = np.asarray(nb, dtype=np.int64)
        nb = nb[nb != c]
        if len(nb):
            out[i] = float((z[nb] @ z[c]).mean())
    return out


def select_candidates(motion: np.ndarray, candidates: np.ndarray, neighbours: Sequence) -> np.ndarray:
    """The candidates whose :func:`motion_correlation` is above the mean over all candidates."""
    corr = motion_correlation(motion, candidates, neighbours)
    return np.asarray(candidates)[corr > corr.mean()]


def deform_frames(neutral: np.ndarray, keys: KeyPoints, *, kernel: str = "thin_plate", smoothing: float = 0.0,
                  points: np.ndarray | None = None) -> np.ndarray:
    """``D^t(points)`` for every frame : (n_frames, n_points, 3) float64; points default to all of F^0."""
    return _predict(np.asarray(neutral, np.float64), keys.index, keys.positions, kernel, smoothing, points)


def _predict(neutral, index, positions, kernel, smoothing, points=None):
    system = rbf_system(neutral[index], kernel=kernel, smoothing=smoothing)
    n_frames, k, _ = positions.shape
    coefs = system.solve(positions.transpose(1, 0, 2).reshape(k, 3 * n_frames))
    pts = neutral if points is None else np.asarray(points, np.float64)
    return system.evaluate(pts, coefs).reshape(len(pts), n_frames, 3).transpose(1, 0, 2)


def _observed_motion(pred: np.ndarray, neutral: np.ndarray, surfaces: Sequence, cap: float) -> np.ndarray:
    """(n_frames, n_vertices, 3) motion of F^0 as the scans show it: ``D^t(F^0)`` moved along the scan's normal onto
    the nearest scan point's tangent plane (where a scan point is within ``cap``), minus F^0. Candidates are selected
    on it, so that motion the key points cannot see yet (a cheek puff between landmarks) draws key points to it."""
    out = pred.copy()
    for t in range(1, len(pred)):
        dist, j = surfaces[t].tree.query(pred[t], distance_upper_bound=cap)
        ok = np.isfinite(dist)
        n = surfaces[t].normals[j[ok]]
        out[t, ok] -= n * ((pred[t, ok] - surfaces[t].points[j[ok]]) * n).sum(1)[:, None]
    return out - neutral


def _surface_error(pred: np.ndarray, surfaces: Sequence, cap: float = np.inf, covered: Sequence | None = None) -> float:
    """Mean point-to-plane distance from D^t(F^0) to the scans, frames 1.. (0 for a single frame), each truncated at
    ``cap``; with ``covered`` (per frame a bool mask of F^0's points) only over those points."""
    if len(pred) < 2:
        return 0.0
    return float(np.mean([surfaces[t].distance(pred[t] if covered is None else pred[t][covered[t]], cap).mean()
                          for t in range(1, len(pred))]))


def _register_frames(neutral, index, positions, n_fixed, scenes, surfaces, rigids, moving, spacing, cap, config,
                     progress, rng):
    """Refine the free key points in every frame t >= 1; returns new positions (n_frames, k, 3).
    rigids : per frame, the head's rigid motion (a function of points, see :func:`_rigid_motion`)."""
    system = rbf_system(neutral[index], kernel=config.kernel, smoothing=config.smoothing)
    operator = system.operator(neutral[moving])
    free = np.arange(len(index)) >= n_fixed
    bases = None
    if config.nodes is not None:
        bases = [smooth_basis(neutral[index], free, k or len(index), rng) for k in config.nodes]
    # the prior of every free key point: a thin-plate RBF through the landmarks (where the detector put them) and
    # through anchors far from them that follow the head's rigid motion only (the skull, the neck, where the
    # landmarks' own RBF merely extrapolates). It comes from the landmarks and the rigid motion only, never from a
    # previous round's registration, so that sliding along the surface cannot add up over rounds.
    rest = neutral[index]
    far_pool = moving[cKDTree(rest[:n_fixed]).query(neutral[moving])[0] > config.rigid_beyond * spacing]
    anchors = far_pool[_farthest_points(neutral[far_pool], min(config.n_rigid_anchors, len(far_pool)), rng)] \
        if len(far_pool) else np.zeros(0, np.int64)
    prior_op = rbf_system(neutral[np.r_[index[:n_fixed], anchors]], kernel=config.kernel).operator(rest)
    out = positions.copy()
    priors = np.empty_like(positions)
    cache = {}  # the registration's normal equations: the same for every frame
    bending = _bending(rest, n_fixed) if config.field > 0 else None
    for t in range(1, len(positions)):
        prior = priors[t] = prior_op @ np.concatenate([positions[t, :n_fixed], rigids[t](neutral[anchors])])
        if not config.registration:  # ablation: the key points stay at their prior
            out[t, n_fixed:] = prior[n_fixed:]
            if progress is not None:
                progress(1)
            continue
        out[t] = register(operator, positions[t], scenes[t], spacing=spacing, free=free, config=config.gmm,
                          bases=bases, anchor_to=prior, cache=cache).controls
        confidence = None
        if config.project and config.fit_neighbours:  # onto a local quadric of the scan, where it is well fixed
            moved, normals, sigma = _fit_heights(out[t, n_fixed:], surfaces[t], k=config.fit_neighbours,
                                                 tilt=config.fit_tilt)
            trusted = sigma < config.fit_max_sigma * surfaces[t].spacing
            out[t, n_fixed:][trusted] = moved[trusted]
            confidence = trusted.astype(np.float64)  # the field takes the normal parts of these only
        elif config.project:
            out[t, n_fixed:] = _project(out[t, n_fixed:], surfaces[t], cap)
        if config.gate:  # where the prior already lies on the scan the data have nothing to correct: keep it
            if confidence is None:
                keep = surfaces[t].distance(prior[n_fixed:], cap) < config.gate * spacing
            else:  # the prior's height over the scan's quadric, where that is well fixed
                on, _, sigma_p = _fit_heights(prior[n_fixed:], surfaces[t], k=config.fit_neighbours)
                keep = (sigma_p < config.fit_max_sigma * surfaces[t].spacing) & (
                    np.linalg.norm(on - prior[n_fixed:], axis=1) < config.gate * spacing)
            out[t, n_fixed:][keep] = prior[n_fixed:][keep]
        if config.field > 0:  # one smooth field in 3D through the normal parts of the key points' offsets
            if confidence is None:
                normals = surfaces[t].normals[surfaces[t].tree.query(out[t, n_fixed:])[1]]
            held = keep if config.gate else None  # the gated ones are held at their prior more firmly
            out[t, n_fixed:] = prior[n_fixed:] + _smooth_offsets(out[t, n_fixed:] - prior[n_fixed:], normals,
                                                                 bending, config.field, config.field_anchor, held,
                                                                 config.field_anchor_gated, confidence)
        if progress is not None:
            progress(1)
    if config.registration and config.temporal > 0 and len(out) > 2:
        # the scans' sampling (a new random subset, new noise each frame) is independent from frame to frame, the
        # skin's motion is not: the key points' offsets from their prior are smoothed over time
        offsets = scipy.ndimage.gaussian_filter1d(out[1:, n_fixed:] - priors[1:, n_fixed:], config.temporal, axis=0,
                                                  mode="nearest")
        out[1:, n_fixed:] = priors[1:, n_fixed:] + offsets
    return out


def _bending(rest: np.ndarray, n_fixed: int, *, k: int = 8) -> scipy.sparse.csr_matrix:
    """(n_free, n_free) sparse ``Lf^T Lf``: the squared graph Laplacian of the key points in F^0 (``k`` nearest
    neighbours, weights ``exp(-(d / 2 s)^2)``, s the median neighbour distance) on the free key points, the fixed
    ones (landmarks) held at a zero offset. ``delta^T (Lf^T Lf) delta`` is a discrete bending energy of the free key
    points' offset field."""
    n = len(rest)
    dist, nb = cKDTree(rest).query(rest, k=min(k + 1, n))
    dist, nb = dist[:, 1:], nb[:, 1:]
    s = max(float(np.median(dist)), 1e-12)
    adj = scipy.sparse.coo_matrix((np.exp(-(dist.ravel() / (2.0 * s)) ** 2),
                                   (np.repeat(np.arange(n), nb.shape[1]), nb.ravel())), (n, n)).tocsr()
    adj = adj + adj.T
    lap = (scipy.sparse.diags(np.asarray(adj.sum(1)).ravel()) - adj).tocsc()[:, n_fixed:]
    return (lap.T @ lap).tocsr()


def _smooth_offsets(offsets: np.ndarray, normals: np.ndarray, bending, weight: float, anchor: float,
                    held: np.ndarray | None = None, held_anchor: float = 1.0,
                    confidence: np.ndarray | None = None) -> np.ndarray:
    """The free key points' offsets from their prior (n_free, 3) as one smooth field in 3D that keeps their parts
    along the scan's normal: ``delta`` minimises

        sum_k (n_k . delta_k - n_k . offset_k)^2 + a_k |delta_k|^2 + weight * delta^T (bending (x) I_3) delta

    (n_k the normal of the scan point nearest to key point k; bending: :func:`_bending`; a_k = ``anchor``, or
    ``held_anchor`` where ``held``: the gate's key points, whose prior already lies on the scan; with
    ``confidence`` (n_free,) the first term of key point k is weighted by confidence_k, 0 where the scan does not
    fix its normal part), and then each key point's part along its normal is set back to the measured one (where
    confidence_k > 0.5), so that only the moves along the surface come from the field. The scan fixes a key point only along its normal; where the normals of neighbouring key
    points differ, the smoothness turns their normal moves into moves along the surface, and the anchor holds what
    neither fixes at the prior. Conjugate gradients with the 3x3 diagonal blocks as preconditioner, from the normal
    parts (approximate: relative residual 1e-6)."""
    r = (offsets * normals).sum(1)
    n = len(r)
    c = np.ones(n) if confidence is None else np.asarray(confidence, np.float64)
    a = np.full(n, float(anchor))
    if held is not None:
        a[np.asarray(held, bool)] = held_anchor
    nn = c[:, None, None] * normals[:, :, None] * normals[:, None, :] + a[:, None, None] * np.eye(3)
    inv = np.linalg.inv(nn + weight * bending.diagonal()[:, None, None] * np.eye(3))

    def matvec(v):
        d = v.reshape(n, 3)
        return (np.einsum("nij,nj->ni", nn, d) + weight * (bending @ d)).ravel()

    def precond(v):
        return np.einsum("nij,nj->ni", inv, v.reshape(n, 3)).ravel()

    shape = (3 * n, 3 * n)
    b = (normals * (c * r)[:, None]).ravel()
    sol, _ = scipy.sparse.linalg.cg(scipy.sparse.linalg.LinearOperator(shape, matvec=matvec, dtype=np.float64), b,
                                    x0=b.copy(), rtol=1e-6, maxiter=200,
                                    M=scipy.sparse.linalg.LinearOperator(shape, matvec=precond, dtype=np.float64))
    sol = sol.reshape(n, 3)
    fix = c > 0.5  # the measured normal parts, where measured well
    sol[fix] -= normals[fix] * ((sol[fix] * normals[fix]).sum(1) - r[fix])[:, None]
    return sol


def refine_key_points(
    neutral: np.ndarray,
    scans: Sequence[np.ndarray],
    landmarks: np.ndarray,
    landmark_index: np.ndarray,
    *,
    config: SamplerConfig = SamplerConfig(),
    motion: np.ndarray | None = None,
    progress: Callable[[int], None] | None = None,
) -> KeyPoints:
    """Find key points on F^0 and their positions in every frame so that ``D^t(F^0)`` follows the scans.

    neutral : (n_vertices, 3) F^0. scans : n_frames point sets (n_t, 3), scans[0] is F^0 (its order is not used).
    landmarks : (n_frames, n_land, 3) detected landmark positions per frame. landmark_index : (n_land,) their
    vertices in F^0. motion : optional (n, n_vertices, 3) motion of F^0 that candidates are selected on (default:
    ``D^t(F^0) - F^0`` of the current round). progress : called with the number of frames registered.
    """
    neutral = np.ascontiguousarray(neutral, dtype=np.float64)
    landmark_index = np.asarray(landmark_index, dtype=np.int64)
    n_frames = len(scans)
    landmarks = np.asarray(landmarks, dtype=np.float64)
    if landmarks.shape != (n_frames, len(landmark_index), 3):
        raise ValueError(f"landmarks {landmarks.shape} do not match {n_frames} frames of {len(landmark_index)}")
    rng = np.random.default_rng(config.seed)
    n_fixed = len(landmark_index)
    index = landmark_index.copy()
    positions = landmarks.copy()
    positions[0] = neutral[index]
    surfaces = [_Surface(s) for s in scans]
    tree0 = cKDTree(neutral)
    base_spacing = mesh_spacing(neutral)
    cell = config.thin_cell * base_spacing
    moving_pool = thin(neutral, cell, rng)
    spacing = mesh_spacing(neutral[moving_pool]) if len(moving_pool) > 1 else cell
    scenes = [np.asarray(s, np.float64)[thin(s, cell, rng)] for s in scans]
    radius = config.neighbour_radius * base_spacing
    rigids = None
    cap = 4.0 * base_spacing  # truncation of the scan distance (template parts the scans do not cover)

    pred = _predict(neutral, index, positions, config.kernel, config.smoothing)
    # the error is taken over the points of F^0 that have scan within ``cap`` at the start (the 68-landmark
    # deformation), each frame its own set: template parts no scan covers (the back of the head) would add the
    # same ``cap`` to every round and dilute the relative gain that decides when to stop
    covered = [np.isfinite(s.tree.query(p, distance_upper_bound=cap)[0]) for s, p in zip(surfaces, pred, strict=True)]
    covered = [c if c.any() else np.ones_like(c) for c in covered]
    error = _surface_error(pred, surfaces, cap, covered)
    errors, n_keys = [error], [len(index)]
    log.info("sampler: %d key points, error %.4g", len(index), error)
    for round_ in range(config.max_rounds):
        pool = np.setdiff1d(np.arange(len(neutral)), index)
        if len(pool) == 0:
            break
        cand = rng.choice(pool, min(config.n_candidates, len(pool)), replace=False)
        kept = select_candidates(_observed_motion(pred, neutral, surfaces, cap) if motion is None else motion, cand,
                                 tree0.query_ball_point(neutral[cand], radius))
        new_index = np.concatenate([index, kept])
        new_positions = np.concatenate([positions, pred[:, kept]], axis=1)
        # the neighbourhoods of all key points: the moving set of the registration
        near = cKDTree(neutral[new_index]).query(neutral[moving_pool], distance_upper_bound=2 * radius)[0]
        moving = moving_pool if config.whole else moving_pool[np.isfinite(near)]
        if n_frames > 1 and len(moving):
            if rigids is None:  # the head's motion per frame does not depend on the key points: once
                rigids = [None] + [_rigid_motion(neutral[moving_pool], surfaces[t], landmarks[t], neutral[index[:n_fixed]],
                                                 spacing) for t in range(1, n_frames)]
            new_positions = _register_frames(neutral, new_index, new_positions, n_fixed, scenes, surfaces, rigids,
                                             moving, spacing, cap, config, progress, rng)
        new_pred = _predict(neutral, new_index, new_positions, config.kernel, config.smoothing)
        new_error = _surface_error(new_pred, surfaces, cap, covered)
        log.info("sampler round %d: %d key points (+%d of %d candidates), error %.4g", round_ + 1,
                 len(new_index), len(kept), len(cand), new_error)
        if new_error >= error:
            break
        gain = (error - new_error) / max(error, 1e-300)
        index, positions, pred, error = new_index, new_positions, new_pred, new_error
        errors.append(error)
        n_keys.append(len(index))
        if gain < config.min_improvement:
            break
    return KeyPoints(index, positions, n_fixed, tuple(errors), tuple(n_keys))
