"""Where a capture stands and how it ended: its state, a snapshot of its counters, its result."""

from __future__ import annotations

import enum
from dataclasses import dataclass
from pathlib import Path


class CaptureState(enum.Enum):
    """Where a capture is."""

    IDLE = "idle"
    RUNNING = "running"
    STOPPING = "stopping"
    DONE = "done"


@dataclass(frozen=True)
class CaptureStats:
    """A snapshot of the counters.

    Attributes
    ----------
    frames_received : int
        Frames the camera delivered.
    rows_written : int
        Rows in the recording (frames + dropped rows).
    drops : int
        Rows flagged dropped (camera gaps and queue discards).
    queue_drops : int
        Frames discarded because the queue stayed full for ``block_s``.
    queue_depth, queue_capacity, max_queue_depth : int
    write_rate_hz : float
        Rows written per second since the first frame arrived.
    camera_rate_hz : float
        The camera's frame rate, measured on its own clock (frame ids over timestamps; by arrival when it gives no
        advancing timestamps).
    writer_capacity_hz : float
        Rows per second of time spent writing: what the disk path could sustain.
    elapsed_s : float
    state : str
    finishing : str
        While the recording is finalised after its last frame, what is being written ("writing the ground truth:
        frame 120 of 300", "closing the recording"); "" otherwise.
    """

    frames_received: int = 0
    rows_written: int = 0
    drops: int = 0
    queue_drops: int = 0
    queue_depth: int = 0
    queue_capacity: int = 0
    max_queue_depth: int = 0
    write_rate_hz: float = 0.0
    camera_rate_hz: float = 0.0
    writer_capacity_hz: float = 0.0
    elapsed_s: float = 0.0
    state: str = CaptureState.IDLE.value
    finishing: str = ""


@dataclass(frozen=True)
class CaptureResult:
    """How a capture ended.

    ``reason`` is ``done`` (N frames), ``stopped`` (:meth:`CaptureService.stop`) or
    ``error``; ``frames_in_recording`` is read back from the recording on disk (None when
    it cannot be opened), ``message`` says it all in one line.
    """

    path: Path
    reason: str
    message: str
    frames_in_recording: int | None
    stats: CaptureStats
    error: str | None = None

    @property
    def ok(self) -> bool:
        """True unless the capture ended on an error."""
        return self.reason != "error"
