"""Reconstruct only a region and a time window of a recording.

Read only the camera frames of the window (``read_capture(path, start, stop)``), crop a region anywhere in
the frame, and reconstruct that: ``origin=(row, col)`` gives the crop's corner in the camera frame, so the
code's phase follows it, and ``missing=`` the window's dropped frames (a whole recording,
``reconstruct_video(rec)``, brings its own).

    python examples/reconstruct_a_region.py [REC.zarr]
"""

import sys

from _sample import sample_recording

import flexvox_core as fv

path = sys.argv[1] if len(sys.argv) > 1 else sample_recording()
rec = fv.open_recording(path)
F, H, W = rec.shape
start, stop = F // 4, F // 4 + max(2, F // 2)             # camera frames [start, stop)
y0, x0 = H // 4 + 1, W // 4 + 1                           # the region's corner: anywhere, on the tile grid or not
y1, x1 = y0 + H // 2, x0 + W // 2

frames, code = fv.read_capture(path, start, stop)
part = fv.reconstruct_video(frames[:, y0:y1, x0:x1], code, origin=(y0, x0),
                            missing=rec.dropped[start:stop])    # (sub-frames, y1 - y0, x1 - x0)
print(f"frames {start}..{stop - 1}, rows {y0}..{y1 - 1}, columns {x0}..{x1 - 1}: {part.shape}")
if rec.has_ground_truth:
    truth = rec.ground_truth[start * rec.K: stop * rec.K][:, y0:y1, x0:x1]
    print(f"PSNR {fv.psnr(truth, part):.2f} dB against the ground truth")
