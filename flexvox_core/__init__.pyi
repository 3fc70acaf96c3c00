# The public names of flexvox_core, listed once: lazy_loader reads this stub (each name is imported when first asked
# for) and so do type checkers and editors. docs/python.md is the guide to them; tests/test_public_api.py checks
# that each has a docstring and an example.

# Submodules, attributes of the package.
from . import codes, design, divisions, forward, multiplex, tiles
from ._version import __version__

# Codes: design one, or build one from a firing order.
from .codes import (
    code_from_order,
    is_identity_code,
    neighbour_separation,
    order_from_code,
    sequential_order,
    validate_code,
    verify,
)
from .design import DesignResult, design_code
from .divisions import Division, enumerate_divisions, parse_division
from .multiplex import MultiplexedCode, multiplexed_code, s_matrix
from .tiles import MAX_TILE_SIDE, parse_tile, validate_tile

# The forward model and simulation.
from .forward import capture, sample_mask, sparse_volume, tiled_code
from .simulate import EFFECTS, SCENES, SimulationResult, render_scene, simulate_video

# Reconstruction.
from .methods import METHODS, Method, MethodOutput, run
from .video_api import reconstruct_video  # not `reconstruct`: flexvox_core.reconstruct holds the algorithms
from .motion import motion_aware
from .batch import BatchResult, reconstruct_batch

# Scores against a ground truth.
from .metrics import clip_psnr, psnr, psnr_per_frame, ssim, ssim_per_frame

# Accuracy without ground truth: an estimated PSNR from the recording alone.
from .accuracy import AccuracyEstimate, NoiseModel, NotEstimable, estimate_accuracy, estimate_recording
# A knob (diffusion time, division) chosen by the estimate; the module is `choice`, so `fv.choose` stays the function.
from .choice import Choice, choose, choose_recording

# Files: recordings, videos (OME-Zarr, TIFF, MP4, npy).
from .recording import Recording, RecordingError, open_recording, write_simulation
from .capture_reader import open_capture, read_capture
from .video_io import open_video_store, read_video, write_video
