"""Batch-reconstruct a folder of recordings.

Every ``*.zarr`` recording in a folder, reconstructed chunk by chunk with dask into ``OUT/NAME.zarr``
(OME-Zarr); one that cannot be reconstructed is reported and skipped. Give ``--scheduler
tcp://HOST:8786`` to run the chunks on a dask cluster.

    python examples/batch_a_folder.py [FOLDER] [OUT] [--scheduler ADDRESS]
"""

import argparse
from pathlib import Path

from _sample import sample_recording

import flexvox_core as fv

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("folder", nargs="?", type=Path)
parser.add_argument("out", nargs="?", type=Path, default=Path("batch-out"))
parser.add_argument("--scheduler", help="a dask.distributed scheduler's address (default: local threads)")
args = parser.parse_args()
if args.folder is None:                                   # no folder: two simulated recordings
    args.folder = Path("recordings")
    args.folder.mkdir(exist_ok=True)
    for seed, scene in enumerate(("balls", "drummer")):
        sample_recording(args.folder / f"{scene}.zarr", scene=scene, seed=seed)
args.out.mkdir(exist_ok=True)
for path in sorted(args.folder.glob("*.zarr")):
    try:
        result = fv.reconstruct_batch(path, args.out / path.name, fv.Method("diffusion"), chunk_frames=8,
                                      scheduler=args.scheduler, overwrite=True)
    except ValueError as exc:
        print(f"{path.name}: skipped ({exc})")
        continue
    print(f"{path.name} -> {result.path}: {result.shape}, {result.seconds:.2f} s on {result.scheduler}")
