"""Training on several threads (``aamtrack.train.workers``) gives the model one thread gives, bit for bit."""

import json
import threading

import numpy as np
import pytest
from conftest import SEED, SYNTH_COUPLES

from aamtrack.model import save_model
from aamtrack.train.pipeline import TrainConfig, train_model
from aamtrack.train.workers import PerThread, beside, ordered_map


def _arrays(model, path) -> dict:
    """The model file's arrays and its metadata without the timings, as saved."""
    save_model(model, path)
    with np.load(path) as z:
        out = {k: z[k] for k in z.files if k != "meta"}
        meta = json.loads(str(z["meta"]))
    meta["config"].pop("timings")
    out["meta"] = meta
    return out


def test_a_model_trained_on_two_threads_is_the_one_trained_on_one(tmp_path):
    """The synthetic 3D model with its landmark cascades and all three landmark validators (each validator's random
    draws stay in the calling thread, the threads' results come back in order): every array identical."""
    import synth3d

    candide = synth3d.synthetic_candide()
    images, points, _, _ = synth3d.posed_faces(candide, 16, np.random.default_rng(SEED))
    cfg = TrainConfig(couples=SYNTH_COUPLES, map_refine_rounds=1, n_corrective=4, validator_images=60,
                      landmark_starts=6)
    one, _ = train_model(images, points, "3d", candide=candide, config=cfg, workers=1)
    two, _ = train_model(images, points, "3d", candide=candide, config=cfg, workers=2)
    assert one.landmark_validator is not None  # the threaded work ran
    a, b = _arrays(one, tmp_path / "one.npz"), _arrays(two, tmp_path / "two.npz")
    assert a.keys() == b.keys()
    assert a.pop("meta") == b.pop("meta")
    different = [k for k in a if not np.array_equal(a[k], b[k])]
    assert different == []


def test_ordered_map_gives_results_in_order_and_draws_in_the_calling_thread():
    """Results in the items' order whatever order the threads finish in; the items' generator runs in the caller."""
    import time

    caller, seen = threading.get_ident(), []

    def items():
        for i in range(20):
            seen.append(threading.get_ident())
            yield i

    def slow_first(i):
        time.sleep(0.02 if i % 3 == 0 else 0.0)
        return i * i, threading.get_ident()

    out = list(ordered_map(slow_first, items(), 3))
    assert [r for r, _ in out] == [i * i for i in range(20)]
    assert set(seen) == {caller}
    assert len({t for _, t in out} - {caller}) >= 2  # the work did run on other threads


def test_ordered_map_passes_an_error_on():
    def fails(i):
        if i == 5:
            raise ValueError("item 5")
        return i

    with pytest.raises(ValueError, match="item 5"):
        list(ordered_map(fails, range(50), 2))


def test_per_thread_makes_one_object_per_thread():
    made = PerThread(object)
    mine = made.get()
    assert made.get() is mine
    other = []
    t = threading.Thread(target=lambda: other.append(made.get()))
    t.start()
    t.join()
    assert other[0] is not mine


def test_beside_runs_on_another_thread_and_hands_back_result_or_error():
    import time

    caller = threading.get_ident()
    got = beside(lambda x: (time.sleep(0.05), x, threading.get_ident())[1:], 7, workers=2)
    value, where = got()
    assert value == 7 and where != caller
    assert beside(lambda: threading.get_ident(), workers=1)() == caller  # one worker: run when asked, here
    for workers in (1, 2):
        made = beside(list, range(3), workers=workers)
        assert made() is made()  # run once

    def fails():
        raise OSError("no such cascade")

    with pytest.raises(OSError, match="no such cascade"):
        beside(fails, workers=2)()
