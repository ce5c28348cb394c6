"""The suite's report: a Markdown table per regime (a row per method: mean AEE, AEE noc where the regime marks
occluded pixels, AE, ms per pair, ratios against DIS of the same run, per-variant AEE, AUSE, the worst pair
and the peers that beat it at <= 1.5x its time), the target checks, and a plot of AEE against time."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core.photometric import UNRELIABLE

from ..common import md_table
from .methods import DIS_MEDIUM, DIS_ULTRAFAST, PEER_NAMES
from .photometric import UNCHANGED, UNCHANGED_RGB

COLOUR = ("white_balance", UNCHANGED_RGB)  # against the unchanged RGB pairs
# issue 25's reading of the unexplained fraction (photometric.UNRELIABLE, the node's WARN level): a family's pair
# is handled when its AEE is within HANDLED x the same pair's unchanged AEE (the invariance target), wrong when it
# is at least WRONG x that and WRONG_PX px more; a handled pair should read below the level, a wrong one above it
HANDLED, WRONG, WRONG_PX = 1.3, 2.0, 0.5


def _num(v: float | None, fmt: str) -> str:
    return "-" if v is None else format(v, fmt)


def regime_table(name: str, r: dict[str, Any]) -> str:
    """Markdown table of one regime."""
    methods = r["methods"]
    variants = list(next(iter(methods.values())).get("per_variant", {}))
    has_ause = any(m.get("ause") is not None for m in methods.values())
    has_noc = any(m.get("aee_noc") is not None for m in methods.values())
    head = ["method", "mean AEE"] + (["AEE noc"] if has_noc else [])
    head += ["AE (deg)", "ms/pair", "time / DIS med", "time / DIS uf", "AEE / DIS med"]
    head += [f"AEE {v}" for v in variants] + (["AUSE (rel)"] if has_ause else [])
    head += ["worst pair (AEE)", "beaten by (<= 1.5x time)"]
    rows = []
    for n, m in methods.items():
        row = [n if n not in PEER_NAMES else f"peer: {n}", f"**{m['aee']:.4f}**"]
        row += [_num(m.get("aee_noc"), ".4f")] if has_noc else []
        row += [_num(m["ae"], ".2f"), _num(1e3 * m["seconds"], ".1f"), _num(m.get(f"time_vs_{DIS_MEDIUM}"), ".2f"),
                _num(m.get(f"time_vs_{DIS_ULTRAFAST}"), ".2f"), _num(m.get(f"aee_vs_{DIS_MEDIUM}"), ".2f")]
        row += [_num(m["per_variant"][v]["aee"], ".4f") for v in variants]
        if has_ause:
            row.append("-" if m.get("ause") is None else f"{m['ause']:.3f} ({m['ause_rel']:.2f})")
        worst = max(m["per_pair"], key=lambda p: m["per_pair"][p]["aee"])
        row.append(f"{m['per_pair'][worst]['aee']:.3f} {worst}")
        if n not in PEER_NAMES:
            row.append(", ".join(r["beaten_by"].get(n, [])) or "no")
        else:
            row.append("")
        rows.append(row)
    out = [f"**{name}**: {r['title']} ({len(r['pairs'])} pairs)", "", *md_table(head, rows)]
    if any("/" in p["variant"] for p in r["pairs"]):  # photometric families: 'family/variant'
        out += ["", "Per family: mean AEE and its ratio to the same method's unchanged pairs (white balance: the "
                "unchanged RGB pairs)", "", family_table(r)]
        signal = signal_table(r)
        if signal:
            out += ["", f"The unexplained fraction as a signal (level {UNRELIABLE}): a pair is *handled* within "
                    f"{HANDLED}x its unchanged pair's AEE, *wrong* at {WRONG}x and {WRONG_PX} px more; counts of "
                    "pairs, and how many of them read on the wrong side of the level", "", signal]
    return "\n".join(out)


def family_means(r: dict[str, Any]) -> dict[str, dict[str, float]]:
    """A regime whose variants are 'family/variant' (the photometric regimes): family -> method -> mean AEE."""
    methods = r["methods"]
    by_family: dict[str, dict[str, list[float]]] = {}
    for pair in r["pairs"]:
        per = by_family.setdefault(pair["variant"].split("/")[0], {n: [] for n in methods})
        for n, m in methods.items():
            per[n].append(m["per_pair"][pair["name"]]["aee"])
    return {f: {n: float(np.mean(v)) for n, v in per.items()} for f, per in by_family.items()}


def family_ratios(means: dict[str, dict[str, float]]) -> dict[str, dict[str, float]]:
    """:func:`family_means` over the same method's mean on the unchanged pairs (white balance: the RGB ones)."""
    return {family: {n: v / means.get(UNCHANGED_RGB if family in COLOUR else UNCHANGED, means[UNCHANGED])[n]
                     for n, v in mean.items()} for family, mean in means.items()}


def family_table(r: dict[str, Any]) -> str:
    """Markdown table of a photometric regime: per family, each method's mean AEE and its ratio to the same
    method's mean AEE on the unchanged pairs."""
    means = family_means(r)
    ratios = family_ratios(means)
    rows = [[family, *(f"{mean[n]:.3f} ({ratios[family][n]:.2f}x)" for n in mean)] for family, mean in means.items()]
    return "\n".join(md_table(["family", *r["methods"]], rows, right=True))


def _unchanged_of(r: dict[str, Any]) -> dict[str, str]:
    """Each pair of a photometric regime -> the name of its unchanged pair (white balance: the unchanged RGB
    one); the regimes list a frame pair's unchanged samples before its variants (photometric_samples)."""
    base: dict[str, str] = {}
    out = {}
    for p in r["pairs"]:
        v = p["variant"]
        if v in (UNCHANGED, UNCHANGED_RGB):
            base[v] = p["name"]
        out[p["name"]] = base[UNCHANGED_RGB if v.split("/")[0] in COLOUR else UNCHANGED]
    return out


def pair_kind(aee: float, ref: float, unchanged: bool) -> str | None:
    """A photometric pair's kind for the signal: 'unchanged', 'handled' (AEE within HANDLED x its unchanged pair's
    ``ref``), 'wrong' (WRONG x and WRONG_PX px more), or None in between."""
    if unchanged:
        return "unchanged"
    if aee <= HANDLED * ref:
        return "handled"
    return "wrong" if aee >= WRONG * ref and aee >= ref + WRONG_PX else None


def misread(kind: str, unexplained: float) -> bool:
    """The fraction is on the wrong side of UNRELIABLE for a pair of ``kind`` (:func:`pair_kind`)."""
    return unexplained < UNRELIABLE if kind == "wrong" else unexplained >= UNRELIABLE


def signal_groups(r: dict[str, Any], method: str) -> dict[str, list[float]]:
    """The unexplained fractions of ``method``'s pairs on a photometric regime, by :func:`pair_kind` ('unchanged',
    'handled', 'wrong'; pairs in between left out)."""
    base = _unchanged_of(r)
    pp = r["methods"][method]["per_pair"]
    groups: dict[str, list[float]] = {"unchanged": [], "handled": [], "wrong": []}
    for name, q in pp.items():
        kind = pair_kind(q["aee"], pp[base[name]]["aee"], name == base[name])
        if kind:
            groups[kind].append(q["unexplained"])
    return groups


def signal_table(r: dict[str, Any]) -> str:
    """Markdown table of how well each flow_node method's unexplained fraction (FlowResult.unexplained, per pair)
    tells a wrong flow from a right one on a photometric regime: per method the unchanged pairs and the families'
    pairs handled or wrong (module constants), each 'n (k)', k the pairs on the wrong side of UNRELIABLE (an
    unchanged or handled pair at or above it, a wrong pair below it), and the range of the fraction. Empty when
    no method recorded the fraction."""
    rows = []
    for n, m in r["methods"].items():
        pp = m["per_pair"]
        if n in PEER_NAMES or not all("unexplained" in q for q in pp.values()):
            continue
        groups = signal_groups(r, n)
        cells = []
        for g, vals in groups.items():
            off = sum(misread(g, u) for u in vals)
            span = f", {min(vals):.2f}-{max(vals):.2f}" if vals else ""
            cells.append(f"{len(vals)} ({off}{span})")
        rows.append([n, *cells, str(len(pp) - sum(len(v) for v in groups.values()))])
    return "\n".join(md_table(["method", "unchanged (above level, range)", "handled (above level, range)",
                                "wrong (below level, range)", "in between"], rows, right=True)) if rows else ""


def summary_table(res: dict[str, Any]) -> str:
    """One row per regime, one column per method: mean AEE (px) and, in brackets, time / DIS medium of the
    same run (DIS medium itself: its ms per pair)."""
    names = list(dict.fromkeys(n for r in res["regimes"].values() for n in r["methods"]))
    rows = []
    for reg, r in res["regimes"].items():
        cells = []
        for n in names:
            m = r["methods"].get(n)
            if m is None:
                cells.append("-")
            elif n == DIS_MEDIUM:
                cells.append(f"{m['aee']:.3f} ({1e3 * m['seconds']:.1f} ms)")
            else:
                cells.append(f"{m['aee']:.3f} ({_num(m.get(f'time_vs_{DIS_MEDIUM}'), '.2f')}x)")
        rows.append([reg, *cells])
    return "\n".join(md_table(["regime", *names], rows, right=True))


def targets_table(checks: list[dict[str, Any]]) -> str:
    """Markdown table of the target checks: met / missed / not run, with the numbers."""
    verdict = {None: "not run", True: "met", False: "**missed**"}
    rows = [[c["target"], c["regime"], c["method"], verdict[c["met"]], c["detail"]] for c in checks]
    return "\n".join(md_table(["target", "regime", "method", "result", "numbers"], rows))


def run_line(res: dict[str, Any], note: str = "") -> str:
    """How a result was run: its command, split (and ``note``), start, wall time and commit."""
    return (f"Command: `{res.get('command', 'run_suite(...)').strip()}`; split `{res['split']}`{note}; started "
            f"{res.get('started', '?')}, wall {res.get('wall_seconds', 0) / 60:.0f} min; "
            f"commit {res.get('versions', {}).get('commit', '?')}")


def markdown(res: dict[str, Any]) -> str:
    """The whole report: how it was run, every regime's table, then the target checks."""
    v = res.get("versions", {})
    quick = " (QUICK: fewer pairs, indicative only)" if res["quick"] else ""
    clock = ", the process's CPU time" if res.get("clock") == "cpu" else ""
    head = (run_line(res, quick) + f"; numpy {v.get('numpy', '?')}, "
            f"OpenCV {v.get('opencv', '?')}, scikit-image {v.get('scikit-image', '?')}, numba {v.get('numba', '?')}; "
            f"per pair the median of {res['repeats']} interleaved timed runs ({res['slow_repeats']} for the TV-L1 "
            f"peers and a method slower than {res['slow_seconds']} s per pair){clock}. Times in ms, ratios against DIS "
            "in the same run.")
    parts = [head, "**Summary**: mean AEE (px) per regime and, in brackets, time / DIS medium (same run)",
             summary_table(res)] + [regime_table(n, r) for n, r in res["regimes"].items()]
    parts += ["**Targets (issue 11)**", "", targets_table(res.get("targets", []))]
    return "\n\n".join(parts) + "\n"


def summary(res: dict[str, Any]) -> str:
    """BENCHMARKS.md's part: how it was run, the mean-AEE table and the target count (the rest: the .md)."""
    checks = res.get("targets", [])
    met = sum(c["met"] is True for c in checks)
    missed = [c for c in checks if c["met"] is False]
    head = (run_line(res) + ". Mean AEE (px) per regime, in brackets time / DIS medium in the same run (DIS medium: "
            "ms per pair).")
    tail = f"Target checks: **{met} met, {len(missed)} missed**" + "".join(
        f"\n- missed: {c['target']} ({c['regime']}, {c['method']}): {c['detail']}" for c in missed)
    return "\n\n".join([head, summary_table(res), tail]) + "\n"


def plot(res: dict[str, Any], path: Path) -> None:
    """AEE (log) against ms per pair (log), one panel per regime, presets as dots, peers as squares; nothing for a
    run without times (``--repeats 0``: AEE only)."""
    timed = [m for r in res["regimes"].values() for m in r["methods"].values() if m["seconds"] > 0]  # nan: untimed
    if not timed:
        return
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FormatStrFormatter, LogLocator

    names = list(res["regimes"])
    cols = 3
    rows = (len(names) + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 3.9 * rows), squeeze=False)
    for ax, name in zip(axes.flat, names, strict=False):
        for n, m in res["regimes"][name]["methods"].items():
            if not m["seconds"] > 0:
                continue
            peer = n in PEER_NAMES
            ax.scatter(1e3 * m["seconds"], m["aee"], marker="s" if peer else "o", c="tab:grey" if peer else "tab:blue")
            ax.annotate(n, (1e3 * m["seconds"], m["aee"]), fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.set(xscale="log", yscale="log", title=name, xlabel="ms per pair (same run)", ylabel="mean AEE (px)")
        ax.grid(True, which="both", alpha=0.3)
        for axis in (ax.xaxis, ax.yaxis):
            axis.set_major_formatter(FormatStrFormatter("%g"))
            axis.set_minor_formatter(FormatStrFormatter(""))
        ax.yaxis.set_minor_locator(LogLocator(subs=(2.0, 5.0)))
        ax.yaxis.set_minor_formatter(FormatStrFormatter("%g"))
    for ax in list(axes.flat)[len(names):]:
        ax.axis("off")
    fig.suptitle("flow_node presets (dots) and peers (squares): AEE against time per regime")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=90)
    plt.close(fig)


BEGIN, END = "<!-- suite:begin (generated by python -m bench.suite) -->", "<!-- suite:end -->"


def update_benchmarks(path: Path, body: str) -> None:
    """Replace the text between the suite markers in BENCHMARKS.md (appending the markers if missing)."""
    text = path.read_text()
    block = f"{BEGIN}\n{body}{END}"
    if BEGIN in text and END in text:
        head, rest = text.split(BEGIN, 1)
        text = head + block + rest.split(END, 1)[1]
    else:
        text = text.rstrip("\n") + "\n\n" + block + "\n"
    path.write_text(text)
