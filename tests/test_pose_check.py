"""The mesh renderer (aamtrack.mesh.render) and the angle metrics of benchmarks/pose_check.py on synthetic meshes and textures whose answers
are known by construction (one test on a helen_train photo, marked shared_data)."""

import sys
from pathlib import Path

import cv2
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from conftest import SEED, shared_path  # noqa: E402
from pose_check import angle_errors, geodesic_deg, rotation, sweep_bins  # noqa: E402

from aamtrack.mesh.render import orient_triangles, posed  # noqa: E402
from aamtrack.mesh.render import render_mesh as render  # noqa: E402
from aamtrack.mesh.shape_model import ShapeModel, rotation_matrix  # noqa: E402

SIZE = 240
Q_SRC = np.array([0.0, 0.0, 0.0, 80.0, 120.0, 120.0])  # the texture photo: the dome seen from the front


def dome(n: int = 11, height: float = 0.5, z0: float = 0.0):
    """(n*n, 3) vertices of a height field z = z0 + height (1 - (x^2 + y^2) / 2) over [-1, 1]^2, and its
    triangles wound counter-clockwise seen from +z (model frame, y up)."""
    g = np.linspace(-1.0, 1.0, n)
    x, y = np.meshgrid(g, g)  # row i: y = g[i]
    V = np.column_stack([x.ravel(), y.ravel(), z0 + height * (1 - 0.5 * (x.ravel() ** 2 + y.ravel() ** 2))])
    tri = []
    for i in range(n - 1):
        for j in range(n - 1):
            k = i * n + j
            tri += [(k, k + 1, k + n + 1), (k, k + n + 1, k + n)]
    return V, np.array(tri, np.int64)


def surface_texture(x, y):
    """Grey value of the synthetic skin at model point (x, y): smooth, between 40 and 220."""
    return 130.0 + 90.0 * np.sin(3.0 * x + 0.5) * np.cos(2.0 * y - 0.3)


def photo_of_dome(V):
    """The source photo: the dome at Q_SRC, every pixel inside it the texture of the surface point it sees."""
    v, u = np.mgrid[0:SIZE, 0:SIZE].astype(float)
    x, y = (u - Q_SRC[4]) / Q_SRC[3], -(v - Q_SRC[5]) / Q_SRC[3]
    img = np.where((np.abs(x) <= 1.05) & (np.abs(y) <= 1.05), surface_texture(x, y), 0.0)
    return np.clip(np.round(img), 0, 255).astype(np.uint8)


def reference_render(V, tri, q):
    """Slow, obvious reference: per front-facing triangle, the pixel centres inside it (barycentric), valued
    by the texture at the model point they see. (H, W) float with NaN outside, and (H, W) bool 'one pixel
    or more inside' (away from every triangle edge of the silhouette). Valid for a height field seen at
    moderate angles (no front face hides another)."""
    uv, _ = posed(V, q)
    out = np.full((SIZE, SIZE), np.nan)
    v, u = np.mgrid[0:SIZE, 0:SIZE].astype(float)
    for t in tri:
        a, b, c = uv[t]
        area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        if area2 >= 0:
            continue
        T = np.array([[b[0] - a[0], c[0] - a[0]], [b[1] - a[1], c[1] - a[1]]])
        l1, l2 = np.linalg.solve(T, np.stack([u.ravel() - a[0], v.ravel() - a[1]]))
        inside = (l1 >= 0) & (l2 >= 0) & (l1 + l2 <= 1)
        X = (1 - l1 - l2)[inside, None] * V[t[0]] + l1[inside, None] * V[t[1]] + l2[inside, None] * V[t[2]]
        out.ravel()[np.flatnonzero(inside)] = surface_texture(X[:, 0], X[:, 1])
    core = cv2.erode((~np.isnan(out)).astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    return out, core


def test_posed_matches_the_package_projection_and_rotation():
    V, tri = dome()
    rng = np.random.default_rng(SEED)
    sm = ShapeModel(kind="3d", mean=V, shape_units=np.zeros((0, len(V), 3)), basis=np.zeros((0, len(V), 3)),
                    triangles=tri.astype(np.int32), landmark_map=np.zeros((68, len(V))), shape_names=(),
                    coef_names=(), coef_lo=np.zeros(0), coef_hi=np.zeros(0), shape_sd=np.zeros(0))
    for _ in range(5):
        q = np.r_[rng.uniform(-0.8, 0.8, 3), rng.uniform(50, 150), rng.uniform(0, 300, 2)]
        uv, z = posed(V, q)
        assert np.abs(uv - sm.project(q)).max() < 1e-9
        assert np.abs(rotation(*q[:3]) - rotation_matrix(*q[:3])).max() < 1e-12
        assert np.allclose(z, V @ rotation(*q[:3])[2])


def test_angle_errors_known_rotations():
    e = angle_errors([0.0, np.radians(10.0), 0.0], [0.0, 0.0, 0.0])
    assert abs(e["yaw"] - 10.0) < 1e-9 and e["pitch"] == 0.0 and e["roll"] == 0.0
    assert abs(e["geodesic"] - 10.0) < 1e-6  # one axis: geodesic = that angle
    e = angle_errors([0.0, 0.0, np.radians(179.0)], [0.0, 0.0, np.radians(-179.0)])
    assert abs(e["roll"] - 2.0) < 1e-9 and abs(e["geodesic"] - 2.0) < 1e-6  # wrapped, not 358
    # composing any pose with a 7-degree turn about any axis is 7 degrees away
    rng = np.random.default_rng(SEED)
    R = rotation(*rng.uniform(-1, 1, 3))
    axis = rng.normal(size=3)
    axis /= np.linalg.norm(axis)
    K = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    a = np.radians(7.0)
    turn = np.eye(3) + np.sin(a) * K + (1 - np.cos(a)) * K @ K
    assert abs(geodesic_deg(R, R @ turn) - 7.0) < 1e-6


def test_orient_triangles_rewinds_a_scrambled_mesh_outwards():
    V, tri = dome()
    rng = np.random.default_rng(SEED)
    scrambled = tri.copy()
    flip = rng.random(len(tri)) < 0.4
    scrambled[flip] = scrambled[flip][:, ::-1]
    for mesh in (scrambled, tri[:, ::-1]):
        fixed = orient_triangles(mesh, V)
        n = np.cross(V[fixed[:, 1]] - V[fixed[:, 0]], V[fixed[:, 2]] - V[fixed[:, 0]])
        assert (n[:, 2] > 0).all()  # the dome's every face points towards +z
        assert sorted(map(sorted, fixed.tolist())) == sorted(map(sorted, tri.tolist()))  # same triangles


def test_markers_land_where_the_projection_says():
    V, tri = dome()
    rng = np.random.default_rng(SEED)
    src_uv, _ = posed(V, Q_SRC)
    texture = rng.integers(0, 60, (SIZE, SIZE), dtype=np.uint8)
    inner = np.flatnonzero((np.abs(V[:, 0]) < 0.7) & (np.abs(V[:, 1]) < 0.7))[::3]
    for i in inner:
        cv2.circle(texture, tuple(int(c) for c in np.round(src_uv[i] * 16)), 40, 255, -1, cv2.LINE_AA, shift=4)
    q = np.array([0.25, 0.45, -0.35, 90.0, 117.3, 124.6])
    img, drawn = render(texture, src_uv, posed(V, q)[0], posed(V, q)[1], tri, np.zeros((SIZE, SIZE), np.uint8))
    n, labels = cv2.connectedComponents((img > 150).astype(np.uint8))
    assert n - 1 == len(inner)  # one blob per marker, none lost or split
    expected = posed(V, q)[0][inner]
    w = img.astype(float) * (img > 150)
    for k in range(1, n):
        vv, uu = np.nonzero(labels == k)
        c = np.array([(uu * w[vv, uu]).sum(), (vv * w[vv, uu]).sum()]) / w[vv, uu].sum()
        assert np.linalg.norm(expected - c, axis=1).min() < 1.0  # within a pixel


def test_back_faces_are_culled():
    V, tri = dome(height=0.0)  # a flat sheet
    src_uv, _ = posed(V, Q_SRC)
    texture = np.full((SIZE, SIZE), 200, np.uint8)
    bg = np.zeros((SIZE, SIZE), np.uint8)
    facing = np.array([0.0, 0.0, 0.0, 80.0, 120.0, 120.0])
    away = facing.copy()
    away[1] = np.pi  # turned round: seen from behind
    _, drawn = render(texture, src_uv, *posed(V, facing), tri, bg)
    assert drawn.mean() > 0.3  # the sheet, 160 x 160 of 240 x 240
    img, drawn = render(texture, src_uv, *posed(V, away), tri, bg)
    assert not drawn.any() and not img.any()
    _, drawn = render(texture, src_uv, *posed(V, facing), tri[:, ::-1], bg)  # wound the other way
    assert not drawn.any()
    sideways = facing.copy()
    sideways[1] = np.radians(100)  # just past edge-on
    assert not render(texture, src_uv, *posed(V, sideways), tri, bg)[1].any()


def test_nearer_triangles_are_drawn_over_farther_ones_whatever_their_order():
    near, tri = dome(n=5, height=0.0, z0=0.5)
    far = near.copy()
    far[:, 2] = -0.5
    far[:, 0] += 0.5  # overlapping half of the near sheet
    V = np.vstack([near, far])
    T = np.vstack([tri, tri + len(near)])  # the far sheet listed last
    texture = np.zeros((SIZE, SIZE), np.uint8)
    src_uv = np.vstack([np.full((len(near), 2), 30.0) + posed(near, [0, 0, 0, 10, 0, 0])[0],
                        np.full((len(far), 2), 180.0) + posed(near, [0, 0, 0, 10, 0, 0])[0]])
    texture[10:50, 10:50] = 200  # the near sheet's source
    texture[160:200, 160:200] = 60  # the far sheet's source
    for q in ([0.0, 0.0, 0.0, 60.0, 100.0, 120.0], [0.2, -0.3, 0.1, 60.0, 100.0, 120.0]):
        img, drawn = render(texture, src_uv, *posed(V, q), T, np.zeros((SIZE, SIZE), np.uint8))
        cx, cy = posed(np.array([[0.75, 0.0, 0.5]]), q)[0][0]  # inside both sheets, seen through the near one
        assert img[int(round(cy)), int(round(cx))] == 200
        fx, fy = posed(np.array([[1.35, 0.0, -0.5]]), q)[0][0]  # the far sheet alone
        assert img[int(round(fy)), int(round(fx))] == 60


@pytest.mark.parametrize("q", [Q_SRC, np.array([0.0, 0.0, 0.0, 80.0, 120.0, 120.0]) + [0.2, 0.5, 0.3, 5, 3.4, -2.7]],
                         ids=["source pose", "turned"])
def test_render_matches_the_surface_texture(q):
    """Zero rotation (the source pose) must reproduce the photo inside the mesh; a turned render must show
    the texture of the surface points a slow barycentric reference says each pixel sees."""
    V, tri = dome()
    photo = photo_of_dome(V)
    src_uv, _ = posed(V, Q_SRC)
    img, drawn = render(photo, src_uv, *posed(V, q), tri, np.zeros((SIZE, SIZE), np.uint8))
    ref, core = reference_render(V, tri, q)
    assert core.sum() > 5000 and drawn[core].all()
    err = np.abs(img[core].astype(float) - ref[core])
    if q is Q_SRC:
        assert np.abs(img[drawn].astype(float) - photo[drawn]).mean() < 0.5  # the photo itself
    # bilinear sampling of an 8-bit texture varying by up to ~4 grey levels per pixel
    assert err.mean() < 1.5 and np.percentile(err, 99) < 6.0


@pytest.mark.shared_data
def test_real_photo_rolled_matches_opencv_rotation():
    """A helen_train photo on a flat mesh (Delaunay triangles of its 68 labels): the identity render
    reproduces it; a 30-degree roll about a point equals cv2.warpAffine's rotation of the photo there."""
    from scipy.spatial import Delaunay

    from aamtrack.io.dataset import find_pairs, load_pair

    img_path, pts_path = find_pairs(shared_path("300w", "helen_train"))[0]
    photo, pts = load_pair(img_path, pts_path)
    tri = Delaunay(pts).simplices
    c = pts.mean(0)
    V = np.column_stack([pts[:, 0] - c[0], -(pts[:, 1] - c[1]), np.zeros(len(pts))])  # model frame, y up
    tri = orient_triangles(tri, V)
    bg = np.zeros_like(photo)
    q0 = np.array([0.0, 0.0, 0.0, 1.0, c[0], c[1]])
    img, drawn = render(photo, pts, *posed(V, q0), tri, bg)
    assert drawn.sum() > 1000
    assert np.abs(img[drawn].astype(float) - photo[drawn]).mean() < 0.5
    q = q0.copy()
    q[2] = np.radians(30.0)  # roll: model +z rotation, counter-clockwise on screen
    img, drawn = render(photo, pts, *posed(V, q), tri, bg)
    expect = cv2.warpAffine(photo, cv2.getRotationMatrix2D((float(c[0]), float(c[1])), 30.0, 1.0),
                            photo.shape[::-1], flags=cv2.INTER_LINEAR)
    core = cv2.erode(drawn.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert core.sum() > 1000
    assert np.abs(img[core].astype(float) - expect[core]).mean() < 1.0  # grey levels


def test_the_band_draws_the_head_past_its_jaw_line():
    """pose_check's renders: Candide's mesh alone ends inside the labelled jaw line, so a frontal render of it
    puts the jaw landmarks' truth on the background; with the band (``BAND``) every jaw landmark lies on the
    drawn head, at least 2 px inside its edge, frontal, pitched, rolled and turned by up to 30 degrees. The band
    leaves the mesh's own vertices where they were."""
    from pose_check import BAND, CANVAS, TexturedFace, true_q

    from aamtrack.model import load_model
    from aamtrack.models import default_model_path

    model = load_model(default_model_path("3d"))
    sm = model.shape
    photo = np.random.default_rng(SEED).integers(60, 200, (CANVAS, CANVAS, 3), dtype=np.uint8)
    bg = np.zeros((CANVAS, CANVAS, 3), np.uint8)
    for band, inside in ((0.0, False), (BAND, True)):
        fit_p = np.r_[true_q(model, None, (0, 0, 0), False), np.zeros(sm.n_shape)]
        face = TexturedFace(model, photo, fit_p, "noise", band=band)
        assert np.allclose(face.src_uv[:sm.n_vertices], posed(sm.shape3d(fit_p[:sm.n_q], None), fit_p)[0])
        # (turned further, the far side's jaw points are the head's silhouette itself, as in photos)
        for pose in ((0, 0, 0), (0, 15, 0), (-30, 0, 0), (30, 0, 0), (0, 0, 30), (15, 30, 30)):
            q = true_q(model, None, pose, False)
            uv, z = face.view(q)
            _, drawn = render(photo, face.src_uv, uv, z, face.triangles, bg)
            core = cv2.erode(drawn.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
            jaw = np.round(sm.landmark_map[:17] @ uv[:sm.n_vertices]).astype(int)
            on = core[jaw[:, 1], jaw[:, 0]]
            if inside:
                assert on.all()
            elif pose == (0, 0, 0):  # turned, the mesh alone covers some of the far side's jaw points
                assert not on.any()


def test_the_warped_texture_puts_each_labelled_point_on_its_landmark():
    """pose_check's default textures (``--source warped``): the photo is drawn so its human-labelled points fall
    on the model's 68 landmarks, whatever the landmark fit left between them; a marker drawn at each labelled
    point lands on its landmark's truth in renders at other poses (within a pixel), and without the warp it lands
    as far off as the labels were (here a smooth 3-5 px displacement)."""
    from pose_check import BAND, CANVAS, TexturedFace, true_q

    from aamtrack.model import load_model
    from aamtrack.models import default_model_path

    model = load_model(default_model_path("3d"))
    sm = model.shape
    fit_p = np.r_[true_q(model, None, (0, 0, 0), False), np.zeros(sm.n_shape)]
    fitted = sm.landmarks(fit_p[:sm.n_q], None)
    centre = fitted.mean(0)
    labels = fitted + np.c_[3.0 + 0.02 * (fitted[:, 1] - centre[1]), 4.0 - 0.02 * (fitted[:, 0] - centre[0])]
    bg = np.zeros((CANVAS, CANVAS, 3), np.uint8)
    ys, xs = np.mgrid[:CANVAS, :CANVAS]
    for points, within in ((labels, 1.0), (None, None)):
        face = TexturedFace(model, bg, fit_p, "markers", band=BAND, points=points)
        for pose in ((0, 0, 0), (10, 15, 0), (0, -15, 10)):
            q = true_q(model, None, pose, False)
            truth = sm.landmarks(q, None)
            errors = []
            for i in (30, 36, 45, 48, 54, 57, 8, 19, 24):  # nose tip, eye and mouth corners, lip, chin, brows
                face.image = np.zeros((CANVAS, CANVAS, 3), np.uint8)
                cv2.circle(face.image, tuple(int(round(v * 16)) for v in labels[i]), 2 * 16, (255, 255, 255), -1,
                           shift=4)
                r = face.render(q, bg)[..., 0].astype(float)
                assert r.sum() > 0, (pose, i)
                errors.append(np.hypot((xs * r).sum() / r.sum() - truth[i, 0], (ys * r).sum() / r.sum() - truth[i, 1]))
            if within is not None:
                assert max(errors) < within, (pose, np.round(errors, 2))  # px
            else:
                assert min(errors) > 2.5, (pose, np.round(errors, 2))  # px: the labels' displacement, turned


def test_sweep_bins_group_frames_by_turn_and_count_the_confident_wrong_ones():
    """The yaw sweep's table (``pose_check.sweep_bins``) on hand-made frames: grouped by |yaw| either way, lost
    frames counted but kept out of the means, and a tracked frame off by more than the bound counted wrong."""
    def row(yaw, error=None, estimate=None, confidence=0.0):
        return {"yaw": yaw, "success": error is not None, "error": error, "yaw_estimate": estimate,
                "confidence": confidence}

    rows = [row(3.0, 0.03, 5.0, 1.0), row(-10.0, 0.05, -4.0, 0.8),  # 0-15: both tracked, 2 and 6 degrees off
            row(20.0, 0.04, 18.0, 1.0), row(-29.9, None),            # 15-30: one lost
            row(61.0, 0.30, 40.0, 0.9), row(-70.0, 0.10, -50.0, 0.7), row(74.0, None)]  # 60-75
    bins = sweep_bins(rows, width=15, wrong=0.10)
    assert [(b["from"], b["to"], b["frames"], b["tracked"]) for b in bins] == [(0, 15, 2, 2), (15, 30, 2, 1),
                                                                               (60, 75, 3, 2)]
    assert bins[0]["error_mean"] == pytest.approx(0.04) and bins[0]["wrong"] == 0
    assert bins[0]["confidence_mean"] == pytest.approx(0.9) and bins[0]["yaw_error_median"] == pytest.approx(4.0)
    assert bins[1]["error_mean"] == pytest.approx(0.04) and bins[1]["yaw_error_median"] == pytest.approx(2.0)
    assert bins[2]["wrong"] == 1  # 0.30 is wrong; 0.10 is not above the bound
    assert bins[2]["error_mean"] == pytest.approx(0.20) and bins[2]["yaw_error_median"] == pytest.approx(20.5)
    assert sweep_bins([row(80.0, None)])[0]["error_mean"] is None  # a bin with nothing tracked has no mean
