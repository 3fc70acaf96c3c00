"""What ``flexvox capture --durable`` costs: write rate with and without flushing every frame.

Writes the same camera frames (uint16 counts, as a real camera delivers them) through
:class:`~flexvox_core.recording.RecordingWriter` twice per round — the default (the OS flushes
its page cache when it likes: a killed process loses nothing, a power cut may lose the last
seconds) and ``fsync=True`` (every frame's chunk, its folders and its journal record reach the
disk before the next frame: a power cut loses at most the frame in flight) — alternating the
order over several rounds, in one folder on the disk under test. Prints frames per second and
MB/s of each and their ratio, and how the durable rate compares with the camera rates a capture
needs. Nothing passes or fails on time.

    .venv/bin/python bench/bench_durable.py [--frames 150] [--size 480x640] [--rounds 3] [--dir DIR]

``--dir`` picks the disk (default: a temporary folder under the current directory, i.e. the
disk the checkout is on, not a RAM-backed /tmp).
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from flexvox_core.design import design_code  # noqa: E402
from flexvox_core.recording import RecordingWriter, open_recording, recording_attrs  # noqa: E402


def write(path: Path, frames: np.ndarray, durable: bool) -> float:
    """Seconds to write ``frames`` as a capture does (append, then close)."""
    attrs = recording_attrs(design_code((4, 4)).code, rate_hz=15.0, kind="captured",
                            storage={"kind": "counts", "black_level": 0, "gain": 1.0, "electrons_per_unit": 65535.0})
    t0 = time.perf_counter()
    w = RecordingWriter(path, height=frames.shape[1], width=frames.shape[2], dtype="uint16", attrs=attrs,
                        fsync=durable)
    for i, f in enumerate(frames):
        w.append(f, frame_id=i, timestamp=i / 15)
    w.close()
    seconds = time.perf_counter() - t0
    assert open_recording(path).verify() == []
    shutil.rmtree(path)
    return seconds


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=150)
    ap.add_argument("--size", default="480x640", help="HxW (default 480x640)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--dir", type=Path, default=Path.cwd())
    args = ap.parse_args()
    H, W = (int(v) for v in args.size.split("x"))
    rng = np.random.default_rng(0)
    # Camera-like content (noise on a smooth picture) so the chunks compress as real ones do.
    yy, xx = np.mgrid[0:H, 0:W]
    base = 20000 + 15000 * np.sin(xx / 37.0) * np.cos(yy / 23.0)
    frames = np.clip(base[None] + rng.normal(0, 300, (args.frames, H, W)), 0, 65535).astype(np.uint16)
    mb = frames[0].nbytes / 1e6
    times = {False: [], True: []}
    with tempfile.TemporaryDirectory(dir=args.dir, prefix=".bench-durable-") as tmp:
        for r in range(args.rounds):
            for durable in ((False, True) if r % 2 == 0 else (True, False)):
                times[durable].append(write(Path(tmp) / f"r{r}-{int(durable)}.zarr", frames, durable))
    print(f"{args.frames} frames of {H}x{W} uint16 ({mb:.2f} MB each), {args.rounds} rounds, in {args.dir}")
    rate = {}
    for durable, label in ((False, "default (page cache)"), (True, "--durable (fsync per frame)")):
        med = statistics.median(times[durable])
        rate[durable] = args.frames / med
        print(f"  {label:<28} {rate[durable]:7.1f} frames/s  {rate[durable] * mb:7.1f} MB/s   "
              f"(median of {', '.join(f'{t:.2f}' for t in times[durable])} s)")
    print(f"  durable / default: {rate[True] / rate[False]:.2f}x the write rate "
          f"({1e3 / rate[True] - 1e3 / rate[False]:+.1f} ms per frame)")
    for hz in (15, 30, 60):
        verdict = "keeps up" if rate[True] >= hz else "does NOT keep up"
        print(f"  a {hz} Hz camera at {H}x{W}: --durable {verdict} ({rate[True] / hz:.1f}x headroom)")


if __name__ == "__main__":
    main()
