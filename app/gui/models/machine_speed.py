"""How fast this machine reconstructs: a quick calibration run of a method's kernels (Qt-free).

The bench table (:mod:`flexvox_app.gui.models.expected_quality`) was measured elsewhere, on small clips, on
the kernels alone; the Review workspace runs the whole chunked runner (overlap recomputed, the
sample range, the PSNR against ground truth) on this machine. Its throughput alone mis-predicted
the time by up to 5×. So the first time a method is used for a code with K slots,
:func:`calibrate` runs it — through the same :func:`~flexvox_app.gui.models.jobs.run_reconstruction` and
the same chunking as a full reconstruction — on two small simulated clips of the same length and
different frame sizes, and fits ``seconds = c · sub-frames processed · pixels^p`` (:class:`SpeedModel`:
linear in time, a power of the frame's pixels, since per-frame costs such as the optical flow at an
automatic scale grow slower than the pixel count; sub-frames processed count the overlap each chunk
recomputes, :func:`processed_voxels`). The Review workspace caches the model in its settings
(:meth:`SpeedModel.to_json`) and logs measured against expected after every full reconstruction,
so the estimate can be checked.

The calibration uses the method's default options; other options scale the time by the bench's
relative cost of those options against the defaults (:func:`estimate_seconds`).
"""

from __future__ import annotations

import json
import logging
import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from flexvox_app.gui.models.expected_quality import expected
from flexvox_app.gui.models.jobs import CancelToken, chunk_frames_for, run_reconstruction
from flexvox_core.methods import Method
from flexvox_core.methods.runner import chunk_plan

_logger = logging.getLogger(__name__)

SIZES = ((48, 64), (120, 160))
"""Frame sizes (H, W) of the two calibration clips."""
FRAMES = 6
"""Camera frames of each calibration clip."""
SCENE = "balls"
P_RANGE = (0.5, 1.25)
"""The exponent of the pixel count is kept in this range (two noisy points can say anything)."""


@dataclass(frozen=True)
class SpeedModel:
    """``seconds = c · sub-frames processed · pixels^p`` for one method (default options) and K on this machine.

    Attributes
    ----------
    method : str
    K : int
    c : float
        Seconds per sub-frame processed of one pixel (at p = 1, seconds per voxel).
    p : float
        How the time grows with the frame's pixel count (1: in proportion), clipped to [0.5, 1.25].
    points : list of (voxels processed, pixels per frame, seconds)
        The calibration's measurements.
    version : str
        The software version that measured it (a new version measures again).
    """

    method: str
    K: int
    c: float
    p: float
    points: tuple
    version: str

    def seconds(self, voxels: float, pixels: float) -> float:
        """Expected seconds for ``voxels`` voxels processed in frames of ``pixels`` pixels."""
        return self.c * (voxels / pixels) * pixels ** self.p

    def to_json(self) -> str:
        """The model as JSON (what the settings keep)."""
        return json.dumps(asdict(self))

    @classmethod
    def from_json(cls, text: str) -> SpeedModel | None:
        """A model from :meth:`to_json`'s text; None when the text is missing or not a model."""
        try:
            d = json.loads(text)
            return cls(method=str(d["method"]), K=int(d["K"]), c=float(d["c"]), p=float(d["p"]),
                       points=tuple(tuple(p) for p in d["points"]), version=str(d["version"]))
        except (TypeError, ValueError, KeyError):
            return None


def settings_key(method: str, K: int) -> str:
    """Where the settings keep the model of ``method`` at ``K`` slots."""
    return f"speed/{method}/K{int(K)}"


def _version() -> str:
    from flexvox_core._version import __version__

    return str(__version__)


def is_current(model: SpeedModel | None) -> bool:
    """True when ``model`` exists and was measured by this software version."""
    return model is not None and model.version == _version()


def processed_voxels(method: Method, n_frames: int, K: int, H: int, W: int, chunk_frames: int | None = None) -> int:
    """Voxels the chunked runner processes for a full reconstruction (each chunk with its overlap).

    ``chunk_frames`` defaults to what the Review workspace uses (:func:`~flexvox_app.gui.models.jobs.chunk_frames_for`).
    """
    if chunk_frames is None:
        chunk_frames = chunk_frames_for(method, n_frames, K)
    chunks = chunk_plan(n_frames, chunk_frames, method.overlap(K))
    return sum(c.hi - c.lo for c in chunks) * K * H * W


def _clip(code, size, frames: int):
    from flexvox_core.simulate.scenes import render_scene
    from flexvox_core.simulate.simulator import simulate_video

    K = code.shape[2]
    video = render_scene(SCENE, frames * K, *size, seed=0)
    return np.asarray(simulate_video(video, code).frames, np.float32)


def calibrate(method_name: str, code, *, cancel: CancelToken | None = None) -> SpeedModel:
    """Measure ``method_name`` (default options) with ``code`` on this machine (see the module docstring).

    Runs a warm-up on part of the small clip, then each clip twice (the faster run counts).
    Takes about half a second for diffusion and two for motion-aware here.
    :class:`~flexvox_app.gui.models.jobs.Cancelled`
    when ``cancel`` is set.
    """
    from flexvox_core.design import design_code

    method = Method(method_name)
    code = np.asarray(code, bool)
    K = int(code.shape[2])
    tile = code.shape[:2]
    identity = design_code(tuple(int(v) for v in tile)).code  # the runner takes identity-code captures
    clips = [_clip(identity, size, FRAMES) for size in SIZES]
    cancel = cancel or CancelToken()

    def timed(frames) -> float:
        cancel.check()
        chunk = chunk_frames_for(method, frames.shape[0], K)
        t0 = time.perf_counter()
        run_reconstruction(frames, identity, method, cancel=cancel, chunk_frames=chunk)
        return time.perf_counter() - t0

    timed(clips[0][:2])  # warm-up: imports, caches, the first call's set-up
    points = []
    for clip, repeats in zip(clips, (2, 2), strict=True):
        seconds = min(timed(clip) for _ in range(repeats))
        H, W = clip.shape[1:]
        points.append((processed_voxels(method, clip.shape[0], K, H, W), H * W, max(seconds, 1e-6)))
    (v1, n1, t1), (v2, n2, t2) = points
    p = min(P_RANGE[1], max(P_RANGE[0], math.log((t2 / v2 * n2) / (t1 / v1 * n1)) / math.log(n2 / n1)))
    c = t2 / ((v2 / n2) * n2 ** p)  # through the larger clip
    model = SpeedModel(method=method.name, K=K, c=float(c), p=float(p), points=tuple(points), version=_version())
    _logger.info("speed of %s at K=%d on this machine: time ∝ sub-frames × pixels^%.2f (measured %s)", method.name,
                 K, model.p, ", ".join(f"{v / 1e6:.2f} Mvoxels in {t:.3f} s" for v, _, t in points))
    return model


def estimate_seconds(model: SpeedModel, table: dict | None, method: Method, code, *, n_frames: int, H: int,
                     W: int) -> float:
    """Expected seconds of a full reconstruction of ``n_frames`` frames of H×W with ``method`` and ``code``.

    The calibrated model gives the time of the method's default options; other options scale it by the bench's
    relative cost of those options (1 when the bench has nothing for them).
    """
    K = int(np.asarray(code).shape[2])
    voxels = processed_voxels(method, n_frames, K, H, W)
    seconds = model.seconds(voxels, H * W)
    default = Method(method.name)
    if method != default:
        mine = expected(table, method, code, voxels=voxels)
        base = expected(table, default, code, voxels=voxels)
        if mine is not None and base is not None and base.seconds > 0 and math.isfinite(mine.seconds):
            seconds *= mine.seconds / base.seconds
    return float(seconds)
