"""The suite records flow_node's unexplained fraction per pair and reads it as issue 25's signal
(bench/suite/report.signal_table): handled pairs should read below the WARN level, wrong ones above it."""

from __future__ import annotations

import numpy as np

from bench.suite import metrics, report
from bench.suite.methods import FlowNode
from flow_node.core.config import FlowConfig
from flow_node.core.photometric import UNRELIABLE


def _pair(name: str, variant: str) -> dict[str, str]:
    return {"name": name, "variant": variant}


def test_score_pair_keeps_the_unexplained_fraction_when_given() -> None:
    gt = np.zeros((8, 8, 2), np.float32)
    flow = gt + np.float32(0.5)
    assert "unexplained" not in metrics.score_pair((flow, None), gt)
    scored = metrics.score_pair((flow, None, 0.25), gt)
    assert scored["unexplained"] == 0.25 and abs(scored["aee"] - np.sqrt(0.5)) < 1e-6


def test_flow_node_method_reports_the_result_s_fraction() -> None:
    rng = np.random.default_rng(0)
    f0 = rng.random((48, 64), dtype=np.float32)
    f1 = np.roll(f0, 1, axis=1)
    method = FlowNode(FlowConfig.preset("fastest").replace(backend="numpy"))
    flow, conf, unexplained = method.run((f0, f1, None))
    assert flow.shape == (48, 64, 2) and conf is None and 0.0 <= unexplained <= 1.0


def test_signal_table_counts_each_side_of_the_level() -> None:
    pairs = [_pair("a_unchanged", "unchanged"), _pair("a_g1", "gamma/0.5"), _pair("a_g2", "gamma/2"),
             _pair("a_g3", "gamma/0.8"), _pair("a_rgb_unchanged", "unchanged rgb"),
             _pair("a_wb", "white_balance/gains")]
    hi, lo = UNRELIABLE + 0.1, UNRELIABLE - 0.1
    per_pair = {"a_unchanged": (1.0, lo), "a_g1": (1.2, hi),  # handled, but flagged: 1 on the wrong side
                "a_g2": (5.0, lo),  # wrong (>= 2x and >= +0.5 px) but not flagged: 1 on the wrong side
                "a_g3": (1.6, hi),  # in between: not judged
                "a_rgb_unchanged": (10.0, lo), "a_wb": (12.0, lo)}  # judged against the RGB pair: handled
    r = {"pairs": pairs, "methods": {
        "ours": {"per_pair": {k: {"aee": a, "unexplained": u} for k, (a, u) in per_pair.items()}},
        "dis_medium": {"per_pair": {k: {"aee": a} for k, (a, _) in per_pair.items()}}}}
    table = report.signal_table(r)
    rows = [line for line in table.splitlines() if line.startswith("| ours")]
    assert len(rows) == 1 and "dis_medium" not in table
    cells = [c.strip() for c in rows[0].strip("|").split("|")]
    assert cells[1].startswith("2 (0,")  # the two unchanged pairs, neither flagged
    assert cells[2].startswith("2 (1,")  # a_g1 and a_wb handled; a_g1 flagged
    assert cells[3].startswith("1 (1,")  # a_g2 wrong and unflagged
    assert cells[4] == "1"
    # a method without the fraction gets no row; none at all: no table
    del r["methods"]["ours"]
    assert report.signal_table(r) == ""


def test_family_ratios_take_white_balance_over_the_rgb_pairs() -> None:
    """bench.suite.report.family_ratios (BENCHMARKS' invariance tables, bench.suite.invariance_tables): a family's
    mean AEE over the same method's on the unchanged pairs, white balance over the unchanged RGB ones."""
    pairs = [_pair("a_unchanged", "unchanged"), _pair("a_g1", "gamma/0.5"), _pair("a_g2", "gamma/2"),
             _pair("a_rgb_unchanged", "unchanged rgb"), _pair("a_wb", "white_balance/gains")]
    aee = {"a_unchanged": 1.0, "a_g1": 1.5, "a_g2": 2.5, "a_rgb_unchanged": 4.0, "a_wb": 5.0}
    r = {"pairs": pairs, "methods": {"ours": {"per_pair": {k: {"aee": a} for k, a in aee.items()}}}}
    ratios = report.family_ratios(report.family_means(r))
    assert ratios["gamma"]["ours"] == 2.0 and ratios["white_balance"]["ours"] == 1.25
    assert ratios["unchanged"]["ours"] == 1.0
