"""Export a reconstruction for Fiji (ImageJ).

A ``.tif`` stack, one float32 page per sub-frame, whose ImageJ metadata carries the frame interval in
seconds: Fiji's time axis (Image > Properties) then reads real time.

    python examples/export_for_fiji.py [REC.zarr] [OUT.tif]
"""

import sys

import tifffile
from _sample import sample_recording

import flexvox_core as fv

path = sys.argv[1] if len(sys.argv) > 1 else sample_recording()
out = sys.argv[2] if len(sys.argv) > 2 else "video.tif"
rec = fv.open_recording(path)
video = fv.reconstruct_video(rec)                         # its code and dropped frames come with it
step = 1 / (rec.camera_hz * rec.K)                        # seconds between sub-frames
fv.write_video(out, video, time_step=step, overwrite=True)
with tifffile.TiffFile(out) as tif:
    print(f"{out}: {len(tif.pages)} pages, frame interval {tif.imagej_metadata['finterval']:.6f} s")
