"""``flow_bag eval`` over many bags, in parallel on Dask.

Inputs are bag folders, folders holding bags (searched recursively), glob patterns and text files that list
bags (one path a line, ``#`` comments, relative to the list's folder). Every bag is one Dask task running
:func:`evaluate_bag`: the single-bag :func:`~flow_node.bag.evaluate.run_eval` into ``OUT/bags/<name>/``, so
each bag gets exactly what ``flow_bag eval BAG --output OUT/bags/<name>`` writes. The scheduler is an embedded
``distributed.LocalCluster`` (one single-threaded worker process per core; one worker is a thread of this
process) or, with ``scheduler``, an existing cluster; both go through the same ``Client.submit`` /
``as_completed`` path. Workers must see the
bags and ``OUT`` under the same paths (a shared file system) and have flow_node installed.

A bag that fails is reported with its one-line reason; the others go on. A bag whose content (hash of its
files) and configuration (every engine setting, topics, colour scale, PNG choice) match the key stored with
its output is skipped, so an interrupted batch resumes where it stopped. dask and distributed are imported
only when a batch runs.
"""

from __future__ import annotations

import glob
import hashlib
import importlib
import json
import os
import socket
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict, replace
from pathlib import Path
from typing import Any

from ..core.config import FlowConfig
from ..core.errors import ClusterError, FlowError, one_line
from ..process import keep_freed_environ
from .bagio import BagError
from .evaluate import run_eval
from .progress import BatchProgress
from .results import BATCH_FORMAT, BagJob, BagOutcome, EvalOptions

KEY_FILE = "batch_key.json"  # written into a bag's output folder once it is complete
PROGRESS_TOPIC = "flow_bag-progress"  # Dask event topic of the per-frame progress
BAG_SUFFIXES = (".mcap", ".db3")
GLOB_CHARS = frozenset("*?[")
# Environment of the embedded cluster's worker processes (Dask's nanny sets it before it starts them): one
# thread per worker for the numeric libraries (Dask's default), and glibc keeping freed memory as the executables'
# main() does (flow_node/process.py; docs/node.md, "Memory allocation") instead of Dask's MALLOC_TRIM_THRESHOLD_=65536,
# under which every per-frame array is a fresh mmap faulted in again (tasks ran up to 2x slower).
WORKER_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", **keep_freed_environ()}
# Dask settings of the embedded cluster: its periodic bookkeeping made quiet. With the defaults an idle one-worker
# cluster and its client spend ~49 ms of CPU per second (mostly holding the GIL the bag's thread needs): the worker's
# statistical profiler samples the task's stack every 10 ms, the memory monitor reads the process' memory every
# 100 ms, the event loop's tick runs every 20 ms, the system monitor every 0.5 s and work stealing every 1 s.
# A batch uses none of them (no dashboard; bags are queued on the scheduler and handed to the next free worker),
# and without them the cluster idles at ~5 ms per second (issue 14, "Quiet cluster" in
# `git show a451d03:BENCHMARKS.md`). A cluster given with --scheduler keeps its own settings.
QUIET_CLUSTER = {"distributed.worker.profile.enabled": False, "distributed.worker.memory.monitor-interval": "1s",
                 "distributed.admin.tick.interval": "1s", "distributed.admin.system-monitor.interval": "2s",
                 "distributed.scheduler.work-stealing": False}


# ------------------------------------------------------------------------------------------------ inputs
def is_bag(path: Path) -> bool:
    """A rosbag2 folder (metadata.yaml or a storage file in it), or a single .mcap/.db3 file."""
    if path.is_file():
        return path.suffix in BAG_SUFFIXES
    return path.is_dir() and ((path / "metadata.yaml").is_file()
                              or any(p.suffix in BAG_SUFFIXES for p in path.iterdir() if p.is_file()))


def is_single_bag(inputs: Sequence[str]) -> bool:
    """True for one input that is a bag, or that single-bag eval reports as it always did: a path that does
    not exist, or a folder with no bag in it."""
    if len(inputs) != 1 or GLOB_CHARS & set(inputs[0]):
        return False
    p = Path(inputs[0])
    return not p.exists() or is_bag(p) or (p.is_dir() and not _bags_below(p, None))


def _bags_below(folder: Path, exclude: Path | None) -> list[Path]:
    """Bag folders under ``folder`` (not descending into a bag, hidden folders or ``exclude``), sorted."""
    found = []
    for root, dirs, _files in os.walk(folder):
        here = Path(root)
        if is_bag(here):
            found.append(here)
            dirs[:] = []
            continue
        dirs[:] = sorted(d for d in dirs if not d.startswith(".")
                         and (exclude is None or (here / d).resolve() != exclude))
    return found


def _list_file(path: Path) -> list[str]:
    """Entries of a bag list: one path a line, blank lines and ``#`` comments ignored, relative paths
    taken from the list's folder."""
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise BagError(f"{path}: cannot read the bag list: {exc}") from exc
    entries = [line.split("#", 1)[0].strip() for line in lines]
    return [e if os.path.isabs(e) else str(path.parent / e) for e in entries if e]


def find_bags(inputs: Sequence[str], exclude: str | Path | None = None) -> list[Path]:
    """Bags named by ``inputs`` (bag folders or files, folders of bags, globs, list files), in input
    order without duplicates; ``exclude`` (the batch's output) is never searched. A path that does not
    exist is kept (its evaluation reports it); a folder or glob with no bag in it is a BagError."""
    out: dict[Path, Path] = {}
    for bag in _collect(inputs, Path(exclude).resolve() if exclude is not None else None):
        out.setdefault(bag.resolve(), bag)
    if not out:
        raise BagError("no bag to evaluate")
    return list(out.values())


def _collect(inputs: Sequence[str], skip: Path | None) -> list[Path]:
    """The bags of :func:`find_bags`, duplicates included."""
    found: list[Path] = []
    for item in inputs:
        here = Path(item).resolve()
        if skip is not None and (here == skip or skip in here.parents):
            continue  # the batch's own output (a glob or list may name it)
        p = Path(item)
        if GLOB_CHARS & set(item) and not p.exists():
            matches = sorted(glob.glob(item, recursive=True))
            if not matches:
                raise BagError(f"{item}: no file or folder matches")
            found += _collect(matches, skip)
        elif not p.exists() or is_bag(p):
            found.append(p.parent if p.is_file() else p)
        elif p.is_file():
            found += _collect(_list_file(p), skip)
        else:
            below = _bags_below(p, skip)
            if not below:
                raise BagError(f"{item}: no rosbag2 folder in it")
            found += below
    return found


def output_names(bags: Sequence[Path]) -> list[str]:
    """A distinct folder name per bag: its path relative to the bags' common folder, '/' -> '__'."""
    resolved = [b.resolve() for b in bags]
    root = Path(os.path.commonpath(resolved)) if len(resolved) > 1 else resolved[0].parent
    if root in resolved:
        root = root.parent
    return ["__".join(b.relative_to(root).parts) for b in resolved]


# ------------------------------------------------------------------------------------------------ keys
def config_digest(configs: Sequence[FlowConfig], opts: EvalOptions) -> str:
    """sha256 of everything except the bag that decides a bag's output: every engine setting of every
    model, topics, colour scale, PNG frames, and the batch format."""
    data = {"format": BATCH_FORMAT, "configs": [c.to_dict() for c in configs],
            "options": {k: v for k, v in asdict(opts).items() if k != "progress"}}
    return hashlib.sha256(json.dumps(data, sort_keys=True, default=str).encode()).hexdigest()


def bag_digest(bag: str | Path, chunk: int = 1 << 20) -> str:
    """sha256 over a bag's files (relative name and bytes of each, in name order): its content, wherever
    it lies. A missing bag hashes to a BagError."""
    p = Path(bag)
    folder = p.parent if p.is_file() else p
    if not folder.is_dir():
        raise BagError(f"{bag}: no such bag")
    h = hashlib.sha256()
    for f in sorted(x for x in folder.rglob("*") if x.is_file()):
        h.update(str(f.relative_to(folder)).encode() + b"\0")
        with f.open("rb") as fh:
            while block := fh.read(chunk):
                h.update(block)
        h.update(b"\0")
    return h.hexdigest()


def cached_key(output: Path) -> str | None:
    """The key stored with a complete bag output, or None."""
    try:
        return str(json.loads((output / KEY_FILE).read_text())["key"])
    except (OSError, ValueError, KeyError, TypeError):
        return None


def make_jobs(bags: Sequence[Path], out: Path, configs: Sequence[FlowConfig], opts: EvalOptions) -> list[BagJob]:
    """One job per bag, outputs in ``out/bags/<name>``; worker-side options (no terminal progress)."""
    digest = config_digest(configs, opts)
    worker_opts = replace(opts, progress=False)
    return [BagJob(str(b), n, str(out / "bags" / n), tuple(configs), worker_opts, digest)
            for b, n in zip(bags, output_names(bags), strict=True)]


# ------------------------------------------------------------------------------------------------ one bag
def _frame_events(name: str, period: float = 0.25) -> Callable[[int, int], None] | None:
    """A progress callback that sends (done, total) to the client as Dask events, at most every
    ``period`` s and on the last frame; None outside a Dask worker."""
    try:
        from distributed import get_worker

        worker = get_worker()
    except (ImportError, ValueError):
        return None
    last = [0.0]

    def send(done: int, total: int) -> None:
        now = time.monotonic()
        if done >= total or now - last[0] >= period:
            last[0] = now
            worker.log_event(PROGRESS_TOPIC, {"name": name, "done": done, "total": total})

    return send


def evaluate_bag(job: BagJob) -> BagOutcome:
    """The task of one bag: skip it if its output carries the same key, else run the single-bag eval into
    ``job.output`` and store the key. Never raises: a failure becomes a 'failed' outcome."""
    start = time.monotonic()
    out = Path(job.output)
    outcome = BagOutcome(job.bag, job.name, "failed", host=socket.gethostname(), pid=os.getpid())
    try:
        key = hashlib.sha256(f"{bag_digest(job.bag)}:{job.config_digest}".encode()).hexdigest()
        outcome.key = key
        if cached_key(out) == key:
            outcome.status = "skipped"
        else:
            out.parent.mkdir(parents=True, exist_ok=True)
            (out / KEY_FILE).unlink(missing_ok=True)
            run_eval(job.bag, out, job.configs, job.opts, _frame_events(job.name))
            (out / KEY_FILE).write_text(json.dumps({"key": key, "bag": job.bag}) + "\n")
            outcome.status = "done"
        outcome.report = json.loads((out / "report.json").read_text())
    except FlowError as exc:
        outcome.reason = str(exc)
    except Exception as exc:  # noqa: BLE001 - one broken bag must not stop the batch
        outcome.reason = f"{type(exc).__name__}: {one_line(exc, None)}"
    outcome.seconds = time.monotonic() - start
    return outcome


# ------------------------------------------------------------------------------------------------ Dask
def default_workers() -> int:
    """Cores available to this process."""
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1


def _restore_environ(before: dict[str, str]) -> None:
    """Put this process's environment back to ``before``: Dask's nanny writes its pre-spawn environment
    into the parent process each time it starts a worker, and must not change the caller's."""
    for k in set(os.environ) - set(before):
        del os.environ[k]
    os.environ.update(before)


@contextmanager
def dask_client(scheduler: str | None, workers: int | None = None, connect_timeout: float = 30.0,
                worker_timeout: float = 60.0) -> Iterator[Any]:
    """A ``distributed.Client``: connected to ``scheduler`` (tcp://host:port; within ``connect_timeout``
    s, then waiting up to ``worker_timeout`` s for a worker), or to an embedded LocalCluster of ``workers``
    single-threaded workers (default: one per core): worker processes, or for one worker a worker thread in
    this process (:func:`local_cluster`). ClusterError if neither works; closed on exit."""
    from distributed import Client, Worker

    cluster = client = None
    environ = dict(os.environ)
    try:
        if scheduler:
            client = Client(scheduler, timeout=connect_timeout)
            client.wait_for_workers(1, timeout=worker_timeout)
        else:
            cluster = local_cluster(workers or default_workers())
            _restore_environ(environ)
            client = Client(cluster)
    except (OSError, TimeoutError, ValueError) as exc:
        for resource in (client, cluster):
            if resource is not None:
                resource.close()
        _restore_environ(environ)
        where = f"the Dask scheduler at {scheduler}" if scheduler else "a local Dask cluster"
        raise ClusterError(f"cannot start or reach {where}: {one_line(exc, None)}") from exc
    try:
        yield client
    except BaseException:
        # Ctrl-C: a worker thread of this process cannot be stopped, so the close does not wait for its task
        # (its output stays an unfinished hidden folder, as when a worker process is killed)
        for worker in cluster.workers.values() if cluster is not None else ():
            if isinstance(worker, Worker):
                cluster.sync(worker.close, executor_wait=False)
        raise
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
        _restore_environ(environ)  # a worker restarted by its nanny wrote it again


def local_cluster(workers: int) -> Any:
    """The embedded ``LocalCluster``. Several workers: one single-threaded process each (the numba kernels release
    the GIL, but the engine's Python and numpy stages between them do not), started by Dask's nanny with WORKER_ENV
    and the preload dask_worker.py (a fast exit). One worker: a worker thread in this process (``processes=False``),
    the one batch layout in which no two bags compute at once anyway. It spares the fixed cost of a worker process
    (docs/bags.md): spawning it, importing distributed, flow_node, OpenCV and numba a second time,
    loading the JIT cache there, and waiting for it to exit; tasks, events and results go through the same scheduler
    and Client calls (in-process comm)."""
    import dask
    from distributed import LocalCluster

    if workers == 1:
        with dask.config.set(QUIET_CLUSTER):
            return LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=":0")
    with dask.config.set({**QUIET_CLUSTER, "distributed.nanny.pre-spawn-environ": WORKER_ENV,
                          "distributed.worker.preload": [f"{__package__}.dask_worker"]}):
        return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                            dashboard_address=":0")


def run_jobs(client: Any, jobs: Sequence[BagJob], progress: BatchProgress) -> list[BagOutcome]:
    """Submit every job to ``client`` and collect the outcomes in job order; a task lost with its worker
    (killed, out of memory) becomes a 'failed' outcome."""
    from distributed import as_completed

    client.subscribe_topic(PROGRESS_TOPIC, progress.on_event)
    futures = {client.submit(evaluate_bag, job, key=f"flow_bag-{job.name}-{job.config_digest[:8]}-{os.getpid()}",
                             pure=False, retries=0): job for job in jobs}
    done: dict[str, BagOutcome] = {}
    try:
        for fut in as_completed(futures):
            job = futures[fut]
            try:
                outcome = fut.result()
            except Exception as exc:  # noqa: BLE001 - the worker died or the task was lost
                outcome = BagOutcome(job.bag, job.name, "failed",
                                     reason=f"task lost: {type(exc).__name__}: {one_line(exc, None)}")
            done[job.name] = outcome
            progress.finish(outcome)
    finally:
        client.unsubscribe_topic(PROGRESS_TOPIC)
        for fut in futures:
            fut.release()
    return [done[j.name] for j in jobs]


def run_batch(inputs: Sequence[str], output: str | Path, configs: Sequence[FlowConfig], opts: EvalOptions,
              scheduler: str | None = None, workers: int | None = None) -> list[BagOutcome]:
    """Evaluate every bag of ``inputs`` on Dask into ``output``/bags/, then write the batch report
    (``output``/report.json, report.md, PNGs). Returns the outcomes in input order."""
    out = Path(output)
    if out.exists() and not out.is_dir():
        raise BagError(f"output {out} exists and is not a folder")
    jobs = make_jobs(find_bags(inputs, exclude=out), out, configs, opts)
    out.mkdir(parents=True, exist_ok=True)
    start = time.monotonic()
    progress = BatchProgress(len(jobs), opts.progress)
    try:
        with dask_client(scheduler, workers) as client:
            # the report's imports (matplotlib: ~1 s) while the workers compute, not after them
            report_import = threading.Thread(target=importlib.import_module, args=(f"{__package__}.batch_report",),
                                             daemon=True)
            report_import.start()
            outcomes = run_jobs(client, jobs, progress)
            workers_seen = len(client.nthreads())
    finally:
        progress.close()
    report_import.join()
    from .batch_report import write_batch_report

    where = f"{scheduler or 'embedded LocalCluster'}, {workers_seen} workers"
    write_batch_report(outcomes, out, configs, time.monotonic() - start, where)
    return outcomes
