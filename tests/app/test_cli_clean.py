"""What a killed writer leaves, `flexvox clean`, and what is not a recording (through the real command line)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from tests.app.command_line import assert_refused, flexvox


def dead_pid() -> int:
    """The id of a process that has ended (waited for, so no process has it now unless the id is reused)."""
    child = subprocess.Popen([sys.executable, "-c", "pass"])
    child.wait()
    return child.pid


def killed_write(folder, name="kk.zarr", pid=None):
    """What ``reconstruct -o NAME`` killed by SIGKILL leaves: its partial store and its lock file."""
    pid = dead_pid() if pid is None else pid
    stem, suffix = name.rsplit(".", 1)
    partial = folder / f".{stem}.partial-{pid}-a1b2c3.{suffix}"
    partial.mkdir()
    (partial / "zarr.json").write_text("{}")
    lock = folder / f".{name}.lock"
    lock.write_text(f"{pid} flexvox reconstruct rec.zarr -o {name}\n")
    return partial, lock


@pytest.fixture(scope="module")
def rec(tmp_path_factory):
    from flexvox_app.cli.main import main

    folder = tmp_path_factory.mktemp("clean")
    path = folder / "rec.zarr"
    assert main(["simulate", "drummer", "--size", "24x32", "--frames", "2", "--tile", "2x2", "-o", str(path)]) == 0
    return path


def test_clean_lists_a_killed_writers_leftovers_and_removes_them_on_request(tmp_path):
    partial, lock = killed_write(tmp_path)
    assert_refused(flexvox("info", tmp_path / "kk.zarr"), 2,
                   rf"kk.zarr: no such recording; an unfinished write left {partial.name} beside it "
                   rf"\(`flexvox clean .*` lists such leftovers and removes them\)")
    listed = flexvox("clean", tmp_path)
    assert listed.returncode == 0, listed.stderr
    assert f"{partial.name}: the unfinished output of kk.zarr by process" in listed.stdout
    assert f"{lock.name}: the lock file of kk.zarr; its writer no longer runs" in listed.stdout
    assert f"2 of 2 can go: flexvox clean {tmp_path} --remove" in listed.stdout
    assert partial.exists() and lock.exists()  # listing removes nothing
    removed = flexvox("clean", tmp_path, "--remove")
    assert removed.returncode == 0 and "removed 2 of 2" in removed.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    assert flexvox("clean", tmp_path).stdout.strip() == f"{tmp_path}: no leftovers of unfinished writes"


def test_clean_never_removes_what_a_running_writer_holds(tmp_path):
    from flexvox_core.writer_lock import WriterLock

    partial, _ = killed_write(tmp_path, "mine.zarr", pid=os.getpid())  # this process runs
    with WriterLock(tmp_path / "busy.zarr"):
        proc = flexvox("clean", tmp_path, "--remove")
        assert proc.returncode == 0, proc.stderr
        assert f".busy.zarr.lock: the lock file of busy.zarr; kept: its writer runs (process {os.getpid()}" \
            in proc.stdout
        assert f"{partial.name}: the unfinished output of mine.zarr by process {os.getpid()}; kept: its writer runs" \
            in proc.stdout
        assert (tmp_path / ".busy.zarr.lock").exists() and partial.exists()


def test_clean_keeps_an_earlier_output_that_is_now_its_only_copy(tmp_path):
    aside = tmp_path / f".run.replaced-{dead_pid()}-0a0b0c.zarr"
    aside.mkdir()
    proc = flexvox("clean", tmp_path, "--remove")
    assert "the only copy; rename it back to run.zarr to keep it; kept" in proc.stdout
    assert aside.exists()


def test_the_next_write_to_the_output_removes_a_killed_writers_leftovers_and_says_so(rec, tmp_path):
    partial, _ = killed_write(tmp_path, "kk.zarr")
    proc = flexvox("reconstruct", rec, "--method", "diffusion", "-o", tmp_path / "kk.zarr")
    assert proc.returncode == 0, proc.stderr
    assert f"found and removed {partial.name}, the unfinished output of a writer of kk.zarr that no longer runs" \
        in proc.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kk.zarr"]


@pytest.mark.parametrize("make, message", [
    (lambda p: p.write_text("my notes\n"), r"notes is a file, not a flexvox recording \(a recording is a .zarr folder"),
    (lambda p: p.mkdir(), r"notes is a folder but not a flexvox recording: it holds no zarr.json"),
])
def test_info_on_something_that_is_not_a_recording_exits_2_in_words(tmp_path, make, message):
    target = tmp_path / "notes"
    make(target)
    proc = flexvox("info", target)
    assert_refused(proc, 2, message)
    assert proc.stdout == ""


def test_a_store_zarr_cannot_read_is_damaged_in_words(tmp_path):
    store = tmp_path / "bad.zarr"
    store.mkdir()
    (store / "zarr.json").write_text("{not json")
    proc = flexvox("info", store)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert "its zarr.json is not readable JSON: the file is damaged or truncated" in proc.stdout
    assert "Error" not in proc.stdout + proc.stderr  # no exception class names (JSONDecodeError, GroupNotFoundError)


def test_bench_out_onto_a_file_says_it_takes_a_folder(tmp_path):
    notes = tmp_path / "notes.txt"
    notes.write_text("keep me")
    assert_refused(flexvox("bench", "--quick", "-o", notes), 2,
                   r"-o .*notes.txt is a file; -o takes a folder, where results.csv, results.json and pareto.png go")
    assert notes.read_text() == "keep me"


def _overwrite_killed_before_its_first_frame(path):
    """What `flexvox capture -o PATH --overwrite` killed before its first frame leaves: the new, empty recording in
    PATH's place and the old one moved aside."""
    from flexvox_core.recording import RecordingWriter, open_recording
    from tests.killed_writer import kill

    rec = open_recording(path)
    F, H, W = rec.shape
    kill(RecordingWriter(path, height=H, width=W, dtype="float32", attrs={**rec.attrs, "kind": "captured"},
                         overwrite=True))
    [aside] = [p for p in path.parent.iterdir() if ".replaced-" in p.name]
    return aside


def test_a_capture_killed_before_its_first_frame_never_loses_the_recording_it_was_replacing(tmp_path, capsys):
    from flexvox_app.cli.main import main
    from flexvox_core.recording import open_recording

    path = tmp_path / "run1.zarr"
    assert main(["simulate", "balls", "--size", "24x32", "--frames", "3", "--tile", "2x2", "-o", str(path)]) == 0
    old = open_recording(path).frames[:]
    capsys.readouterr()
    aside = _overwrite_killed_before_its_first_frame(path)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out
    assert (f"interrupted: the capture was killed before its first frame; `flexvox info --repair` deletes it and puts "
            f"back {aside.name}, the earlier recording it had moved aside to replace it") in out
    assert (f"note: {aside.name} beside it is the earlier run1.zarr, moved aside when a capture began to replace it; "
            "run1.zarr holds no frame (that capture stopped before its first frame), so this is the only copy; "
            f"`flexvox info --repair {path}` puts it back") in out
    assert "lists such leftovers and removes them" not in out  # no advice to remove the only copy
    assert main(["clean", str(tmp_path), "--remove"]) == 0
    out = capsys.readouterr().out
    assert f"{aside.name}: the earlier run1.zarr, moved aside when a capture began" in out
    assert "so this is the only copy; `flexvox info --repair" in out and "puts it back; kept" in out
    assert aside.is_dir()
    assert main(["info", "--repair", str(path)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{path}: put back {aside.name}, the earlier run1.zarr that an overwriting capture killed "
                          "before its first frame had moved aside; 3 frames\n") and out.strip().endswith("OK")
    np.testing.assert_array_equal(open_recording(path).frames[:], old)
    assert sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith(".lock")) == ["run1.zarr"]


def test_info_on_a_missing_output_names_the_earlier_one_as_the_only_copy_not_as_a_leftover(tmp_path):
    aside = tmp_path / f".run.replaced-{dead_pid()}-0a0b0c.zarr"
    aside.mkdir()
    assert_refused(flexvox("info", tmp_path / "run.zarr"), 2,
                   rf"run.zarr: no such recording; {aside.name} beside it is the earlier run.zarr, moved aside by "
                   r"process \d+, which stopped before the new one took its place: the only copy; rename it back to "
                   r"run.zarr to keep it$")
