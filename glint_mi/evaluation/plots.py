"""Figures shared by the demo, the notebooks and the benchmarks (matplotlib, Agg-safe)."""
from __future__ import annotations

import numpy as np

BUFFERS = ("rgb", "depth", "normal", "transparency", "interface", "reflection", "transmission")


def show_buffers(buffers: dict, names=BUFFERS, width_per_panel: float = 2.6):
    """One row of panels: linear colours shown in sRGB, normals as 0.5 n + 0.5, scalar maps with a colour bar."""
    import matplotlib.pyplot as plt

    from glint_mi.conventions import linear_to_srgb

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


def training_curves(history: list[dict], path=None):
    """Loss terms (log scale), Gaussians and rays/s against iteration; saved to ``path`` when given."""
    import matplotlib

    if path is not None:
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from glint_mi.config import LOSS_NAMES

    it = np.array([h["iteration"] for h in history])
    fig, ax = plt.subplots(1, 3, figsize=(13, 3.4))
    win = max(1, len(history) // 50)
    smooth = lambda v: np.convolve(v, np.ones(win) / win, mode="valid")
    for name in LOSS_NAMES:
        v = np.array([h.get(name, 0.0) for h in history], float)
        if np.any(v > 0):
            ax[0].plot(it[win - 1:], smooth(v), label=name, lw=2 if name == "total" else 1)
    ax[0].set_yscale("log"), ax[0].set_xlabel("iteration"), ax[0].set_title("losses (weighted)")
    ax[0].legend(fontsize=7, ncol=2)
    ax[1].plot(it, [h.get("gaussians", 0) for h in history])
    ax[1].set_xlabel("iteration"), ax[1].set_title("Gaussians (kept sets)")
    ax[2].plot(it[win - 1:], smooth(np.array([h.get("rays_per_s", 0.0) for h in history], float)))
    ax[2].set_xlabel("iteration"), ax[2].set_title("rays / s")
    fig.tight_layout()
    if path is not None:
        fig.savefig(path, dpi=100)
        plt.close(fig)
    return fig


def convergence_figure(curves: dict[str, list[dict]], path) -> None:
    """Test-view metrics against training seconds, one line per run (``curves``: label -> rows of a run's
    ``convergence.csv``); runs of the same method share a colour, scenes differ by marker."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels = [("psnr", "PSNR (dB)"), ("ssim", "SSIM"), ("normal_mae", "normal MAE (deg)"), ("absrel", "depth AbsRel"),
              ("t_iou", "transparency IoU"), ("t_off_glass", "mean t off glass")]
    finite = lambda key: any(np.isfinite(float(r.get(key, "nan") or "nan")) for rows in curves.values() for r in rows)
    panels = [p for p in panels if finite(p[0])]  # a capture without ground truth has image metrics only
    methods = sorted({label.split(" / ")[0] for label in curves})
    scenes = sorted({label.split(" / ")[-1] for label in curves})
    colour = {m: f"C{i}" for i, m in enumerate(methods)}
    marker = {s: "os^vDx*+"[i % 8] for i, s in enumerate(scenes)}
    fig, ax = plt.subplots(1, len(panels), figsize=(3.3 * len(panels), 3.0), squeeze=False)
    ax = ax[0]
    for label, rows in curves.items():
        m, sc = label.split(" / ")[0], label.split(" / ")[-1]
        x = [float(r["train_s"]) / 60 for r in rows]
        for a, (key, title) in zip(ax, panels):
            a.plot(x, [float(r.get(key, "nan") or "nan") for r in rows], color=colour[m], marker=marker[sc], ms=3, lw=1,
                   label=label if a is ax[0] else None)
    for a, (_, title) in zip(ax, panels):
        a.set_title(title, fontsize=9)
        a.set_xlabel("training minutes", fontsize=8)
        a.tick_params(labelsize=7)
    ax[0].legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)

