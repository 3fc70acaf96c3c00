"""How the accuracy estimate (:mod:`flexvox_core.accuracy`) runs a method on the capture and on its probe.

Most methods run through their public entry (:func:`flexvox_core.methods.run`). Motion-aware estimates its
optical flow from the samples, so a probe that moves samples would move the flow, and with it every voxel's
trajectory: the change would not be the sample's own pull. :class:`HeldRuns` runs motion-aware's stages
(:func:`flexvox_core.motion.stages.run_stages`) itself, and the probe reuses the first run's flow (each pass's)
and the first run's sample range (which scales the long reach's range weight and bounds the result): with the
flow held, what is left is a linear smoother along fixed trajectories, save the long reach's range weight and
the local choice's blend (:mod:`flexvox_core.accuracy`, "motion-aware"). The held flow is the one the method
computes from the capture, so the first run equals :func:`~flexvox_core.methods.run`'s (a test checks it).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from flexvox_core.methods import Method
    from flexvox_core.motion.stages import Window
    from flexvox_core.progress import Progress

Run = Callable[[np.ndarray], np.ndarray]
"""A method's run: camera frames (F, H, W) float32 to the video (F·K, H, W)."""


class Steps:
    """The estimate's progress over its reconstructions, in camera frames (``runs × F`` in all).

    ``report`` (``progress(done, total)``, :mod:`flexvox_core.progress`) is called as a run advances (through
    :func:`flexvox_core.methods.run`'s own progress, after each chunk) and after each run; an exception it raises
    stops the estimate there, as it stops the runner.

    Parameters
    ----------
    report : callable(done, total) or None
    frames : int
        Camera frames per run.
    runs : int
        The runs planned (:meth:`more` adds the ones found needed later).
    """

    def __init__(self, report: Progress | None, frames: int, runs: int) -> None:
        self.report, self.frames, self.runs, self.done = report, frames, runs, 0

    def more(self, runs: int) -> None:
        """``runs`` more runs are needed."""
        self.runs += runs

    def during(self) -> Progress | None:
        """The progress callback of the next run (its ``(done, total)`` scaled to its share of the estimate)."""
        report = self.report
        if report is None:
            return None
        base, F, total = self.done * self.frames, self.frames, self.runs * self.frames
        return lambda done, of: report(base + min(F, done * F // max(of, 1)), total)

    def finished(self) -> None:
        """One run done: say so (the check between runs)."""
        self.done += 1
        if self.report is not None:
            self.report(self.done * self.frames, self.runs * self.frames)


def holds_flow(method: Method) -> bool:
    """Whether the estimate runs ``method`` with its flow held (:class:`HeldRuns`)."""
    return method.name == "motion-aware"


class HeldRuns:
    """Motion-aware on ``frames`` and on probes of them, every run with the flow of the first.

    Parameters
    ----------
    frames : ndarray (F, H, W) float32
        The capture (identity code).
    code : ndarray (m, n, K)
    method : Method
        Motion-aware, with its options.
    missing : ndarray (F,) bool, optional
    device : str
        ``cpu``, ``cuda`` or ``auto`` (:func:`flexvox_core.motion.pipeline.engine_for`).
    """

    def __init__(self, frames: np.ndarray, code: np.ndarray, method: Method, *, missing: np.ndarray | None = None,
                 device: str = "cpu") -> None:
        from flexvox_core.gaps import as_missing
        from flexvox_core.motion.options import check_sample_range
        from flexvox_core.motion.pipeline import engine_for

        self.code = code
        self.options = method.options
        self.missing = as_missing(missing, frames.shape[0])
        self.sample_range = check_sample_range(frames, self.missing, None)
        self.device, _ = engine_for(self.options, device)
        self.flows: list[Any] = []  # each pass's flow, as the first run's engine made it (host arrays on the GPU)

    def _window(self, frames: np.ndarray) -> Window:
        from flexvox_core.motion.stages import Window

        return Window.plan(np.ascontiguousarray(frames, np.float32), self.code, self.options, self.sample_range,
                           missing=self.missing)

    def run(self, frames: np.ndarray) -> np.ndarray:
        """The video of ``frames``: the first call computes the flow and keeps it, later calls reuse it."""
        from flexvox_core.motion.stages import run_stages

        engine = _engine(self.device)(self._window(frames), self.flows)
        return np.asarray(run_stages(engine).video, np.float32)

    __call__ = run

    def flow_only(self, frames: np.ndarray) -> None:
        """Compute and keep the flow of ``frames`` without the rest of the run (one pass; a reconstruction already
        made by the method gives the video)."""
        if self.options.passes != 1:
            self.run(frames)
            return
        engine = _engine(self.device)(self._window(frames), self.flows)
        engine.gated_flow(engine.high_tr())


def _engine(device: str) -> Callable[[Window, list[Any]], Any]:
    """The engine class of ``device`` whose ``gated_flow`` keeps each pass's flow in the list it is given while the
    list is short of it, and returns the kept flow once it is there."""
    if device == "cuda":
        return _held_cuda()
    from flexvox_core.motion.stages import CpuStages

    class HeldCpu(CpuStages):
        def __init__(self, window: Window, flows: list[Any]) -> None:
            super().__init__(window)
            self.flows = flows

        def gated_flow(self, current: Any) -> Any:
            i = self.passes_run
            if i < len(self.flows):
                self.passes_run += 1
                self.last = self.passes_run == self.window.passes
                return self.flows[i]
            field = super().gated_flow(current)
            self.flows.append(field)
            return field

    return HeldCpu


def _held_cuda() -> Callable[[Window, list[Any]], Any]:
    from flexvox_core.motion.gpu.engine import CudaStages

    class HeldCuda(CudaStages):
        def __init__(self, window: Window, flows: list[Any]) -> None:
            super().__init__(window)
            self.flows = flows
            self.flow_passes = 0

        def gated_flow(self, current: Any) -> Any:
            i = self.flow_passes
            self.flow_passes += 1
            if i < len(self.flows):
                w = self.window
                flow = self.ws.get(_flow_buffer(), (w.S, *w.frames.shape[1:], 2))
                flow.copy_to_device(self.flows[i])
                return flow
            flow = super().gated_flow(current)
            self.flows.append(flow.copy_to_host())
            return flow

    return HeldCuda


def _flow_buffer() -> Any:
    from flexvox_core.motion.gpu.engine import Buffers

    return Buffers.FLOW
