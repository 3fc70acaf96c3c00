"""Batch-reconstruction memory: peak RSS for recordings 10x apart in length, same chunk size.

Each run is a fresh subprocess (``flexvox_core.batch.reconstruct_batch`` on dask's local
threads); its peak RSS comes from ``resource.getrusage(RUSAGE_CHILDREN).ru_maxrss`` in the
parent. For contrast, the in-memory ``reconstruct_video`` of the short recording is measured too
(it holds the whole (F*K, H, W) video). The recordings are synthetic (a looping coded
capture of random video), written frame by frame. Each child reports its own peak
(``RUSAGE_SELF``), so the rows do not depend on their order.

    python bench/bench_batch_memory.py [--frames 60] [--factor 10] [--size 120x160] [--chunk 16]
                                       [--method diffusion|motion-aware|...]

What nc's peak holds, and how it moved when nc's time blur was compiled: docs/benchmarks.md, "Figures behind the
code".
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from flexvox_core.design import design_code  # noqa: E402
from flexvox_core.forward import capture  # noqa: E402
from flexvox_core.recording import RecordingWriter, recording_attrs  # noqa: E402

CHILD = """
import json, sys, time
sys.path.insert(0, {root!r})
import resource
from flexvox_core.methods import Method
mode, rec, out, chunk, method = sys.argv[1], sys.argv[2], sys.argv[3], int(sys.argv[4]), sys.argv[5]
t = time.perf_counter()
if mode == "batch":
    from flexvox_core.batch import reconstruct_batch
    reconstruct_batch(rec, out, Method(method), chunk_frames=chunk)
else:
    from flexvox_core.capture_reader import read_capture
    from flexvox_core.video_api import reconstruct_video as reconstruct
    frames, code = read_capture(rec)
    video = reconstruct(frames, code, Method(method), chunk_frames=chunk)
print(json.dumps({{"seconds": time.perf_counter() - t,
                  "peak_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}}))
"""


def make_recording(path: Path, frames: int, H: int, W: int, code) -> None:
    K = code.shape[2]
    rng = np.random.default_rng(5)
    loop = capture(rng.random((4 * K, H, W)).astype(np.float32), code)  # 4 frames, repeated
    attrs = recording_attrs(code, rate_hz=15.0, kind="captured", storage={"kind": "float"})
    with RecordingWriter(path, height=H, width=W, dtype="float32", attrs=attrs) as w:
        for f in range(frames):
            w.append(loop[f % 4], frame_id=f, timestamp=f / 15)


def peak_rss_mib(mode: str, rec: Path, out: Path, chunk: int, method: str) -> tuple[float, float]:
    """The child's own peak RSS (MiB) and its seconds of reconstruction."""
    proc = subprocess.run([sys.executable, "-c", CHILD.format(root=str(ROOT)), mode, str(rec), str(out), str(chunk),
                           method], capture_output=True, text=True, timeout=1800, check=True)
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    return report["peak_mib"], report["seconds"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--factor", type=int, default=10)
    ap.add_argument("--size", default="120x160")
    ap.add_argument("--chunk", type=int, default=16)
    ap.add_argument("--method", default="diffusion", help="the method reconstructed with (default: diffusion, nc)")
    args = ap.parse_args()
    H, W = (int(v) for v in args.size.split("x"))
    code = design_code((4, 4)).code
    K = code.shape[2]
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        rows = []
        short, long_ = args.frames, args.frames * args.factor
        for F in (short, long_):
            make_recording(tmp / f"r{F}.zarr", F, H, W, code)
        for mode, F in (("batch", short), ("batch", long_), ("in-memory", short)):
            rss, secs = peak_rss_mib(mode, tmp / f"r{F}.zarr", tmp / f"o-{mode}-{F}.zarr", args.chunk, args.method)
            video_mib = F * K * H * W * 4 / 2**20
            rows.append((mode, F, rss, secs, video_mib))
        print(f"{H}x{W}, K = {K}, chunk {args.chunk} frames ({args.chunk * K * H * W * 4 / 2**20:.0f} MiB of output "
              f"per chunk), {args.method} at its defaults")
        print(f"{'mode':<10} {'frames':>7} {'video MiB':>10} {'peak RSS MiB':>13} {'seconds':>8}")
        for mode, F, rss, secs, vm in rows:
            print(f"{mode:<10} {F:>7} {vm:>10.0f} {rss:>13.0f} {secs:>8.1f}")
        (_, _, first, _, _), (_, _, second, _, _), (_, _, whole, _, _) = rows
        print(f"batch peak, {args.factor}x the frames: {second / first:.2f}x; in-memory / batch at {short} frames: "
              f"{whole / first:.2f}x")


if __name__ == "__main__":
    main()
