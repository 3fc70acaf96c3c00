"""The live preview at the camera's pace: refresh rate, latency, resolution and CPU share of four strategies.

A simulated camera delivers coded frames of the built-in ``balls`` scene (K = 16, 4×4 code) at 15 Hz
from its own thread; the preview loop takes the newest frames whenever it is free (newest wins),
reconstructs them with motion-aware, then rests as long as the run took (half a core at most), as the
Capture workspace's preview does. Four strategies in the same run, each for ``--seconds``:

* ``stride`` — the frame subsampled with a stride that grows when a run exceeds the 0.6-s budget and
  shrinks only when the finer run (time ∝ pixels) is predicted under half of it (an aliased picture of the
  whole field);
* ``region`` — full resolution, the whole frame when the measured cost of a pixel says it fits the budget,
  else a region of it (``flexvox_app.capture.live_preview``), each run from scratch over the newest 3 frames,
  showing the newest;
* ``stream`` — what the Capture workspace runs: the same regions rule, motion-aware by the streaming
  reconstructor (the frame before the newest over the same 3-frame window, the frames and flow pairs kept
  between runs);
* ``nc`` — the fast preview the operator may choose instead: constant-tensor ``nc`` over the same
  regions rule (in practice the whole frame);
* ``gpu`` (with ``--device cuda``) — streaming motion-aware on the GPU with all its stages, the whole frame every
  run, no rest between runs: every camera frame should be previewed.

``--soak S`` then runs the ``gpu`` preview for S seconds at the largest size and prints, per tenth of the soak,
the previews per second, the latency and the GPU and host memory in use.

Printed per size and strategy: previews per second, the pixels each preview covers (at which
sampling), the time from a frame's arrival to its preview being ready (median and 90th percentile),
the CPU share (the process's CPU time over the wall time, in cores: the camera thread is nearly
idle), and the camera thread's late frames: frames it delivered more than one period after their time,
which a real camera with one buffer would have dropped (the GUI tests record with the preview on and
check that the simulated rig drops none).

``--region-cpu SIDE`` then runs motion-aware from scratch on a fixed SIDE×SIDE region of the last size's frames
(the ``region`` preview's run, its 3 frames, with the preview's options; ``--region-all``: every stage at the
region's own flow scale), ``--calls`` times after one warm-up, and prints the process's CPU
seconds per stage and in all (medians): the region's cost without the camera's pace or the machine's load in
it (``taskset -c 0`` makes it one core's).

Figures only, never pass/fail. Usage: ``python bench/bench_live_preview.py [--seconds S] [--sizes 160x120,640x480]
[--strategies stride,region,stream,nc] [--device cuda] [--soak S] [--region-cpu SIDE [--calls N] [--region-all]]``.
"""

from __future__ import annotations

import argparse
import contextlib
import math
import statistics
import threading
import time
from unittest import mock

import numpy as np

from flexvox_app.capture.live_preview import PixelCost, PreviewReconstructor, preview_region, reconstruct_preview
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.simulate.scenes import render_scene
from rig_drivers.interfaces import Frame

RATE_HZ = 15.0
BUDGET_S = 0.6
N_FRAMES = 3


class Camera(threading.Thread):
    """Coded frames at RATE_HZ, the newest kept with its arrival time."""

    def __init__(self, frames: np.ndarray):
        super().__init__(daemon=True)
        self.frames, self.stop = frames, threading.Event()
        self.lock, self.recent, self.arrived = threading.Lock(), [], {}
        self.late = 0

    def run(self) -> None:
        t0, i = time.monotonic(), 0
        while not self.stop.is_set():
            if time.monotonic() - (t0 + i / RATE_HZ) > 1 / RATE_HZ:
                self.late += 1
            f = Frame(self.frames[i % len(self.frames)], frame_id=i, timestamp_s=i / RATE_HZ)
            with self.lock:
                self.recent = (self.recent + [f])[-N_FRAMES:]
                self.arrived[i] = time.monotonic()
            i += 1
            time.sleep(max(0.0, t0 + i / RATE_HZ - time.monotonic()))

    def newest(self):
        with self.lock:
            return list(self.recent)


def _stride_run(frames, code, tile, stride):
    """The old preview: a subsampled capture of the same code (stride ≡ 1 mod lcm(m, n))."""
    from flexvox_core.motion import motion_aware

    t0 = time.perf_counter()
    stack = np.stack([f.image for f in frames])[:, ::stride, ::stride]
    motion_aware(np.ascontiguousarray(stack, np.float32), code)
    return time.perf_counter() - t0, stack.shape[1] * stack.shape[2]


def _from_scratch(frames, code, region):
    """Motion-aware from scratch over the newest frames of ``region``, the newest shown (the ``region`` strategy)."""
    from flexvox_app.capture.live_preview import PreviewResult, normalise
    from flexvox_core.motion import motion_aware

    t0 = time.perf_counter()
    stack = np.ascontiguousarray(region.crop(np.stack([normalise(f.image) for f in frames])))
    video = motion_aware(stack, code, refine_time=0.0).video[-code.shape[2]:]
    return PreviewResult(video, int(frames[-1].frame_id), len(frames), region, frames[-1].image.shape,
                         time.perf_counter() - t0, (0.0, 1.0))


def run_strategy(name: str, cam: Camera, code, tile, shape, seconds: float, on_tick=None) -> dict:
    step = math.lcm(*tile)
    stride, cost = None, PixelCost()
    stream = PreviewReconstructor("cuda" if name == "gpu" else "cpu")
    rates, latencies, pixels, run_seconds = [], [], [], []
    cpu0, t_end = time.process_time(), time.monotonic() + seconds
    wall0 = time.monotonic()
    last_id = -1
    while time.monotonic() < t_end:
        frames = cam.newest()
        if not frames or frames[-1].frame_id == last_id:
            time.sleep(0.005)
            continue
        last_id = frames[-1].frame_id
        if name == "stride":
            if stride is None:
                stride = 1
                while -(-shape[0] // stride) * -(-shape[1] // stride) > 160 * 120:
                    stride += step
            secs, px = _stride_run(frames, code, tile, stride)
            if secs > BUDGET_S:
                stride += step
            elif stride > 1:
                finer = max(1, stride - step)
                if secs * (stride / finer) ** 2 < BUDGET_S / 2:
                    stride = finer
            label = f"every {stride}th pixel" if stride > 1 else "every pixel"
        elif name == "gpu":
            r = stream.run(frames, code, None, "motion-aware")
            secs, px, label = r.seconds, r.region.pixels, "whole frame"
        else:
            region = preview_region(shape, tile, cost.pixels_for(BUDGET_S, 160 * 120))
            method = "nc" if name == "nc" else "motion-aware"
            if name == "stream":
                r = stream.run(frames, code, region, method)
            elif name == "nc":
                r = reconstruct_preview(frames, code, region, method)
            else:
                r = _from_scratch(frames, code, region)
            secs, px = r.seconds, region.pixels
            cost.add(secs, px)
            label = "whole frame" if r.whole_frame else "region, full resolution"
        done = time.monotonic()
        latencies.append(done - cam.arrived[r.frame_id if name != "stride" else last_id])
        rates.append(done)
        pixels.append((px, label))
        run_seconds.append(secs)
        if on_tick is not None:
            on_tick(done, latencies[-1])
        if name != "gpu":
            time.sleep(secs)  # rest as long as the run took: at most half a core
    wall = time.monotonic() - wall0
    cpu = time.process_time() - cpu0
    hz = (len(rates) - 1) / (rates[-1] - rates[0]) if len(rates) > 1 else 0.0
    px, label = pixels[-1] if pixels else (0, "-")
    return {"hz": hz, "lat50": float(np.median(latencies)) if latencies else float("nan"),
            "lat90": float(np.percentile(latencies, 90)) if latencies else float("nan"),
            "px": px, "label": label, "cpu": cpu / wall, "runs": len(rates), "late": cam.late,
            "run_ms": 1000 * float(np.median(run_seconds)) if run_seconds else float("nan"),
            "skipped": max(0, int(round(wall * RATE_HZ)) - len(rates))}


def _memory() -> tuple[float, float]:
    """(GPU memory in use, host resident memory) in MiB."""
    import resource

    from numba import cuda

    free, total = cuda.current_context().get_memory_info()
    return (total - free) / 2**20, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def soak(frames, code, tile, shape, seconds: float) -> None:
    """The GPU preview for ``seconds``: per tenth, previews/s, latency and memory."""
    ticks = []
    cam = Camera(frames)
    cam.start()
    try:
        r = run_strategy("gpu", cam, code, tile, shape, seconds, on_tick=lambda t, lat: ticks.append((t, lat)))
    finally:
        cam.stop.set()
        cam.join()
    print(f"\nsoak: {seconds:g} s of the GPU preview at {shape[1]}x{shape[0]}: {r['runs']} previews, "
          f"{r['skipped']} camera frames not previewed, camera late {r['late']}")
    print("| part | previews/s | latency median / max s | GPU MiB | host max RSS MiB |")
    print("|---|---|---|---|---|")
    if len(ticks) < 2:
        return
    t0, t1 = ticks[0][0], ticks[-1][0]
    for k in range(10):
        a, b = t0 + (t1 - t0) * k / 10, t0 + (t1 - t0) * (k + 1) / 10
        part = [lat for t, lat in ticks if a <= t < b or (k == 9 and t == b)]
        gpu, host = _memory()
        rate = len(part) / max(b - a, 1e-9)
        lat = f"{np.median(part):.3f} / {max(part):.3f}" if part else "-"
        print(f"| {k + 1}/10 | {rate:.2f} | {lat} | {gpu:.0f} | {host:.0f} |", flush=True)


def region_cpu(frames: np.ndarray, code: np.ndarray, side: int, calls: int, everything: bool = False) -> None:
    """Motion-aware on a fixed ``side``² region of ``frames``' last 3 frames (top-left on the code's grid), with the
    preview's options (:func:`~flexvox_app.capture.live_preview.preview_options` of the whole frame) or, ``all``, every
    stage at the region's own flow scale: the process's CPU seconds per stage and in all, medians of ``calls`` calls
    after a warm-up."""
    from flexvox_app.capture.live_preview import preview_options
    from flexvox_core.motion import stages
    from flexvox_core.motion.pipeline import motion_aware

    H, W = frames.shape[1:]
    if side > min(H, W):
        raise SystemExit(f"--region-cpu {side}: larger than the {W}x{H} frames")
    y0, x0 = (H - side) // 8 * 4, (W - side) // 8 * 4  # centred, on the 4x4 code's grid
    region = np.ascontiguousarray(frames[-N_FRAMES:, y0:y0 + side, x0:x0 + side])
    options = {} if everything else {"sample_range": (0.0, 1.0), **preview_options((H, W))}
    used: dict[str, float] = {}
    plain = stages.StageTimes.__call__

    @contextlib.contextmanager
    def timed(self, stage):
        start = time.process_time()
        with plain(self, stage):
            yield
        used[stage] = used.get(stage, 0.0) + time.process_time() - start

    runs = []
    with mock.patch.object(stages.StageTimes, "__call__", timed):
        for _ in range(calls + 1):
            used.clear()
            start = time.process_time()
            motion_aware(region, code, **options)
            runs.append({**used, "all": time.process_time() - start})
    runs = runs[1:]  # the warm-up: numba's compilation
    names = list(runs[-1])
    how = "every stage, the region's own flow scale" if everything else f"the preview's options {options}"
    print(f"\nmotion-aware on a {side}x{side} region, {N_FRAMES} frames, {how}, {calls} calls: CPU ms (median)")
    print("| " + " | ".join(names) + " |")
    print("|---" * len(names) + "|")
    print("| " + " | ".join(f"{statistics.median(r.get(n, 0.0) for r in runs) * 1000:.0f}" for n in names) + " |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--sizes", default="160x120,640x480")
    ap.add_argument("--strategies", default="stride,region,stream,nc")
    ap.add_argument("--device", choices=("cpu", "cuda"), default="cpu",
                    help="cuda: add the GPU preview (strategy gpu) to each size")
    ap.add_argument("--soak", type=float, default=0.0, metavar="S", help="then the GPU preview for S seconds")
    ap.add_argument("--region-cpu", type=int, default=0, metavar="SIDE",
                    help="then motion-aware on a fixed SIDE x SIDE region: CPU seconds per stage")
    ap.add_argument("--calls", type=int, default=8, help="--region-cpu's calls (after one warm-up)")
    ap.add_argument("--region-all", action="store_true",
                    help="--region-cpu with every stage at the region's own flow scale, not the preview's options")
    args = ap.parse_args()
    tile = (4, 4)
    code = design_code(tile).code
    strategies = [s for s in args.strategies.split(",") if s] + (["gpu"] if args.device == "cuda" else [])
    print(f"15 Hz camera, K = 16, motion-aware preview of {N_FRAMES} frames, budget {BUDGET_S} s, "
          f"{args.seconds:g} s per row")
    print("| size | preview | previews/s | pixels per preview (last) | arrival to ready, median / p90 s "
          "| CPU | run ms (median) | runs | not previewed | camera late |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for size in args.sizes.split(","):
        w, h = (int(v) for v in size.split("x"))
        truth = render_scene("balls", 8 * 16, h, w, seed=0)
        frames = capture(truth, code).astype(np.float32)
        for name in strategies:
            cam = Camera(frames)
            cam.start()
            try:
                r = run_strategy(name, cam, code, tile, (h, w), args.seconds)
            finally:
                cam.stop.set()
                cam.join()
            print(f"| {w}x{h} | {name} | {r['hz']:.2f} | {r['px']} ({r['label']}) | {r['lat50']:.3f} / "
                  f"{r['lat90']:.3f} | {r['cpu']:.2f} cores | {r['run_ms']:.1f} | {r['runs']} | {r['skipped']} | "
                  f"{r['late']} |", flush=True)
    if args.soak > 0:
        soak(frames, code, tile, (h, w), args.soak)
    if args.region_cpu:
        region_cpu(frames, code, args.region_cpu, args.calls, args.region_all)


if __name__ == "__main__":
    main()
