"""Figures shared by the demo, the notebooks and the benchmarks (matplotlib, Agg-safe)."""
from __future__ import annotations

import numpy as np

BUFFERS = ("rgb", "depth", "normal", "transparency", "interface", "reflection", "transmission")


def show_buffers(buffers: dict, names=BUFFERS, width_per_panel: float = 2.6):
    """One row of panels: linear colours shown in sRGB, normals as 0.5 n + 0.5, scalar maps with a colour bar."""
    import matplotlib.pyplot as plt

    from .conventions import linear_to_srgb

    names = [n for n in names if n in buffers]
    fig, axes = plt.subplots(1, len(names), figsize=(width_per_panel * len(names), 2.0), squeeze=False)
    for ax, name in zip(axes[0], names):
        x = buffers[name]
        if name == "normal":
            ax.imshow(np.clip(0.5 * x + 0.5, 0, 1))
        elif x.shape[-1] == 1:
            im = ax.imshow(x[..., 0], cmap="viridis" if "depth" in name else "magma")
            fig.colorbar(im, ax=ax, fraction=0.035)
        else:
            ax.imshow(np.clip(linear_to_srgb(x), 0, 1))
        ax.set_title(name, fontsize=9)
        ax.axis("off")
    fig.tight_layout()
    return fig
