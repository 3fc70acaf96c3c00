"""Compare the reconstruction methods on my recording.

Every built-in method (``fv.METHODS``) on one recording: PSNR and SSIM against its ground truth (a
simulated recording) and the time each took.

    python examples/compare_methods.py [REC.zarr]
"""

import sys
import time

from _sample import sample_recording

import flexvox_core as fv

path = sys.argv[1] if len(sys.argv) > 1 else sample_recording()
rec = fv.open_recording(path)
truth = rec.ground_truth[:] if rec.has_ground_truth else None
print(rec)
for name in fv.METHODS:
    t0 = time.perf_counter()
    video = fv.reconstruct_video(rec, name)                # the recording's code and dropped frames come with it
    seconds = time.perf_counter() - t0
    score = "" if truth is None else f"PSNR {fv.psnr(truth, video):6.2f} dB  SSIM {fv.ssim(truth, video):.3f}  "
    print(f"{name:13s} {score}{seconds:6.2f} s")
