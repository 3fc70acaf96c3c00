"""What a motion-aware reconstruction gives back (:class:`MotionAwareResult`)."""

from __future__ import annotations

from functools import cached_property

import numpy as np

from flexvox_core.flow import FlowField
from flexvox_core.flow.estimate import ScaledFlow
from flexvox_core.motion.tensors import DEFAULT_C, resolution_map
from flexvox_core.reprs import describe_array, html_table, short_repr


class MotionAwareResult:
    """Video and everything a person may want to look at.

    Attributes
    ----------
    video : ndarray (S, H, W) float32 in the samples' range
    high_tr : ndarray (S, H, W) float32
        The Step-1 reconstruction, as the stages after the flow read it: its values rounded to float16
        (:data:`~flexvox_core.motion.stages.HIGH_TR_HELD`; the flow reads them unrounded), made float32 when first
        read.
    flow : FlowField or ScaledFlow
        The gated flow that drove the tensors (confidence from the high-TR flow); a
        :class:`~flexvox_core.flow.estimate.ScaledFlow` (held at the flow's own scale) makes its full-size
        ``flow`` when first read.
    K : int
        Slots of the code.
    c : (c1, c2, c3)
        Eigenvalues of Eq. 4 used.
    seconds : dict
        Time of each step: ``high_tr``, ``flow``, ``diffusion`` (every stage after the flow).
    stage_seconds : dict
        Time of each stage of :mod:`~flexvox_core.motion.stages` (summed over passes).
    device : str
        Where the stages ran: ``cpu`` or ``cuda``.
    device_note : str or None
        Why the CPU ran them when the GPU was asked for (options the GPU's stages do not run as the CPU's,
        :func:`~flexvox_core.motion.stages.cuda_unsupported`); None otherwise.
    tr, sr : ndarray (S, H, W) float32
        Effective resolution chosen per voxel (:func:`~flexvox_core.motion.tensors.resolution_map`),
        computed from ``flow`` when first asked for (two more volumes a plain reconstruction
        does not need).

    ``high_tr`` and ``flow`` may be given as functions of no argument that make them: a GPU run leaves them on
    the card and copies them to the host only when first read.
    """

    def __init__(self, video: np.ndarray, high_tr, flow, K: int, c: tuple = DEFAULT_C, seconds: dict | None = None,
                 stage_seconds: dict | None = None, device: str = "cpu", device_note: str | None = None):
        self.video = video
        self._high_tr = high_tr
        self._flow = flow
        self.K = K
        self.c = c
        self.seconds = dict(seconds or {})
        self.stage_seconds = dict(stage_seconds or {})
        self.device = device
        self.device_note = device_note

    def _facts(self) -> list[tuple[str, str]]:
        seconds = ", ".join(f"{k} {v:.2f} s" for k, v in self.seconds.items()) or "not timed"
        return [("video", describe_array(self.video)), ("K", str(self.K)), ("c", ", ".join(f"{v:g}" for v in self.c)),
                ("device", self.device + (f" ({self.device_note})" if self.device_note else "")),
                ("seconds", seconds)]

    def __repr__(self) -> str:
        total = sum(self.seconds.values())
        return short_repr("MotionAwareResult", [f"video {describe_array(self.video)}", f"K = {self.K}",
                                                f"on {self.device}", f"{total:.2f} s" if self.seconds else ""])

    def _repr_html_(self) -> str:
        return html_table("MotionAwareResult", self._facts())

    @cached_property
    def high_tr(self) -> np.ndarray:
        return self._high_tr() if callable(self._high_tr) else self._high_tr

    @cached_property
    def flow(self) -> FlowField | ScaledFlow:
        return self._flow() if callable(self._flow) else self._flow

    @cached_property
    def _resolution(self) -> tuple[np.ndarray, np.ndarray]:
        return resolution_map(self.flow.flow, self.K, self.c)

    @property
    def tr(self) -> np.ndarray:
        return self._resolution[0]

    @property
    def sr(self) -> np.ndarray:
        return self._resolution[1]
