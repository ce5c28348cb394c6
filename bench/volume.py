"""3-D flow: flow_node's volume engine against scikit-image's ``optical_flow_tvl1`` on exactly rendered volumes.

    python -m bench.volume                 # 64^3 scenes + 128^3 -> bench/results/volume/volume.json (+ .md)
    python -m bench.volume --sizes 48      # a quick run

Frame 1 is a band-limited 3-D texture T sampled at the analytic inverse motion, I1(q) = T(m^-1(q)), so the
true flow is m(p) - p (x, y, z); the scenes and settings: docs/engine.md, "Volumes". scikit-image's flow
(z, y, x) is reordered to x, y, z (its convention is ours, checked on a shift). One call each, interleaved
per scene, after flow_node's warm-up, both on one thread."""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core.volume import VOLUME_CONFIG, estimate_volume

from .common import REPO, machine, md_table, run_record, write_result

RESULTS = REPO / "bench" / "results" / "volume"
# flow_node's volume defaults (core/volume.py VOLUME_CONFIG), both methods on one thread: the shared 2-core
# machine made numba's parallel kernels slower than its single-thread ones while other jobs ran.
CONFIG = VOLUME_CONFIG.replace(threads=1)
SETTINGS: dict[str, Any] = {k: getattr(CONFIG, k) for k in (  # the fields a volume uses, for the JSON
    "model", "alpha", "warps", "iterations", "finest_warps", "finest_iterations", "levels", "scale_factor",
    "min_size", "gradient_scheme", "tolerance", "threads")}
INCOMPRESSIBILITY = 0.2  # beta of the "+incompressible" column
Motion = Callable[[np.ndarray], np.ndarray]  # points (..., 3) x, y, z -> moved points


def texture(rng: np.random.Generator, n: int = 48, fmin: float = 0.02, fmax: float = 0.2
            ) -> tuple[np.ndarray, np.ndarray]:
    """n cosines: radial frequencies log-uniform in [fmin, fmax] cycles/voxel, random 3-D directions, random
    phases. Returns (freqs (n, 3) x, y, z, phases (n,))."""
    radius = np.exp(rng.uniform(math.log(fmin), math.log(fmax), n))
    direction = rng.normal(size=(n, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    return radius[:, None] * direction, rng.uniform(0.0, 2 * math.pi, n)


def render(tex: tuple[np.ndarray, np.ndarray], points: Callable[[np.ndarray], np.ndarray],
           shape: tuple[int, int, int]) -> np.ndarray:
    """T(points(p)) for every voxel p = (x, y, z) of ``shape`` (Z, Y, X), mapped linearly to ~[0.1, 0.9];
    rendered slice by slice (bounded memory). float32."""
    freqs, phases = tex
    amp = math.sqrt(2.0 / len(phases))
    nz, ny, nx = shape
    yy, xx = np.mgrid[0:ny, 0:nx].astype(np.float64)
    out = np.empty(shape, np.float32)
    for k in range(nz):
        p = points(np.stack([xx, yy, np.full_like(xx, k)], axis=-1))
        out[k] = 0.5 + 0.4 * (np.cos(2 * math.pi * (p @ freqs.T) + phases) @ np.full(len(phases), amp)) / 3.5
    return out


def motions(shape: tuple[int, int, int]) -> dict[str, tuple[Motion, Motion]]:
    """Each scene's motion m and its analytic inverse, on points (..., 3) in voxels (x, y, z)."""
    centre = (np.array(shape[::-1], float) - 1.0) / 2.0
    axis = np.array([0.3, -0.4, 1.0])
    axis /= np.linalg.norm(axis)
    t = math.radians(5.0)
    cross = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    rot = np.eye(3) + math.sin(t) * cross + (1 - math.cos(t)) * cross @ cross  # Rodrigues
    n = shape[-1]

    def f(y: np.ndarray, z: np.ndarray) -> np.ndarray:
        return 2.0 * np.sin(2 * math.pi * y / n) * np.cos(2 * math.pi * z / (1.5 * n))

    def g(z: np.ndarray) -> np.ndarray:
        return 1.5 * np.cos(2 * math.pi * z / n)

    def shear(p: np.ndarray) -> np.ndarray:
        x, y, z = p[..., 0], p[..., 1], p[..., 2]
        return np.stack([x + f(y, z), y + g(z), z + 0.7], axis=-1)

    def shear_inv(q: np.ndarray) -> np.ndarray:
        z = q[..., 2] - 0.7
        y = q[..., 1] - g(z)
        return np.stack([q[..., 0] - f(y, z), y, z], axis=-1)

    d = np.array([2.3, -1.6, 0.8])
    s = 1.03
    return {
        "shift": (lambda p: p + d, lambda q: q - d),
        "rotation": (lambda p: (p - centre) @ rot.T + centre, lambda q: (q - centre) @ rot + centre),
        "shear": (shear, shear_inv),
        "zoom": (lambda p: centre + s * (p - centre), lambda q: centre + (q - centre) / s),
    }


def scene(name: str, shape: tuple[int, int, int], seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(v0, v1, gt flow (Z, Y, X, 3) x, y, z, valid mask (Z, Y, X)) of one motion."""
    tex = texture(np.random.default_rng(seed))
    forward, inverse = motions(shape)[name]
    v0 = render(tex, lambda p: p, shape)
    v1 = render(tex, inverse, shape)
    zz, yy, xx = np.mgrid[0:shape[0], 0:shape[1], 0:shape[2]].astype(np.float64)
    p = np.stack([xx, yy, zz], axis=-1)
    moved = forward(p)
    valid = np.all((moved >= 0) & (moved <= np.array(shape[::-1]) - 1), axis=-1)
    return v0, v1, (moved - p).astype(np.float32), valid


def aee3(flow: np.ndarray, gt: np.ndarray, valid: np.ndarray) -> float:
    """Mean 3-D endpoint error over ``valid`` voxels."""
    return float(np.linalg.norm(flow - gt, axis=-1)[valid].mean())


def skimage_flow(v0: np.ndarray, v1: np.ndarray) -> np.ndarray:
    """scikit-image TV-L1 with its defaults, reordered to (Z, Y, X, 3) x, y, z."""
    from skimage.registration import optical_flow_tvl1

    return np.moveaxis(optical_flow_tvl1(v0, v1)[::-1], 0, -1).astype(np.float32)


def run(sizes: list[int], big_scenes: tuple[str, ...], seed: int) -> dict[str, Any]:
    cfg = CONFIG
    cfg_inc = cfg.replace(incompressibility=INCOMPRESSIBILITY)
    estimate_volume(*scene("shift", (24, 24, 24), seed)[:2], cfg_inc)  # compile / load the kernels
    rows = []
    for size in sizes:
        names = tuple(motions((size,) * 3)) if size == sizes[0] else big_scenes
        for name in names:
            v0, v1, gt, valid = scene(name, (size,) * 3, seed)
            row: dict[str, Any] = {"scene": name, "size": size}
            for label, method in (("flow_node", lambda a, b: estimate_volume(a, b, cfg).flow),
                                  ("flow_node_incompressible", lambda a, b: estimate_volume(a, b, cfg_inc).flow),
                                  ("skimage", skimage_flow)):
                start = time.perf_counter()
                flow = method(v0, v1)
                row[label] = {"aee": round(aee3(flow, gt, valid), 4), "seconds": round(time.perf_counter() - start, 3)}
            row["time_ratio"] = round(row["flow_node"]["seconds"] / row["skimage"]["seconds"], 3)
            print(row, flush=True)
            rows.append(row)
    return {"settings": SETTINGS, "incompressibility": cfg_inc.incompressibility, "seed": seed,
            "machine": machine(), "rows": rows}


def markdown(result: dict[str, Any]) -> str:
    lines = [f"`{result['command']}` (seed {result['seed']}); AEE in voxels, time in s (wall clock, both on one "
             f"thread; a shared machine: compare the ratio, measured interleaved). flow_node settings: "
             f"{result['settings']}; +incompressible: incompressibility={result['incompressibility']}.", ""]
    head = ["scene", "size", "flow_node AEE", "+incompressible AEE", "skimage AEE", "flow_node s", "skimage s",
            "time ratio"]
    rows = [[r["scene"], f"{r['size']}^3", str(r["flow_node"]["aee"]), str(r["flow_node_incompressible"]["aee"]),
             str(r["skimage"]["aee"]), str(r["flow_node"]["seconds"]), str(r["skimage"]["seconds"]),
             str(r["time_ratio"])] for r in result["rows"]]
    return "\n".join(lines + md_table(head, rows)) + "\n"


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, action="append", help="cube sides (first: every scene; others: "
                    "--big scenes); default 64 and 128")
    ap.add_argument("--big", default="shift,shear", help="scenes run at the larger sizes")
    ap.add_argument("--seed", type=int, default=7)
    ap.add_argument("--out", type=Path, default=RESULTS / "volume.json")
    args = ap.parse_args(argv)
    command = run_record("bench.volume", argv)["command"]
    result = {"command": command, **run(args.sizes or [64, 128], tuple(args.big.split(",")), args.seed)}
    write_result(args.out.with_suffix(""), result, markdown(result))


if __name__ == "__main__":
    main()
