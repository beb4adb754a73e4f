"""Face profiling (``aamtrack.train.profile``) on the synthetic Candide-like face: marks painted at mesh vertices
in the source image land where the turned mesh puts those vertices, the source's own marks do not remain, and
the turned copies' poses stay within the requested spread."""

import cv2
import numpy as np
import synth3d
from conftest import SEED

from aamtrack.mesh.render import posed
from aamtrack.train.profile import TURNED_READ, TURNED_YAW, ProfileSpread, profile_face, profile_faces, turned_start

SIZE = 240
# eye corners, mouth corners, chin, brow ends (not the nose ridge: at a turn it hides part of its own mark, which
# moves the mark's centroid by up to 2.4 px: occlusion, not misplacement)
CENTRAL = (36, 39, 42, 45, 48, 54, 8, 17, 26)


def _marked_source(sm, q, sigma, vertices):
    """A dark image with a bright disc at the projection of each vertex in ``vertices``."""
    img = np.full((SIZE, SIZE), 40, np.uint8)
    uv, _ = posed(sm.shape3d(q, sigma), q)
    for v in vertices:
        cv2.circle(img, tuple(np.round(uv[v] * 16).astype(int)), 3 * 16, 255, -1, lineType=cv2.LINE_AA, shift=4)
    return img


def _blobs(img):
    n, _, stats, centroids = cv2.connectedComponentsWithStats((img > 150).astype(np.uint8))
    return centroids[1:][stats[1:, cv2.CC_STAT_AREA] >= 5]


def test_turned_marks_land_on_the_turned_vertices():
    sm = synth3d.shape_model(synth3d.synthetic_candide())
    vertices = [int(np.argmax(sm.landmark_map[i])) for i in CENTRAL]
    q = np.zeros(sm.n_q)
    q[:6] = (0.05, 0.1, 0.05, 130.0, SIZE / 2, SIZE / 2)
    sigma = np.random.default_rng(SEED).normal(0, 0.5, sm.n_shape)
    src = _marked_source(sm, q, sigma, vertices)
    assert len(_blobs(src)) == len(vertices)
    for rx, ry in ((0.25, -0.35), (-0.2, 0.4)):
        out, p_new, pts = profile_face(src, np.r_[q, sigma], sm, rx, ry)
        assert out.shape == src.shape and out.dtype == src.dtype
        assert p_new[0] == rx and p_new[1] == ry
        assert np.array_equal(p_new[2:sm.n_q], q[2:]) and np.array_equal(p_new[sm.n_q:], sigma)
        assert np.abs(pts - sm.landmarks(p_new[:sm.n_q], sigma)).max() < 1e-9
        expected, _ = posed(sm.shape3d(p_new[:sm.n_q], sigma), p_new[:sm.n_q])
        found = _blobs(out)
        assert len(found) == len(vertices)  # each mark once: none left behind at the source pose
        d = np.linalg.norm(found[:, None] - expected[vertices][None], axis=2)
        assert d.min(0).max() < 0.75  # sub-pixel: every mark within 0.75 px of its vertex at the new pose


def test_profile_faces_share_and_spread():
    sm = synth3d.shape_model(synth3d.synthetic_candide())
    rng = np.random.default_rng(SEED)
    P = np.zeros((20, sm.n_q + sm.n_shape))
    P[:, :6] = [0.0, 0.0, 0.0, 130.0, SIZE / 2, SIZE / 2]
    P[:, 1] = np.radians(rng.uniform(-30, 30, 20))
    images = [np.full((SIZE, SIZE), 100, np.uint8)] * 20
    spread = ProfileSpread(yaw=45.0, pitch=20.0, max_turn=30.0)
    out, P_new, pts, src = profile_faces(images, P, sm, 0.5, rng=rng, spread=spread)
    assert len(out) == len(P_new) == len(pts) == len(src) == 10 and len(set(src.tolist())) == 10
    yaw, pitch = np.degrees(P_new[:, 1]), np.degrees(P_new[:, 0])
    assert np.abs(yaw).max() <= 45.0 and np.abs(pitch).max() <= 20.0
    assert np.abs(yaw - np.degrees(P[src, 1])).max() <= 30.0 + 1e-9
    assert np.abs(P_new[:, 1] - P[src, 1]).max() > np.radians(5)  # they do turn


def test_turned_starts_turn_the_face_past_the_model_and_read_a_smaller_turn_the_same_way():
    """``turned_start`` (the landmark validator's turned negatives): the face drawn at 60-80 degrees of yaw either
    way, its points the model's at that yaw with everything else the source's, and the start the source's vector
    but for a yaw of 35-50 degrees the same way."""
    from scipy.optimize import minimize_scalar

    sm = synth3d.shape_model(synth3d.synthetic_candide())
    rng = np.random.default_rng(SEED)
    q = np.zeros(sm.n_q)
    q[:6] = (0.1, 0.2, 0.05, 130.0, SIZE / 2, SIZE / 2)
    p = np.r_[q, rng.normal(0, 0.5, sm.n_shape)]
    src = _marked_source(sm, q, p[sm.n_q:], [int(np.argmax(sm.landmark_map[i])) for i in CENTRAL])
    signs = set()
    for _ in range(12):
        img, start, pts = turned_start(src, p, sm, rng)
        assert img.shape == src.shape and img.dtype == src.dtype and not np.array_equal(img, src)
        assert np.flatnonzero(start != p).tolist() == [1]  # only the yaw is not the source's
        read = np.degrees(start[1])
        assert TURNED_READ[0] <= abs(read) <= TURNED_READ[1]

        def miss(yaw_deg, start=start, pts=pts):
            at = start[:sm.n_q].copy()
            at[1] = np.radians(yaw_deg)
            return np.abs(sm.landmarks(at, p[sm.n_q:]) - pts).max()

        lo, hi = TURNED_YAW if read > 0 else (-TURNED_YAW[1], -TURNED_YAW[0])
        best = minimize_scalar(miss, bounds=(lo, hi), method="bounded", options={"xatol": 1e-6})
        assert best.fun < 1e-3  # the points are the model's at a turn of 60-80 degrees the way the start reads
        signs.add(np.sign(read))
    assert signs == {-1.0, 1.0}  # both ways


def test_training_with_turned_copies_still_converges():
    """Profiling is off by default: this keeps its training path (copies joining at a finer couple) exercised, and
    the landmark validator's turned negatives' (``TrainConfig.validator_turned``, off by default too)."""
    from conftest import SYNTH_COUPLES

    from aamtrack.train.pipeline import TrainConfig, train_model

    candide = synth3d.synthetic_candide()
    images, points, _, _ = synth3d.posed_faces(candide, 30, np.random.default_rng(SEED))
    model, _ = train_model(images, points, "3d", candide=candide,
                           config=TrainConfig(couples=SYNTH_COUPLES, map_refine_rounds=1, n_corrective=4,
                                              profile_share=0.5, profile_from_couple=2, validator_turned=2))
    assert model.config["train_start_nme_median"] > 0.05  # the starts are really off
    assert model.config["train_final_nme_median"] < 0.01  # and the cascade brings them back (faces 130 px wide)
    assert model.config["validator_turned"] == 2 and model.landmark_validator is not None
