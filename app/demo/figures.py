"""Figures of the demo report, in the spirit of the paper's Figs. 1, 3, 4, 5 and 7–8."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flexvox_core.flow import flow_to_color, magnitude_image, quiver_image


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _row(path: Path, panels: list[tuple[str, np.ndarray]], *, height: float = 3.2) -> Path:
    plt = _plt()
    fig, axes = plt.subplots(1, len(panels), figsize=(3.3 * len(panels), height), dpi=100)
    for ax, (title, img) in zip(np.atleast_1d(axes), panels, strict=True):
        if img.ndim == 2:
            ax.imshow(img, cmap="gray", vmin=0, vmax=1)
        else:
            ax.imshow(img)
        ax.set_title(title, fontsize=9)
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def fig1_sampling(path, videos: dict[str, np.ndarray], s: int, crop) -> Path:
    """High SR, high TR, motion-aware at one sub-frame, with a zoomed crop below each (Fig. 1)."""
    plt = _plt()
    y0, y1, x0, x1 = crop
    fig, axes = plt.subplots(2, len(videos), figsize=(3.3 * len(videos), 5.6), dpi=100)
    for j, (title, v) in enumerate(videos.items()):
        axes[0, j].imshow(v[s], cmap="gray", vmin=0, vmax=1)
        axes[0, j].add_patch(plt.Rectangle((x0, y0), x1 - x0, y1 - y0, fill=False, color="r", lw=1))
        axes[0, j].set_title(title, fontsize=9)
        axes[1, j].imshow(v[s, y0:y1, x0:x1], cmap="gray", vmin=0, vmax=1, interpolation="nearest")
        for ax in axes[:, j]:
            ax.axis("off")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)


def fig3_rebinning(path, captured: np.ndarray, rebinned: dict[str, np.ndarray], s: int) -> Path:
    """The captured frame and re-binned videos from high SR to high TR (Fig. 3)."""
    return _row(Path(path), [("captured frame", captured)] + [(t, v[s]) for t, v in rebinned.items()])


def fig4_continuum(path, continuum: dict[str, np.ndarray], s: int) -> Path:
    """Diffusion with tensors across the continuum from high SR to high TR (Fig. 4)."""
    return _row(Path(path), [(t, v[s]) for t, v in continuum.items()])


def fig5_flow(path, high_tr: np.ndarray, flow: np.ndarray, tr_map: np.ndarray, K: int) -> Path:
    """Quiver plot and colour-coded flow of the high-TR reconstruction, and the TR chosen (Fig. 5)."""
    top = max(float(np.quantile(np.hypot(flow[..., 0], flow[..., 1]), 0.995)), 0.25)
    plt = _plt()
    fig, axes = plt.subplots(1, 4, figsize=(13.2, 3.2), dpi=100)
    axes[0].imshow(quiver_image(high_tr, flow, step=max(6, min(flow.shape[:2]) // 20)))
    axes[0].set_title("flow (quiver)", fontsize=9)
    axes[1].imshow(flow_to_color(flow, max_magnitude=top))
    axes[1].set_title("flow (colour wheel)", fontsize=9)
    axes[2].imshow(magnitude_image(flow, max_magnitude=top))
    axes[2].set_title("speed (blue still, red fast)", fontsize=9)
    im = axes[3].imshow(tr_map, cmap="viridis", vmin=1, vmax=K)
    axes[3].set_title("effective TR chosen", fontsize=9)
    fig.colorbar(im, ax=axes[3], fraction=0.046)
    for ax in axes:
        ax.axis("off")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)


def fig7_panel(path, frames: np.ndarray, rows: list[int], videos: dict[str, np.ndarray], flow: np.ndarray,
               K: int) -> Path:
    """Rows of: captured frame, high SR, high TR, flow magnitude, motion-aware (Figs. 7–8)."""
    plt = _plt()
    cols = ["captured", *videos.keys()]
    fig, axes = plt.subplots(len(rows), len(cols) + 1, figsize=(2.9 * (len(cols) + 1), 2.5 * len(rows)), dpi=100)
    axes = np.atleast_2d(axes)
    for i, s in enumerate(rows):
        panels = [frames[s // K]] + [v[s] for v in videos.values()]
        for j, img in enumerate(panels):
            axes[i, j].imshow(img, cmap="gray", vmin=0, vmax=1)
        axes[i, len(cols)].imshow(magnitude_image(flow[s]))
        if i == 0:
            for j, t in enumerate([*cols, "flow magnitude"]):
                axes[0, j].set_title(t, fontsize=9)
        for ax in axes[i]:
            ax.axis("off")
    # Put the flow magnitude column before motion-aware, as in the paper.
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return Path(path)
