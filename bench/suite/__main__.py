"""``python -m bench.suite``: run the broad accuracy suite and write its JSON, Markdown and plot.

    python -m bench.suite                       # full, report seeds -> bench/results/suite/suite.{json,md,png}
    python -m bench.suite --quick               # 1-3 min loop -> bench/results/suite/suite_quick.{json,md,png}
    python -m bench.suite --regimes fine_320,exposure --split tune --quick
    python -m bench.suite --regimes photometric_real,real_exact --split report --quick --peers dis_medium,dualtvl1
    python -m bench.suite --quick --split tune --method cand=realtime,alpha=0.03 --method realtime=realtime
    python -m bench.suite --regimes middlebury --peers none --clock cpu --method census=fastest,threads=1 \
        --method grey=fastest,threads=1,photometric=normalise   # census against grey values, CPU time
    python -m bench.suite --update-benchmarks   # also rewrite the generated part of BENCHMARKS.md
    python -m bench.suite --from-json bench/results/suite/suite.json --update-benchmarks   # re-render only
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
from pathlib import Path
from typing import Any

from ..common import REPO, run_record, write_json
from . import report, targets
from .methods import PEERS, parse_method
from .regimes import REGIMES
from .runner import CLOCKS, run_suite

RESULTS = REPO / "bench" / "results" / "suite"


def versions() -> dict[str, Any]:
    """Library versions and the git commit the run measured."""
    import cv2
    import numba
    import numpy
    import skimage

    try:
        commit = subprocess.run(["git", "-C", str(REPO), "describe", "--always", "--dirty"], capture_output=True,
                                text=True, check=False).stdout.strip()
    except OSError:
        commit = "unknown"
    return {"numpy": numpy.__version__, "opencv": cv2.__version__, "scikit-image": skimage.__version__,
            "numba": numba.__version__, "python": platform.python_version(), "commit": commit}


def parse(argv: list[str] | None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m bench.suite", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="fewer pairs and repeats, DIS peers only (1-3 min)")
    ap.add_argument("--split", choices=("tune", "report", "all"), default="report")
    ap.add_argument("--regimes", default="", help=f"comma-separated subset of {', '.join(REGIMES)}")
    ap.add_argument("--peers", default="", help=f"comma-separated subset of {', '.join(PEERS)} "
                    "(default: DIS when quick, all otherwise); 'none' for no peers")
    ap.add_argument("--method", action="append", default=[], metavar="NAME=BASE[,key=value...]",
                    help="run this flow_node config instead of the default set (repeatable); BASE is a preset or "
                    "'default' (FlowConfig()), e.g. --method cand=realtime,alpha=0.03,warps=3")
    ap.add_argument("--repeats", type=int, default=None, help="timed runs per pair (default 5; quick 3)")
    ap.add_argument("--slow-repeats", type=int, default=None,
                    help="timed runs per pair of a method slower than 0.25 s per pair (default 1)")
    ap.add_argument("--clock", choices=tuple(CLOCKS), default="wall",
                    help="time on the wall clock or the process's CPU time (robust to other jobs' load)")
    ap.add_argument("--out", type=Path, default=None, help="JSON path (default bench/results/suite/suite[_quick].json;"
                    " the .md and .png go beside it)")
    ap.add_argument("--update-benchmarks", action="store_true", help="rewrite the generated suite section "
                    "of BENCHMARKS.md (its summary table and target count)")
    ap.add_argument("--from-json", type=Path, default=None, help="re-render a saved result instead of running")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse(argv)
    if args.from_json is not None:
        res = json.loads(args.from_json.read_text())
        out = args.from_json
    else:
        regimes = [r for r in args.regimes.split(",") if r] or None
        peers = None if not args.peers else ([] if args.peers == "none" else args.peers.split(","))
        head = {**run_record("bench.suite", argv), "versions": versions()}  # as the run starts
        res = {**head, **run_suite(dict(map(parse_method, args.method)) or None, regimes, args.split, args.quick, peers,
                                   args.repeats, args.slow_repeats, log=lambda s: print(s, flush=True),
                                   clock=args.clock)}
        out = args.out or RESULTS / ("suite_quick.json" if args.quick else "suite.json")
        res["load_average_end"] = os.getloadavg()
    res["targets"] = targets.all_checks(res)
    write_json(out, res)
    md = report.markdown(res)
    out.with_suffix(".md").write_text(md)
    report.plot(res, out.with_suffix(".png"))
    print(md)
    if args.update_benchmarks:
        report.update_benchmarks(REPO / "BENCHMARKS.md", report.summary(res))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
