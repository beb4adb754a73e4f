"""The 3D model's texture band (``aamtrack.mesh.skirt``) on the synthetic Candide-like face: its ring follows the
landmarks exactly under pose, shape and animation units, the landmarks and the face width are unchanged, and its
triangles form one fold-free strip outside the mesh."""

import numpy as np
import pytest
import synth3d
from conftest import SEED
from matplotlib.path import Path as MplPath

from aamtrack.mesh.shape_model import ShapeModel
from aamtrack.mesh.skirt import JAW, outline_loop, with_skirt
from aamtrack.mesh.texture_map import texture_frame

BAND = 0.15


def _signed_areas(xy, tris):
    a, b, c = xy[tris[:, 0]], xy[tris[:, 1]], xy[tris[:, 2]]
    return 0.5 * ((b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]))


@pytest.mark.parametrize("jaw", [JAW, tuple(range(3, 14))])
def test_ring_follows_the_landmarks_under_pose_and_deformation(jaw):
    sm = synth3d.shape_model(synth3d.synthetic_candide())
    skirted, band = with_skirt(sm, sm.triangles, BAND, jaw)
    n_v = sm.n_vertices
    assert skirted.n_vertices == n_v + len(jaw)
    assert skirted.frontal_width() == sm.frontal_width()
    rng = np.random.default_rng(SEED)
    for _ in range(5):
        q = np.zeros(sm.n_q)
        q[:6] = (*rng.normal(0, 0.2, 3), 100 * np.exp(rng.normal(0, 0.2)), *rng.uniform(80, 160, 2))
        q[6:] = rng.normal(0, 0.5, sm.n_coef)
        sigma = rng.normal(0, 0.7, sm.n_shape)
        lm = sm.landmarks(q, sigma)
        assert np.abs(skirted.landmarks(q, sigma) - lm).max() < 1e-9
        ring = skirted.project(q, sigma)[n_v:]
        expected = (1 + BAND) * lm[list(jaw)] - BAND * lm.mean(0)
        assert np.abs(ring - expected).max() < 1e-9  # exact: the projection is affine, the ring's weights sum to 1
        assert np.abs(skirted.project(q, sigma)[:n_v] - sm.project(q, sigma)).max() < 1e-9


def _disc_face(rng):
    """A ShapeModel laid out like the Candide-3 3D model: a meshed oval face (two rings around a centre, y up), and
    the 68 landmarks as extra vertices in no triangle (landmark map = identity on them), the 17 jaw points on a
    wider oval than the mesh (as the labelled jaw lies outside Candide's outline); random smooth shape and
    animation units."""
    from scipy.spatial import Delaunay

    a = np.linspace(0, 2 * np.pi, 25)[:-1]
    rings = [np.column_stack([r * 0.6 * np.cos(a), r * 0.75 * np.sin(a)]) for r in (0.5, 1.0)]
    mesh = np.vstack([[[0.0, 0.0]], *rings])
    tris = Delaunay(mesh).simplices.astype(np.int32)
    t = np.radians(np.linspace(-100, 100, 17)) - np.pi / 2  # jaw: from one temple under the chin to the other
    jaw = np.column_stack([0.68 * np.cos(t)[::-1], 0.82 * np.sin(t)])
    inner = rng.uniform(-0.3, 0.3, (51, 2))
    xy = np.vstack([mesh, jaw, inner])
    V = np.column_stack([xy, 0.3 * (1 - (xy ** 2).sum(1))])
    n_m = len(mesh)
    L = np.zeros((68, len(V)))
    L[:, n_m:] = np.eye(68)
    smooth = lambda k: np.stack([np.outer(np.cos(xy @ rng.normal(0, 2, 2)), rng.normal(0, 0.03, 3)) for _ in range(k)])
    return ShapeModel(kind="3d", mean=V, shape_units=smooth(4), basis=smooth(3), triangles=tris, landmark_map=L,
                      shape_names=tuple("abcd"), coef_names=tuple("xyz"), coef_lo=-np.ones(3), coef_hi=np.ones(3),
                      shape_sd=np.ones(4))


def test_band_is_one_fold_free_strip_outside_the_mesh():
    sm = _disc_face(np.random.default_rng(SEED))
    tris = sm.triangles
    skirted, band = with_skirt(sm, tris, BAND)
    xy = skirted.mean[:, :2]
    areas = _signed_areas(xy, band)
    assert len(band) >= len(JAW) - 1
    assert (np.abs(areas) > 1e-6).all() and (np.sign(areas) == np.sign(areas[0])).all()  # no fold, no sliver
    loop = outline_loop(tris)
    inside = MplPath(sm.mean[loop, :2]).contains_points(xy[band].mean(1))
    assert not inside.any()  # every band triangle's centroid lies outside the mesh's outline
    plain = texture_frame(sm.mean[:, :2] * [1, -1], tris, 40)
    both = texture_frame(skirted.mean[:, :2] * [1, -1], np.vstack([tris, band]), 40)
    assert (both.pix_vid >= sm.n_vertices).any(axis=1).sum() > 0.1 * len(plain.pix_vid)  # the band has pixels
