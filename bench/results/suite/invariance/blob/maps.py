"""One-off (task blob): error_maps.png from diag.py's saved per-level error maps (run diag.py with a maps dir
first; see summary.md). Usage: python maps.py MAPS_DIR OUT.png"""
from __future__ import annotations

import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

src, out = sys.argv[1], sys.argv[2]
rows = [("illumination_blob_fastest_census_empty_contrast=0", "blob, fastest census (main)"),
        ("unchanged_fastest_census_empty_contrast=0", "unchanged, main"),
        ("illumination_blob_fastest", "blob, empty levels damped (this branch)")]
fig, axes = plt.subplots(len(rows), 3, figsize=(11, 8))
for r, (tag, title) in enumerate(rows):
    for c, level in enumerate((3, 2, 1)):
        err = np.load(f"{src}/err_1002_{tag}_L{level}.npy")
        im = axes[r, c].imshow(err, vmin=0, vmax=2.0 / 2 ** (level - 1), cmap="magma")
        shape = f"{err.shape[1]}x{err.shape[0]}"
        axes[r, c].set_title(f"{title}\nL{level} {shape} AEE {err.mean():.3f} (level px)", fontsize=8)
        axes[r, c].axis("off")
        fig.colorbar(im, ax=axes[r, c], fraction=0.04)
fig.suptitle("s1002 zoom/band3: |flow - ground truth| per level (level px), fastest census", fontsize=10)
fig.tight_layout()
fig.savefig(out, dpi=80)
