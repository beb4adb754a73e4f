"""``aamtrack run --scheduler``: the same per-input tasks on a real Dask cluster (a LocalCluster: a scheduler and
two worker processes on this machine, not a mock) give the same CSVs and batch rows as ``--jobs``."""

from __future__ import annotations

import pytest
from notices import stderr_lines
from test_run_batch import make_folder, rows_by_name, run

distributed = pytest.importorskip("dask.distributed", reason="needs dask[distributed]: pip install 'aamtrack[dask]'")


def test_scheduler_on_a_local_cluster_gives_the_same_csvs_as_jobs(tmp_path, model_file, capsys):
    folder = make_folder(tmp_path, n_videos=3)
    local = tmp_path / "local"
    assert run(folder, "--model", model_file, "--out-dir", local, "--jobs", 1) == 1
    capsys.readouterr()
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None,
                                  silence_logs=40) as cluster:
        out = tmp_path / "dask"
        assert run(folder, "--model", model_file, "--out-dir", out, "--scheduler", cluster.scheduler_address) == 1
        err = stderr_lines(capsys)
        errors = [e for e in err if e.startswith("aamtrack run: error:")]  # (workers may log FFmpeg's own lines)
        assert len(errors) == 1 and "broken.mp4" in errors[0], err
        rows, expected = rows_by_name(out), rows_by_name(local)
        assert {k: (r["status"], r["frames"], r["tracked"], r["lost"]) for k, r in rows.items()} == \
            {k: (r["status"], r["frames"], r["tracked"], r["lost"]) for k, r in expected.items()}
        assert rows["broken.mp4"]["status"] == "failed" and "not a readable video" in rows["broken.mp4"]["error"]
        for k in range(3):
            assert (out / f"clip{k}" / f"clip{k}.csv").read_bytes() == \
                (local / f"clip{k}" / f"clip{k}.csv").read_bytes()
        # a re-run through the cluster: the workers see the finished outputs and skip them
        assert run(folder, "--model", model_file, "--out-dir", out, "--scheduler", cluster.scheduler_address) == 1
        assert [rows_by_name(out)[f"clip{k}.avi"]["status"] for k in range(3)] == ["skipped"] * 3
