"""What SIGKILL leaves of a :class:`~flexvox_core.recording.RecordingWriter`, inside one test process."""

import os


def kill(writer) -> None:
    """Leave the writer's files exactly as they are and release its lock, as the OS does for a killed process."""
    if writer._fd is not None:
        os.close(writer._fd)
        writer._fd = None
    writer._lock.release()
