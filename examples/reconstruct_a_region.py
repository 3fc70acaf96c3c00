"""Reconstruct only a region and a time window of a recording.

Read only the camera frames of the window (``read_capture(path, start, stop)``), crop a region whose
corner sits on the code's tile grid (so the code still applies as it is), reconstruct that.

    python examples/reconstruct_a_region.py [REC.zarr]
"""

import sys

from _sample import sample_recording

import flexvox_core as fv

path = sys.argv[1] if len(sys.argv) > 1 else sample_recording()
rec = fv.open_recording(path)
m, n = rec.tile
F, H, W = rec.shape
start, stop = F // 4, F // 4 + max(2, F // 2)             # camera frames [start, stop)
y0, x0 = (H // 4) // m * m, (W // 4) // n * n             # the region's corner, on the tile grid
y1, x1 = y0 + H // 2, x0 + W // 2

frames, code = fv.read_capture(path, start, stop)
part = fv.reconstruct_video(frames[:, y0:y1, x0:x1], code)     # (sub-frames, y1 - y0, x1 - x0)
print(f"frames {start}..{stop - 1}, rows {y0}..{y1 - 1}, columns {x0}..{x1 - 1}: {part.shape}")
if rec.has_ground_truth:
    truth = rec.ground_truth[start * rec.K: stop * rec.K][:, y0:y1, x0:x1]
    print(f"PSNR {fv.psnr(truth, part):.2f} dB against the ground truth")
