"""Where the colour stage's saving comes from (task photoapi, a one-off on the branch's tree): main's pattern
(each channel's samples and maps taken twice, numpy's sort), once with numpy's sort, once with the numba backend's
sort; census_presmooth 0.45 px, the noise by the numba kernel, CPU time per pair, median of 7 x 5 calls.

    PYTHONPATH=<worktree> python bench/results/suite/photoapi/decompose.py"""

from __future__ import annotations

import time

import numpy as np

from flow_node.core.api import to_planes
from flow_node.core.census_noise import channel_noise
from flow_node.core.colour import channel_maps, normalise_channel_pair, normalised_channels
from flow_node.core.flowio import read_image
from flow_node.core.numba_sort import noise_sigma_numba, sorted_sample_numba

MB = "/work/shared/data/middlebury/"


def main() -> None:
    for n in ("Grove3", "RubberWhale"):
        (_, c0), (_, c1) = (to_planes(read_image(f"{MB}{n}/frame1{k}.png")[..., :3]) for k in (0, 1))

        def twice() -> object:  # main's: maps per channel for the normalisation and again for the noise
            norm = normalise_channel_pair(c0, c1, 1.0, channel_maps(c0, c1, 1.0, 0.45))  # noqa: B023
            return channel_noise((c0, c1), channel_maps(c0, c1, 1.0, 0.45), 1.0, norm, noise_sigma_numba)  # noqa: B023

        def once(sample: object = None) -> object:
            nc = normalised_channels(c0, c1, 1.0, 0.45, sample)  # noqa: B023
            return channel_noise(nc.raw, nc.maps, 1.0, nc.normalised, noise_sigma_numba)

        for name, f in (("twice, numpy sort", twice), ("once, numpy sort", once),
                        ("once, numba sort", lambda: once(sorted_sample_numba))):
            f()
            ts = []
            for _ in range(7):
                t = time.process_time()
                for _ in range(5):
                    f()
                ts.append((time.process_time() - t) / 5)
            print(n, name, f"{1e3 * np.median(ts):.2f} ms")


if __name__ == "__main__":
    main()
