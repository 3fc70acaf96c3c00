"""Pictures of a reconstruction that returns the flow (motion-aware): flow (colour wheel, quiver),
resolution map, and a panel like the paper's Figs. 7–8 (captured frame, high SR, high TR, flow
magnitude, motion-aware)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from flexvox_core.flow import flow_to_color, magnitude_image, quiver_image
from flexvox_core.methods import run
from flexvox_core.reconstruct.diffusion import diffuse

HIGH_SR = (0.05, 0.05, 1.0)
HIGH_TR = (1.0, 1.0, 0.05)


FIGURES = ("flow_color.png", "flow_quiver.png", "resolution_map.png", "panel.png")
"""The files :func:`write_figures` writes."""


def check_figures_dir(out_dir, *, overwrite: bool = False, inputs=()) -> Path:
    """Check, before the reconstruction, that the figures may be written into ``out_dir``: not onto an
    input, not a file, no earlier figures there without ``overwrite``, a folder that takes files.

    Raises
    ------
    flexvox_core.output_errors.OutputError
    """
    from flexvox_core.output_errors import OutputError
    from flexvox_core.output_files import check_writable, refuse_output_onto_input

    out = Path(out_dir).expanduser()
    refuse_output_onto_input(out, inputs)
    if out.exists() and not out.is_dir():
        raise OutputError(f"--figures {out} is a file; the figures go into a folder: choose another path")
    old = [name for name in FIGURES if (out / name).exists()]
    if old and not overwrite:
        raise OutputError(f"--figures {out} already holds {', '.join(old)}; use --overwrite to replace them")
    existing = out
    while not existing.exists():
        existing = existing.parent
    check_writable(existing, out)
    return out


def _save_rgb(path: Path, rgb: np.ndarray) -> None:
    import cv2

    cv2.imwrite(str(path), cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2BGR))


def write_figures(out_dir, frames, code, method, *, max_frames: int = 4, missing=None) -> list[Path]:
    """Reconstruct the first ``max_frames`` camera frames with ``method`` and write PNGs to ``out_dir``.

    ``missing`` (F,) bool: the recording's dropped frames (:mod:`flexvox_core.gaps`).
    ``method`` must return the extras ``flow`` and ``tr`` (motion-aware does). Returns the paths
    written: ``flow_color.png``, ``flow_quiver.png``, ``resolution_map.png``, ``panel.png``.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    f = np.asarray(frames, dtype=np.float32)[:max_frames]
    K = code.shape[2]
    lost = None if missing is None else np.asarray(missing, bool)[:max_frames]
    absent = {"flow", "tr"} - set(method.spec.extras)
    if absent:
        raise ValueError(f"{method.label()} returns no {' and '.join(sorted(absent))}; figures need a method "
                         "that does (motion-aware)")
    r = run(f, code, method, chunk_frames=None, extras=True, missing=lost)
    high_tr = diffuse(f, code, tensor=HIGH_TR, time=2.0, missing=lost)  # motion-aware's own step 1
    s = min(f.shape[0] * K - 2, f.shape[0] * K // 2 + K // 2)  # a sub-frame in the middle
    flows, tr = r.extras["flow"], r.extras["tr"]
    flow = flows[s]
    written = []
    top = max(float(np.quantile(np.hypot(flows[..., 0], flows[..., 1]), 0.995)), 0.25)
    p = out / "flow_color.png"
    _save_rgb(p, flow_to_color(flow, max_magnitude=top))
    written.append(p)
    p = out / "flow_quiver.png"
    _save_rgb(p, quiver_image(high_tr[s], flow, step=max(6, min(flow.shape[:2]) // 20)))
    written.append(p)

    fig, ax = plt.subplots(figsize=(5, 4), dpi=100)
    im = ax.imshow(tr[s], cmap="viridis", vmin=1, vmax=K)
    ax.set_title("effective temporal resolution TR (SR = 1/TR)")
    ax.axis("off")
    fig.colorbar(im, ax=ax, fraction=0.046)
    p = out / "resolution_map.png"
    fig.savefig(p, bbox_inches="tight")
    plt.close(fig)
    written.append(p)

    high_sr = diffuse(f, code, tensor=HIGH_SR, time=3.0)
    panels = [
        ("captured frame", f[s // K], "gray"),
        ("high SR (0.05, 0.05, 1)", high_sr[s], "gray"),
        ("high TR (1, 1, 0.05)", high_tr[s], "gray"),
        ("flow magnitude", magnitude_image(flow, max_magnitude=top), None),
        (method.name, r.video[s], "gray"),
    ]
    fig, axes = plt.subplots(1, 5, figsize=(16, 3.6), dpi=100)
    for ax, (title, img, cmap) in zip(axes, panels, strict=True):
        ax.imshow(img, cmap=cmap, vmin=0 if cmap else None, vmax=1 if cmap else None)
        ax.set_title(title, fontsize=10)
        ax.axis("off")
    fig.tight_layout()
    p = out / "panel.png"
    fig.savefig(p)
    plt.close(fig)
    written.append(p)
    return written
