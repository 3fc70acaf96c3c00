"""An opened recording as the Review workspace sees it (Qt-free model).

Holds the raw frames (normalised to relative units, for playback), the identity-code capture
the reconstructions take (demultiplexed when the recording is multiplexed, by the one reader,
:class:`flexvox_core.capture_reader.CaptureReader`), its code, and the ground truth of simulated
recordings. A multiplexed recording goes as it was captured to the methods that reconstruct it from
its own forward model (:meth:`ReviewSession.input`), demultiplexed to the others. A recording the
reader refuses opens for playback, with the reader's reason in :attr:`ReviewSession.blocked`.
Dropped frames are in :attr:`ReviewSession.missing`: reconstructions bridge them (:mod:`flexvox_core.gaps`).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flexvox_core.capture_reader import CaptureReader, NotReconstructableError
from flexvox_core.divisions import Division
from flexvox_core.reconstruct.rebin import supported_divisions
from flexvox_core.recording import Recording, RecordingError, open_recording

_logger = logging.getLogger(__name__)


def not_a_recording(path) -> str | None:
    """Why ``path`` is plainly no recording, from the file system alone (no data read); None when it may be one
    (:meth:`ReviewSession.open` checks the rest). Asked before anything is given up for it."""
    p = Path(path)
    if not p.exists():
        return f"{p}: no such recording"
    if not p.is_dir():
        return f"{p}: a file, not a recording (a recording is a .zarr folder)"
    if not (p / "zarr.json").is_file() and not (p / ".zgroup").is_file():
        return f"{p}: not a readable Zarr store (nothing in it says it is one)"
    return None


@dataclass
class ReviewSession:
    """A recording opened for review.

    Attributes
    ----------
    path : Path
    recording : Recording
    raw : ndarray (F, H, W) float32
        The frames as captured, in relative units (what playback shows).
    frames : ndarray (F, H, W) float32 or None
        The identity-code capture reconstructions take; None when it cannot be reconstructed.
    code : ndarray (m, n, K) bool
    blocked : str
        Why the recording cannot be reconstructed ("" when it can).
    missing : ndarray (F,) bool or None
        The frames the camera dropped (zero rows), None when none was.
    reader : CaptureReader or None
        The one reader's view of it (None when it refused the recording): which input each method
        takes is its rule (:meth:`~flexvox_core.capture_reader.CaptureReader.takes_multiplexed`).
    """

    path: Path
    recording: Recording
    raw: np.ndarray
    frames: np.ndarray | None
    code: np.ndarray
    blocked: str = ""
    missing: np.ndarray | None = None
    reader: CaptureReader | None = None

    @classmethod
    def open(cls, path) -> ReviewSession:
        """Open ``path``; :class:`~flexvox_core.recording.RecordingError` says what is wrong."""
        path = Path(path)
        rec = open_recording(path)
        raw = rec.normalised_frames()
        if raw.shape[0] == 0:
            raise RecordingError(f"{path}: the recording holds no frames")
        missing = reader = None
        try:
            reader = CaptureReader(rec)
            frames, code, blocked, missing = reader.read(), reader.code, "", reader.missing
        except NotReconstructableError as exc:
            frames, code, blocked = None, rec.code, str(exc)
        _logger.info("opened %s: %d frames of %dx%d, K=%d", path, *raw.shape, rec.K)
        return cls(path, rec, raw.astype(np.float32, copy=False),
                   None if frames is None else np.asarray(frames, np.float32), np.asarray(code, bool), blocked,
                   missing, reader)

    def input(self, method) -> tuple[np.ndarray | None, np.ndarray]:
        """``method``'s input ``(frames, code)``: the multiplexed frames and their code for a method that
        :meth:`~flexvox_core.methods.method.Method.takes_multiplexed`, else :attr:`frames` and :attr:`code`."""
        if self.reader is not None and self.frames is not None and self.reader.takes_multiplexed(method):
            return self.raw, self.reader.code_for(method)
        return self.frames, self.code

    @property
    def K(self) -> int:  # noqa: N802 - the paper's name
        """Slots per camera frame."""
        return int(self.code.shape[2])

    @property
    def n_frames(self) -> int:
        """Camera frames F."""
        return int(self.raw.shape[0])

    @property
    def n_subframes(self) -> int:
        """Sub-frames S = F·K of a reconstruction."""
        return self.n_frames * self.K

    @property
    def shape(self) -> tuple[int, int]:
        """Frame size (H, W)."""
        return int(self.raw.shape[1]), int(self.raw.shape[2])

    @property
    def has_ground_truth(self) -> bool:
        """Simulated recordings carry the true high-speed video."""
        return self.recording.has_ground_truth

    def truth(self, first_frame: int = 0, stop_frame: int | None = None) -> np.ndarray | None:
        """Ground truth of camera frames ``[first_frame, stop_frame)`` (None without one)."""
        if not self.has_ground_truth:
            return None
        K = self.K
        stop = self.n_frames if stop_frame is None else stop_frame
        return self.recording.ground_truth[first_frame * K:stop * K]

    def divisions(self) -> list[Division]:
        """Divisions the code supports (what re-binning can use)."""
        return supported_divisions(self.code)

    def raw_levels(self) -> tuple[float, float]:
        """Display levels of the raw frames: (low, high) at the 0.5 and 99.5 percentiles."""
        sample = self.raw[:: max(1, self.n_frames // 8)]
        lo, hi = (float(v) for v in np.percentile(sample, [0.5, 99.5]))
        return (lo, hi) if hi > lo else (lo, lo + 1.0)

    def summary(self) -> str:
        """One line: frames, size, tile, K, rate, code kind, ground truth."""
        a = self.recording.attrs
        H, W = self.shape
        m, n = a["tile"]
        rate = a.get("rates", {}).get("camera_hz")
        bits = [f"{self.n_frames} frames of {W}×{H}", f"tile {m}×{n}, K = {self.K}"]
        if rate:
            bits.append(f"{rate:.4g} Hz camera → {rate * self.K:.4g} sub-frames/s")
        bits.append("multiplexed (demultiplexed for reconstruction)" if a.get("multiplexed") else "identity code")
        bits.append("simulated, with ground truth" if self.has_ground_truth else a.get("kind", "captured"))
        if self.missing is not None:
            bits.append(f"{int(self.missing.sum())} dropped frame(s), bridged from both sides")
        return "; ".join(bits)
