"""The learned cascade against the Jacobian update on synthetic renders, and the fit validator on non-faces."""

import numpy as np
import pytest

from aamtrack.imaging import to_gray32
from aamtrack.metrics import PIXEL_ORIGIN
from aamtrack.search import Searcher
from aamtrack.train.pipeline import TrainConfig, train_model
from aamtrack.train.shape_fit import fit_landmarks
from aamtrack.train.validator import non_face_images
from conftest import SEED, SYNTH_COUPLES
import synth


@pytest.fixture(scope="module")
def jacobian_model(synth_data):
    images, points = synth_data
    model, _ = train_model(images, points, "2d", config=TrainConfig(couples=SYNTH_COUPLES, update="jacobian"))
    return model


def _displaced_errors(model, rng, shift):
    """Mean landmark error (px) after a search from the truth displaced by ``shift`` of the face width (random
    direction), 6 degrees of roll and 6% of scale, on 10 faces the model has not seen: the search's own points
    (the landmark cascade after it is left out, so the update matrices are what is compared)."""
    images, points = synth.random_faces(10, rng, size=(220, 220), scale=130.0)
    points = points - PIXEL_ORIGIN  # labels are 1-based; the search works in OpenCV's pixels
    searcher = Searcher(model)
    sm = model.shape
    before, after = [], []
    for img, pts in zip(images, points):
        q = fit_landmarks(sm, pts).q
        a = rng.uniform(0, 2 * np.pi)
        q0 = q.copy()
        q0[4:6] += shift * np.ptp(pts[:, 0]) * np.array([np.cos(a), np.sin(a)])
        q0[2] += np.radians(6.0) * rng.choice([-1, 1])
        q0[3] *= np.exp(0.06 * rng.choice([-1, 1]))
        res = searcher.fit(searcher.levels(to_gray32(img)), q0, landmarks=False)
        before.append(np.linalg.norm(sm.landmarks(q0) - pts, axis=1).mean())
        after.append(np.linalg.norm(res.landmarks - pts, axis=1).mean())
    return np.mean(before), np.mean(after)


def test_cascade_recovers_perturbations_better_than_the_jacobian(synth_model, jacobian_model):
    assert synth_model.couples[-1].n_stages > 0 and jacobian_model.couples[-1].n_stages == 0
    # 6% of the face width: within the spread the synthetic model's cascade learned from (no Haar detections on
    # synthetic faces, so only the tracking-like starts: 4% sd). Measured: cascade 0.42 px, Jacobian 0.56 px;
    # at 12% (3 sd, beyond what it learned) the Jacobian does better (3.3 px against 4.9).
    b, cascade = _displaced_errors(synth_model, np.random.default_rng(SEED + 3), 0.06)
    _, jacobian = _displaced_errors(jacobian_model, np.random.default_rng(SEED + 3), 0.06)
    print(f"mean px error from a 6% displaced start {b:.2f}: cascade {cascade:.2f}, Jacobian {jacobian:.2f}")
    assert b > 6.0  # the start is really off
    assert cascade < 1.0  # the cascade lands within a pixel
    assert cascade < jacobian  # and closer than the Jacobian update from the same starts


def test_validator_tells_faces_from_non_faces(synth_model):
    """Fits on synthetic faces score high, the same search on images without a face scores low."""
    rng = np.random.default_rng(SEED + 5)
    images, points = synth.random_faces(6, rng, size=(220, 220), scale=130.0)
    points = points - PIXEL_ORIGIN  # labels are 1-based; the search works in OpenCV's pixels
    searcher = Searcher(synth_model)
    sm = synth_model.shape
    face, non_face = [], []
    for img, pts in zip(images, points):
        q = fit_landmarks(sm, pts).q
        face.append(searcher.fit(searcher.levels(to_gray32(img)), q).confidence)
        for blank in non_face_images((220, 220), rng):
            non_face.append(searcher.fit(searcher.levels(blank), q).confidence)
    print("confidence on faces", np.round(face, 3), "max on non-faces", np.round(max(non_face), 3))
    assert min(face) > 0.5 and max(non_face) < 0.5  # every face accepted, every non-face rejected


@pytest.mark.parametrize("shape", [(300, 40), (40, 300)])  # the primal (M > D) and the dual (M < D) solve
def test_ridge_fit_is_the_ridge_solution(shape):
    """Whichever form solves it, ridge_fit returns the closed-form ridge solution for the alpha it chose."""
    from aamtrack.train.cascade import ridge_fit

    rng = np.random.default_rng(SEED)
    M, D = shape
    X = rng.normal(size=(M, D)) + rng.normal(size=D)
    Y = X[:, :3] @ rng.normal(size=(3, 2)) + 0.1 * rng.normal(size=(M, 2)) + 4.0
    R, b, alpha = ridge_fit(X, Y, groups=np.arange(M) // 2)
    Xc, Yc = X - X.mean(0), Y - Y.mean(0)
    lam = alpha * np.trace(Xc.T @ Xc) / D
    R_ref = np.linalg.solve(Xc.T @ Xc + lam * np.eye(D), Xc.T @ Yc).T
    assert np.abs(R - R_ref).max() < 1e-4 * np.abs(R_ref).max()  # float32 storage
    assert np.abs(b - (Y.mean(0) - X.mean(0) @ R_ref.T)).max() < 1e-3


def test_jacobian_models_validator_learns_from_fits_on_each_couples_own_level(jacobian_model):
    """A Jacobian model's validator learns from the search run on its training starts; each couple must see the
    image at its own resolution (handing every couple the finest couple's image left those fits at a median NME
    of 0.0116 instead of 0.0056 on these synthetic faces)."""
    cfg = jacobian_model.config
    assert cfg["train_final_nme_median"] < 0.008  # eye-distance units; starts at about 0.06
    assert cfg["train_start_nme_median"] > 0.04


def test_ridge_fit_chooses_the_held_out_best_alpha_of_the_grid():
    """ridge_fit tries the alphas from the smallest up and stops where the held-out error rises: on problems whose
    held-out error falls then rises along the grid, that is the grid's best, recomputed here in closed form on the
    same held-out groups; the noise levels move the best alpha along the grid."""
    from aamtrack.train.cascade import ridge_fit

    alphas = (0.03, 0.3, 3.0, 30.0, 300.0)
    chosen = set()
    for noise in (0.05, 3.0, 30.0):
        rng = np.random.default_rng(SEED)
        M, D = 400, 60
        X = rng.normal(size=(M, D)) + rng.normal(size=D)
        Y = X @ rng.normal(size=(D, 2)) * 0.3 + noise * rng.normal(size=(M, 2))
        groups = np.arange(M) // 4
        _, _, alpha = ridge_fit(X, Y, alphas=alphas, groups=groups, rng=np.random.default_rng(3))
        r = np.random.default_rng(3)  # the held-out groups ridge_fit draws
        ug = np.unique(groups)
        held = np.isin(groups, r.choice(ug, max(1, int(0.15 * len(ug))), replace=False))
        Xt, Yt = X[~held], Y[~held]
        Xc, Yc = Xt - Xt.mean(0), Yt - Yt.mean(0)
        errs = []
        for a in alphas:
            R = np.linalg.solve(Xc.T @ Xc + a * np.trace(Xc.T @ Xc) / D * np.eye(D), Xc.T @ Yc)
            pred = (X[held] - Xt.mean(0)) @ R + Yt.mean(0)
            errs.append((((pred - Y[held]) / Y.std(0)) ** 2).mean())
        best = int(np.argmin(errs))
        assert all(np.diff(errs[:best + 1]) < 0) and all(np.diff(errs[best:]) > 0)  # falls, then rises
        assert alpha == alphas[best]
        chosen.add(alpha)
    assert len(chosen) >= 2  # the cases do move the choice
