"""The one reader from a recording to reconstruction input.

A recording's raw frames become what every reconstruction takes, an identity-code capture
``(F, H, W)`` float32 and its code ``(m, n, K)``, in three steps, all here:

1. **validation** — the recording opens (:func:`~flexvox_core.recording.open_recording`); its
   frame ids increase by one from row to row (a repeated, backward or skipped id is refused,
   naming the row). Dropped frames keep their (zero) rows: :attr:`CaptureReader.missing` says
   which, and every reconstruction bridges them or refuses a gap longer than its reach
   (:mod:`flexvox_core.gaps`); a recording whose frames were all dropped is refused. Every frame is checked
   against its checksum as it is read (:class:`~flexvox_core.recording.VerifiedRows`): a missing or
   damaged chunk raises :class:`~flexvox_core.recording.DamagedRecordingError`, never zeros;
2. **normalisation** — counts to relative units with the recording's ``storage`` attributes
   (:func:`flexvox_core.simulate.simulator.normalise_frames`);
3. **demultiplexing** — an S-matrix recording (attributes ``multiplexed``, ``tile``,
   ``placement_order``) is demultiplexed into the identity capture of its placement
   (:func:`flexvox_core.reconstruct.as_identity_capture`), *unless* the method reconstructs multiplexed
   captures from their own forward model
   (:meth:`Method.takes_multiplexed <flexvox_core.methods.method.Method.takes_multiplexed>`): then
   :meth:`CaptureReader.input` hands it the normalised multiplexed frames and the S-matrix code
   (:meth:`~CaptureReader.code_for`, :meth:`~CaptureReader.preparation_for` for the lazy batch).
   Per-tile demultiplexing, which assumes the scene constant over a tile, is the fallback.

:class:`CaptureReader` serves the in-memory callers (:meth:`~CaptureReader.read`: the whole
recording or a window of camera frames ``[start, stop)``) and the lazy chunked batch
(:attr:`~CaptureReader.raw` and :attr:`~CaptureReader.preparation`, which normalises and
demultiplexes one chunk of raw rows; :meth:`~CaptureReader.sample_range` reads the whole
recording's range a chunk at a time). :func:`read_capture` is the one-call form.
"""

from __future__ import annotations

import logging
import warnings
from dataclasses import dataclass
from numbers import Integral

import numpy as np

from flexvox_core.codes import code_from_order
from flexvox_core.gaps import captured, find_gaps
from flexvox_core.multiplex import MultiplexedCode, multiplexed_code
from flexvox_core.recording import Recording, RecordingError, open_recording
from flexvox_core.reprs import short_repr

_logger = logging.getLogger(__name__)


class NotReconstructableError(RecordingError):
    """A recording that opens but cannot be reconstructed; the message says why."""


@dataclass(frozen=True, eq=False)
class Preparation:
    """How raw rows become reconstruction input (small and picklable: dask workers carry it).

    Attributes
    ----------
    storage : dict
        The recording's ``storage`` attributes (float, or counts with gain and black level).
    multiplexed : MultiplexedCode or None
        The S-matrix code of a multiplexed recording.
    """

    storage: dict
    multiplexed: MultiplexedCode | None = None

    def normalise(self, raw) -> np.ndarray:
        """Raw rows ``(n, H, W)`` as float32 relative units."""
        from flexvox_core.simulate.simulator import normalise_frames

        return normalise_frames(np.asarray(raw), self.storage)

    def demultiplex(self, frames) -> np.ndarray:
        """Normalised rows ``(n, H, W)`` as an identity-code capture (unchanged for an identity code)."""
        if self.multiplexed is None:
            return frames
        from flexvox_core.reconstruct import as_identity_capture

        return as_identity_capture(frames, self.multiplexed)[0]

    def __call__(self, raw) -> np.ndarray:
        """Raw rows ``(n, H, W)`` normalised and demultiplexed: ``(n, H, W)`` float32."""
        return self.demultiplex(self.normalise(raw))

    def without_demultiplexing(self) -> Preparation:
        """The same normalisation, the multiplexed frames kept as they are."""
        return Preparation(self.storage)


class CaptureReader:
    """A validated recording read as reconstruction input.

    Parameters
    ----------
    recording : Recording
        An opened recording (:func:`open_capture` opens a path).

    Attributes
    ----------
    recording : Recording
    code : ndarray (m, n, K) bool
        The identity code reconstructions take (a multiplexed recording's placement).
    preparation : Preparation
        Normalisation and demultiplexing of raw rows.

    Raises
    ------
    NotReconstructableError
        Frame ids that do not increase by one, every frame dropped, or multiplexing attributes
        that name no S-matrix code.
    """

    def __init__(self, recording: Recording):
        self.recording = recording
        ids = recording.per_frame("frame_id")
        steps = np.diff(ids)
        if np.any(steps != 1):
            k = int(np.flatnonzero(steps != 1)[0])
            how = "do not increase" if steps[k] < 1 else f"skip {int(steps[k]) - 1} id(s) without a dropped row"
            raise NotReconstructableError(f"{recording.path}: frame ids {how} at row {k + 1} ({ids[k]} then "
                                          f"{ids[k + 1]}); frames must be in capture order, one id apart, to be "
                                          "reconstructed (`flexvox info` lists the problems)")
        dropped = np.asarray(recording.per_frame("dropped"), bool)
        if len(dropped) and dropped.all():
            raise NotReconstructableError(f"{recording.path}: all {len(dropped)} frames were dropped; there is "
                                          "nothing to reconstruct")
        self.missing = dropped if dropped.any() else None
        """Bool (F,): the frames the camera dropped (zero rows), or None when none was."""
        attrs = recording.attrs
        multiplexed = None
        if attrs.get("multiplexed"):
            try:
                multiplexed = multiplexed_code(tuple(attrs["tile"]), placement=attrs.get("placement_order"))
            except (KeyError, TypeError, ValueError) as exc:
                raise NotReconstructableError(f"{recording.path}: a multiplexed recording whose code cannot be "
                                              f"rebuilt from its `tile` and `placement_order` attributes ({exc})"
                                              ) from None
            self.code = code_from_order(multiplexed.placement)
        else:
            self.code = recording.code
        self.preparation = Preparation(attrs["storage"], multiplexed)
        _logger.debug("%s: %d frames, K=%d%s", recording.path, self.n_frames, self.K,
                      ", multiplexed" if multiplexed is not None else "")

    def __repr__(self) -> str:
        H, W = self.shape
        missing = 0 if self.missing is None else int(np.count_nonzero(self.missing))
        m, n = self.code.shape[:2]
        return short_repr(f"CaptureReader {self.recording.path.name}:", [
            f"{self.n_frames} frames of {H}x{W}", f"tile {m}x{n} (K = {self.K})", f"{missing} missing",
            "multiplexed" if self.multiplexed is not None else ""])

    @property
    def n_frames(self) -> int:
        """Camera frames F."""
        return int(self.recording.frames.shape[0])

    @property
    def K(self) -> int:  # noqa: N802 - the paper's name
        """Slots per camera frame."""
        return int(self.code.shape[2])

    @property
    def shape(self) -> tuple[int, int]:
        """Frame size (H, W)."""
        return tuple(int(v) for v in self.recording.frames.shape[1:])

    @property
    def raw(self):
        """The stored frames, exactly :attr:`n_frames` rows, read lazily and checked against their
        checksums (:class:`~flexvox_core.recording.VerifiedRows`), for lazy readers such as dask."""
        return self.recording.frames

    def read(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Camera frames ``[start, stop)`` as reconstruction input.

        Parameters
        ----------
        start, stop : int
            A window of camera frames, ``0 <= start <= stop <= F`` (stop None: F).

        Returns
        -------
        ndarray (stop - start, H, W) float32
            Normalised and demultiplexed.
        """
        return self.preparation.demultiplex(self._normalised(start, stop))

    def _normalised(self, start: int, stop: int | None) -> np.ndarray:
        F = self.n_frames
        stop = F if stop is None else stop
        for name, v in (("start", start), ("stop", stop)):
            if isinstance(v, bool) or not isinstance(v, Integral):
                raise ValueError(f"`{name}` must be a whole number; got {v!r}")
        if not 0 <= start <= stop <= F:
            raise ValueError(f"the window [start, stop) must lie in the recording's {F} frames "
                             f"(0 <= start <= stop <= {F}); got [{start}, {stop})")
        return self.recording.normalised_frames(int(start), int(stop))

    @property
    def multiplexed(self) -> MultiplexedCode | None:
        """The S-matrix code of a multiplexed recording (None: an identity code)."""
        return self.preparation.multiplexed

    def takes_multiplexed(self, method) -> bool:
        """True when ``method`` gets this recording's multiplexed frames as they are (a multiplexed
        recording and a method that :meth:`~flexvox_core.methods.method.Method.takes_multiplexed`)."""
        return self.multiplexed is not None and method.takes_multiplexed()

    def takes_raw(self, method) -> bool:
        """Deprecated name of :meth:`takes_multiplexed` (removed in the next release)."""
        warnings.warn("CaptureReader.takes_raw is deprecated and will be removed in the next release: call "
                      "CaptureReader.takes_multiplexed(method)", DeprecationWarning, stacklevel=2)
        return self.takes_multiplexed(method)

    def code_for(self, method) -> np.ndarray:
        """The code ``method``'s input is captured with: the S-matrix code (m, n, K) when it
        :meth:`takes_multiplexed`, else :attr:`code`."""
        return self.multiplexed.code if self.takes_multiplexed(method) else self.code

    def preparation_for(self, method) -> Preparation:
        """How raw rows become ``method``'s input (no demultiplexing when it :meth:`takes_multiplexed`)."""
        return self.preparation.without_demultiplexing() if self.takes_multiplexed(method) else self.preparation

    def input(self, method, start: int = 0, stop: int | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``method``'s input for camera frames ``[start, stop)``: ``(frames, code)``.

        The normalised multiplexed frames and the S-matrix code for a method that reconstructs them from
        their own forward model; otherwise :meth:`read` (demultiplexed per tile) and :attr:`code`.
        """
        return self.preparation_for(method).demultiplex(self._normalised(start, stop)), self.code_for(method)

    def run(self, method, *, chunk_frames: int | None = 16, progress=None, extras: bool = False,
            device: str = "cpu"):
        """Reconstruct the whole recording with ``method``: its :meth:`input` and its dropped frames
        (:attr:`missing`) through the one runner (:func:`flexvox_core.methods.runner.run`). Every front
        end that reconstructs a recording in memory calls this, so none forgets the dropped frames."""
        from flexvox_core.methods import run

        frames, code = self.input(method)
        return run(frames, code, method, chunk_frames=chunk_frames, progress=progress, extras=extras,
                   missing=self.missing, device=device)

    def gaps(self) -> list:
        """The runs of dropped frames (:class:`~flexvox_core.gaps.Gap`), in order."""
        return [] if self.missing is None else find_gaps(self.missing)

    def sample_range(self, chunk_frames: int = 32, method=None) -> tuple[float, float]:
        """Smallest and largest sample of the whole input (dropped frames' zero rows left out),
        read ``chunk_frames`` frames at a time: ``method``'s input (:meth:`input`; the multiplexed
        frames for a method that takes them), or the demultiplexed capture when None."""
        if isinstance(chunk_frames, bool) or not isinstance(chunk_frames, Integral) or chunk_frames < 1:
            raise ValueError(f"`chunk_frames` must be a whole number >= 1; got {chunk_frames!r}")
        F, raw = self.n_frames, self.raw
        prep = self.preparation if method is None else self.preparation_for(method)
        lo, hi = np.inf, -np.inf
        for start in range(0, F, chunk_frames):
            stop = min(F, start + chunk_frames)
            frames = prep(raw[start:stop])
            frames = captured(frames, None if self.missing is None else self.missing[start:stop])
            if not len(frames):
                continue
            lo, hi = min(lo, float(frames.min())), max(hi, float(frames.max()))
        return lo, hi


def open_capture(recording) -> CaptureReader:
    """A :class:`CaptureReader` of ``recording`` (a path, or an opened :class:`Recording`).

    Raises
    ------
    RecordingError
        The recording cannot be opened (its message says why).
    NotReconstructableError
        It opens but cannot be reconstructed (every frame dropped; a broken multiplexed code).
    """
    rec = recording if isinstance(recording, Recording) else open_recording(recording)
    return CaptureReader(rec)


def read_capture(recording, start: int = 0, stop: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Reconstruction input of a recording in one call: ``(frames, code)``.

    Parameters
    ----------
    recording : str, Path or Recording
    start, stop : int
        Camera frames ``[start, stop)`` (default: all).

    Returns
    -------
    frames : ndarray (stop - start, H, W) float32
        Normalised, demultiplexed identity-code capture.
    code : ndarray (m, n, K) bool
        Its identity code.

    Raises
    ------
    RecordingError
        Cannot be opened; :class:`NotReconstructableError` (a RecordingError): cannot be reconstructed.
    ValueError
        A window outside the recording.
    """
    reader = open_capture(recording)
    return reader.read(start, stop), reader.code
