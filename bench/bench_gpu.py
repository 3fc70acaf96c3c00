"""Motion-aware on the GPU against the CPU, in the same process: time per stage, M voxels/s, memory, PSNR.

Part 1, throughput: a 1-s, 15 Hz, 640×480 clip of each scene with the 4×4 code (K = 16, 73.7 M voxels), through
``motion_aware(..., device="cuda")`` (the camera frames' upload and the result's download included) after one
warm-up run that compiles the kernels; the median of ``--repeat`` runs, each stage's time, M voxels/s, the GPU
memory the run held (the card's and the workspace's, per voxel, next to the runner's estimate), and the CPU
pipeline's time and PSNR on the same clip (``--no-cpu``: skip it). Real time at
this size and rate is 73.7 M voxels/s.

Part 2, accuracy: every motion-aware row of ``flexvox bench`` (its captures: the built-in scenes at K = 8 and 16,
and the SCI clips Runner and Drop when ``$FLEXVOX_DATA`` or ``../shared/data`` holds them), on the CPU and on the
GPU: PSNR of each and the difference; and whether a second GPU run gives the same bits.

Figures only, never pass/fail. Usage:
``python bench/bench_gpu.py [--scenes balls,drummer,fan,pan] [--frames 15] [--repeat 3] [--size 640x480] [--no-cpu]
[--no-rows] [--pairs cpu]``
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.methods import Method
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.motion.stages import STAGES
from flexvox_core.reconstruct import diffuse
from flexvox_core.simulate.scenes import render_scene


def gpu_memory_used() -> float:
    """MiB in use on the current GPU, after numba frees what it holds for freeing later (0 under numba-cuda's
    simulator, which has no card to ask)."""
    import gc

    from numba import cuda

    gc.collect()
    ctx = cuda.current_context()
    if not hasattr(ctx, "deallocations"):
        return 0.0
    ctx.deallocations.clear()
    free, total = ctx.get_memory_info()
    return (total - free) / 2**20


def on_gpu(frames, code, pairs: str):
    """``motion_aware(frames, code, device="cuda")`` with the pairs' flow on ``pairs`` (gpu or cpu), and the peak
    of its workspace in bytes per voxel."""
    from flexvox_core.motion.gpu.engine import CudaStages
    from flexvox_core.motion.options import MotionOptions, check_sample_range
    from flexvox_core.motion.stages import Window, run_stages

    f = np.asarray(frames, np.float32)
    window = Window.plan(f, code, MotionOptions(), check_sample_range(f, None, None))
    stages = CudaStages(window, pairs=pairs)
    result = run_stages(stages)
    return result, stages.ws.peak_nbytes / (window.S * f.shape[1] * f.shape[2])


def throughput(scenes, frames: int, repeat: int, cpu: bool, size=(480, 640), pairs: str = "gpu") -> None:
    from flexvox_core.gpu.device import describe_gpus
    from flexvox_core.gpu.diffusion import diffuse_on_gpu

    code = design_code((4, 4)).code
    gpus = describe_gpus()
    print(f"GPU: {gpus[0].line() if gpus else 'none'}")
    H, W = size
    real_time = H * W * 16 * 15 / 1e6
    print(f"{W}x{H}, K = 16, {frames} frames ({frames * 16} sub-frames), median of {repeat} GPU runs after a warm-up; "
          f"real time at 15 Hz: {real_time:.1f} M voxels/s")
    rows = []
    for scene in scenes:
        truth = render_scene(scene, frames * 16, H, W, seed=0)
        f = capture(truth, code)
        t0 = time.perf_counter()
        on_gpu(f, code, pairs)  # compiles (first scene) and warms the allocator
        warm = time.perf_counter() - t0
        runs = []
        held = 0.0
        for _ in range(repeat):
            base = gpu_memory_used()
            t0 = time.perf_counter()
            g, ws_bytes = on_gpu(f, code, pairs)
            runs.append((time.perf_counter() - t0, g))
            held = max(held, gpu_memory_used() - base)  # the run's workspace, alive with its result
        seconds = statistics.median(s for s, _ in runs)
        g = runs[0][1]
        same = all(np.array_equal(g.video, r.video) for _, r in runs[1:])
        row = {"scene": scene, "gpu_s": seconds, "warm_s": warm, "stages": g.stage_seconds, "held_mib": held,
               "ws_bytes": ws_bytes, "estimate": Method("motion-aware").gpu_voxel_bytes(16, H, W),
               "gpu_psnr": psnr(truth, g.video), "same_bits": same, "voxels": truth.size}
        t0 = time.perf_counter()
        nc_gpu = diffuse_on_gpu(f, code, tensor=(0.05, 0.05, 1.0), time=4.0)
        row["nc_gpu_s"] = time.perf_counter() - t0
        if cpu:
            t0 = time.perf_counter()
            c = motion_aware(f, code)
            row["cpu_s"] = time.perf_counter() - t0
            row["cpu_psnr"] = psnr(truth, c.video)
            row["cpu_split"] = c.seconds
            t0 = time.perf_counter()
            nc_cpu = diffuse(f, code, tensor=(0.05, 0.05, 1.0), time=4.0)
            row["nc_cpu_s"] = time.perf_counter() - t0
            row["nc_diff"] = float(np.abs(nc_cpu - nc_gpu).max())
        rows.append(row)
        print(f"  {scene}: GPU {seconds * 1000:.0f} ms ({truth.size / seconds / 1e6:.0f} M voxels/s), warm-up "
              f"{warm:.1f} s" + (f", CPU {row['cpu_s']:.1f} s" if cpu else ""), flush=True)
    print("\n| scene | GPU ms | M voxels/s | × real time | GPU PSNR | CPU s | CPU PSNR | GPU − CPU dB | speed-up "
          "| held GiB | same bits |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        rate = r["voxels"] / r["gpu_s"] / 1e6
        cpu_part = (f"{r['cpu_s']:.2f} | {r['cpu_psnr']:.2f} | {r['gpu_psnr'] - r['cpu_psnr']:+.3f} | "
                    f"{r['cpu_s'] / r['gpu_s']:.0f}x") if "cpu_s" in r else "- | - | - | -"
        print(f"| {r['scene']} | {r['gpu_s'] * 1000:.0f} | {rate:.0f} | {rate / real_time:.1f} | {r['gpu_psnr']:.2f} | "
              f"{cpu_part} | {r['held_mib'] / 1024:.1f} | {r['same_bits']} |")
    print("\nGPU memory per voxel (the window's sub-frames × H × W): the workspace's peak, the card's memory in use "
          "after the run (held GiB above), and the estimate the runner sizes chunks with "
          "(MotionAware.gpu_voxel_bytes):")
    for r in rows:
        card = r["held_mib"] * 2**20 / r["voxels"]
        print(f"  {r['scene']}: workspace {r['ws_bytes']:.1f} B/voxel, card {card:.1f} B/voxel, estimate "
              f"{r['estimate']:.1f} B/voxel" + ("" if r["ws_bytes"] <= r["estimate"] else "  EXCEEDS THE ESTIMATE"))
    print("\nGPU time per stage, ms (the first repeat; each stage synchronised):")
    print("| scene | " + " | ".join(s for s in (*STAGES, "download")) + " |")
    print("|---|" + "---|" * (len(STAGES) + 1))
    for r in rows:
        print(f"| {r['scene']} | " + " | ".join(f"{r['stages'].get(s, 0) * 1000:.1f}" for s in (*STAGES, "download"))
              + " |")
    print("\nfixed-tensor nc (0.05, 0.05, 1), n = 4:")
    for r in rows:
        extra = (f"; CPU {r['nc_cpu_s'] * 1000:.0f} ms, max |GPU − CPU| {r['nc_diff']:.1e}" if "nc_cpu_s" in r else "")
        print(f"  {r['scene']}: GPU {r['nc_gpu_s'] * 1000:.0f} ms (upload and download included){extra}")


def bench_rows() -> None:
    from flexvox_app.accuracy_bench import cases, methods_for
    from flexvox_core.methods import run

    print("\nflexvox bench's motion-aware rows, CPU against GPU (PSNR dB):")
    print("| capture | method | CPU | GPU | GPU − CPU | CPU s | GPU s |")
    print("|---|---|---|---|---|---|---|")
    worst = 0.0
    first = None
    for case in cases(quick=False):
        for family, method in methods_for(case, quick=False):
            if family != "motion-aware":
                continue
            t0 = time.perf_counter()
            c = run(case.frames, case.code, method, chunk_frames=None, device="cpu").video
            tc = time.perf_counter() - t0
            t0 = time.perf_counter()
            g = run(case.frames, case.code, method, chunk_frames=None, device="cuda").video
            tg = time.perf_counter() - t0
            pc, pg = psnr(case.truth, c), psnr(case.truth, g)
            worst = max(worst, abs(pg - pc))
            first = first or (case, method, g)
            print(f"| {case.name} | {method.label()} | {pc:.2f} | {pg:.2f} | {pg - pc:+.3f} | {tc:.2f} | {tg:.2f} |",
                  flush=True)
    case, method, g = first
    again = run(case.frames, case.code, method, chunk_frames=None, device="cuda").video
    print(f"\nlargest |GPU − CPU| over the rows: {worst:.3f} dB; a second GPU run of {case.name}, {method.label()}: "
          f"{'the same bits' if np.array_equal(g, again) else 'DIFFERENT bits'}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="balls,drummer,fan,pan")
    ap.add_argument("--frames", type=int, default=15)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-cpu", action="store_true", help="skip the CPU runs of part 1")
    ap.add_argument("--no-rows", action="store_true", help="skip part 2 (flexvox bench's rows)")
    ap.add_argument("--size", default="640x480", metavar="WxH", help="part 1's picture size (default 640x480)")
    ap.add_argument("--pairs", choices=("gpu", "cpu"), default="gpu",
                    help="part 1: where the flow of image pairs runs (cpu: OpenCV's DIS on the host)")
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.lower().split("x"))
    throughput(args.scenes.split(","), args.frames, args.repeat, not args.no_cpu, (h, w), args.pairs)
    if not args.no_rows:
        bench_rows()


if __name__ == "__main__":
    main()
