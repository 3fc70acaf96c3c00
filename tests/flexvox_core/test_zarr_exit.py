"""A process that used zarr exits quietly even when zarr's I/O thread is slow to stop (a loaded machine)."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]

# zarr's I/O thread is kept busy for 1 s as the process exits: zarr's own exit hook waits only 0.2 s for it, then
# fails to close the running loop and prints a traceback. Importing `flexvox_core.recording` (argv[2]) must prevent it.
SCRIPT = """
import importlib, sys, time
import numpy as np, zarr
group = zarr.open_group(sys.argv[1], mode="w")
group.create_array("a", shape=(4,), dtype="f4")[:] = np.arange(4)
if len(sys.argv) > 2:
    importlib.import_module(sys.argv[2])
from zarr.core import sync
sync._get_loop().call_soon_threadsafe(time.sleep, 1.0)
print("done")
"""


def run(tmp_path, *module):
    return subprocess.run([sys.executable, "-c", SCRIPT, str(tmp_path / "z.zarr"), *module], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)


@pytest.mark.parametrize("module", ["flexvox_core.recording", "flexvox_core.zarr_exit"])
def test_zarr_io_thread_busy_at_exit_leaves_stderr_empty(tmp_path, module):
    proc = run(tmp_path, module)
    assert proc.returncode == 0 and proc.stdout == "done\n", proc.stderr
    assert proc.stderr == ""


def test_without_the_hook_zarr_prints_a_traceback_at_exit(tmp_path):
    """What the hook is for: zarr's own exit hook alone prints a traceback when its thread is slow."""
    proc = run(tmp_path)
    assert proc.returncode == 0 and "Cannot close a running event loop" in proc.stderr, proc.stderr


def test_stop_zarr_io_stops_the_thread_and_zarr_starts_a_new_one_after(tmp_path):
    import numpy as np
    import zarr
    from zarr.core import sync

    from flexvox_core.zarr_exit import stop_zarr_io

    group = zarr.open_group(str(tmp_path / "z.zarr"), mode="w")
    group.create_array("a", shape=(3,), dtype="f4")[:] = np.arange(3)
    thread = sync.iothread[0]
    assert thread is not None and thread.is_alive()
    assert stop_zarr_io(wait_s=30) and not thread.is_alive() and sync.loop[0] is None
    assert stop_zarr_io() is True  # nothing left to stop
    np.testing.assert_array_equal(zarr.open_group(str(tmp_path / "z.zarr"), mode="r")["a"][:], np.arange(3))
