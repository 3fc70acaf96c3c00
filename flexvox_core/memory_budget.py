"""Refusing work that would not fit in memory, before anything is allocated.

Without a check, a request for a 100000×100000 simulation would start allocating 37 GiB and die in the middle.
Each entry point that allocates in proportion to its request estimates what it will need
(:func:`simulation_bytes`, :func:`reconstruction_bytes`, :func:`render_bytes`, :func:`video_load_bytes`,
:func:`shutter_pattern_bytes`) and calls
:func:`check_fits`, which compares it with the memory available now and refuses with the GiB it
would need and what to do instead. The estimates are deliberately rough (the arrays a job holds
at its peak, times its working copies); they catch requests that are off by orders of magnitude,
not a few percent.
"""

from __future__ import annotations

import logging
import os

_logger = logging.getLogger(__name__)

GIB = 1024 ** 3
FLOAT = 4
"""Bytes per float32 sample."""


class MemoryBudgetError(ValueError):
    """The request would not fit in memory; the message gives the GiB it needs and what is available."""


def available_bytes() -> int | None:
    """Memory available to a new allocation now (Linux ``MemAvailable``; else free physical pages), or None."""
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (AttributeError, ValueError, OSError):
        return None


def check_fits(needed: float, what: str, advice: str) -> None:
    """Raise :class:`MemoryBudgetError` when ``needed`` bytes exceed what is available now.

    ``what`` names the request ("--size 100000x100000 with 16 frames of K = 16"), ``advice``
    what to do instead. Does nothing when the available memory cannot be read.
    """
    avail = available_bytes()
    _logger.debug("%s: needs about %.2f GiB; %s available", what, needed / GIB,
                  "unknown" if avail is None else f"{avail / GIB:.2f} GiB")
    if avail is not None and needed > avail:
        raise MemoryBudgetError(f"{what} needs about {_amount(needed)} of memory; this machine has "
                                f"{_amount(avail)} available: {advice}")


def _amount(nbytes: float) -> str:
    """Bytes in GiB with one decimal (MiB below 0.1 GiB, where that would read 0.0)."""
    return f"{nbytes / GIB:.1f} GiB" if nbytes >= 0.1 * GIB else f"{nbytes / 1024 ** 2:.0f} MiB"


def render_bytes(subframes: int, height: int, width: int) -> float:
    """A rendered scene: the video and one working copy."""
    return 2.0 * subframes * height * width * FLOAT


def video_load_bytes(stored_bytes: int, pixels: int, colour: bool) -> float:
    """Reading a video file as float32: its samples as stored, the float32 video, and (colour) the RGB
    float32 copy luminance is computed from (measured: 1.25 to 1.5 float videos grey, 4.75 colour)."""
    return stored_bytes + (4.0 if colour else 1.25) * pixels * FLOAT


def shutter_pattern_bytes(K: int, projector_size: tuple[int, int], camera_size: tuple[int, int]) -> float:
    """Shutter patterns for a projector: per projector pixel its mapped coordinates (about 50 bytes) and two
    copies of its K slots, plus the code tiled over the camera (measured: 49 + 2K bytes per projector pixel)."""
    return (56.0 + 2.0 * K) * projector_size[0] * projector_size[1] + float(K) * camera_size[0] * camera_size[1]


def simulation_bytes(frames: int, K: int, height: int, width: int) -> float:
    """A simulation: the high-speed video (kept as ground truth), its working copies for the effects, and
    the coded frames."""
    video = frames * K * height * width * FLOAT
    return 3.0 * video + 2.0 * frames * height * width * FLOAT


def reconstruction_bytes(frames: int, K: int, height: int, width: int, chunk_frames: int | None,
                         overlap: int | None) -> float:
    """An in-memory reconstruction: the output video, plus a chunk's working set (with its overlap)."""
    out = frames * K * height * width * FLOAT
    chunk = frames if chunk_frames is None or overlap is None else min(frames, chunk_frames + 2 * overlap)
    return out + 6.0 * chunk * K * height * width * FLOAT
