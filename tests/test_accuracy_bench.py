"""Helpers of benchmarks/accuracy.py and benchmarks/peers.py on hand-made arrays whose answers are worked out in
the comments, and the aamtrack runner on a synthetic video."""

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from _common import run_script  # noqa: E402
from accuracy import (  # noqa: E402
    AamRun,
    by_turn_and_region,
    jitter_vs_reference,
    main,
    run_aamtrack,
    summarize_stills,
    turn_table,
    video_scores,
)
from accuracy import label_turn as accuracy_label_turn  # noqa: E402
from conftest import SEED  # noqa: E402


def _face68(eye_gap: float = 10.0) -> np.ndarray:
    """A (68, 2) shape: random points, with the outer eye corners 36 and 45 exactly ``eye_gap`` px apart."""
    shape = np.random.default_rng(SEED).uniform(0.0, 50.0, size=(68, 2))
    shape[36] = (20.0, 30.0)
    shape[45] = (20.0 + eye_gap, 30.0)
    return shape


# ------------------------------------------------------------------------------------------ summarize_stills


def test_stills_summary_counts_undetected_and_rejected_as_failures():
    # 5 images: 3 fitted (0.02, 0.06, 0.12), 1 found but rejected (NaN), 1 not found (NaN)
    errors = np.array([0.02, 0.06, 0.12, np.nan, np.nan])
    found = np.array([True, True, True, True, False])
    s = summarize_stills(errors, found, thresholds=[0.0, 0.05, 0.10, 0.15])
    assert s["n_images"] == 5 and s["n_found"] == 4 and s["detection_rate"] == pytest.approx(0.8)
    assert s["n_fitted"] == 3 and s["n_rejected"] == 1
    assert s["nme_mean"] == pytest.approx(0.2 / 3)  # (0.02 + 0.06 + 0.12) / 3, fitted images only
    assert s["nme_median"] == pytest.approx(0.06)
    assert s["failures"] == 3  # 0.12 > 0.10, the rejected and the undetected one
    assert s["failure_rate"] == pytest.approx(0.6)
    # CED over all 5: <= 0: none; <= 0.05: one; <= 0.10: two; <= 0.15: three (the two NaN never count)
    np.testing.assert_allclose(s["ced"], [0.0, 0.2, 0.4, 0.6])


def test_stills_summary_threshold_is_inclusive_and_default_grid():
    s = summarize_stills([0.10, 0.05], [True, True])
    assert s["failures"] == 0  # exactly 0.10 is not above 0.10
    assert len(s["thresholds"]) == 31 and s["thresholds"][0] == 0.0 and s["thresholds"][-1] == pytest.approx(0.15)
    assert s["ced"][10] == pytest.approx(0.5)  # threshold 0.05 includes the 0.05 image
    assert s["ced"][-1] == 1.0


def test_stills_summary_rejects_inconsistent_input():
    with pytest.raises(ValueError, match="no detection"):
        summarize_stills([0.05], [False])  # an error without a detection cannot happen
    with pytest.raises(ValueError, match="does not match"):
        summarize_stills([0.05, 0.06], [True])


def test_stills_summary_nothing_found():
    s = summarize_stills([np.nan, np.nan], [False, False], thresholds=[0.1])
    assert s["detection_rate"] == 0.0 and s["failures"] == 2 and s["ced"] == [0.0]
    assert math.isnan(s["nme_mean"]) and math.isnan(s["nme_median"])


def test_confidence_rank_correlation_over_fitted_images():
    from accuracy import confidence_rank_correlation

    # fitted images: confidence falls as the error grows (perfectly ranked); the NaN errors (not fitted) are left out
    conf = np.array([0.9, 0.8, 0.7, 0.0, 0.6, 0.3])
    err = np.array([0.02, 0.03, 0.05, np.nan, 0.07, np.nan])
    assert confidence_rank_correlation(conf, err) == pytest.approx(-1.0)
    assert confidence_rank_correlation(conf[[0, 1, 2, 4]], err[[4, 2, 1, 0]]) == pytest.approx(1.0)
    # one pair out of order among four: rank differences (3, 0, 0, -3), rho = 1 - 6 * 18 / (4 * 15) = -0.8
    assert confidence_rank_correlation([0.9, 0.8, 0.7, 0.6], [0.02, 0.05, 0.03, 0.07]) == pytest.approx(-0.8)
    assert math.isnan(confidence_rank_correlation([0.5, 0.5, 0.5], [0.01, 0.02, 0.03]))  # a constant confidence
    assert math.isnan(confidence_rank_correlation([0.9, 0.1], [0.01, 0.02]))  # under 3 fitted images
    with pytest.raises(ValueError, match="does not match"):
        confidence_rank_correlation([0.9], [0.01, 0.02])


# ---------------------------------------------------------------------------------------- jitter_vs_reference


def test_jitter_against_reference_on_the_same_pairs():
    # 5 frames, 2 points. Reference moves 0.5 px in x every frame; the track 1.0 px in y every frame.
    n = 5
    ref = np.zeros((n, 2, 2))
    ref[:, :, 0] = 0.5 * np.arange(n)[:, None]
    track = np.zeros((n, 2, 2))
    track[:, :, 1] = 1.0 * np.arange(n)[:, None]
    still = np.array([False, True, True, True, True])  # pairs (1,2), (2,3), (3,4)
    j = jitter_vs_reference(track, ref, still)
    assert j["jitter_px"] == pytest.approx(1.0)
    assert j["ref_jitter_px"] == pytest.approx(0.5)
    assert j["ratio"] == pytest.approx(2.0)
    assert j["n_pairs"] == 3


def test_jitter_leaves_out_pairs_where_the_track_is_lost():
    # The reference moves 0, 1, 3, 3 px between frames; the track is lost on frame 3, so only the pairs (0,1) and
    # (1,2) are left for both: the reference's 3-px pairs next to the lost frame must not count.
    ref = np.zeros((5, 1, 2))
    ref[:, 0, 0] = [0.0, 0.0, 1.0, 4.0, 7.0]
    track = np.zeros((5, 1, 2))
    track[:, 0, 0] = [0.0, 0.0, 2.0, np.nan, 9.0]
    j = jitter_vs_reference(track, ref, np.ones(5, dtype=bool))
    # pairs (0,1): track 0, ref 0; (1,2): track 2, ref 1; (2,3) and (3,4): lost -> out
    assert j["n_pairs"] == 2
    assert j["jitter_px"] == pytest.approx(1.0)  # (0 + 2) / 2
    assert j["ref_jitter_px"] == pytest.approx(0.5)  # (0 + 1) / 2
    assert j["ratio"] == pytest.approx(2.0)


def test_jitter_ratio_is_nan_when_the_reference_does_not_move():
    still_ref = np.zeros((4, 3, 2))
    track = still_ref + np.arange(4)[:, None, None]
    j = jitter_vs_reference(track, still_ref, np.ones(4, dtype=bool))
    assert j["ref_jitter_px"] == 0.0 and math.isnan(j["ratio"])
    assert j["jitter_px"] == pytest.approx(math.sqrt(2))  # every point moves (1, 1) per frame


# ------------------------------------------------------------------------------------------------ video_scores


def test_video_scores_against_both_references():
    # 4 frames of the same face (eye gap 10 px); the track is 1 px off in x on frames 0, 1, 3 and lost on 2.
    face = _face68(10.0)
    ref68 = np.stack([face] * 4)
    pred = ref68 + (1.0, 0.0)
    pred[2] = np.nan
    subset = [8, 30, 33, 36, 39, 42, 45, 48, 51, 54, 57]
    ref_mp = ref68[:, subset] + (0.0, 2.0)  # MediaPipe sits 2 px lower: error sqrt(1 + 4) px / 10 px
    s = video_scores(pred, ref68, ref_mp, still_mask=np.ones(4, dtype=bool))
    assert s["n_frames"] == 4 and s["lost"] == 1
    assert s["dlib"]["nme_mean"] == pytest.approx(0.1) and s["dlib"]["nme_p95"] == pytest.approx(0.1)
    assert s["mp"]["nme_mean"] == pytest.approx(math.sqrt(5) / 10)
    assert s["dlib"]["share_failed"] == pytest.approx(0.25)  # the lost frame only: 0.1 is not above 0.10
    assert s["mp"]["share_failed"] == pytest.approx(1.0)  # lost, or 0.224 > 0.10
    assert math.isnan(s["dlib"]["nme"][2])
    # nothing moves: one still pair (0,1) left with the track defined on both frames
    assert s["dlib"]["jitter"]["jitter_px"] == 0.0 and s["dlib"]["jitter"]["n_pairs"] == 1


def test_video_scores_without_references_and_length_check():
    pred = np.zeros((3, 68, 2))
    assert video_scores(pred) == {"n_frames": 3, "lost": 0}
    with pytest.raises(ValueError, match="frames"):
        video_scores(pred, np.zeros((2, 68, 2)))


# ------------------------------------------------------------------------------------- peers.comparison_lines


def _row(name, fps, sub_ref, sub_mp, tracking=True):
    return {"name": name, "fps": fps, "sub_ref_mean": sub_ref, "sub_mp_mean": sub_mp, "tracking": tracking}


def test_comparison_line_ratio_and_nme_difference():
    from peers import comparison_lines

    rows = [
        _row("dlib detect every frame (up0)", 900.0, 0.005, 0.020, tracking=False),  # fastest, but no tracker
        _row("dlib tracking (up0)", 400.0, 0.004, 0.025),
        _row("mediapipe face mesh", 200.0, 0.030, 0.0),
        _row("aamtrack 3D tracking", 100.0, 0.050, 0.045),
    ]
    (line,) = comparison_lines(rows)
    assert "0.25x the fps" in line and "dlib tracking (up0), 400.0 fps" in line  # 100 / 400
    # dlib ref: dlib rows are left out, MediaPipe 0.030 -> +0.020; MP ref: MediaPipe left out, best dlib 0.020
    assert "vs dlib ref 0.0500 (mediapipe face mesh 0.0300, +0.0200)" in line
    assert "vs MP ref 0.0450 (dlib detect every frame (up0) 0.0200, +0.0250)" in line


def test_comparison_line_without_peers():
    from peers import comparison_lines

    (line,) = comparison_lines([_row("aamtrack 2D tracking", 300.0, 0.03, 0.04)])
    assert "no peer ran in a tracking mode" in line and "(no other peer)" in line


# ------------------------------------------------------------------------------ run_aamtrack on synthetic faces


def test_run_aamtrack_video_and_stills(synth_model, tmp_path):
    import synth

    from aamtrack.model import save_model

    path = tmp_path / "synth.npz"
    save_model(synth_model, path)
    frames, truth = synth.moving_face_frames(8)
    blank = np.full_like(frames[0], 128)  # no face: the detector finds nothing

    video = run_aamtrack(frames, path, still=False)
    assert isinstance(video, AamRun) and video.name == "aamtrack 2D"
    assert video.landmarks.shape == (8, 68, 2) and video.times.shape == (8,)
    assert list(video.status) == ["detected"] + ["tracked"] * 7 and video.detector_runs == 1
    assert (video.wall_times >= video.times).all()  # the stages are part of the whole step
    err = np.linalg.norm(video.landmarks - truth, axis=-1).mean()
    assert err < 1.5  # about a pixel, as in the tracker's own tests

    # Frames 0 and 3 are ones Haar finds on their own (it misses the synthetic face on some frames).
    stills = run_aamtrack([frames[0], blank, frames[3]], path, still=True)
    assert list(stills.status) == ["detected", "lost", "detected"]  # each image starts with no track
    assert stills.detector_runs == 3 and list(stills.found) == [True, False, True]
    assert np.isnan(stills.landmarks[1]).all()
    assert stills.confidence[1] == 0.0 and (stills.confidence[[0, 2]] >= 0.5).all()  # accepted fits only
    err = np.linalg.norm(stills.landmarks[[0, 2]] - truth[[0, 3]], axis=-1).mean()
    assert err < 1.0  # from a Haar box alone, within a pixel on the model's own faces


@pytest.mark.parametrize("what", ["stills", "video", "model"])
def test_a_missing_input_is_one_line_before_any_work(tmp_path, capsys, what):
    args = {"stills": ["--stills", str(tmp_path / "no_such_folder"), "--video", "none"],
            "video": ["--stills", "none", "--video", str(tmp_path / "no_such.mp4")],
            "model": ["--models", str(tmp_path / "no_such.npz"), "--stills", "none", "--video", "none"]}[what]
    with pytest.raises(SystemExit) as stop:
        run_script(lambda: main(args + ["--json", str(tmp_path / "out.json")]), "accuracy")
    assert stop.value.code == 1
    captured = capsys.readouterr()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("accuracy: ") and "no_such" in err[0]
    assert "machine" not in captured.out and not (tmp_path / "out.json").exists()  # before any work


def test_benchmark_scripts_turn_input_errors_into_one_line_and_leave_bugs_alone(capsys):
    from aamtrack.errors import ModelFileError

    def bad_input():
        raise ModelFileError("/x/m.npz: no such model file")

    with pytest.raises(SystemExit) as stop:
        run_script(bad_input, "bench")
    assert stop.value.code == 1 and capsys.readouterr().err == "bench: /x/m.npz: no such model file\n"
    with pytest.raises(SystemExit) as stop:
        run_script(lambda: 0, "bench")
    assert stop.value.code == 0

    def bug():
        raise ZeroDivisionError("a bug keeps its traceback")

    with pytest.raises(ZeroDivisionError):
        run_script(bug, "bench")


# ------------------------------------------------------------------------------ label_turn, by_turn_and_region


def _symmetric_face() -> np.ndarray:
    """A (68, 2) shape symmetric about x = 0 for the points label_turn reads: the nose tip (30) on the axis, the
    jaw line's ends (0, 16) at x = -+40, y = 0; the outer eye corners (36, 45) 40 px apart."""
    face = _face68(eye_gap=40.0)
    face[30] = (0.0, 20.0)
    face[0], face[16] = (-40.0, 0.0), (40.0, 0.0)
    return face


def test_label_turn_is_zero_for_a_frontal_face_and_signed_by_the_side_turned_away():
    frontal = _symmetric_face()
    turned = frontal.copy()
    turned[30, 0] = 15.0  # nose tip towards point 16: farther from 0 (L = hypot(55, 20)) than from 16 (hypot(25, 20))
    other = frontal.copy()
    other[30, 0] = -15.0  # the same turn the other way: the distances swap
    t = accuracy_label_turn(np.stack([frontal, turned, other]))
    L, R = math.hypot(55.0, 20.0), math.hypot(25.0, 20.0)
    assert t[0] == pytest.approx(0.0, abs=1e-12)
    assert t[1] == pytest.approx((L - R) / (L + R)) and t[1] > 0.2
    assert t[2] == pytest.approx(-t[1])
    with pytest.raises(ValueError, match="68, 2"):
        accuracy_label_turn(np.zeros((2, 5, 2)))


def test_by_turn_and_region_splits_fits_by_turn_and_region():
    # 3 labelled faces, turns 0.0, 0.2 and -0.5 (bins 0-0.15, 0.15-0.30 and 0.45-); eye distance 40 px.
    ref = np.stack([_symmetric_face()] * 3)
    pred = ref.copy()
    pred[1, :17, 0] += 4.0   # face 1: its 17 jaw points 4 px off = 0.1 eye distances, NME 17 * 0.1 / 68 = 0.025
    pred[2] = np.nan         # face 2: not fitted
    rows = by_turn_and_region(pred, ref, [0.0, 0.2, -0.5])
    assert [r["n_images"] for r in rows] == [1, 1, 0, 1, 3] and [r["n_fitted"] for r in rows] == [1, 1, 0, 0, 2]
    assert rows[0]["nme_mean"] == pytest.approx(0.0) and rows[1]["nme_mean"] == pytest.approx(0.025)
    assert rows[1]["regions"]["jaw"] == pytest.approx(0.1) and rows[1]["regions"]["eyes"] == pytest.approx(0.0)
    assert math.isnan(rows[2]["nme_mean"]) and math.isnan(rows[3]["nme_mean"])  # nothing fitted there
    assert rows[4]["turn_to"] == math.inf and rows[4]["nme_mean"] == pytest.approx(0.0125)  # all: (0 + 0.025) / 2
    assert rows[4]["regions"]["jaw"] == pytest.approx(0.05)
    with pytest.raises(ValueError, match="differ in number"):
        by_turn_and_region(pred, ref, [0.0, 0.2])
    # the printed table: a header, then one line a bin per model, "-" where none was fitted; columns aligned
    # past a model's name longer than the default width
    lines = turn_table([{"name": "a_model_name_of_26_letters", "by_turn": rows}]).splitlines()
    assert len(lines) == 1 + len(rows) and lines[0].split()[:2] == ["model", "turn"]
    assert lines[2].split()[1:7] == ["0.15-0.30", "1", "1", "0.0250", "0.1000", "0.0000"]
    assert lines[3].split()[1:5] == ["0.30-0.45", "0", "0", "-"] and lines[5].split()[1:4] == ["all", "3", "2"]
    assert len({len(line) for line in lines}) == 1  # every line as wide as the header
