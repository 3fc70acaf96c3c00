"""What a killed writer leaves, `flexvox clean`, and what is not a recording (through the real command line)."""

from __future__ import annotations

import os
import subprocess
import sys

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
