"""Crash safety: a capture process killed with SIGKILL leaves a recording that opens and holds
every frame it had committed."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import zarr

from flexvox_core.recording import RecordingError, open_recording, recover_recording

ROOT = Path(__file__).resolve().parents[3]


def _frames_now(path) -> int:
    try:
        return open_recording(path).n_frames
    except RecordingError:
        return 0  # not created yet


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs SIGKILL (POSIX)")
def test_sigkill_mid_capture_leaves_every_committed_frame(tmp_path):
    path = tmp_path / "killed.zarr"
    proc = subprocess.Popen(
        [sys.executable, "-m", "flexvox_app.cli.capture", "--frames", "100000", "-o", str(path), "--size", "24x32",
         "--tile", "2x2", "--rate", "100", "--scene", "balls"],
        cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        seen = 0
        deadline = time.monotonic() + 40
        while seen < 40 and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.05)
            seen = _frames_now(path)
        assert proc.poll() is None, proc.stderr.read().decode()
        assert seen >= 40, f"the capture wrote only {seen} frames in 40 s"
        os.kill(proc.pid, signal.SIGKILL)
        assert proc.wait(timeout=10) == -signal.SIGKILL
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait(timeout=10)
        proc.stderr.close()
    rec = open_recording(path)
    assert rec.interrupted and rec.n_frames >= seen
    n = rec.n_frames
    assert rec.frames.shape == (n, 24, 32) and rec.frames[:].shape == (n, 24, 32)
    ids = rec.per_frame("frame_id")
    assert len(ids) == n and np.all(np.diff(ids) == 1)
    written = ~rec.per_frame("dropped")
    assert np.all(rec.frames[:][written].max(axis=(1, 2)) > 0)  # real frames, not fill values
    # Recovery turns it into an ordinary recording that plain zarr reads with exact shapes.
    assert recover_recording(path) == n
    rec2 = open_recording(path)
    assert not rec2.interrupted and rec2.n_frames == n
    g = zarr.open_group(str(path), mode="r")
    assert g["frames"].shape[0] == g["frame_id"].shape[0] == n
    np.testing.assert_array_equal(g["frame_id"][:], ids)
