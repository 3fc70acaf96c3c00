"""Motion-aware's CPU and GPU engines on one tiny capture, one option at a time (cupy's ``numpy_cupy_allclose``
habit: one body, both engines).

Every :class:`~flexvox_core.motion.options.MotionOptions` field has a case with a value other than its default
(:data:`FIELD_VALUES`), and so do the routes around them (:data:`ROUTES`: two passes, a dropped frame, kept
sub-frames, a multiplexed capture). A case either gives the CPU's video within :data:`TOLERANCE` on the GPU, or
runs on the CPU with a note saying why. ``python -m tests.flexvox_core.gpu.parity_cases`` (with
``NUMBA_ENABLE_CUDASIM=1`` where there is no GPU) prints the table docs/gpu.md shows.
"""

from __future__ import annotations

import numpy as np

from tests.flexvox_core.gpu.tiny import CODE, tiny_capture

TOLERANCE = 1e-4
"""max |CPU − GPU| over the video (values in [0, 1]): float32 sums in another order, DIS on the card."""

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

ROUTES = ("defaults", "dropped frame", "kept sub-frames", "multiplexed")
"""The runs around the options: the defaults, a dropped frame (bridged along the flow), a window that keeps a
part of its sub-frames (a stream's), a multiplexed capture (the method's own route)."""

FRAMES, HEIGHT, WIDTH, NOISE = 2, 8, 8, 0.01


def case_ids() -> list[str]:
    return [*(f"{k}={v!r}" for k, v in FIELD_VALUES.items()), *ROUTES]


def run_case(case: str) -> tuple[float | None, str | None]:
    """(max |CPU − GPU| over the video, None) when the GPU ran the case; (None, the note) when it went to the CPU
    (the CPU's video then checked equal to a CPU run's, bit for bit)."""
    from flexvox_core.motion.options import MotionOptions, sample_bounds
    from flexvox_core.motion.pipeline import run_window

    _, frames = tiny_capture("balls", FRAMES, HEIGHT, WIDTH, noise=NOISE)
    if case == "multiplexed":
        return _multiplexed()
    options, missing, keep = {}, None, None
    if case == "dropped frame":
        _, frames = tiny_capture("balls", 3, HEIGHT, WIDTH, noise=NOISE)
        missing = np.array([False, True, False])
        frames[1] = 0
    elif case == "kept sub-frames":
        keep = (4, 8)
    elif case != "defaults":
        name = case.split("=", 1)[0]
        options = {name: FIELD_VALUES[name]}
    o = MotionOptions(**options)
    bounds = sample_bounds(frames, missing, None)
    cpu = run_window(frames, CODE, o, bounds, missing=missing, keep=keep)
    gpu = run_window(frames, CODE, o, bounds, missing=missing, keep=keep, device="cuda")
    assert cpu.device == "cpu" and cpu.device_note is None
    if gpu.device == "cpu":
        assert gpu.device_note
        np.testing.assert_array_equal(gpu.video, cpu.video)
        return None, gpu.device_note
    assert gpu.video.shape == cpu.video.shape
    return float(np.abs(gpu.video.astype(np.float64) - cpu.video).max()), None


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
    rows = ["| case | max \\|CPU − GPU\\| | where it ran |", "|---|---|---|"]
    for case in case_ids():
        diff, note = run_case(case)
        rows.append(f"| `{case}` | {'—' if diff is None else f'{diff:.1e}'} | "
                    f"{'GPU' if note is None else 'CPU: ' + note} |")
    return "\n".join(rows)


if __name__ == "__main__":
    print(table())
