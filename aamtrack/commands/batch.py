"""``aamtrack run`` on many inputs: folders and globs of videos, several at once in worker processes
(``--jobs``) or on a Dask cluster (``--scheduler``), finished inputs skipped on a re-run, and ``batch.csv``.

Each input is one task, :func:`run_task`: it tracks the input with :func:`aamtrack.commands.run.track_file`
into ``<out-dir>/<name>/`` (all of its outputs committed together, or none) and returns one row of
``batch.csv``. A task never raises for a bad input: the row says ``failed`` and why, and the other inputs go on.
The same function runs in this process (``--jobs 1``), in a pool of worker processes, or on Dask workers, which
write their outputs to the (shared) output folder themselves.
"""

from __future__ import annotations

import contextlib
import csv
import glob
import hashlib
import io
import logging
import multiprocessing
import os
import re
import signal
import sys
import threading
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from pathlib import Path

from tqdm import tqdm

from ..errors import AamtrackError, InputError
from ..io.atomic import atomic_write
from ..io.frames import VIDEO_SUFFIXES, display_name, natural_key
from ..track.smooth import SmoothConfig

log = logging.getLogger(__name__)

BATCH_COLUMNS = ("input", "frames", "tracked", "lost", "fps", "status", "error")
DASK_HINT = 'pip install "aamtrack[dask]"'
_MAX_NAME = 100


# -- which inputs ------------------------------------------------------------------------------------------
def _videos_in(paths) -> list[Path]:
    return sorted((p for p in paths if p.is_file() and p.suffix.lower() in VIDEO_SUFFIXES),
                  key=lambda p: natural_key(str(p)))


def expand_inputs(args: list[str]) -> tuple[list[str], bool]:
    """The inputs the command line names, and whether they make a batch.

    A video or image file is one input. A folder holding video files (by suffix, see ``VIDEO_SUFFIXES``) gives
    each video as an input; a folder of images is one image sequence, as for a single run. A glob pattern
    matching video files likewise gives each; one matching images is one sequence. An argument that names
    nothing stays an input (it fails as a single run would, and in a batch only its own row says so).
    Batch: more than one argument, or a folder or glob of videos.
    """
    items, batch = [], len(args) > 1
    for arg in args:
        path = Path(arg)
        if path.is_dir():
            videos = _videos_in(path.iterdir())
        elif not os.path.lexists(arg) and glob.has_magic(arg):
            videos = _videos_in(Path(p) for p in glob.glob(arg))
        else:
            videos = []
        if videos:
            items += [str(v) for v in videos]
            batch = True
        else:
            items.append(arg)
    return items, batch


def safe_name(stem: str) -> str:
    """``stem`` as a folder and file name that is safe everywhere: letters, digits, ``.``, ``_``, ``-``."""
    name = re.sub(r"[^A-Za-z0-9._-]+", "_", stem).strip("._")[:_MAX_NAME]
    return name or "input"


def output_names(items: list[str]) -> list[str]:
    """One output name per input: its safe stem; inputs whose names would collide (``a/clip.mp4`` and
    ``b/clip.mp4``, or ``clip.mp4`` and ``clip.avi``, also by case) all get ``<stem>_<8 hex digits of a hash of
    the absolute path>``, which does not depend on the other inputs or their order."""
    from .run import output_base

    stems = [safe_name(output_base(i)[1]) for i in items]
    count: dict[str, int] = {}
    for s in stems:
        count[s.lower()] = count.get(s.lower(), 0) + 1
    names = []
    for item, stem in zip(items, stems, strict=True):
        if count[stem.lower()] > 1:
            digest = hashlib.sha1(os.fsencode(os.path.abspath(item))).hexdigest()[:8]
            stem = f"{stem[:_MAX_NAME - 9]}_{digest}"
        names.append(stem)
    return names


# -- one task ------------------------------------------------------------------------------------------------
def file_sha256(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for block in iter(lambda: f.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def run_options(*, model_path: Path, overlay: bool | str, pts: bool, report: bool, replay: bool, fps, smooth) -> dict:
    """What a finished input's summary records of the run that made it; a re-run with other options (or another
    model file, by content) redoes the input. overlay: as ``run.track_file`` takes it (True, or "fast")."""
    try:
        digest = file_sha256(model_path)
    except OSError:
        digest = None  # the model's own loading says what is wrong with it
    return {"model": str(Path(model_path).resolve()), "model_sha256": digest, "video": overlay, "pts": pts,
            "report": report, "realtime": replay, "fps": fps,
            "smooth": None if smooth is None else [smooth.min_cutoff, smooth.beta, smooth.d_cutoff,
                                                    smooth.follow_jumps, smooth.look_ahead]}


def _row(task: dict, status: str, summary: dict | None = None, error: str = "") -> dict:
    s = summary or {}
    fps = s.get("fps_end_to_end")
    return {"input": task["input"], "frames": s.get("frames_read", ""), "tracked": s.get("frames_tracked", ""),
            "lost": s.get("frames_lost", ""), "fps": f"{fps:.1f}" if isinstance(fps, (int, float)) else "",
            "status": status, "error": error, "name": task["name"]}


def finished_summary(task: dict) -> dict | None:
    """The summary of an earlier run of this task with the same input and options, if its outputs are there."""
    import json

    folder = Path(task["out_dir"])
    try:
        summary = json.loads((folder / f"{task['name']}.json").read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    batch = summary.get("batch") if isinstance(summary, dict) else None
    if not isinstance(batch, dict) or batch.get("input") != task["input_abs"] or batch.get("options") != task["options"]:
        return None
    if not (folder / f"{task['name']}.csv").is_file():
        return None
    return summary


_local = threading.local()  # per worker thread: {model path: warmed-up Tracker}


def warm_tracker(model_path: Path):
    """This thread's Tracker of the model file ``model_path``, made and warmed up (numba's kernels loaded) on first
    use: a batch's tasks and ``aamtrack fit``'s workers share it, and workers forked after it was made inherit it."""
    from ..model import load_model
    from ..track.benchmark import warmup
    from ..track.tracker import Tracker

    cache = getattr(_local, "trackers", None)
    if cache is None:
        cache = _local.trackers = {}
    key = str(model_path)
    if key not in cache:
        cache[key] = Tracker(load_model(model_path))
        warmup(cache[key])
    return cache[key]


def error_text(exc: BaseException) -> str:
    """One line for an input's failure, as the command line would print it."""
    if isinstance(exc, AamtrackError):
        return str(exc)
    if isinstance(exc, OSError):
        where = f"{display_name(exc.filename)}: " if exc.filename else ""
        return f"{where}{exc.strerror or exc}"
    if isinstance(exc, MemoryError):
        return "out of memory"
    return f"internal error: {type(exc).__name__}: {exc}".splitlines()[0]


def run_task(task: dict, on_frame=None) -> dict:
    """Track one input of a batch (see the module docstring); returns its ``batch.csv`` row."""
    from ..track.pipeline import keep_freed_memory
    from .run import track_file

    keep_freed_memory()  # on Dask workers too (a worker process of --jobs has it from its parent already)
    if not task["overwrite"]:
        done = finished_summary(task)
        if done is not None:
            return _row(task, "skipped", done)
    o = task["options"]
    smooth = None if o["smooth"] is None else SmoothConfig(*o["smooth"])
    try:
        summary = track_file(task["input"], model_path=Path(task["model_path"]), out_dir=Path(task["out_dir"]),
                             overlay=o["video"], pts=o["pts"], replay=o["realtime"], fps=o["fps"], progress=False,
                             smooth=smooth, report=o["report"], name=task["name"], on_frame=on_frame,
                             tracker=warm_tracker(Path(task["model_path"])), decode_threads=_decode_threads,
                             extra={"batch": {"input": task["input_abs"], "options": task["options"]}})
    except Exception as exc:  # noqa: BLE001 - any failure is this input's row; the batch goes on
        log.info("%s: failed: %s", task["input"], exc, exc_info=not isinstance(exc, (AamtrackError, OSError)))
        return _row(task, "failed", error=error_text(exc))
    return _row(task, "done", summary)


# -- worker processes ------------------------------------------------------------------------------------------
_progress = None  # in a worker process: the queue its frame counts go to
_decode_threads = None  # FFmpeg's decoding threads per input (None: its default, one per core)


def _init_worker(progress, quiet: bool) -> None:
    """A worker process of ``--jobs N``: the other workers keep the other cores busy, so its own work stays in
    its threads: one FFmpeg decoding thread and no OpenCV worker threads (same frames and results; measured on
    the 2-core VM, shared, 8 clips of 250 frames with --jobs 2, three interleaved pairs each: about 5% less CPU
    time from each of the two, and no slower)."""
    global _progress, _decode_threads
    _progress = progress
    _decode_threads = 1
    signal.signal(signal.SIGINT, signal.default_int_handler)
    import cv2

    if cv2.getNumThreads() != 1:  # (forked from ``_run_local``, it has 1 already: a change now could hang)
        cv2.setNumThreads(1)
    if quiet:  # as cli.quiet_native_logs in the parent (FFmpeg's level comes with the environment)
        cv_log = getattr(getattr(cv2, "utils", None), "logging", None)
        if cv_log:
            cv_log.setLogLevel(cv_log.LOG_LEVEL_SILENT)


class _Counter:
    """Frames done, sent to the parent's progress bar in bunches."""

    def __init__(self, send, every: int = 25):
        self.send, self.every, self.n = send, every, 0

    def __call__(self, n: int) -> None:
        self.n += n
        if self.n >= self.every:
            self.send(self.n)
            self.n = 0

    def flush(self) -> None:
        if self.n:
            self.send(self.n)
            self.n = 0


def _worker_task(task: dict) -> dict:
    counter = _Counter(_progress.put) if _progress is not None else None
    try:
        return run_task(task, on_frame=counter)
    finally:
        if counter is not None:
            counter.flush()


def _pool_context():
    """Worker processes are forked where the platform can (Linux) and the process has no other thread: they
    inherit the imported modules and the parent's warmed-up tracker, so a worker starts in milliseconds instead of
    seconds of imports and numba cache loads. The pool forks all its workers at the first submit, before this
    module starts any thread. A fork copies only the forking thread: a lock another thread held at that moment (a
    program calling ``run_batch`` while its own threads use OpenCV) stays held in the child for ever, and the
    worker hung in its first OpenCV call (once in CI's run of the test that does this). With other threads alive
    the workers start from a fork server instead: a fresh process that imports this module once and forks them."""
    methods = multiprocessing.get_all_start_methods()
    if "fork" in methods and threading.active_count() == 1:
        return multiprocessing.get_context("fork")
    for method in ("forkserver", "spawn"):
        if method in methods:
            ctx = multiprocessing.get_context(method)
            if method == "forkserver":  # (takes effect when the server starts: the first such pool in a process)
                ctx.set_forkserver_preload([__name__])
            return ctx
    return multiprocessing.get_context()  # pragma: no cover


@contextlib.contextmanager
def worker_pool(workers: int):
    """A pool of ``workers`` worker processes (``_pool_context``, each set up by ``_init_worker``), all started
    before this yields (pool, progress queue): threads the caller starts afterwards (a progress bar's) are never
    forked. A worker process sends frame counts to the queue (``_worker_task``). On a failure or a stop signal in
    the ``with`` block, the workers get SIGINT (on which a worker discards its temporaries, as a single run does;
    Ctrl-C reaches them anyway, one process group) and the queued work is cancelled."""
    import cv2

    ctx = _pool_context()
    progress = ctx.Queue()
    quiet = os.environ.get("OPENCV_FFMPEG_LOGLEVEL") == "-8"
    # OpenCV's thread pool does not survive a fork: a worker forked while the parent's pool threads existed could
    # hang for ever in its first OpenCV call (cv2.setNumThreads in ``_init_worker``: seen once in a test run, and
    # every time when the pool was busy in another thread at the fork). With one thread OpenCV keeps no pool
    # threads, so none are forked; the parent only coordinates while the workers run, and gets its threads back.
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_init_worker,
                               initargs=(progress, quiet))
    try:
        pool.submit(int).result()  # a forking pool starts all its workers at the first submit: now
        yield pool, progress
    except BaseException as exc:
        if getattr(exc, "signum", None) is not None or not isinstance(exc, KeyboardInterrupt):
            for p in list((getattr(pool, "_processes", None) or {}).values()):
                try:
                    os.kill(p.pid, signal.SIGINT)
                except OSError:
                    pass
        pool.shutdown(wait=True, cancel_futures=True)
        raise
    finally:
        cv2.setNumThreads(threads)
    pool.shutdown(wait=True)
    progress.close()


def _run_local(tasks: list[dict], jobs: int, make_bar, on_row) -> None:
    if jobs <= 1 or len(tasks) <= 1:
        bar = make_bar()
        try:
            for k, task in enumerate(tasks):
                on_row(k, run_task(task, on_frame=bar.update), bar)
        finally:
            bar.close()
        return
    stop = threading.Event()
    with worker_pool(min(jobs, len(tasks))) as (pool, progress):
        pump = bar = None
        try:
            pending = {pool.submit(_worker_task, t): k for k, t in enumerate(tasks)}
            bar = make_bar()

            def drain():
                while not stop.is_set():
                    try:
                        n = progress.get(timeout=0.2)
                    except Exception:  # noqa: BLE001 - queue.Empty, or the queue closed at the end
                        continue
                    if n is None:  # the end (sent below): no waiting out the timeout
                        return
                    bar.update(n)

            pump = threading.Thread(target=drain, name="aamtrack-progress", daemon=True)
            pump.start()
            while pending:
                done, _ = wait(pending, return_when=FIRST_COMPLETED)
                for fut in done:
                    k = pending.pop(fut)
                    try:
                        row = fut.result()
                    except KeyboardInterrupt:
                        raise
                    except BaseException as exc:  # a worker that died (killed, out of memory)
                        row = _row(tasks[k], "failed", error=f"worker process failed: {error_text(exc)}")
                    on_row(k, row, bar)
        finally:
            stop.set()
            if pump is not None:
                progress.put(None)
                pump.join()
            if bar is not None:
                bar.close()


# -- Dask ------------------------------------------------------------------------------------------------------------
def require_dask():
    try:
        from dask import distributed
    except ImportError:
        raise InputError(f"--scheduler needs Dask's distributed scheduler, which is not installed: {DASK_HINT}") \
            from None
    return distributed


def _run_dask(tasks: list[dict], address: str, make_bar, on_row) -> None:
    distributed = require_dask()
    try:
        client = distributed.Client(address, timeout="20s")
    except (OSError, ValueError, TimeoutError) as exc:
        raise InputError(f"--scheduler {address}: cannot connect to the Dask scheduler ({exc})") from None
    futures = []
    bar = make_bar()
    try:
        futures = client.map(run_task, tasks, pure=False, key=[f"aamtrack-{t['name']}-{os.urandom(4).hex()}"
                                                                for t in tasks])
        index = {f.key: k for k, f in enumerate(futures)}
        for fut in distributed.as_completed(futures):
            k = index[fut.key]
            try:
                row = fut.result()
            except Exception as exc:  # noqa: BLE001 - a worker lost, a task that could not run
                row = _row(tasks[k], "failed", error=f"dask: {error_text(exc)}")
            bar.update(row["frames"] if isinstance(row["frames"], int) and row["status"] == "done" else 0)
            on_row(k, row, bar)
    except BaseException:
        if futures:
            client.cancel(futures)
        raise
    finally:
        bar.close()
        client.close()


# -- the batch -------------------------------------------------------------------------------------------------------
def run_batch(items: list[str], *, out_dir: Path, model_path: Path, options: dict, jobs: int = 1,
              scheduler: str | None = None, overwrite: bool = False, progress: bool = True,
              say=None) -> list[dict]:
    """Track every input of ``items`` into ``out_dir/<name>/``; write ``out_dir/batch.csv``; return its rows
    (in input order). ``say`` prints a line (each failure as it happens)."""
    if scheduler is not None:
        require_dask()  # before any work
    out_dir = Path(out_dir)
    from ..io.atomic import OutputSet

    OutputSet(out_dir).prepare()  # the folder exists and is writable, before the work
    out_abs = out_dir.resolve()
    names = output_names(items)
    tasks = [{"input": item if scheduler is None else os.path.abspath(item), "input_abs": os.path.abspath(item),
              "name": name, "out_dir": str(out_abs / name), "model_path": str(Path(model_path).resolve()),
              "options": options, "overwrite": overwrite} for item, name in zip(items, names, strict=True)]
    rows: list[dict | None] = [None] * len(tasks)
    todo = list(range(len(tasks)))
    if scheduler is None:  # the outputs are visible here: skip finished inputs without starting workers
        for k, task in enumerate(tasks):
            done = None if overwrite else finished_summary(task)
            if done is not None:
                rows[k] = _row(task, "skipped", done)
        todo = [k for k in todo if rows[k] is None]
        if todo:
            warm_tracker(Path(model_path))  # a bad model fails the batch here, once; forked workers inherit it
    else:
        from ..model import load_model

        load_model(model_path)  # a bad model fails here, not once per input on the workers
    total = sum(_frame_count(items[k]) for k in todo)

    def make_bar():
        return tqdm(total=total or None, unit="frame", file=sys.stderr, disable=not progress or None,
                    desc=f"{len(todo)} of {len(tasks)} inputs", smoothing=0.1)

    def on_row(j, row, bar):
        rows[todo[j]] = row
        if row["status"] == "failed" and say is not None:
            text = row["error"] if row["error"].startswith(str(row["input"])) else f"{row['input']}: {row['error']}"
            with bar.external_write_mode(file=sys.stderr):
                say(f"aamtrack run: error: {display_name(text)}")

    run = [tasks[k] for k in todo]
    if run:
        if scheduler is not None:
            _run_dask(run, scheduler, make_bar, on_row)
        else:
            _run_local(run, jobs, make_bar, on_row)
    write_batch_csv(out_dir / "batch.csv", rows)
    return rows


def _frame_count(item: str) -> int:
    """The frame count the container states (0 if unknown or unreadable): for the progress bar only."""
    import cv2

    from ..io.frames import opencv_path

    if Path(item).suffix.lower() not in VIDEO_SUFFIXES or not os.path.isfile(item):
        return 0
    try:
        with opencv_path(item) as name:
            cap = cv2.VideoCapture(name, cv2.CAP_FFMPEG)
        n = cap.get(cv2.CAP_PROP_FRAME_COUNT) if cap.isOpened() else 0
        cap.release()
    except (InputError, cv2.error):
        return 0
    return int(n) if 0 < n < 1e9 else 0


def write_batch_csv(path: Path, rows: list[dict]) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(BATCH_COLUMNS)
    for r in rows:
        w.writerow([display_name(r[c]) if c == "input" else r[c] for c in BATCH_COLUMNS])
    with atomic_write(path, "w", newline="") as f:
        f.write(buf.getvalue())


def read_batch_csv(path) -> list[dict]:
    with open(path, encoding="utf-8", newline="") as f:
        return list(csv.DictReader(f))


def default_jobs() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def summary_line(rows: list[dict], seconds: float, out_dir: Path) -> str:
    n = {s: sum(r["status"] == s for r in rows) for s in ("done", "skipped", "failed")}
    frames = sum(r["frames"] for r in rows if r["status"] == "done" and isinstance(r["frames"], int))
    return (f"{len(rows)} inputs: {n['done']} done, {n['skipped']} skipped, {n['failed']} failed; {frames} frames "
            f"tracked in {seconds:.1f} s ({frames / max(seconds, 1e-9):.0f} fps overall) -> "
            f"{display_name(out_dir / 'batch.csv')}")


