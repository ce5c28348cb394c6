"""flow_bag eval over many bags on Dask: the embedded LocalCluster and a separate `dask scheduler` + `dask
worker` on loopback; per-bag results identical to single-bag eval, a corrupt bag reported while the others
finish, the cache skipping evaluated bags and re-running them when a parameter changes."""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace as NS

import cv2
import psutil
import pytest
import small_frames
from rosbags.rosbag2 import Reader

from flow_node.bag import plots
from flow_node.bag.batch import dask_client, find_bags, output_names
from flow_node.bag.cli import main as flow_bag
from flow_node.bag.report import per_frame_plot
from flow_node.bag.results import FrameRecord
from flow_node.bag.synth import SynthSpec, write_synth_bag
from flow_node.core.errors import ClusterError
from flow_node.process import keep_freed_environ

FAST = small_frames.CLI_ARGS + ["-q"]
TIMES = {"seconds", "wall_seconds", "seconds_mean", "seconds_median"}  # the only fields allowed to differ
SCENES = {"translation": "mcap", "rotation": "sqlite3", "robot2/zoom": "mcap"}
AEE_BOUND = 0.3  # px; the zero-flow AEE of these scenes is 0.5-2 px


def untimed(data):
    """report.json without timings (recursively)."""
    if isinstance(data, dict):
        return {k: untimed(v) for k, v in data.items() if k not in TIMES}
    if isinstance(data, list):
        return [untimed(v) for v in data]
    return data


def flow_messages(bag: Path) -> dict[str, list[bytes]]:
    """Raw CDR bytes per output topic of an eval output bag."""
    out: dict[str, list[bytes]] = {}
    with Reader(bag) as reader:
        for conn, _t, raw in reader.messages():
            out.setdefault(conn.topic, []).append(bytes(raw))
    return out


def make_bags(root: Path) -> Path:
    """Three tiny synthetic bags (one nested one level deeper, one sqlite3) and a copy with garbage storage."""
    for k, (name, storage) in enumerate(SCENES.items()):
        (root / name).parent.mkdir(parents=True, exist_ok=True)
        write_synth_bag(root / name, SynthSpec(scene=Path(name).name, frames=4, size=(48, 40), storage=storage,
                                               seed=k))
    shutil.copytree(root / "translation", root / "corrupt")
    storage = next((root / "corrupt").glob("*.mcap"))
    storage.write_bytes(b"not an mcap file " * 200)  # nothing to recover (a truncated one is read up to the cut)
    return root


def batch_report(out: Path) -> dict:
    return json.loads((out / "report.json").read_text())


def statuses(out: Path) -> dict[str, str]:
    return {r["bag"]: r["status"] for r in batch_report(out)["bags"]}


@pytest.fixture(scope="module")
def bags(tmp_path_factory) -> Path:
    return make_bags(tmp_path_factory.mktemp("batch") / "bags")


def test_inputs_folders_globs_and_lists(bags, tmp_path):
    """A folder is searched recursively, globs expand, a list file's relative lines resolve; no duplicates."""
    found = find_bags([str(bags)])
    assert sorted(output_names(found)) == ["corrupt", "robot2__zoom", "rotation", "translation"]
    listing = tmp_path / "bags.txt"
    listing.write_text(f"# week 12\n{os.path.relpath(bags / 'rotation', tmp_path)}\n\n{bags / 'translation'}  # ok\n")
    found = find_bags([str(listing), str(bags / "rot*"), str(bags / "robot2")])
    assert [p.resolve() for p in found] == [(bags / n).resolve() for n in ("rotation", "translation", "robot2/zoom")]


def test_the_output_folder_is_never_an_input(bags, tmp_path):
    out = tmp_path / "out"
    shutil.copytree(bags / "rotation", out / "bags" / "rotation" / "bag")  # what a batch output holds
    assert find_bags([str(bags / "rotation"), str(out), str(tmp_path / "o*")], exclude=out) == [bags / "rotation"]


def test_plots_leave_out_missing_values(tmp_path):
    """None, NaN and inf never reach a line, bar or histogram, and never fail the PNG."""
    nan, inf = float("nan"), float("inf")
    fig, (a, b, c) = plots.new_figure(3)
    plots.line_panel(a, {"m": [(0, 1.0), (1, None), (2, nan), (3, 2.0), (4, inf)], "empty": [(0, nan)]}, "t", "x", "y")
    assert [list(line.get_xdata()) for line in a.lines] == [[0.0, 3.0]]
    plots.bar_panel(b, ["b0", "b1", "b2"], {"m": [0.5, None, nan]}, "t", "y")
    assert [round(p.get_height(), 6) for p in b.patches] == [0.5]
    assert sum(t.get_text() == "n/a" for t in b.texts) == 2
    plots.histogram_panel(c, {"m": [nan, None], "k": []}, "t", "x")
    assert [t.get_text() for t in c.texts] == ["no data"]
    plots.save(fig, tmp_path / "p.png")
    assert (tmp_path / "p.png").read_bytes()[:4] == b"\x89PNG"


def test_an_unreachable_scheduler_is_a_one_line_error():
    with socket.socket() as s:  # a loopback port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(ClusterError, match=rf"^cannot start or reach the Dask scheduler at tcp://127.0.0.1:{port}: "):
        with dask_client(f"tcp://127.0.0.1:{port}", connect_timeout=1):
            pass


@pytest.fixture(scope="module")
def singles(bags, tmp_path_factory) -> Path:
    """Single-bag eval's output of each good bag, in ``singles/<name>``."""
    root = tmp_path_factory.mktemp("single")
    for name in ("translation", "rotation", "robot2/zoom"):
        assert flow_bag(["eval", str(bags / name), "--output", str(root / name), *FAST]) == 0
    return root


def assert_as_single_bag_eval(singles: Path, out: Path, report: dict) -> None:
    """Each good bag's output in the batch ``out`` is what single-bag eval writes: same report (but
    timings), same flow bytes, same files (and the cache key); the corrupt one failed with its reason."""
    assert report["counts"] == {"bags": 4, "done": 3, "skipped": 0, "failed": 1}
    (failure,) = report["failures"]
    assert failure["bag"] == "corrupt" and "corrupt" in failure["reason"] and "\n" not in failure["reason"]
    assert not (out / "bags" / "corrupt").exists()
    for name in ("translation", "rotation", "robot2/zoom"):
        single = singles / name
        mine = out / "bags" / name.replace("/", "__")
        assert untimed(json.loads((mine / "report.json").read_text())) == \
            untimed(json.loads((single / "report.json").read_text()))
        assert flow_messages(mine / "bag") == flow_messages(single / "bag")
        assert sorted(p.name for p in mine.iterdir()) == sorted([p.name for p in single.iterdir()] + ["batch_key.json"])
    rows = {r["bag"]: r for r in report["bags"]}
    assert all(rows[n]["pairs_with_gt"] == 3 and rows[n]["aee_mean"] < AEE_BOUND
               for n in ("translation", "rotation", "robot2__zoom"))


def test_batch_on_the_embedded_cluster(bags, singles, tmp_path, capsys):
    out = tmp_path / "out"
    environ = dict(os.environ)
    assert flow_bag(["eval", str(bags), "--output", str(out), "--workers", "2", *FAST]) == 1  # one bag failed
    assert dict(os.environ) == environ  # Dask's nanny writes the workers' environment into its parent
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("flow_bag eval: error: 1 of 4 bags failed (first: corrupt: ")
    report = batch_report(out)
    assert report["scheduler"] == "embedded LocalCluster, 2 workers"
    assert all(r["pid"] != os.getpid() for r in report["bags"])  # ran in the cluster's worker processes
    for name in ("aee_per_bag.png", "time_per_frame.png"):
        assert (out / name).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "## Failed bags" in (out / "report.md").read_text()
    assert_as_single_bag_eval(singles, out, report)


def test_one_worker_is_a_thread_of_this_process(bags, singles, tmp_path, monkeypatch):
    """--workers 1: the embedded cluster's one worker is a thread of the client's process (no process to
    spawn); the same tasks, events and results through the scheduler, and outputs as single-bag eval's."""
    from flow_node.bag.progress import BatchProgress

    seen: set[str] = set()
    on_event = BatchProgress.on_event
    monkeypatch.setattr(BatchProgress, "on_event", lambda self, e: (seen.add(e[1]["name"]), on_event(self, e)))
    out = tmp_path / "out"
    environ = dict(os.environ)
    assert flow_bag(["eval", str(bags), "--output", str(out), "--workers", "1", *FAST]) == 1
    assert dict(os.environ) == environ
    report = batch_report(out)
    assert report["scheduler"] == "embedded LocalCluster, 1 workers"
    assert {r["pid"] for r in report["bags"] if r["status"] != "failed"} == {os.getpid()}
    assert seen == {"translation", "rotation", "robot2__zoom"}  # per-frame progress came as Dask events
    assert_as_single_bag_eval(singles, out, report)


def test_rerun_skips_evaluated_bags_and_a_changed_parameter_reruns_them(bags, tmp_path):
    """The cache: same configuration, nothing re-evaluated (outputs untouched), the corrupt bag retried; a
    changed parameter re-evaluates every bag. Both reruns share one cluster (started once, --scheduler)."""
    from distributed import LocalCluster

    out = tmp_path / "out"
    with LocalCluster(n_workers=1, threads_per_worker=1, dashboard_address=None) as cluster:
        remote = ["--scheduler", cluster.scheduler_address]
        assert flow_bag(["eval", str(bags), "--output", str(out), *FAST, *remote]) == 1
        report = batch_report(out)
        assert report["counts"] == {"bags": 4, "done": 3, "skipped": 0, "failed": 1}
        stamps = {p: p.stat().st_mtime_ns for p in (out / "bags").rglob("*") if p.is_file()}

        assert flow_bag(["eval", str(bags), "--output", str(out), *FAST, *remote]) == 1
        assert statuses(out) == {"corrupt": "failed", "translation": "skipped", "rotation": "skipped",
                                 "robot2__zoom": "skipped"}
        assert {p: p.stat().st_mtime_ns for p in (out / "bags").rglob("*") if p.is_file()} == stamps
        assert [r.get("aee_mean") for r in batch_report(out)["bags"]] == [r.get("aee_mean") for r in report["bags"]]

        assert flow_bag(["eval", str(bags), "--output", str(out), *FAST, *remote, "--set", "median_filter=3"]) == 1
    assert statuses(out) == {"corrupt": "failed", "translation": "done", "rotation": "done", "robot2__zoom": "done"}
    rerun = json.loads((out / "bags" / "rotation" / "report.json").read_text())["models"][0]
    assert rerun["config"]["median_filter"] == 3  # (realtime's census term weighs with census_alpha, not alpha)
    assert rerun["summary"]["aee_mean"] != {r["bag"]: r for r in report["bags"]}["rotation"]["aee_mean"]


def _stop(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        if p.poll() is None:
            p.terminate()
    for p in procs:
        try:
            p.wait(timeout=15)
        except subprocess.TimeoutExpired:
            for child in psutil.Process(p.pid).children(recursive=True):
                child.kill()
            p.kill()
            p.wait(timeout=5)


@pytest.mark.slow  # a Dask scheduler and worker in their own processes
def test_batch_on_a_separate_dask_scheduler_and_worker(bags, tmp_path):
    """`dask scheduler` and `dask worker` (distributed's CLIs) on 127.0.0.1, ephemeral port; --scheduler."""
    good = tmp_path / "good"
    for name in ("translation", "rotation"):
        shutil.copytree(bags / name, good / name)
    dask = str(Path(sys.executable).with_name("dask"))
    info = tmp_path / "scheduler.json"
    logs = [(tmp_path / f"{n}.log").open("w") for n in ("scheduler", "worker")]
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(info)], stdout=logs[0], stderr=subprocess.STDOUT)]
    try:
        deadline = time.monotonic() + 60
        while not info.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(info.read_text())["address"]
        assert address.startswith("tcp://127.0.0.1:")
        procs.append(subprocess.Popen([dask, "worker", address, "--nthreads", "1", "--nworkers", "1",
                                       "--host", "127.0.0.1", "--no-dashboard"], stdout=logs[1],
                                      stderr=subprocess.STDOUT))
        out = tmp_path / "out"
        assert flow_bag(["eval", str(good), "--output", str(out), "--scheduler", address, *FAST]) == 0
        report = batch_report(out)
        assert report["counts"] == {"bags": 2, "done": 2, "skipped": 0, "failed": 0}
        assert report["scheduler"] == f"{address}, 1 workers"
        worker_pids = {c.pid for c in psutil.Process(procs[1].pid).children(recursive=True)} | {procs[1].pid}
        assert {r["pid"] for r in report["bags"]} <= worker_pids  # evaluated by the separate worker
        assert all(r["pairs_with_gt"] == 3 and r["aee_mean"] < AEE_BOUND for r in report["bags"])
    finally:
        _stop(procs[::-1])
        for f in logs:
            f.close()
    assert all(p.poll() is not None for p in procs)


def test_single_bag_plot_tolerates_missing_values(tmp_path):
    """per_frame.png (matplotlib): an AEE row only with ground truth; NaN, None and skipped frames are left out."""
    records = [FrameRecord(0, 0, skipped="first frame"), FrameRecord(1, 1, 0, 0.01, 5, aee=float("nan")),
               FrameRecord(2, 2, 1, None, None, aee=None), FrameRecord(3, 3, 2, 0.02, 5, aee=0.3)]
    heights = []
    for recs in (records, [FrameRecord(r.index, r.stamp_ns, r.previous_stamp_ns, r.seconds) for r in records]):
        per_frame_plot(NS(runs=[NS(label="l1_tv", records=recs)]), tmp_path / "p.png")
        heights.append(cv2.imread(str(tmp_path / "p.png")).shape[0])
    assert heights[0] == 2 * heights[1] > 0  # AEE panel above the time panel only where there is ground truth


@pytest.mark.ros  # imports the node (rclpy), in a subprocess
def test_single_bag_eval_and_the_node_do_not_import_dask(bags, tmp_path):
    """dask/distributed load only when a batch runs (they cost ~1 s of imports)."""
    code = ("import sys; import flow_node.ros.node; from flow_node.bag.cli import main; "
            f"rc = main(['eval', {str(bags / 'rotation')!r}, '-o', {str(tmp_path / 'o')!r}, *{FAST!r}]); "
            "print(rc, sorted(m for m in sys.modules if m.split('.')[0] in ('dask', 'distributed')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.split() == ["0", "[]"]


def test_worker_processes_skip_the_final_collections():
    """The embedded cluster's worker processes load the preload dask_worker.py (through Dask's config, via
    the nanny), whose teardown freezes the GC so that the process exits without walking every object."""
    import gc

    from distributed import Client

    from flow_node.bag import dask_worker
    from flow_node.bag.batch import local_cluster

    with local_cluster(2) as cluster, Client(cluster) as client:
        loaded = client.run(lambda: "flow_node.bag.dask_worker" in sys.modules)
    assert list(loaded.values()) == [True, True]
    before = gc.get_freeze_count()  # not 0 everywhere: python 3.12's startup may freeze objects itself
    try:
        dask_worker.dask_teardown(None)
        assert gc.get_freeze_count() > before
    finally:
        gc.unfreeze()


@pytest.mark.parametrize("workers", [1, 2])
def test_the_embedded_cluster_keeps_its_bookkeeping_quiet(workers):
    """The embedded cluster's workers (a thread of this process, or processes) run without the statistical
    profiler and work stealing, and no periodic callback of theirs fires more often than once a second: with
    Dask's defaults those took ~25 ms of CPU a second, mostly holding the GIL the bag's task needs."""
    from distributed import Client

    from flow_node.bag.batch import local_cluster

    def callbacks(dask_worker):
        return {name: pc.callback_time for name, pc in dask_worker.periodic_callbacks.items()}

    with local_cluster(workers) as cluster, Client(cluster) as client:
        per_worker = client.run(callbacks)
        extensions = set(cluster.scheduler.extensions)
    assert len(per_worker) == workers
    for found in per_worker.values():
        assert "profile" not in found and "profile-cycle" not in found
        assert min(found.values()) >= 1000, found
    assert "stealing" not in extensions


def _mmapped_bytes_while_holding_40_mb() -> int:
    """In a worker: bytes glibc serves by mmap (mallinfo2's hblkhd) while a 40 MB array is alive."""
    import ctypes

    import numpy as np  # the function is shipped to the worker by value: its imports go with it

    class MallInfo2(ctypes.Structure):
        _fields_ = [(name, ctypes.c_size_t) for name in ("arena", "ordblks", "smblks", "hblks", "hblkhd",
                                                          "usmblks", "fsmblks", "uordblks", "fordblks", "keepcost")]

    libc = ctypes.CDLL("libc.so.6")
    libc.mallinfo2.restype = MallInfo2
    held = np.ones(40 << 17)  # 40 MB of float64: above glibc's largest dynamic mmap threshold (32 MB)
    mapped = int(libc.mallinfo2().hblkhd)
    del held
    return mapped


@pytest.mark.parametrize("preload", [True, False])
def test_the_worker_preload_keeps_freed_memory(preload, monkeypatch):
    """A worker of any cluster that preloads flow_node.bag.dask_worker (dask_setup) serves large arrays from the
    heap, as the flow_node executables do; without the preload (Dask's nanny's environment) they are fresh mmaps
    -- the control, showing the probe can tell."""
    from distributed import Client, LocalCluster

    for name in keep_freed_environ():  # an earlier embedded cluster's nanny may have written them into ours
        monkeypatch.delenv(name, raising=False)

    kw = {"preload": ["flow_node.bag.dask_worker"]} if preload else {}
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None, **kw) as cluster, \
            Client(cluster) as client:
        (mapped,) = client.run(_mmapped_bytes_while_holding_40_mb).values()
    assert (mapped < 40 << 20) if preload else (mapped >= 40 << 20), mapped
