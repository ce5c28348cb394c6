"""Diagnostics level rules and window accounting (plain Python: NodeStats and level_of)."""

from __future__ import annotations

import time

import numpy as np

from flow_node.core.refine import SolveStats
from flow_node.pipeline.stream import FlowOutput
from flow_node.ros.diagnostics import ERROR, OK, WARN, NodeStats, level_of, status


def output(value: float) -> FlowOutput:
    flow = np.full((4, 5, 2), value, np.float32)
    return FlowOutput(flow, 2, 1, 0.01, None, "numpy", "l1_tv", 1.0, 10.0)  # type: ignore[arg-type]


def test_levels_in_order_of_severity() -> None:
    s = NodeStats()
    assert level_of(s.window(), ready=False) == (WARN, "warming up the engine")
    assert level_of(s.window(), ready=True) == (WARN, "no image received yet")
    s.received(False)
    s.solved(0.02, 0.001, 0.0005, output(3.0))
    assert level_of(s.window(), ready=True) == (OK, "computing flow")
    s.received(False)
    s.received(True)  # the first one was replaced while waiting
    s.received(True)
    level, msg = level_of(s.window(), ready=True)
    assert level == WARN and "dropped 2 of 3" in msg
    s.received(False)
    s.received(False)
    s.rejected("step 3 < 8 bytes per row")
    level, msg = level_of(s.window(), ready=True)
    assert level == WARN and "1 frame(s) rejected: step 3" in msg
    s.received(False)
    s.rejected("unsupported encoding 'nv12'")
    level, msg = level_of(s.window(), ready=True)
    assert level == ERROR and "all 1 frame(s) rejected" in msg
    s.received(False)
    s.error("RuntimeError: boom")
    level, msg = level_of(s.window(), ready=True)
    assert level == ERROR and "boom" in msg


def test_solver_slower_than_input_warns_with_both_times() -> None:
    s = NodeStats()
    for _ in range(5):
        s.received(False)
    s.solved(0.120, 0.001, 0.0005, output(1.0))
    time.sleep(0.25)  # 5 frames in ~0.25 s: one every ~50 ms, solved in 120 ms
    level, msg = level_of(s.window(), ready=True)
    assert level == WARN and msg.startswith("solver too slow for the input: 120 ms per pair, a frame every")
    interval = float(msg.split("a frame every ")[1].split(" ms")[0])
    assert 48 <= interval <= 70
    for _ in range(3):
        s.received(False)
    s.solved(0.010, 0.001, 0.0005, output(1.0))
    time.sleep(0.1)  # every ~33 ms, solved in 10 ms: keeps up
    assert level_of(s.window(), ready=True) == (OK, "computing flow")


def test_numba_fallback_is_a_warning_below_every_other_state() -> None:
    s = NodeStats()
    s.received(False)
    s.solved(0.010, 0.001, 0.0005, output(1.0))
    fallback = "numba not importable (No module named 'numba'): running the numpy reference backend"
    assert level_of(s.window(), ready=True, backend_warning=fallback) == (WARN, fallback)
    assert level_of(s.window(), ready=False, backend_warning=fallback) == (WARN, f"warming up the engine; {fallback}")
    s.received(False)
    s.error("RuntimeError: boom")
    level, msg = level_of(s.window(), ready=True, backend_warning=fallback)
    assert level == ERROR and msg.startswith("engine failed on 1 frame(s)") and msg.endswith(fallback)


def test_stale_input_warns_after_three_periods() -> None:
    s = NodeStats()
    s.received(False)
    s.window()
    time.sleep(0.05)
    w = s.window()  # a 50 ms period, input 50 ms ago: fine
    assert level_of(w, ready=True)[0] == OK
    time.sleep(0.2)
    w = s.window()  # 200 ms period, input 250 ms ago: fine (< 3 periods)
    assert level_of(w, ready=True)[0] == OK
    time.sleep(0.02)
    w = s.window()  # 20 ms period, input 270 ms ago: stale
    level, msg = level_of(w, ready=True)
    assert level == WARN and msg.startswith("no image for")


def test_status_values_and_window_reset() -> None:
    s = NodeStats()
    for k in range(4):
        s.received(False)
        s.solved(0.010 * (k + 1), 0.001 * (k + 1), 0.0005 * (k + 1), output(0.6))
    s.analysed(0.002)  # the derived outputs of two of them (~/motion/* subscribed)
    s.analysed(0.004)
    time.sleep(0.2)  # 4 frames in > 0.2 s: every 50+ ms, slower than the 25 ms mean solve (else "too slow")
    w = s.window()
    st = status(w, name="cam_flow: optical flow", hardware_id="cam", ready=True, backend="numpy", model="l2_tv",
                input_scale=0.5, resolution="5x4")
    values = {kv.key: kv.value for kv in st.values}
    assert st.name == "cam_flow: optical flow" and st.hardware_id == "cam" and st.level == OK
    assert values["solve time mean (ms)"] == "25.00" and values["solve time max (ms)"] == "40.00"
    assert values["node overhead mean (ms)"] == "2.50" and values["publish time mean (ms)"] == "1.25"
    assert values["frames published"] == "4" and values["model"] == "l2_tv" and values["input scale"] == "0.5"
    assert values["frames analysed (motion)"] == "2" and values["derived outputs mean (ms)"] == "3.00"
    expected = np.hypot(0.6, 0.6)
    assert abs(float(values["flow magnitude max (px)"]) - expected) < 1e-3
    assert abs(float(values["flow magnitude p95 (px)"]) - expected) < 1e-3
    assert s.solve_max == 0.04 and abs(s.solve_total - 0.1) < 1e-12
    # the next window starts empty: no solve times, totals kept
    values = {kv.key: kv.value for kv in status(s.window(), name="n", hardware_id="h", ready=True,
                                                backend="numpy", model="l1_tv", input_scale=1.0,
                                                resolution="5x4").values}
    assert values["solve time mean (ms)"] == "n/a" and values["publish time mean (ms)"] == "n/a"
    assert values["frames published"] == "4" and values["frames analysed (motion)"] == "2"
    assert values["derived outputs mean (ms)"] == "n/a"


def test_an_unreliable_flow_warns_and_is_counted() -> None:
    """A flow that leaves most pixels unexplained (census.reliability) is a WARN, not OK."""
    from flow_node.core.photometric import UNRELIABLE

    s = NodeStats()
    good, bad = output(1.0), output(1.0)
    good.unexplained, bad.unexplained = 0.05, UNRELIABLE + 0.2
    s.received(False)
    s.solved(0.02, 0.001, 0.0005, good)
    w = s.window()
    assert level_of(w, ready=True) == (OK, "computing flow") and w.unreliable == 0
    for out in (bad, good):
        s.received(False)
        s.solved(0.02, 0.001, 0.0005, out)
    w = s.window()
    level, msg = level_of(w, ready=True)
    assert level == WARN and "unreliable on 1 frame(s)" in msg
    values = {kv.key: kv.value for kv in status(w, name="n: flow", hardware_id="", ready=True, backend="numpy",
                                                model="l1_tv", input_scale=1.0, resolution="5x4").values}
    assert values["unreliable frames"] == "1" and values["unexplained pixels (%)"] == "5.0"


def test_stream_fallbacks_are_counted_with_their_reason() -> None:
    """The stream mode's pairs (SolveStats.stream): predicted ones and full solves with the check that failed."""
    s = NodeStats()
    kinds = ["", "predicted", "predicted", "full: prediction does not fit (0.80 unexplained)", "predicted"]
    for kind in kinds:
        out = output(1.0)
        out.stats = SolveStats(stream=kind)
        s.received(False)
        s.solved(0.01, 0.001, 0.0005, out)
    values = {kv.key: kv.value for kv in status(s.window(), name="n: flow", hardware_id="", ready=True,
                                                backend="numpy", model="l1_tv", input_scale=1.0,
                                                resolution="5x4").values}
    assert values["stream frames predicted"] == "3" and values["stream fallbacks (full solves)"] == "1"
    assert values["last stream fallback"] == "prediction does not fit (0.80 unexplained)"
