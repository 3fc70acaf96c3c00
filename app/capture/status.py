"""Where a capture stands and how it ended: its state, a snapshot of its counters, its result."""

from __future__ import annotations

import enum
from dataclasses import dataclass
from pathlib import Path

from flexvox_core.reprs import html_table


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

    def __repr__(self) -> str:
        return (f"<CaptureStats {self.state}: {self.rows_written} rows written ({self.drops} dropped, "
                f"{self.queue_drops} by the queue), {self.frames_received} frames received, camera "
                f"{self.camera_rate_hz:.1f} Hz, writing {self.write_rate_hz:.1f} Hz, {self.elapsed_s:.1f} s>")

    def _repr_html_(self) -> str:
        return html_table("CaptureStats", [
            ("state", self.state + (f" ({self.finishing})" if self.finishing else "")),
            ("frames received", self.frames_received), ("rows written", self.rows_written),
            ("dropped", f"{self.drops} ({self.queue_drops} by the queue)"),
            ("queue", f"{self.queue_depth} of {self.queue_capacity} (most {self.max_queue_depth})"),
            ("camera rate", f"{self.camera_rate_hz:.2f} Hz"), ("write rate", f"{self.write_rate_hz:.2f} Hz"),
            ("writer capacity", f"{self.writer_capacity_hz:.2f} Hz"), ("elapsed", f"{self.elapsed_s:.2f} s")])


@dataclass(frozen=True)
class CaptureResult:
    """How a capture ended.

    ``reason`` is ``done`` (N frames), ``stopped`` (:meth:`CaptureService.stop`) or
    ``error``; ``frames_in_recording`` is read back from the recording on disk (None when
    it cannot be opened), ``message`` says it all in one line. ``warnings`` are
    :attr:`CaptureService.warnings`: what the recording was made with that is worth reading (a
    phase that is a guess at this timing, no calibration); the recording's attributes hold them too.
    """

    path: Path
    reason: str
    message: str
    frames_in_recording: int | None
    stats: CaptureStats
    error: str | None = None
    warnings: tuple[str, ...] = ()

    def __repr__(self) -> str:
        return f"<CaptureResult {self.reason}: {self.message}>"

    @property
    def ok(self) -> bool:
        """True unless the capture ended on an error."""
        return self.reason != "error"
