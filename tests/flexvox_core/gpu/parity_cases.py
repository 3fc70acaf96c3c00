"""Motion-aware's CPU and GPU engines on tiny captures, one option at a time (cupy's ``numpy_cupy_allclose``
habit: one body, both engines). The one CPU/GPU matrix: ``test_parity.py`` runs every case in ``make test``.

Every :class:`~flexvox_core.motion.options.MotionOptions` field has a case with a value other than its default
(:data:`FIELD_VALUES`), on a clip where that value changes the CPU's video (:data:`CLIPS`: the default clip
unless the option needs more pixels, more frames or a still background to matter), and so do the routes around
them (:data:`ROUTES`: a dropped frame, kept sub-frames, a multiplexed capture, DIS on the card). A case either
gives the CPU's video within :data:`TOLERANCE` on the GPU, or runs on the CPU with a note saying why. The GPU's
image pairs run through OpenCV's DIS on the host (``pairs="cpu"``: the engine's switch), so every case but
``DIS on the card`` times the GPU's own kernels, not the simulator's DIS. ``python -m
tests.flexvox_core.gpu.parity_cases`` (with ``NUMBA_ENABLE_CUDASIM=1`` where there is no GPU) prints the table
docs/gpu.md shows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from tests.flexvox_core.gpu.tiny import CODE, K, tiny_capture

TOLERANCE = 5e-6
"""max |CPU − GPU| over the video (values in [0, 1]): float32 sums in another order (the largest measured: see
docs/gpu.md's table)."""

FIELD_VALUES = {
    "flow": "farneback",
    "passes": 2,
    "time": 3.0,
    "c": (0.9, 0.08, 0.06),
    "refine_time": 0.0,
    "gate": (0.02, 0.1),
    "flow_scale": 0.5,
    "still_speed": None,
    "flow_consistency": True,
    "slow_speed": None,
    "slow_reach": 1.5,
    "local_choice": False,
    "noise_aware": False,
}
"""A value other than the default for every field of MotionOptions (a test checks that every field has one)."""


@dataclass(frozen=True)
class Clip:
    """A tiny capture of a built-in scene with the 2×2 code (:func:`tests.flexvox_core.gpu.tiny.tiny_capture`)."""

    scene: str = "balls"
    frames: int = 2
    height: int = 8
    width: int = 8
    noise: float = 0.01

    def capture(self) -> np.ndarray:
        """The frames (F, H, W) float32; a scene ``a+b`` puts scene a in the left half and b in the right."""
        if "+" not in self.scene:
            return tiny_capture(self.scene, self.frames, self.height, self.width, noise=self.noise)[1]
        from flexvox_core import capture
        from flexvox_core.simulate.scenes import render_scene

        S, half = self.frames * K, self.width // 2
        truth = np.concatenate([_SMOOTH[name](S, self.height, w) if name in _SMOOTH else
                                render_scene(name, S, self.height, w)
                                for name, w in zip(self.scene.split("+"), (half, self.width - half), strict=True)],
                               axis=2)
        frames = capture(truth, CODE) + np.random.default_rng(0).normal(0, self.noise, (self.frames, self.height,
                                                                                        self.width))
        return np.clip(frames, 0, 1).astype(np.float32)


def _flat(S: int, H: int, W: int) -> np.ndarray:
    """A still grey wall."""
    return np.full((S, H, W), 0.4, np.float32)


def _drift(S: int, H: int, W: int) -> np.ndarray:
    """A smooth, faint pattern drifting right at 2 px per sub-frame (flat against the noise: the noise-aware
    smoothing's wide kernel takes over there)."""
    s, y, x = np.mgrid[:S, :H, :W].astype(np.float32)
    return (0.5 + 0.04 * np.sin(2 * np.pi * (x - 2 * s) / 12) * np.cos(2 * np.pi * y / 16)).astype(np.float32)


_SMOOTH = {"flat": _flat, "drift": _drift}

DEFAULT_CLIP = Clip()
CLIPS = {
    "flow_scale": Clip(width=18),  # the flow never runs below 16 px a side: 8×18 at 0.5 is 8×16
    "flow_consistency": Clip(width=18),
    "local_choice": Clip("static+drift", 2, 8, 24, noise=0.03),
    "noise_aware": Clip("static+drift", 2, 12, 20, noise=0.03),
}
"""The clips of the options that give the default clip's video bit for bit (the rest run on
:data:`DEFAULT_CLIP`)."""

ROUTES = ("defaults", "dropped frame", "kept sub-frames", "multiplexed", "DIS on the card")
"""The runs around the options: the defaults, a dropped frame (bridged along the flow), a window that keeps a
part of its sub-frames (a stream's), a multiplexed capture (the method's own route), and the defaults with the
optical flow's pairs on the (simulated) card, through :func:`~flexvox_core.motion.motion_aware`."""


def case_ids() -> list[str]:
    return [*(f"{k}={v!r}" for k, v in FIELD_VALUES.items()), *ROUTES]


def option_of(case: str) -> str | None:
    """The MotionOptions field a case sets (None: a route)."""
    return None if case in ROUTES else case.split("=", 1)[0]


def run_case(case: str) -> tuple[float | None, str | None]:
    """(max |CPU − GPU| over the video, None) when the GPU ran the case; (None, the note) when it went to the CPU
    (the CPU's video then checked equal to a CPU run's, bit for bit). A field's case first checks that its value
    changes the CPU's video on its clip."""
    from flexvox_core.motion.gpu.engine import CudaStages
    from flexvox_core.motion.options import MotionOptions, sample_bounds
    from flexvox_core.motion.pipeline import engine_for, run_window
    from flexvox_core.motion.stages import Window, run_stages

    if case == "multiplexed":
        return _multiplexed()
    if case == "DIS on the card":
        return _dis_on_the_card()
    name = option_of(case)
    frames = CLIPS.get(name or "", DEFAULT_CLIP).capture()
    options, missing, keep = {}, None, None
    if case == "dropped frame":
        frames = Clip(frames=3).capture()
        missing = np.array([False, True, False])
        frames[1] = 0
    elif case == "kept sub-frames":
        keep = (4, 8)
    elif name is not None:
        options = {name: FIELD_VALUES[name]}
    o = MotionOptions(**options)
    bounds = sample_bounds(frames, missing, None)
    cpu = run_window(frames, CODE, o, bounds, missing=missing, keep=keep)
    assert cpu.device == "cpu" and cpu.device_note is None
    if name is not None:
        default = run_window(frames, CODE, MotionOptions(), bounds)
        assert not np.array_equal(cpu.video, default.video), f"{case} gives the default video on its clip"
    device, note = engine_for(o, "cuda")
    if device == "cpu":
        assert note
        gpu = run_window(frames, CODE, o, bounds, missing=missing, keep=keep, device="cuda")
        assert (gpu.device, gpu.device_note) == ("cpu", note)
        np.testing.assert_array_equal(gpu.video, cpu.video)
        return None, note
    window = Window.plan(frames, CODE, o, bounds, missing=missing, keep=keep)
    gpu = run_stages(CudaStages(window, pairs="cpu"))
    assert gpu.device == "cuda" and gpu.video.shape == cpu.video.shape
    return _diff(gpu.video, cpu.video), None


def _diff(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(np.float64) - b).max())


def _dis_on_the_card():
    """The defaults through ``motion_aware(device="cuda")``: every stage on the device, DIS included; the flow
    within 10⁻³ px and the high-TR video within float rounding too."""
    from flexvox_core.motion.pipeline import motion_aware

    frames = DEFAULT_CLIP.capture()
    cpu = motion_aware(frames, CODE)
    gpu = motion_aware(frames, CODE, device="cuda")
    assert (gpu.device, cpu.device) == ("cuda", "cpu") and gpu.flow.params["pairs"] == "gpu"
    assert set(gpu.stage_seconds) >= {"high_tr", "gated_flow", "trajectory_gather", "local_choice", "download"}
    np.testing.assert_allclose(gpu.high_tr, cpu.high_tr, atol=TOLERANCE)
    np.testing.assert_allclose(gpu.flow.flow, cpu.flow.flow, atol=1e-3)
    return _diff(gpu.video, cpu.video), None


def _multiplexed():
    from flexvox_core import capture
    from flexvox_core.methods import Method
    from flexvox_core.methods.runner import run
    from flexvox_core.multiplex import multiplexed_code
    from flexvox_core.simulate.scenes import render_scene

    code = multiplexed_code((1, 3)).code
    frames = np.asarray(capture(render_scene("balls", 3 * 3, 8, 9, seed=0), code), np.float32)
    method = Method("motion-aware")
    cpu = run(frames, code, method)
    gpu = run(frames, code, method, device="cuda")
    assert gpu.device == "cpu" and gpu.device_note
    np.testing.assert_array_equal(gpu.video, cpu.video)
    return None, gpu.device_note


def table() -> str:
    """The parity table as markdown: each case, its max |CPU − GPU| or its routing note."""
    rows = ["| case | clip | max \\|CPU − GPU\\| | where it ran |", "|---|---|---|---|"]
    for case in case_ids():
        diff, note = run_case(case)
        clip = CLIPS.get(option_of(case) or "", DEFAULT_CLIP)
        if case == "dropped frame":
            clip = Clip(frames=3)
        size = "8×9, K = 3" if case == "multiplexed" else f"{clip.scene} {clip.frames}×{clip.height}×{clip.width}"
        rows.append(f"| `{case}` | {size} | {'—' if diff is None else f'{diff:.1e}'} | "
                    f"{'GPU' if note is None else 'CPU: ' + note} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(table())
