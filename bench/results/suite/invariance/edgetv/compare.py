"""Mean AEE per regime and its ratio to a base method (the first one, or --base NAME), from bench.suite JSON files.

    python3 bench/results/suite/invariance/edgetv/compare.py [--base NAME] RUN.json [RUN2.json ...]
"""

import json
import sys


def main(args: list[str]) -> None:
    base = None
    if args and args[0] == "--base":
        base, args = args[1], args[2:]
    for path in args:
        with open(path) as f:
            run = json.load(f)
        print("##", path)
        for regime, x in run["regimes"].items():
            methods = x["methods"]
            ref = methods[base or next(iter(methods))]["aee"]
            cells = [f"{m} {v['aee']:.4f} ({v['aee'] / ref:.3f})" for m, v in methods.items()]
            print(f"{regime:24s}", " | ".join(cells))


if __name__ == "__main__":
    main(sys.argv[1:])
