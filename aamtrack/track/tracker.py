"""Video tracker: detection, then frame-to-frame active search, confidence, loss and re-detection.

``Tracker.track(frames)`` is a generator: it takes frames (objects with ``index``, ``timestamp``, ``image``
(BGR/grey or None) and optionally ``dropped``) and yields one FrameResult per frame, in order. Its loop state
(the current parameters, the person's sigma) lives in the generator's locals, so one Tracker can serve several
videos. With several faces in view the largest is tracked.
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, replace
from typing import Iterable, Iterator

import numpy as np

from ..detector import HaarDetector, guess_points, mirrored, unturn
from ..imaging import crop_gray32, frame_structure, smoothed, thumbnail, unsharp
from ..io.pts import N_LANDMARKS
from ..mesh.landmark_fit import LandmarkFitter
from ..mesh.landmarks import mirror_points, similarity_fit
from ..mesh.shape_model import N_POSE, initial_pose
from ..mesh.skirt import JAW
from ..metrics import PIXEL_ORIGIN, nme
from ..model import Model
from ..search import Searcher
from ..result import FitResult, FrameResult
from .replay import ReplayFrame

log = logging.getLogger(__name__)

TRACKED_STARTS = ("auto", "landmarks", "similarity", "search")
BACKFILL_REASON = "tracked back from frame {}"  # ``FrameResult.reason`` of a frame tracked back from a detection


def weighted_median(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """Per column of ``values`` (n, m), the weighted median: the smallest value whose sorted predecessors and
    itself carry at least half the total weight (``weights`` (n,), positive). With equal weights and an even n it is
    the lower of the two middle values, not their mean."""
    values = np.asarray(values, float)
    order = np.argsort(values, axis=0, kind="stable")
    cum = np.cumsum(np.asarray(weights, float)[order], axis=0)
    k = (cum < 0.5 * cum[-1]).sum(axis=0)  # the first sorted position reaching half the weight
    cols = np.arange(values.shape[1])
    return values[order[k, cols], cols]


def _motion(p: np.ndarray, q: np.ndarray) -> tuple[float, float]:
    """(turn, rescale) from search vector q to p: the largest change of the three angles (radians) and |log| of
    the scale ratio."""
    return float(np.abs(p[:3] - q[:3]).max()), abs(float(np.log(p[3] / q[3])))


@dataclass(frozen=True)
class TrackerConfig:
    """min_confidence: below it (the model's fit validator) a frame's fit is not accepted; the detector then runs
    (at once in the same frame for a tracked one, ``redetect_lost``; else on the next frame).
    redetect_lost: a tracked frame whose search is lost is looked for again at once in the same frame (the
    detector's thorough search, as the next frame would have it), and reported as a detection if that fit is
    accepted. A face that jumps further than the tracked search reaches (a hand-held camera's shake, a quick head
    move) was lost for a frame each time: the robustness suite's shake (cap12 moved by jumps of up to 0.35 eye
    distances a frame, 3D): 85.1% of its frames tracked -> 100%; frames a tracked search keeps cost nothing more.
    min_inside: share of the 68 landmarks that must lie inside the frame. A face partly out of the frame is fitted
    on what the frame shows (where its crop reaches the frame's edge, ``Tracker.crop``, the search's texture pixels
    and the landmark cascade's patches outside it count as missing: ``_kernels.warp._fill_outside``,
    ``_kernels.patches._blank_outside``), so half a face can be kept
    (0.7 before those; see benchmarks/README.md, "robustness.py", partly out of the frame).
    max_turn, max_rescale: a frame whose fit turned more than ``max_turn`` radians about any axis or rescaled
    by more than ``max_rescale`` (log) since the previous frame is taken as lost: no head does that in 1/25 s,
    a search that slid onto the background does (the residual alone can miss it on textured backgrounds).
    max_shape_score: a fit whose 68 points score above this as a face shape (``Model.shape_prior``,
    ``mesh.shape_prior``: about 1 for a hand label, lower for the tracker's usual fits) is taken as lost, whatever
    its confidence: the points no longer make a face (an occluder's edge pulled the mouth and chin up, a mesh left
    behind by a head turned past profile or by a camera jump). 0 turns the test off. Set above every fit measured
    on faces as they are (2026-11-29, shipped 3D model: helen_test's 327 fits 0.98 at most, cap12's frames 0.76,
    the robustness suite's video variants 0.94, its still variants 1.05) with a margin; what it changed is in
    benchmarks/README.md ("occlusion.py").
    shape_recheck_above: an accepted tracked fit whose points score above this (but not above
    ``max_shape_score``) gets a second look: the same frame's detection fit (``detect_and_fit``, quick) replaces it
    when accepted and of a more plausible shape (``_second_look``). No frame of cap12 or of the robustness suite's
    variants but the shaken one scores above 1.0 (0.94 at most), so it costs them nothing but the score (about 4
    us a frame); measured 2026-11-29 (3D): occlusion.py's hand over the mouth, covered frames above NME 0.10 29 ->
    22 (NME 0.0849 -> 0.0812), half face 51 -> 49; robustness shake 0.0228 -> 0.0222; still_shots 95.0% -> 94.9%
    within 0.08 (41 above 0.10 either way); hard clips as before. 0 turns it off.
    roi_margin: the search works on a crop of the face's box grown by this share of its size on each side.
    roi_margin_tracked: the same on tracked frames. The search's own reach (about 0.3 eye distances from the
    motion-predicted start) is smaller than either margin, so a tighter crop loses no more faces: the robustness
    suite's shake (jumps of up to 0.35 eye distances a frame), 3D, without ``redetect_lost``: 199 frames lost at
    0.3, 207 at 0.15. At 0.2 instead of 0.3 (2026-11-28): a tracked 640x480 frame's crop and feature levels cost
    0.12 ms less (1.59 -> 1.47 ms, pyramid + search, in place on the sample clip), cap12 3D 0.0275 -> 0.0276, 2D
    0.0259 -> 0.0260, robustness video rows within 0.0003 (dim_small 96.3% -> 96.0% tracked), hard clips the
    same (hard2 0.0396 -> 0.0399), still_shots 3D 93.8% -> 93.9% within 0.08, 2D 89.2% -> 89.0%.
    predict: constant-velocity prediction of the pose (damped by ``predict_damping``).
    sigma_frames: 3D models search the person's shape units with the pose in this many good frames (fits of
    confidence at least ``sigma_min_confidence``, so a poor fit of the first frames cannot set the person's
    shape), then hold the median of those estimates (0: search them in every frame). One person per shot is
    assumed: sigma is kept through losses and re-detections, and estimated anew after a shot change
    (``sigma_per_shot``).
    sigma_restart: while the person's shape units are being estimated, a tracked frame's search starts them at
    the median of the estimates so far (the previous fit's pose and coefficients refitted to its landmarks with
    that shape: ``tracked_start``), not at the previous frame's fit; before the first estimate, at the previous
    fit's (a face never fitted confidently, e.g. turned far, would restart at 0 every frame: worse fits).
    Carried from frame to frame, pose and shape walked together along what the 68 2D points cannot tell apart
    (pitch against the face's depth proportions): an unchanging frame of the sample clip shown 60 times pitched
    by 4.3 degrees more over frames 20-59 (0.3 with the restart), a render of a frontal face (``pose_check.py``'s
    drift) by 8 degrees over the estimate's 50 frames (1.2 for the whole 100 with it). Measured when added
    (2026-11-28, shipped 3D model, restart against the previous frame's): cap12 against dlib 0.0277 -> 0.0264;
    robustness video rows all still pass, clean 0.0262 -> 0.0249, dim_small 96.2% / 0.0337 -> 96.0% / 0.0316;
    hard clips 2, 4-7 0.0393 / 0.0314 / 0.0300 / 0.0350 / 0.0306 -> 0.0388 / 0.0306 / 0.0278 / 0.0310 / 0.0286;
    still_shots within 0.08 93.8% -> 94.3% (12 more frames above 0.10, all in the one shot that follows the
    mirrored copy of its face either way); pose check video geodesic median / p95 7.04 / 13.05 -> 6.45 / 11.52
    (with expression 7.04 / 9.06 -> 6.80 / 9.60). Restarting at 0 instead of the median measured better on cap12
    (0.0251) and worse on dim_small (93.5% tracked, under the 95% bar) and hard2 (0.0455).
    sigma_running: while the person's shape units are being estimated, every search of a clear face after the
        first estimate holds them at the median of the estimates so far (as it holds the final median after), and
        every frame reports its pose, shape units and 3D landmarks with the median as it stands (its own estimate
        in), so the estimate's end changes nothing: with the search's shape units free until the median was held,
        the pose stepped once at frame ``sigma_frames`` (three frames of the sample clip each shown 60 times:
        1.7 / 2.1 / 2.7 degrees of pitch, 0.00 with it; pitch range over all 60 frames 1.9 / 2.2 / 2.7 -> 0.8 /
        1.0 / 1.5 degrees, all but 0.03 of it in the first five frames). A dim face's search still searches them
        (``FitResult.dim``): its estimate is the search's own (``shape_sample``), which a held search would only
        repeat, locking the first frames' median in (held there too: robustness dim_small 97.0% -> 96.1% tracked,
        +0.0103 -> +0.0107). Measured when added (2026-11-29, shipped 3D model, against the search's free shape
        units): robustness video rows the same within 0.0001 but shake +0.0029 -> +0.0034; hard clips 2, 4-7 the
        same; still_shots 92.6% -> 92.5% within 0.08, 132 -> 120 frames above 0.10; ``pose_check.py --grid axes
        --faces 4``: drift over 100 frames of a frontal render, pitch 1.6-2.9 -> 0.25-0.54 degrees, yaw 0.2-0.7 ->
        0.16-0.42; video geodesic median / p95 4.36 / 8.54 -> 4.54 / 8.69 (with expression 3.94 / 8.24 -> 3.89 /
        8.53); ``video_pose.py`` (cap12's turns against MediaPipe's) the same: pitch / yaw RMS 2.68 / 1.50 -> 2.68
        / 1.52; stills (``fit_still``) unchanged.
    sigma_yaw_weight: the median of the shape estimates (``sigma_frames``, ``sigma_running``) is weighted by how
        frontal each frame's search read the face, exp(-(yaw / sigma_yaw_weight)^2) (radians; 0: the plain median).
        A turned face's 68 points read the shape with the turn (the far jaw line is the head's silhouette, not
        Candide's jaw vertices), so frames turned by more than about the weight count for little while frontal
        ones are there, and a shot that is turned throughout keeps its estimates, all weighed about alike (the
        weights are relative). Measured when added (2026-11-29, shipped 3D model, against the plain median):
        ``pose_check.py --grid axes --faces 4`` video geodesic median / p95 4.54 / 8.69 -> 4.10 / 7.77 (with
        expression 3.89 / 8.53 -> 3.44 / 7.35; weight 0.35: 4.21 / 7.94 and 3.50 / 7.33); ``still_shots.py``
        92.5% -> 92.6% within 0.08, median shot mean 0.0385 -> 0.0380, 120 frames above 0.10 either way (0.35:
        0.0382); robustness video rows within 0.0001 (dim_small 97.0% -> 97.2% tracked, +0.0103), hard clips and
        cap12 (0.0195 against dlib) the same. Dropping the turned frames' estimates instead (|yaw| above 0.35)
        lost the shots turned throughout: median shot mean 0.0407.
    sigma_from_landmarks: each of those estimates is the landmark fit's shape units (``Tracker.shape_sample``:
    pose, coefficients and shape units fitted to the fit's final 68 points, as the poster's sigma learning fits
    annotated points), not the texture search's; a dim face's fit gives the search's (its points follow the
    noise: with them too, robustness dim_small 96.0% / 0.0316 -> 95.3% / 0.0333, hard2 0.0388 -> 0.0430).
    Measured when added (2026-11-28, with ``sigma_restart``, against the search's estimates): cap12 against dlib
    0.0264 -> 0.0257 (the 2D model: 0.0260), MediaPipe's 11 points 0.0271 -> 0.0274; robustness video rows all
    pass, clean 0.0249 -> 0.0242, mirror 0.0252 -> 0.0244, the others -0.0007 to +0.0003 (overexposed 0.0238 ->
    0.0241; dim_small the same: its fits are dim); hard clips the same but hard5 0.0278 -> 0.0287, hard7 0.0286
    -> 0.0268; still_shots 94.3% / 0.0394 / 62 above 0.10 -> 94.3% / 0.0386 / 58; pose check (band 0.25) video
    geodesic median / p95 5.19 / 7.44 -> 4.54 / 7.12. Fitted to the points less the landmark cascade's shape
    term's move (as ``landmark_start``): pose 3.84 / 7.65 but cap12 0.0271. Three steps reach scipy's
    least-squares answer (a test); about 0.2 ms, on the first ``sigma_frames`` confident frames only.
    pose_from_points: a 3D fit's reported pose (rotation, translation, scale: the CSV's pose columns, the overlay's
    axes) is that of a landmark fit (``Tracker.reported_pose``: two Gauss-Newton steps from the search's fit, the
    shape units held) to the final points without the 17 jaw points, rather than the texture search's own. The
    jaw points are the tracker's least accurate (helen_test stills, 3D: NME 0.060 on them against 0.016 on the
    eyes), and Candide's are fixed points of the mesh, where a turned face's far jaw line is its silhouette: the
    search's pose, and a fit to all 68 points, read a head's turn short. Measured when added (2026-11-28,
    ``benchmarks/pose_check.py --grid axes``, textures warped onto the labels), geodesic median / p95: 4 faces,
    still fits (``fit_still``) 4.82 / 13.05 -> 4.84 / 9.47 (with expression 5.07 / 15.95 -> 4.97 / 11.24), video
    4.43 / 7.82 -> 4.62 / 7.84 (3.91 / 7.66 -> 4.08 / 7.63): the turned stills' error falls, video is about the
    same (pitch better, yaw worse: median 3.74 -> 3.04, 1.65 -> 2.32); the first 2 faces alone: fit 5.04 / 12.73
    -> 4.74 / 8.51, video 5.55 / 8.50 -> 4.70 / 7.84; from all 68 points instead: fit 7.23 / 15.14, video 6.81 /
    12.82. On cap12 the pose moves less from frame to frame (median change of pitch 0.22 -> 0.16 degrees, yaw 0.18
    -> 0.14) and reads the head 7 degrees less pitched (mean -23.9 -> -16.5 degrees; no absolute truth there), and
    its turns follow MediaPipe Face Mesh's 3D points more closely (each frame's rotation of their mean shape,
    generalised Procrustes, deviations from the video's mean compared: RMS difference pitch / yaw / roll 3.92 /
    1.92 / 0.72 -> 2.49 / 1.52 / 0.57 degrees, correlation of pitch 0.72 -> 0.86). On dim
    faces (``hard_clips.py`` hard2, hard4, hard6: every fit dim) it moves 10-25% more than the search's (the points
    follow the noise: pitch median 1.15 -> 1.39, 0.70 -> 0.88, 0.81 -> 1.05 degrees); dim fits are not left out,
    as the shape estimates leave them out, because a pose switching source with the dim flag would jump by the
    two's difference (median 7 degrees of pitch on cap12). The mesh, 3D landmarks and animation units stay the
    search's; the points are the same.
    skip_coarse: a detection's second search (``refine_detection``) skips this many of the coarsest couples (they
    give the capture range the first search needs).
    skip_coarse_tracked: frames tracked from the previous frame skip this many of the coarsest couples
    (frame-to-frame motion is smaller than a detection's error); None (default): 2 for 3D models (only the finest
    couple searches), 1 for 2D ones. From the landmark start (``tracked_start``) the 3D model's middle couple
    pulled fits of faces it fits less well away from the points (``still_shots.py``, 3D: frames within NME 0.08
    82.3% -> 89.8%, tracked frames above 0.10 218 -> 85; cap12 0.0223 -> 0.0222 raw, at 5x speed 0.0224 ->
    0.0226), and it costs a couple's search less; the 2D model gained on the shots (89.1% -> 90.3%) but lost on
    cap12 (0.0244 -> 0.0295, its jaw). For detections, 2 measured worse on helen_test stills (3D: 95.5% -> 94.8%
    within 0.08). Capped so that the finest couple always searches.
    coarser_below: a tracked frame searched with fewer couples than ``skip_coarse`` allows whose confidence is
    below this is searched again from the same start with those couples, and the more confident fit kept: the
    middle couple is what holds noisy and blurred frames (cap12 with noise of sd 25, 3D: +0.0119 over clean with
    the finest couple alone, +0.0085 with this at 0.99; blur +0.0265 / +0.0214), at the cost of a second search on
    those frames only (still shots 89.8% -> 90.4%). 0 never does. A frame judged by the model's validator for dim
    faces (``FitResult.dim``) is searched so whatever its confidence, and the second search kept unless less
    confident: that validator reads 1.0 on most noisy faces (cap12 with noise of sd 25: +0.0035 without this).
    refine_detection: after a detection, search once more from the chosen fit, as a tracked frame would
    (helen_test stills, 3D: share below NME 0.05 55.2% -> 58.2%, median 0.0462 -> 0.0449).
    starts: after a detection the search runs from each (scale factor, vertical shift as a share of the face
    width, roll in radians) applied to the rough pose from the box, and keeps the most confident fit (Haar
    boxes vary in scale and in how far down the face they sit, and say nothing of roll).
    turned_retry_below: a detection found upright whose best fit is less confident than this also tries the
    detector's turned frames (``Tracker.detect_and_fit``); 0 never does.
    sharpen_soft, sharpen_amount: a still (``fit_still``, ``aamtrack fit``) whose own fit reads as a soft face
    (``FitResult.soft``: the soft landmark cascade took it) is fitted again, detection and all, on the image
    unsharp-masked (``imaging.unsharp``: Gaussian sigma ``sharpen_soft`` times the fit's outer eye-corner
    distance, ``amount`` ``sharpen_amount``), and that fit is kept if accepted and more confident (or the only one
    accepted). helen_test blurred by 0.03 / 0.06 / 0.09 eye distances (shipped 3D model, /tmp harness, the
    first look's points as the only size guess): within NME 0.08 96.4% -> 97.6%, 91.8% -> 94.8%, 78.5% -> 86.4%,
    mean over the fits 0.0386 -> 0.0376, 0.0432 -> 0.0415, 0.0491 -> 0.0469; clean helen_test has no soft fit and
    is unchanged. Costs a second ``fit_still`` on soft stills only. 0 never does. (Not for video frames: the
    robustness suite's blurred video passes without it, and a frame has no time for a second look.)
    smooth_dim: a still whose fit was refused and judged as a dim, noisy face's (``FitResult.dim``: the validator
    for those) is fitted again, detection and all, on the image smoothed by a Gaussian of ``smooth_dim`` times
    that fit's outer eye-corner distance (``imaging.smoothed``), and that fit kept if accepted. Sensor noise
    on a small, dark face is what both Haar and the search trip on; smoothing by 0.015 eye distances (0.7 px on a
    face 45 px between the eyes) divides white noise's sd by about 2.4 and barely softens the face. The robustness
    suite's stills (helen_test, shipped 3D model, ``benchmarks/robustness.py --video none``): dim_small 87.3% ->
    89.7% within NME 0.08 (fitted 301 -> 311, mean NME of the fits 0.0444 -> 0.0450; 0.022: 89.1%, 0.035: 89.1%),
    2D 88.2% -> 89.4% (306 -> 310); noise 97.3% -> 97.6% (323 -> 326, 0.0349 -> 0.0359); the other 13 still rows
    the same to the digit; 150 noise stills (``tests/test_shipped_models.py``'s set) none fitted either way. Every
    dim still smoothed instead, the smoothed look the only one (/tmp harness, 1.0 px): 80.3%: the search reads a
    smoothed face less well than a noisy one where both are found, so it is a second look only. Costs a second
    ``fit_still`` on refused dim stills only (dim_small 271 -> 316 s for its 330, each run beside another). 0
    never does. (Not for video frames, as ``sharpen_soft``.)
    landmark_stages_tracked: on a tracked frame, only the last this many stages of the landmark cascade
    (``aamtrack.landmark_cascade``) run, from the search's points (0, the default: all of them); detections run
    all. Two stages (the default before 2026-11-22) were nearly as good on cap12 (raw NME 0.0241 against 0.0232
    for all four) but not on faces unlike the training set's: the first stage's large patches are what brings
    the search's points back, and a search from the previous frame leaves them about as far off as a detection's.
    All four cost about 0.17 ms a frame more (each stage about 0.09 ms on one core; descriptors 0.06, regression
    0.02).
    tracked_start: where a tracked frame's search starts. "landmarks": the previous fit moved by one Gauss-Newton
    step of the landmark fit (pose and coefficients, the person's shape held) onto the previous frame's final
    landmarks (``Tracker.landmark_start``); "similarity": the previous fit moved in the image plane only (roll,
    scale, translation; ``Tracker.realign``); "search": the previous search's own result (before 2026-11-22);
    "auto" (default): "landmarks" for 3D models, "similarity" for 2D ones. The update cascades are learned for
    one pass from perturbed starts; run again and again from their own output they walk off faces they do not
    fit well, while the landmark cascade's points are the better estimate of where the face is. Measured with
    ``benchmarks/still_shots.py`` (held-out helen_test photos played as shots; figures in benchmarks/README.md):
    3D "landmarks" ahead of "similarity" (and of "search" by far), which leaves yaw, pitch and the animation
    units to the search; 2D "similarity" ahead of "landmarks" (which moves only the 2D model's PCA modes: cap12
    0.0260 -> 0.0289 with it). With "auto", a 2D track starts from "landmarks" after a soft face's fit
    (``FitResult.soft``, the soft landmark cascade's points): on blurred faces the 2D search from the similarity
    start walks off where the landmark start holds it (the robustness suite's blur video, 2D: NME 0.0530 ->
    0.0399; with "landmarks" on every frame 0.0399 too, but clean 0.0233 -> 0.0272); its other rows, still_shots
    and cap12 are unchanged (no soft frames). A start given explicitly holds for every fit.
    start_expression: a 3D "landmarks" start (``Tracker.landmark_start``) of a clear face's fit takes this share
    of the landmark fit's animation units and the rest from the search's own: the landmark fit reads the
    expression from the cascade's final points, the next search and cascade start from it, and on a face the
    model fits less well that loop feeds on itself (a bearded man in ``still_shots.py``: NME 0.059 at the
    detection, the mouth and jaw walking down into the beard frame by frame, 0.12 from the fifth frame on at
    confidence 0.99). Half of each breaks the loop there (its 60 frames 0.0501; all 40 shots within 0.08 92.5% ->
    94.9%, 600-frame shots 90.3% -> 98.6%; cap12 0.0195 -> 0.0196, helen_test 0.0339 -> 0.0340); dim faces'
    starts (whose points follow the noise) are left as they were (with them too: hard2 0.0359 -> 0.0370). 1.0:
    the landmark fit's alone (before 2026-12-02).
    cut_below: a frame whose thumbnail (``imaging.thumbnail``, 32x24 grey) correlates with the previous frame's
    below this is a new shot: the track restarts with a detection rather than searching from a face that is no
    longer there (0 never does). Consecutive frames of cap12 correlate at 0.90 or more (0.98 at the 1st
    percentile), the cuts between ``still_shots.py``'s photos at 0.70 at most (median 0.08), hard cuts within
    cap12 (light changes, black) at 0.49 at most; a uniform frame (a thumbnail of zeros) counts as a change too.
    About 0.06 ms a frame, in the decoding thread when the frames come from ``pipeline.grey_frames`` (``aamtrack
    run``).
    sigma_per_shot: the person's shape (``sigma_frames``) is estimated anew after a shot change: a cut may show
    another person, and a held sigma that is not theirs costs more than the estimate's first frames
    (``still_shots.py``, each shot another person: see benchmarks/README.md).
    landmark_pass: an accepted detection's fit is searched once more as the next frame of a video would be
    (``search_from`` from ``tracked_start``: from the landmark cascade's points for 3D models), the landmark
    cascade run again, and the more confident fit kept. A still (``aamtrack fit``) is then fitted as a video's
    second frame of it would be: helen_test stills, shipped 3D model mean NME 0.0356 -> 0.0346 (median 0.0321 ->
    0.0321, within 0.08 97.0% -> 97.6%), 2D 0.0351 -> 0.0349; the models before (2026-11-26) 3D 0.0375 -> 0.0366,
    2D 0.0356 -> 0.0355 (keeping the pass's fit always measured the same). Costs a tracked frame's search on
    detection frames only.
    rescue: when the detection's fit is still not accepted (confidence below ``min_confidence``), the search
    also runs from the box moved by each (x shift, y shift, scale) (shifts in box widths, about the box's
    centre), all on one crop, and the most confident fit is kept (``Tracker.rescue``). Haar's box can sit on
    a face's forehead and hair under side light, where no start of the box itself reaches the face; () never
    does. Costs about as much as one detection's fit, on frames where a box was found but its fit failed.
    more_boxes: a detection's fit still not accepted after ``rescue`` tries up to this many other boxes in turn
    (``HaarDetector.more``: the upright search's smaller boxes, then searches after other equalisations and with
    a second cascade) until one's fit is accepted, and keeps the most confident fit: under uneven light the
    largest box is often not the face (helen_test lit from one side, 23 of 330 rejected after rescue). Costs a
    detection's fit per box, on frames whose fits all failed (frames with no face at all, where Haar finds
    nothing, cost only the searches); 0 never does.
    thorough_every: while a video has no accepted face, the detector's costly searches (uneven light, the
    smallest faces: ``HaarDetector.find``) and ``more_boxes`` run on the first frame of each loss (and of each
    shot change while tracking) and then on every this many frames; the frames between run the quick searches
    only. A frame with no face costs 2 to 13 times as much with them (one core: grey 640x480 28 against 56 ms;
    1920x1080 grey 26 against 286 ms, cap12's background 94 against 834 ms, dark sensor noise 0.33 against 4.4 s),
    so a long stretch without a face would crawl; with 8, a lost 1920x1080 frame costs on average 65 / 186 / 845
    ms (30 / 97 / 335 ms before these searches), and a small or side-lit face that comes into view is found within
    8 frames. 1: every frame.
    lost_stride, lost_stride_after: once a video has gone ``lost_stride_after`` frames without an accepted face
    (the count ``thorough_every`` keeps), only every ``lost_stride``-th frame runs the quick searches (the
    thorough ones keep their schedule); those frames and the ones between are reported lost with "no face detected
    (1 frame in 3 searched ...)" (one kind of reason for the events log), and a face found a frame or two later is
    tracked back over the frames not searched (``backfill``). 1: every frame, as
    before 2026-12-01. A frame without a face costs the searches for one, 30-300 ms at 640x480 against about 2 ms
    tracked; measured 2026-12-01 (Intel Xeon VM, one core, /tmp harness: the sample clip with frames 100-249
    replaced by ``hard_clips.py``'s dark, noisy empty room, the person leaving for 6 s), 3: 68.1 -> 38.4 s and
    119 -> 51 s for the 302 frames in two runs, 74 of the 150 empty frames not searched, every face frame tracked
    either way and the face back on its first frame; ``hard_clips.py``'s hard2 (a far, dim face found on some
    frames only, 92 lost) to hard7, the robustness suite's video rows (blank gaps of 20 frames) and
    ``still_shots.py`` the same to the digit. Refused fits count too: counting only frames where
    Haar found nothing, the noisy room's false boxes kept restarting the count (45 frames not searched).
    dim_tracked_min, dim_recent, dim_near: a fit judged by the validator for dim faces (``FitResult.dim``) is
    accepted from confidence ``dim_tracked_min`` instead of ``min_confidence`` when it follows an accepted fit of
    the previous frame (a tracked frame), or when it lies where a fit was accepted at most ``dim_recent`` fitted
    frames before in the same shot (frames where no face was found to fit do not count; centres within ``dim_near``
    face widths, size and pose within ``max_rescale`` and ``max_turn``: ``Tracker._near``). That validator's bias
    was lowered until it accepts no more held-out non-faces than about the landmark validator does (0.7%,
    ``TrainConfig.wary_rate``), at the cost of 12% of good dim fits held out; a face that was just there is most
    likely still there. cap12 shrunk to 45 px between the eyes, dark and noisy (the robustness suite's dim_small,
    3D): tracked 88.7% -> 95.9%, NME 0.0329 -> 0.0327; its lost frames' fits had NME 0.035-0.06 at confidences
    0.07-0.45. Frames of a shot with no accepted fit, and clear faces, still need ``min_confidence``; a cut
    (``cut_below``) forgets the recent fit.
    dim_min_structure: a fit judged by the validator for dim faces is refused, whatever its confidence, in a frame
    whose variation is at the grain of noise (``imaging.frame_structure`` below this; 0: no such check). That
    validator accepted fits of blurred noise that Haar's smallest searches take for faces, in the image and in its
    mirror alike (``fit_still``); over 330 noise stills (/tmp, 2026-11-30: Gaussian, blurred 0-3 px, and other
    textures) the 3D model fitted 13, nine of them so, at frame structures 0.13-0.20; now those nine are refused
    (the other four, noise blurred by 3-8 px into blotches, were judged by the landmark validator and are left).
    The faces of the robustness suite (helen_test and cap12 under each of its variants) and ``hard_clips.py``
    read 0.35 or more but for small30_hd's (a small photo in a flat grey 1920 x 1080 frame: its variation is finer
    than the frame's eighth; 133 of 330 below 0.25), whose fits are not judged dim. A known blind spot: a dense
    crowd of very small faces varies at the faces' grain too (mosaics of helen_test faces, each tile 1.6 face
    widths: tiles of 40 px at 1280 x 720 and 45-60 px at 1920 x 1080, about 12-19 px between the eyes, read
    0.16-0.22; tiles of 45-90 px at 640 x 480 to 1280 x 720 read 0.25-0.49), so a dim fit of one such face is
    refused. A frame under 256 pixels on a side is not judged. Cost: only on frames with a dim fit, about 0.4 ms
    at 640 x 480.
    backfill: a stretch of lost frames that ends in a detection is tracked backwards from it, frame by frame
    (each searched from the next one's fit as a tracked frame is from the previous one's, and judged the same way,
    ``loss_reason``), until a fit is refused; those frames' results wait for it, at most this many (0: none), and
    never across a shot change. A face is often found a few frames after it comes back (small, dim, turned: the
    detector misses it, or the fit of a detection is refused where a tracked one is not). ``hard_clips.py``
    (2026-11-29, 3D, 12): hard2 190 -> 192 of 300 face frames tracked (NME 0.0421 either way), hard6 298 -> 300
    (0.0300), hard7 294 -> 300 (0.0251 -> 0.0252), hard4 and hard5 as before; robustness dim_small 96.1% -> 96.2%,
    the blank gaps never tracked. The results of a lost stretch come out up to this many frames late."""

    min_confidence: float = 0.5
    min_inside: float = 0.5
    max_turn: float = 0.35
    max_rescale: float = 0.25
    max_shape_score: float = 1.2
    shape_recheck_above: float = 1.0
    roi_margin: float = 0.3
    roi_margin_tracked: float = 0.2
    redetect_lost: bool = True
    predict: bool = True
    predict_damping: float = 0.5
    sigma_frames: int = 50
    sigma_min_confidence: float = 0.9
    sigma_restart: bool = True
    sigma_running: bool = True
    sigma_yaw_weight: float = 0.2
    sigma_from_landmarks: bool = True
    pose_from_points: bool = True
    skip_coarse: int = 1
    skip_coarse_tracked: int | None = None
    coarser_below: float = 0.99
    refine_detection: bool = True
    starts: tuple = ((1.0, 0.0, 0.0), (0.9, 0.0, 0.0), (1.1, 0.0, 0.0), (1.0, -0.06, 0.0), (1.0, 0.06, 0.0),
                     (1.0, 0.0, -0.21), (1.0, 0.0, 0.21))
    turned_retry_below: float = 0.9
    sharpen_soft: float = 0.05
    sharpen_amount: float = 2.0
    smooth_dim: float = 0.015
    landmark_stages_tracked: int = 0
    tracked_start: str = "auto"
    start_expression: float = 0.5
    cut_below: float = 0.6
    sigma_per_shot: bool = True
    landmark_pass: bool = True
    rescue: tuple = ((0.0, 0.3, 1.0), (0.0, -0.3, 1.0), (0.3, 0.0, 1.0), (-0.3, 0.0, 1.0), (0.0, 0.3, 1.25),
                     (0.0, -0.3, 1.25), (0.3, 0.0, 1.25), (-0.3, 0.0, 1.25))
    more_boxes: int = 3
    thorough_every: int = 8
    lost_stride: int = 3
    lost_stride_after: int = 25
    dim_tracked_min: float = 0.2
    dim_recent: int = 25
    dim_near: float = 0.25
    dim_min_structure: float = 0.25
    backfill: int = 12

    def __post_init__(self):
        if self.tracked_start not in TRACKED_STARTS:
            raise ValueError(f"tracked_start {self.tracked_start!r}: one of {', '.join(TRACKED_STARTS)}")
        if not 0.0 <= self.start_expression <= 1.0:
            raise ValueError(f"start_expression {self.start_expression!r}: a share between 0 and 1")


def _summed(a: dict, b: dict) -> dict:
    """Two results' stage timings (seconds by stage) added stage by stage."""
    return {k: a.get(k, 0.0) + b.get(k, 0.0) for k in {*a, *b}}


class Tracker:
    """Detection, frame-to-frame search, validation and re-detection for one model (see module docstring)."""

    def __init__(self, model: Model, *, config: TrackerConfig = TrackerConfig(),
                 detector: HaarDetector | None = None):
        self.model = model
        self.config = config
        self.searcher = Searcher(model)
        self._still = False  # inside ``fit_still`` (``fit_roi``)
        self.detector = detector or HaarDetector()
        self.mm_per_unit = model.shape.mm_per_unit()
        self._landmark_fitter = LandmarkFitter(model.shape)
        # (``reported_pose``: the landmarks without the jaw line's)
        self._pose_fitter = LandmarkFitter(model.shape, points=np.setdiff1d(np.arange(N_LANDMARKS), JAW))
        skip = config.skip_coarse_tracked
        skip = (2 if model.shape.kind == "3d" else 1) if skip is None else skip
        self.skip_tracked = max(0, min(skip, len(model.couples) - 1))  # the finest couple always searches
        how = config.tracked_start
        self.tracked_start_kind = ("landmarks" if model.shape.kind == "3d" else "similarity") if how == "auto" else how
        self.soft_start_kind = "landmarks" if how == "auto" else self.tracked_start_kind  # after a soft face's fit
        # the ROI needs to cover only what the texture maps sample (Candide's scalp is not in them)
        self.roi_vertices = np.unique(np.concatenate([t.frame.pix_vid.ravel() for t in model.textures]))

    # -- one image -------------------------------------------------------------------------------------
    def crop(self, image: np.ndarray, starts: list, margin: float | None = None) -> tuple:
        """One crop of the frame around the faces of all ``starts`` (grown by ``margin``, default ``roi_margin``)
        and its feature levels (built on demand): (levels, (x0, y0) of the crop in the frame)."""
        v = np.concatenate([self.searcher.project(p)[self.roi_vertices] for p in starts])
        lo, hi = v.min(0), v.max(0)
        m = (self.config.roi_margin if margin is None else margin) * (hi - lo).max()
        H, W = image.shape[:2]
        x0, y0 = int(max(0, np.floor(lo[0] - m))), int(max(0, np.floor(lo[1] - m)))
        x1, y1 = int(min(W, np.ceil(hi[0] + m))), int(min(H, np.ceil(hi[1] + m)))
        if x1 - x0 < 8 or y1 - y0 < 8:
            x0, y0, x1, y1 = 0, 0, W, H
        # a crop reaching the frame's edge: past it is missing (``Levels.edge``); approximate where it reaches one
        # edge only: past its other sides, inside the frame, is read as missing too (close_up, still_shots moved)
        edge = x0 == 0 or y0 == 0 or x1 == W or y1 == H
        return self.searcher.levels(crop_gray32(image, x0, y0, x1, y1), edge=edge), np.array([x0, y0], float)

    def fit_roi(self, image: np.ndarray, starts: list, shape_params=None, *, first: int = 0, crop=None,
                landmarks: bool = True, last: int = 0, soft: bool | None = None,
                dim: bool | None = None) -> tuple[FitResult, float]:
        """Search from each start (n_params,) on one crop of the frame around them all (exact: the model is
        translation-equivariant), keep the most confident fit and run the landmark cascade on it (unless
        ``landmarks`` is False; its ``last`` stages only when given, ``Searcher.refine_landmarks``, as for a dim
        face if ``dim``, and while ``fit_still`` runs as for a still's: ``Model.dim_cascade``); ``crop`` (from ``crop``) reuses a crop and its levels; ``soft`` picks the couples
        (``Searcher.fit``).
        Returns (result in frame coordinates, seconds spent on the crop's feature images)."""
        t0 = time.perf_counter()
        levels, off = self.crop(image, starts) if crop is None else crop
        crop_starts = []
        for p in starts:
            p = np.array(p, float)
            p[4:6] -= off
            crop_starts.append(p)
        factors = self.searcher.factors(crop_starts[0])
        for r in sorted(set(factors[first:]), reverse=True):  # now (timed apart from the search), fine to coarse
            levels.get(r)
        t_pyr = time.perf_counter() - t0
        best = None
        for p in crop_starts:
            res = self.searcher.fit(levels, p, shape_params, first=first,
                                    factors=factors if len(crop_starts) == 1 else None, landmarks=False, soft=soft)
            if best is None or res.confidence > best.confidence:
                best = res
        if landmarks:
            best = self.searcher.refine_landmarks(levels, best, factors[-1] if len(crop_starts) == 1 else None,
                                                  last=last, dim=dim, still=self._still)
        p = best.p.copy()
        p[4:6] += off
        return replace(best, p=p, landmarks=best.landmarks + off, vertices=best.vertices + off), t_pyr

    def fit_detection(self, image: np.ndarray, found: tuple, shape_params=None) -> tuple[FitResult, float]:
        """The most confident fit from the starts of one detection (box, angle) (``fit_starts``). Returns (fit,
        seconds spent on the crop and its levels)."""
        return self.fit_starts(image, self.detection_starts(found[0], shape_params, angle=found[1],
                                                            shape=image.shape), shape_params)

    def fit_starts(self, image: np.ndarray, starts: list, shape_params=None) -> tuple[FitResult, float]:
        """The most confident fit from several starts on one crop, then one more search from it on the same crop
        and levels (``refine_detection``): a detection's fit (``fit_detection``, ``rescue``). Returns (fit,
        seconds spent on the crop and its levels)."""
        t0 = time.perf_counter()
        crop = self.crop(image, starts)
        t_crop = time.perf_counter() - t0
        res, t_pyr = self.fit_roi(image, starts, shape_params, crop=crop, landmarks=not self.config.refine_detection)
        if self.config.refine_detection:
            res, t_more = self.fit_roi(image, [res.p], shape_params, first=self.config.skip_coarse, crop=crop)
            t_pyr += t_more
        return res, t_crop + t_pyr

    def detect_and_fit(self, image: np.ndarray, shape_params=None, *, thorough: bool = True,
                       found: tuple | None = None) -> tuple[FitResult | None, dict]:
        """Find a face (``HaarDetector.find``) and fit it (``fit_detection``). When the face was found upright but
        its best fit's confidence stays below ``turned_retry_below``, the detector also looks in the frame turned
        by each of its ``rolled`` angles and the most confident of all the fits is kept: an upright Haar box on a
        face rolled by about 30 degrees starts the search too far off in roll (helen_test turned by 30 degrees,
        100 stills: 69% -> 83% with NME <= 0.08; upright stills unchanged). A face found only in a turned frame is
        also looked for in the turned frames the detector had not tried yet, and the most confident fit kept: in
        the frame turned the wrong way a face is rolled twice as far, and a box found there is mostly not on it
        (helen_test turned by 30 degrees counter-clockwise: 28 faces found first in the frame turned the wrong
        way, 17 of them fitted with NME > 0.08). A turned frame's fit replaces an accepted upright one only if its
        box is at least half as large as the upright box: a small patch elsewhere is not the face (helen_test: a
        face fitted upright at 0.88 lost to a 25 px "face" on a mark on its cheek, at 0.99), while a larger box is
        most often the face the upright frame missed (rolled stills: the upright box is then mostly a small
        patch, accepted at 0.6-0.8; requiring about equal sizes lost 4% of them). A fit still not accepted
        then tries the moved boxes of ``rescue``, then other boxes (``more_boxes``). Without ``thorough`` the
        detector's costly searches (``HaarDetector.find``) and the other boxes are left out
        (``TrackerConfig.thorough_every``). ``found``: ``find``'s (box, angle) when the caller has it already
        (``fit_still``'s mirrored image). Returns (fit or None, timings)."""
        t0 = time.perf_counter()
        if found is None:
            found = self.detector.find(image, thorough=thorough)
        timings = {"detect": time.perf_counter() - t0}
        if found is None:
            return None, timings
        t1 = time.perf_counter()
        res, t_pyr = self.fit_detection(image, found, shape_params)
        t_detect = 0.0
        others, upright = (), None
        if found[1] == 0.0 and res.confidence < self.config.turned_retry_below:
            others = self.detector.rolled
            upright = found[0][2] if res.confidence >= self.config.min_confidence else None
        elif found[1] in self.detector.rolled:  # the turned frames after the one found: one of them is wrong
            others = self.detector.rolled[self.detector.rolled.index(found[1]) + 1:]
        for angle in others:
            t2 = time.perf_counter()
            boxes = self.detector.detect_all(image, angle)
            t_detect += time.perf_counter() - t2
            if len(boxes):
                alt, t = self.fit_detection(image, (boxes[0], angle), shape_params)
                t_pyr += t
                if alt.confidence > res.confidence and (upright is None or 2.0 * boxes[0][2] >= upright):
                    res = alt
        if res.confidence < self.config.min_confidence and self.config.rescue:
            alt, t = self.rescue(image, found, shape_params)
            t_pyr += t
            if alt.confidence > res.confidence:
                res = alt
        if res.confidence < self.config.min_confidence and self.config.more_boxes > 0 and thorough:
            boxes = self.detector.more(image, [found[0]] if found[1] == 0.0 else [])
            for _ in range(self.config.more_boxes):
                t2 = time.perf_counter()
                box = next(boxes, None)
                t_detect += time.perf_counter() - t2
                if box is None:
                    break
                alt, t = self.fit_detection(image, (box, 0.0), shape_params)
                t_pyr += t
                if alt.confidence > res.confidence:
                    res = alt
                if res.confidence >= self.config.min_confidence:
                    break
        res, t = self.landmark_pass(image, res, shape_params)
        t_pyr += t
        timings["detect"] += t_detect
        timings["pyramid"] = t_pyr
        timings["search"] = time.perf_counter() - t1 - t_pyr - t_detect
        return res, timings

    def search_from(self, image: np.ndarray, start: np.ndarray, shape_params=None, *,
                    last: int | None = None, soft: bool | None = None, dim: bool | None = None,
                    margin: float | None = None) -> tuple[FitResult, float]:
        """A tracked frame's search: from ``start`` (the search vector ``tracked_start`` made) with the coarsest
        ``skip_tracked`` couples skipped, searched again with the coarser couple too when its confidence is below
        ``coarser_below`` (the more confident fit kept), then the landmark cascade's last ``last`` stages
        (``landmark_stages_tracked`` by default); with the soft couples if ``soft`` (the fit it starts from was a
        soft face's, ``FitResult.soft``), the landmark cascade as for a dim face if ``dim`` (the fit it starts from
        was a dim face's, ``FitResult.dim``; None: as the face looks). Returns (fit, seconds spent on the crop and
        its levels). ``margin``: the crop's (``crop``; default ``roi_margin``)."""
        cfg = self.config
        last = cfg.landmark_stages_tracked if last is None else last
        t0 = time.perf_counter()
        crop = self.crop(image, [start], margin)
        t_pyr = time.perf_counter() - t0
        res, t = self.fit_roi(image, [start], shape_params, first=self.skip_tracked, crop=crop, last=last, soft=soft,
                              dim=dim)
        t_pyr += t
        if (res.confidence < cfg.coarser_below or res.dim) and self.skip_tracked > cfg.skip_coarse:
            # the same start on the same crop and levels, with the coarser couple too
            alt, t = self.fit_roi(image, [start], shape_params, first=cfg.skip_coarse, crop=crop, last=last,
                                  soft=soft, dim=dim)
            t_pyr += t
            if alt.confidence > res.confidence or (res.dim and alt.confidence >= res.confidence):
                res = alt
        return res, t_pyr

    def rescue(self, image: np.ndarray, found: tuple, shape_params=None) -> tuple[FitResult, float]:
        """The most confident fit from the rough poses of the detection's box (box, angle) moved by each of
        ``TrackerConfig.rescue`` (x shift, y shift, scale), searched as a detection's starts are (``fit_starts``).
        Returns (fit, seconds spent on the crop and its levels)."""
        (x, y, w, h), angle = found
        starts = [self.initial_p((x + dx * w + 0.5 * w * (1.0 - s), y + dy * w + 0.5 * h * (1.0 - s), s * w, s * h),
                                 shape_params, angle=angle, shape=image.shape) for dx, dy, s in self.config.rescue]
        return self.fit_starts(image, starts, shape_params)

    def detection_starts(self, box, shape_params=None, *, angle: float = 0.0, shape: tuple = (0, 0)) -> list:
        """The search starts after a detection: the rough pose from the box (poster: guessed feature points,
        least squares; a box found in the frame turned by ``angle`` degrees, of ``shape``, has its points turned
        back) varied by the configured scale, vertical shift and roll."""
        p0 = self.initial_p(box, shape_params, angle=angle, shape=shape)
        starts = []
        for scale, shift, roll in self.config.starts:
            p = p0.copy()
            p[3] *= scale
            p[5] += shift * p0[3] * self.searcher.width
            p[2] += roll
            starts.append(p)
        return starts

    def initial_p(self, box, shape_params=None, *, angle: float = 0.0, shape: tuple = (0, 0)) -> np.ndarray:
        """Search vector of the rough pose from a detection box, coefficients 0, the person's shape units (or 0)."""
        return self.points_p(unturn(guess_points(box, self.model.detector_box_points), angle, shape), shape_params)

    def points_p(self, points: np.ndarray, shape_params=None) -> np.ndarray:
        """Search vector of the rough pose fitted to 68 points (OpenCV's pixels), coefficients 0, the person's shape
        units (or 0)."""
        sm = self.model.shape
        sigma = np.zeros(sm.n_shape) if shape_params is None else np.asarray(shape_params, float)
        return np.r_[initial_pose(sm, points, None), sigma]

    def tracked_start(self, res: FitResult) -> np.ndarray:
        """Where the next frame's search starts after the accepted fit res (``TrackerConfig.tracked_start``)."""
        how = self.soft_start_kind if res.soft else self.tracked_start_kind
        if how == "landmarks":
            return self.landmark_start(res)
        if how == "similarity":
            return self.realign(res)
        return res.p

    def shape_sample(self, res: FitResult) -> np.ndarray:
        """One estimate of the person's shape units from the accepted fit res (``TrackerConfig.sigma_frames``):
        with ``sigma_from_landmarks``, the landmark fit's (pose, coefficients and shape units: three Gauss-Newton
        steps from res.p, ``LandmarkFitter.refit``) to the fit's final 68 points; else, or for a dim face's fit
        (whose points follow the noise), the search's own."""
        n_q = self.model.shape.n_q
        if self.config.sigma_from_landmarks and not res.dim:
            return self._landmark_fitter.refit(res.p, res.landmarks, 3, fit_sigma=True)[n_q:]
        return res.p[n_q:].copy()

    def _person(self, samples: list, yaws: list) -> np.ndarray:
        """The person's shape units from the estimates so far (``shape_sample``) and the yaw each was read at: their
        median, weighted by how frontal each frame was (``TrackerConfig.sigma_yaw_weight``)."""
        s = self.config.sigma_yaw_weight
        if s <= 0:
            return np.median(samples, axis=0)
        z = (np.asarray(yaws) / s) ** 2
        return weighted_median(np.asarray(samples), np.exp(z.min() - z))  # (relative weights: no underflow)

    def landmark_start(self, res: FitResult) -> np.ndarray:
        """res.p moved by one Gauss-Newton step of the landmark fit (``mesh.landmark_fit.LandmarkFitter.refit``:
        pose and coefficients, the shape units held) onto the fit's final landmarks, less what the landmark
        cascade's shape term moved them by (``FitResult.landmark_prior``): the 3D model has a shape prior of its
        own, and fitted to points already pulled towards the usual 2D shape it read less of the head's turn
        (pose check, video, geodesic median / p95 7.33 / 16.30 degrees onto the final points, 5.88 / 13.36 onto
        these, 2026-11-26), while the 2D landmarks gain from the term."""
        pts = res.landmarks if res.landmark_prior is None else res.landmarks - res.landmark_prior
        p = self._landmark_fitter.refit(res.p, pts)
        a = self.config.start_expression
        if self.model.shape.kind == "3d" and a != 1.0 and not res.dim:  # (``TrackerConfig.start_expression``)
            anim = slice(N_POSE, self.model.shape.n_q)
            p[anim] = a * p[anim] + (1.0 - a) * res.p[anim]
        return p

    def realign(self, res: FitResult) -> np.ndarray:
        """res.p with its in-plane pose (roll, scale, translation) moved by the least-squares similarity that takes
        the search's own 68 points (``landmark_map`` @ its mesh) onto the fit's final ones (the landmark cascade's):
        where the next frame's search starts. Searching from the search's own result frame after frame iterates a
        learned update that was trained for one pass from perturbed starts, and on faces unlike the training set's
        it walks off (see ``TrackerConfig.tracked_start``); the cascade's points are the better estimate of where the face
        is. With s R, t the similarity (row vectors, x -> s x R + t), the projection u = k (R3 X)_x + Tx,
        v = -k (R3 X)_y + Ty becomes the model's own with k s, roll rz - atan2(R01, R00) and T -> s T R + t."""
        p = res.p.copy()
        src = self.model.shape.landmark_map @ res.vertices
        s, R, t = similarity_fit(src, res.landmarks)
        p[2] -= np.arctan2(R[0, 1], R[0, 0])
        p[3] *= s
        p[4], p[5] = s * (p[4:6] @ R) + t
        return p

    def loss_reason(self, res: FitResult, image: np.ndarray, p_before: np.ndarray | None, *,
                    near: bool = False) -> str:
        """Why a fit in the frame ``image`` is not accepted ("" when it is): the validator's confidence, the
        landmarks in the frame, from the previous frame's ``p_before``, a turn or rescale no head makes in one
        frame, and the points' shape (``max_shape_score``). A dim face's fit
        (``FitResult.dim``) that follows the previous frame's, or lies ``near`` a fit accepted a moment ago, needs
        only ``dim_tracked_min``; and needs a frame that does not look like noise (``dim_min_structure``)."""
        cfg = self.config
        least = cfg.dim_tracked_min if (p_before is not None or near) and res.dim else cfg.min_confidence
        if res.confidence < least:
            return f"low confidence {res.confidence:.2f} < {least:.2f}"
        if res.dim and cfg.dim_min_structure > 0 and (structure := frame_structure(image)) < cfg.dim_min_structure:
            return f"a dim fit in a frame that looks like noise (structure {structure:.2f})"
        shape = image.shape[:2]
        inside = self._inside(res.landmarks, shape)
        if inside < cfg.min_inside:
            return f"{inside:.0%} of the landmarks inside the frame"
        if p_before is not None:
            turn, rescale = _motion(res.p, p_before)
            if turn > cfg.max_turn:
                return f"turned {turn:.2f} rad in one frame"
            if rescale > cfg.max_rescale:
                return f"rescaled by {rescale:.2f} (log) in one frame"
        prior = self.model.shape_prior
        if prior is not None and cfg.max_shape_score > 0:
            score = prior.score(res.landmarks)
            if score > cfg.max_shape_score:
                return f"implausible face shape ({score:.2f} > {cfg.max_shape_score:.2f})"
        return ""

    def _second_look(self, image: np.ndarray, res: FitResult, shape_params, timings: dict) -> tuple:
        """An accepted tracked fit res whose points score above ``shape_recheck_above`` as a face shape
        (``Model.shape_prior``) is checked against a detection's fit of the same frame (``detect_and_fit``, quick),
        which replaces it when accepted and of a more plausible shape. Returns (fit, status)."""
        prior, cfg = self.model.shape_prior, self.config
        if prior is None or cfg.shape_recheck_above <= 0:
            return res, "tracked"
        score = prior.score(res.landmarks)
        if score <= cfg.shape_recheck_above:
            return res, "tracked"
        alt, t_det = self.detect_and_fit(image, shape_params, thorough=False)
        for k, v in t_det.items():
            timings[k] = timings.get(k, 0.0) + v
        if alt is None or self.loss_reason(alt, image, None) or prior.score(alt.landmarks) >= score:
            return res, "tracked"
        return alt, "detected"

    def _near(self, p: np.ndarray, q: np.ndarray) -> bool:
        """Whether the fit p is where the fit q was: centres within ``dim_near`` face widths, sizes within
        ``max_rescale`` (log), pose within ``max_turn`` (``_motion``, as ``loss_reason`` bounds one frame's)."""
        cfg = self.config
        if np.hypot(*(p[4:6] - q[4:6])) > cfg.dim_near * q[3] * self.searcher.width:
            return False
        turn, rescale = _motion(p, q)
        return turn <= cfg.max_turn and rescale <= cfg.max_rescale

    def _inside(self, pts: np.ndarray, shape: tuple) -> float:
        H, W = shape
        ok = (pts[:, 0] >= 0) & (pts[:, 0] < W) & (pts[:, 1] >= 0) & (pts[:, 1] < H)
        return float(ok.mean())

    def reported_pose(self, res: FitResult) -> np.ndarray:
        """The pose part q of res.p a frame's result reports: for a 3D model with ``pose_from_points``, a landmark
        fit's (two Gauss-Newton steps from res.p, shape units held) to res.landmarks without the jaw's; else res's."""
        n_q = self.model.shape.n_q
        if not self.config.pose_from_points or self.model.shape.kind != "3d":
            return res.p[:n_q]
        q = self._pose_fitter.refit(res.p, res.landmarks, 2)[:n_q]
        return q if np.isfinite(q).all() and q[3] > 0 else res.p[:n_q]  # (degenerate points: the search's)

    def _result(self, frame, status, res: FitResult | None, timings, reason: str = "") -> FrameResult:
        conf = 0.0 if res is None else res.confidence
        if res is None or status not in ("detected", "tracked"):
            return FrameResult(frame=frame.index, timestamp=frame.timestamp, status=status, confidence=conf,
                               timings=timings, reason=reason)
        sm = self.model.shape
        q, sigma = res.p[:sm.n_q], res.p[sm.n_q:]
        is3d = sm.kind == "3d"
        pose = self.reported_pose(res)
        o = PIXEL_ORIGIN  # the search works in OpenCV's pixels; results are in the package's 1-based ones
        return FrameResult(
            frame=frame.index, timestamp=frame.timestamp, status=status, confidence=conf,
            landmarks=res.landmarks + o, landmarks3d=sm.landmarks3d(q, sigma) * self.mm_per_unit if is3d else None,
            rotation=pose[:3].copy(), translation=pose[4:6] + o, scale=float(pose[3]),
            anim_params=q[N_POSE:].copy() if is3d else np.zeros(0),
            shape_params=sigma.copy() if is3d else q[N_POSE:].copy(),
            vertices=res.vertices + o, timings=timings, reason=reason)

    # -- a still -------------------------------------------------------------------------------------
    def fit_still(self, frame, *, mirror: bool = True, agree: float = 0.08, agree_dim: float = 0.05) -> FrameResult:
        """One image on its own (``aamtrack fit``): a one-frame ``track``, detection then search. With ``mirror``
        the mirrored image is fitted too, from its own detection, whenever the image had a fit (accepted or not);
        where Haar finds no face in the mirrored image (it is not symmetric), from the image's own box mirrored
        (``detector.mirrored``; robustness suite, stills, 3D: dim_small 81.5% -> 82.1% within NME 0.08, dark_cast
        97.9% -> 98.2%, the other 13 variants the same), and where it finds none in the image, the image is fitted
        from the mirrored image's box mirrored back (no face in either: not fitted, after two of the detector's
        thorough searches; same suite: small30_hd, noise and side_light one image more within 0.08 each, overexposed
        one more fit, above 0.08).
        (Every mirror fit from the mirrored box, saving the second detection: 31% less time over the suite, but
        noise 0.0349 -> 0.0363, side_light 96.1% -> 94.8%, small30_hd 96.1% -> 94.5%, blur 91.5% -> 90.9%: the
        second detection's independent box is worth its time.)

        Both accepted: when they agree (mean point distance at most ``agree`` outer eye-corner distances) the 68
        points are the mean of the two (the mirror's moved back, left and right swapped) and the confidence their
        mean; the pose, mesh, 3D landmarks and coefficients stay the image's own fit's. Two fits that disagree leave
        the image's own fit as it is when it is the more confident; when the mirror's is, the image is fitted again
        from the mirror's points moved back (``fit_at_points``) and that fit, if accepted and agreeing with the
        mirror's, takes the image's place and is averaged with it as above. Test-time flipping, as landmark
        detectors evaluate with (e.g. HRNet's flip test): the two fits start from different boxes and read
        mirrored patches, so their errors are partly independent. helen_test stills (2026-11-27, shipped models):
        3D mean NME 0.03503 -> 0.03472 (within 0.08 98.2% -> 98.5%), Spearman(confidence, NME) -0.64 -> -0.65;
        2D 0.0354 -> 0.0353; twice the time (averaging only the landmark cascade's points from one search's start,
        cheaper, gained a tenth as much: 0.03503 -> 0.03498). Fits that disagree are few (helen_test under the
        robustness suite's variants, 3D: 0-4 of 330 per variant), and the more confident of the two was within NME
        0.08 in 33 of 34 such cases (2026-11-27, 3D and 2D, /tmp harness; the other: confidences 0.80 and 0.80).

        A fit judged by the validator for dim faces (``FitResult.dim``) needs the other's agreement (within
        ``agree``) to stand: accepted alone, where the mirror's fit lies elsewhere, it is rejected ("dim fit ...
        from the mirrored image's"). A face gives two fits that agree; noise, where Haar's smallest searches find
        "faces", seldom does: of 150 noise stills (/tmp, Gaussian, grey and colour, means 15-180, sd 3-50, blurred
        0-3 px, 640x480 to 1280x720) the shipped 3D model fitted 14, and the mirror's fit disagreed (0.5-18 eye
        distances apart) with 8 of the 13 it could be compared with (2026-11-30). With the dim validator learned
        on noise too (``TrainConfig.dim_tiny``; prototype, /tmp), this rule took those 150 from 7 fitted to 2, and
        helen_test made small, dark and noisy (robustness suite, dim_small) from 87.0% to 85.8% within NME 0.08
        (mean NME of the fits 0.0443 -> 0.0441): of its dim fits it rejected, two were within 0.08; and three good
        mirror fits are no longer refitted (below). A cost taken for the issue's "no noise frame is ever
        tracked"; no threshold on either fit's confidence separated the two. Noise whose two fits agree is left to
        the frame's structure (``TrackerConfig.dim_min_structure``): with it, none of those 150 is fitted.

        Image rejected, mirror accepted: the image is fitted again from the mirror's points moved back, and that
        fit stands (averaged as above) if accepted and agreeing; else the image stays rejected (the mirror's
        detection can be another face: helen_test turned by 30 degrees, a mirror fit 1.2 eye distances off). A dim
        mirror fit is refitted so only where the image's own fit agrees with it (the refit, starting at the
        mirror's points, would agree with them on noise too).
        Both rejected: two fits judged by the validator for dim faces (``FitResult.dim``) that agree within
        ``agree_dim`` are accepted from ``dim_tracked_min`` (``loss_reason``'s ``near``), as a dim fit where a face
        just was is in a video: the mirror's fit, from its own detection and mirrored patches, is the second
        sighting (helen_test made small, dark and noisy (the robustness suite's dim_small), 3D, /tmp harness: of the
        fits rejected on both sides that agree within 0.03 with both confidences at least 0.2, 17 within NME 0.08
        and 3 above; fits that disagree were mostly off). ``agree_dim`` 0.03 -> 0.05 once noise's dim fits were
        refused for the frame (``TrackerConfig.dim_min_structure``; noise pairs were the risk of a looser bar):
        the same suite's dim_small 86.7% -> 87.3% within NME 0.08 (fitted 299 -> 301, the two new ones at 0.039 and
        0.074; mean NME of the fits 0.0443 -> 0.0444), its noise variant the same; 0.08 fitted one more, above
        0.08 (mean 0.0448).

        An image whose own fit reads soft (a blurred face) is fitted again, all of the above, on the image
        sharpened (``TrackerConfig.sharpen_soft``), and the more confident accepted result kept; one whose fit of a
        dim, noisy face was refused, on the image smoothed (``TrackerConfig.smooth_dim``). ``frame``: an
        object with ``index``, ``timestamp``, ``image`` as ``track`` takes."""
        if frame.image is None:
            return next(iter(self.track([frame])))
        self._still = True  # its fits of a dim face take the model's cascade for those (``fit_roi``)
        try:
            res, fit = self._fit_still(frame, mirror, agree, agree_dim)
            cfg = self.config
            eye = 1.0 if fit is None else max(float(np.linalg.norm(fit.landmarks[45] - fit.landmarks[36])), 1.0)
            if cfg.sharpen_soft > 0 and fit is not None and fit.soft:  # a blurred face: look again, sharpened
                res = self._look_again(frame, res, unsharp(frame.image, cfg.sharpen_soft * eye, cfg.sharpen_amount),
                                       mirror, agree, agree_dim)
            if cfg.smooth_dim > 0 and not res.success and fit is not None and fit.dim:  # a dim, noisy face refused:
                res = self._look_again(frame, res, smoothed(frame.image, cfg.smooth_dim * eye), mirror, agree,
                                       agree_dim)  # look again, smoothed
            return res
        finally:
            self._still = False

    def _look_again(self, frame, res: FrameResult, image: np.ndarray, mirror: bool, agree: float,
                    agree_dim: float) -> FrameResult:
        """``fit_still``'s second look: ``image`` (the frame's image sharpened or smoothed) fitted as the frame was
        (``_fit_still``); its result replaces ``res`` if accepted and ``res`` is not, or is less confident. The
        time of both looks is counted."""
        alt = self._fit_still(ReplayFrame(frame.index, frame.timestamp, image), mirror, agree, agree_dim)[0]
        kept = alt if alt.success and (not res.success or alt.confidence > res.confidence) else res
        return replace(kept, timings=_summed(res.timings, alt.timings))

    def _fit_still(self, frame, mirror: bool, agree: float, agree_dim: float) -> tuple[FrameResult, FitResult | None]:
        """``fit_still``'s work on one image: (its result, the image's own fit behind it, accepted or not; None
        when no face was found in it)."""
        width = frame.image.shape[1]
        flipped = np.ascontiguousarray(frame.image[:, ::-1]) if mirror else None
        t0 = time.perf_counter()
        found, own = self.detector.find(frame.image), None  # own: the mirrored image's detection
        if found is None and mirror:  # Haar is not symmetric: the mirrored image's face, mirrored back
            own = self.detector.find(flipped)
            found = None if own is None else mirrored(own, width)
        res, fit = self._fit_one(frame, found, time.perf_counter() - t0)
        if not mirror or fit is None:
            return res, fit
        t0 = time.perf_counter()
        if own is None:  # (not looked for yet: the image had its own detection)
            own = self.detector.find(flipped)
        alt, alt_fit = self._fit_one(ReplayFrame(frame.index, frame.timestamp, flipped),
                                     own if own is not None else mirrored(found, width), time.perf_counter() - t0)
        timings = _summed(res.timings, alt.timings)
        if alt_fit is None:
            return replace(res, timings=timings), fit
        shape = frame.image.shape[:2]
        back = mirror_points(alt_fit.landmarks, shape[1], origin=0.0)  # OpenCV's pixels, as the fits'
        apart = float(nme(back, fit.landmarks))
        if res.success:
            if alt.success and apart <= agree:
                return self._averaged(res, alt, back, timings), fit
            if fit.dim and apart > agree:  # a dim fit stands only where the mirror's confirms it
                res = self._result(frame, "lost", fit, timings, f"dim fit {apart:.2f} from the mirrored image's")
            elif not alt.success or alt.confidence <= res.confidence:
                return replace(res, timings=timings), fit
        if alt.success and (not alt_fit.dim or apart <= agree):  # the mirror's fit accepted and the more
            # confident (a dim one confirmed by the image's own): the image's again, from its points
            t0 = time.perf_counter()
            again = self.fit_at_points(frame.image, back)
            timings["search"] = timings.get("search", 0.0) + time.perf_counter() - t0
            if not self.loss_reason(again, frame.image, None) and float(nme(again.landmarks, back)) <= agree:
                return self._averaged(self._result(frame, "detected", again, timings), alt, back, timings), fit
        # the image's fit rejected: two dim fits that agree are accepted as a dim fit near a face is
        dim_pair = (not res.success and fit.dim and alt_fit.dim and apart <= agree_dim
                    and not self.loss_reason(fit, frame.image, None, near=True)
                    and not self.loss_reason(alt_fit, flipped, None, near=True))
        if not dim_pair:
            return replace(res, timings=timings), fit
        return self._averaged(self._result(frame, "detected", fit, timings), alt, back, timings), fit

    def _averaged(self, res: FrameResult, alt: FrameResult, back: np.ndarray, timings: dict) -> FrameResult:
        """``fit_still``'s result of two agreeing fits: res with the mean of its points and the mirror's moved back
        (``back``, OpenCV's pixels), the mean confidence."""
        return replace(res, landmarks=0.5 * (res.landmarks + back + PIXEL_ORIGIN),
                       confidence=0.5 * (res.confidence + alt.confidence), timings=timings)

    def _fit_one(self, frame, found: tuple | None, t_find: float = 0.0) -> tuple[FrameResult, FitResult | None]:
        """A one-frame ``track`` of an image (not None) from the detector's ``found`` (box, angle; None: no face,
        found in ``t_find`` seconds): (its result, the fit behind it, accepted or not; None when no face was
        found)."""
        if found is None:
            return self._result(frame, "lost", None, {"detect": t_find}, "no face detected"), None
        res, timings = self.detect_and_fit(frame.image, found=found)
        timings["detect"] += t_find
        reason = self.loss_reason(res, frame.image, None)
        return self._result(frame, "lost" if reason else "detected", res, timings, reason), res

    def fit_at_points(self, image: np.ndarray, points: np.ndarray) -> FitResult:
        """A detection's fit (``fit_starts``, then the landmark pass) from the rough pose fitted to 68 points
        (OpenCV's pixels) instead of a box's guessed ones: ``fit_still``'s second look at an image where the
        mirrored image's fit was the more confident and the two disagree."""
        return self.landmark_pass(image, self.fit_starts(image, [self.points_p(points)])[0])[0]

    def landmark_pass(self, image: np.ndarray, res: FitResult, shape_params=None) -> tuple[FitResult, float]:
        """An accepted detection's fit searched once more as the next frame of a video would be
        (``TrackerConfig.landmark_pass``), the more confident kept. Returns (fit, seconds spent on the crop and
        its levels)."""
        if not self.config.landmark_pass or res.confidence < self.config.min_confidence:
            return res, 0.0
        alt, t = self.search_from(image, self.tracked_start(res), shape_params, last=0, soft=res.soft, dim=res.dim)
        return (alt if alt.confidence >= res.confidence else res), t

    # -- a video ---------------------------------------------------------------------------------------
    def track(self, frames: Iterable) -> Iterator[FrameResult]:
        """One FrameResult per frame of ``frames``, in order (module docstring). A stretch of lost frames that ends
        in a detection is tracked backwards from it (``TrackerConfig.backfill``): those frames' results wait, up
        to ``backfill`` of them, until the stretch ends."""
        k = self.config.backfill
        held: list = []  # (result, frame) of the lost frames waiting, oldest first
        for res, fit, frame, shape_params, cut in self._tracked(frames):
            if k > 0 and res.status == "lost" and frame.image is not None:
                if cut:  # a new shot: what waits belongs to the one before
                    yield from (r for r, _ in held)
                    held = []
                held.append((res, frame))
                if len(held) > k:
                    yield held.pop(0)[0]
                continue
            if held and res.status == "detected" and fit is not None and not cut:
                yield from self._backfilled(held, fit, shape_params, res.frame)
            else:
                yield from (r for r, _ in held)
            held = []
            yield res
        yield from (r for r, _ in held)

    def _backfilled(self, held: list, fit: FitResult, shape_params, found: int) -> Iterator[FrameResult]:
        """The lost frames ``held`` ((result, frame), oldest first, the frame after the last one a detection's
        ``fit``, at frame ``found``), each searched from the next one's fit as a tracked frame is from the previous
        one's, latest first, until one is not accepted (it and the ones before it stay lost). Yields their results
        in frame order; those tracked say so in their ``reason`` (``BACKFILL_REASON``)."""
        cfg = self.config
        out = [r for r, _ in held]
        after = fit
        for i in range(len(held) - 1, -1, -1):
            res, frame = held[i]
            t0 = time.perf_counter()
            got, t_pyr = self.search_from(frame.image, self.tracked_start(after), shape_params, soft=after.soft,
                                          dim=after.dim, margin=cfg.roi_margin_tracked)
            timings = _summed(res.timings, {"pyramid": t_pyr, "search": time.perf_counter() - t0 - t_pyr})
            if self.loss_reason(got, frame.image, after.p):
                break
            out[i] = self._result(frame, "tracked", got, timings, BACKFILL_REASON.format(found))
            after = got
        yield from out

    def _tracked(self, frames: Iterable) -> Iterator[tuple]:
        """``track``'s loop: per frame (result, its fit or None, the frame, the person's held shape units or None,
        whether the frame starts a new shot)."""
        cfg = self.config
        n_q = self.model.shape.n_q
        p = None          # current search vector, None when there is no track
        p_prev = None     # previous frame's (motion prediction)
        soft = False      # whether the current track's last fit was a soft face's (its next search's couples)
        dim = False       # ... a dim face's (its next landmark cascade without the repeats)
        shape_params = None  # the person's held shape units (3D), once estimated
        sigma_samples = []
        sigma_yaws = []  # the searches' yaw at each of sigma_samples (``sigma_yaw_weight``)
        person = None  # the median of sigma_samples (the person's shape as estimated so far), None without any
        estimate = self.model.shape.n_shape > 0 and cfg.sigma_frames > 0
        thumb = None      # the previous frame's (shot changes)
        misses = 0        # frames since the track was lost (or cut) without an accepted face
        recent = None     # (search vector, n_fitted then) of the shot's last accepted fit
        n_fitted = 0      # frames that had a fit, accepted or not (``dim_recent`` counts these)
        for frame in frames:
            if getattr(frame, "dropped", False):
                yield FrameResult(frame=frame.index, timestamp=frame.timestamp, status="dropped"), None, frame, None, \
                    False
                continue
            if frame.image is None:
                yield FrameResult(frame=frame.index, timestamp=frame.timestamp, status="unreadable"), None, frame, \
                    None, False
                p_prev = None
                continue
            timings = {}
            image = frame.image
            cut = False
            if cfg.cut_below > 0:
                made = getattr(frame, "thumbnail", None)  # made ahead in the decoding thread (``grey_frames``)
                before, thumb = thumb, thumbnail(image) if made is None else made
                cut = before is not None and float((before * thumb).sum()) < cfg.cut_below
                if cut:  # a new shot
                    p = p_prev = recent = None  # (while lost, a cut keeps the thorough searches' schedule: frames of
                    # noise all look like cuts)
                    if cfg.sigma_per_shot:
                        shape_params, sigma_samples, sigma_yaws, person = None, [], [], None
            lost_track = None  # (fit, reason) of this frame's tracked search when it was lost
            striding = cfg.lost_stride > 1 and misses >= cfg.lost_stride_after
            searched_sigma = shape_params
            if searched_sigma is None and cfg.sigma_running and not dim:  # (a dim face's own search is its
                searched_sigma = person  # estimate: ``shape_sample``)
            while True:
                if p is None:
                    thorough = lost_track is not None or misses % max(1, cfg.thorough_every) == 0
                    if not thorough and striding and misses % cfg.lost_stride:
                        res = None  # a long stretch without a face: searched every lost_stride-th frame
                        break
                    res, t_det = self.detect_and_fit(image, searched_sigma, thorough=thorough)
                    for k, v in t_det.items():
                        timings[k] = timings.get(k, 0.0) + v
                    if res is None:
                        break
                    status = "detected"
                else:
                    start, status = p.copy(), "tracked"
                    if cfg.predict and p_prev is not None:
                        step = cfg.predict_damping * (p - p_prev)
                        start[[2, 4, 5]] += step[[2, 4, 5]]
                    t1 = time.perf_counter()
                    res, t_pyr = self.search_from(image, start, searched_sigma, soft=soft, dim=dim,
                                                  margin=cfg.roi_margin_tracked)
                    timings["pyramid"] = t_pyr
                    timings["search"] = time.perf_counter() - t1 - t_pyr
                if lost_track is None:
                    n_fitted += 1
                near = (res.dim and res.confidence < cfg.min_confidence and recent is not None  # (only then it
                        and n_fitted - recent[1] <= cfg.dim_recent and self._near(res.p, recent[0]))  # matters)
                reason = self.loss_reason(res, image, p if status == "tracked" else None, near=near)
                if reason and status == "tracked" and cfg.redetect_lost:
                    lost_track, p, p_prev = (res, reason), None, None  # looked for in this frame at once
                    continue
                if not reason and status == "tracked":
                    res, status = self._second_look(image, res, searched_sigma, timings)
                break
            if res is None or reason:
                if res is None and lost_track is None:
                    why = (f"no face detected (1 frame in {cfg.lost_stride} searched after {cfg.lost_stride_after} "
                           "without one)") if striding else "no face detected"
                    misses += 1
                    yield self._result(frame, "lost", None, timings, why), None, frame, shape_params, cut
                    continue
                if lost_track is not None:  # reported as the tracked search's loss; the detection was thorough
                    res, reason = lost_track
                    misses = 1
                else:
                    misses = misses + 1 if status == "detected" else 0  # a tracked face just lost: thorough next
                p = p_prev = None
                yield self._result(frame, "lost", res, timings, reason), res, frame, shape_params, cut
                continue
            recent = (res.p, n_fitted)
            if estimate and shape_params is None and res.confidence >= cfg.sigma_min_confidence:
                sigma_samples.append(self.shape_sample(res))
                sigma_yaws.append(float(res.p[1]))
                person = self._person(sigma_samples, sigma_yaws)
                if len(sigma_samples) >= cfg.sigma_frames:
                    shape_params = person
            p_prev = p if status == "tracked" else None
            if estimate and shape_params is None and cfg.sigma_restart and person is not None:
                p = res.p.copy()
                p[n_q:] = person
                p = self.tracked_start(replace(res, p=p))
            else:
                p = self.tracked_start(res)
            soft, dim = res.soft, res.dim
            misses = 0
            report = res  # reported with the person's shape as now estimated (``sigma_running``)
            if cfg.sigma_running and person is not None and not np.array_equal(res.p[n_q:], person):
                report = replace(res, p=np.r_[res.p[:n_q], person])
            yield self._result(frame, status, report, timings), res, frame, shape_params, cut
