"""Outputs never destroy inputs: the checks before work, atomic replacement, one writer per path."""

import os
import subprocess
import sys
import textwrap

import pytest

from flexvox_core.output_errors import CLI_OVERWRITE_HINT, OutputBusyError, OutputError
from flexvox_core.output_files import (
    atomic_output,
    check_output,
    check_writable,
    refuse_output_onto_input,
    write_text_atomic,
)
from flexvox_core.writer_lock import WriterLock, lock_holder, lock_path


def test_an_output_is_never_its_input_whatever_the_spelling(tmp_path):
    rec = tmp_path / "rec.zarr"
    rec.mkdir()
    (rec / "zarr.json").write_text("{}")
    with pytest.raises(OutputError, match=r"is the input .*rec.zarr: an output never replaces its input"):
        refuse_output_onto_input(tmp_path / "sub" / ".." / "rec.zarr", [rec])
    os.symlink(rec, tmp_path / "link.zarr")
    with pytest.raises(OutputError, match=r"is the input"):
        check_output(tmp_path / "link.zarr", overwrite=True, inputs=[rec])
    with pytest.raises(OutputError, match=r"holds the input"):
        check_output(tmp_path, overwrite=True, inputs=[rec])
    with pytest.raises(OutputError, match=r"lies inside the input"):
        check_output(rec / "video.npy", overwrite=True, inputs=[rec])
    os.link(rec / "zarr.json", tmp_path / "hard.json")
    with pytest.raises(OutputError, match=r"is the input"):
        refuse_output_onto_input(tmp_path / "hard.json", [rec / "zarr.json"])
    refuse_output_onto_input(tmp_path / "rec2.zarr", [rec, None])  # a sibling is fine


def test_check_output_rules(tmp_path):
    (tmp_path / "old.npy").write_bytes(b"x")
    with pytest.raises(OutputError, match=r"old.npy already exists; choose another path, or pass overwrite=True to "
                                          r"replace it"):
        check_output(tmp_path / "old.npy")
    with pytest.raises(OutputError, match=r"old.npy already exists; use --overwrite to replace it"):
        check_output(tmp_path / "old.npy", hint=CLI_OVERWRITE_HINT)  # the command line's words
    assert check_output(tmp_path / "old.npy", overwrite=True) == tmp_path / "old.npy"
    with pytest.raises(OutputError, match=r"cannot write .*x.npy: the folder .*nowhere does not exist"):
        check_output(tmp_path / "nowhere" / "x.npy")
    (tmp_path / "afile").write_text("")
    with pytest.raises(OutputError, match=r"the folder .*afile does not exist"):
        check_output(tmp_path / "afile" / "x.npy")


def _read_only_folder(tmp_path):
    """A folder that refuses new files, for this user (root ignores permissions: then /proc/sys)."""
    if os.geteuid() != 0:
        folder = tmp_path / "ro"
        folder.mkdir()
        folder.chmod(0o555)
        return folder
    return "/proc/sys"


def test_a_read_only_folder_is_refused_before_any_work(tmp_path):
    folder = _read_only_folder(tmp_path)
    with pytest.raises(OutputError, match=r"cannot write .*out.npy: the folder .* does not accept new files \("):
        check_output(f"{folder}/out.npy")
    with pytest.raises(OutputError, match=r"does not accept new files"):
        check_writable(folder)
    check_writable(tmp_path)
    assert [p.name for p in tmp_path.iterdir() if p.name.startswith(".flexvox-probe")] == []


def test_atomic_output_replaces_only_when_complete(tmp_path):
    out = tmp_path / "v.npy"
    out.write_bytes(b"old")
    with pytest.raises(RuntimeError, match="disk full"), atomic_output(out, overwrite=True) as tmp:
        assert tmp.suffix == ".npy" and tmp.name.startswith(".v.partial-") and tmp.parent == tmp_path
        tmp.write_bytes(b"half")
        raise RuntimeError("disk full")
    assert out.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["v.npy"]
    with atomic_output(out, overwrite=True) as tmp:
        tmp.write_bytes(b"new")
    assert out.read_bytes() == b"new" and sorted(p.name for p in tmp_path.iterdir()) == ["v.npy"]
    with pytest.raises(OutputError, match=r"nothing was written"), atomic_output(tmp_path / "none.npy"):
        pass


def test_atomic_output_replaces_a_folder_and_keeps_it_on_failure(tmp_path):
    out = tmp_path / "store.zarr"
    out.mkdir()
    (out / "old").write_text("old")
    with pytest.raises(OSError), atomic_output(out, overwrite=True) as tmp:
        tmp.mkdir()
        raise OSError(28, "No space left on device")
    assert (out / "old").read_text() == "old"
    with atomic_output(out, overwrite=True) as tmp:
        tmp.mkdir()
        (tmp / "new").write_text("new")
    assert sorted(p.name for p in out.iterdir()) == ["new"] and sorted(p.name for p in tmp_path.iterdir()) == [
        "store.zarr"]
    with pytest.raises(OutputError, match=r"appeared while it was being written"), \
            atomic_output(out, overwrite=False) as tmp:
        tmp.mkdir()
    assert (out / "new").exists()


def test_write_text_atomic(tmp_path):
    p = write_text_atomic(tmp_path / "c.json", "{}\n", overwrite=False)
    assert p.read_text() == "{}\n"
    with pytest.raises(OutputError, match=r"c.json appeared while it was being written"):
        write_text_atomic(tmp_path / "c.json", "[]\n", overwrite=False)
    assert p.read_text() == "{}\n"


def test_one_writer_per_path_and_the_holder_is_named(tmp_path):
    target = tmp_path / "rec.zarr"
    assert lock_holder(target) is None
    with WriterLock(target) as lock:
        assert lock.held and lock_path(target).exists()
        holder = lock_holder(target)
        assert holder is not None and holder.startswith(f"process {os.getpid()}")
        with pytest.raises(OutputBusyError, match=rf"rec.zarr is being written by process {os.getpid()}"):
            WriterLock(target).acquire()
        target.mkdir()
        with pytest.raises(OutputError, match=r"is being written by process \d+"):
            check_output(target, overwrite=True)
    assert not lock_path(target).exists() and lock_holder(target) is None
    (target / "zarr.json").write_text("{}")
    check_output(target, overwrite=True)


def test_a_killed_holder_leaves_no_stale_lock(tmp_path):
    target = tmp_path / "rec.zarr"
    script = textwrap.dedent(f"""
        import os, sys
        from flexvox_core.writer_lock import WriterLock
        WriterLock({str(target)!r}).acquire()
        print("held", flush=True)
        sys.stdin.readline()
        os._exit(0)
    """)
    with subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                          text=True) as child:
        try:
            assert child.stdout.readline().strip() == "held"
            assert lock_holder(target).startswith(f"process {child.pid}")
        finally:
            child.kill()
            child.wait(timeout=30)
    assert lock_path(target).exists()  # the file stays ...
    assert lock_holder(target) is None  # ... but the OS released the lock with the process
    with WriterLock(target):
        pass


def test_a_link_to_a_recording_shares_its_lock(tmp_path):
    target = tmp_path / "live.zarr"
    target.mkdir()
    os.symlink(target, tmp_path / "link.zarr")
    with WriterLock(target):
        with pytest.raises(OutputBusyError, match=r"link.zarr is being written by process"):
            WriterLock(tmp_path / "link.zarr").acquire()
        assert lock_holder(tmp_path / "link.zarr") is not None


def test_an_atomic_output_holds_the_lock_while_it_writes(tmp_path):
    out = tmp_path / "race.zarr"
    with atomic_output(out) as tmp:
        tmp.mkdir()
        with pytest.raises(OutputBusyError, match=r"race.zarr is being written by process"):
            WriterLock(out).acquire()  # a capture starting now is refused
    with WriterLock(out), pytest.raises(OutputBusyError), atomic_output(out, overwrite=True):
        pass  # and a write cannot start on a path a capture holds
    assert out.is_dir() and not [p for p in tmp_path.iterdir() if p.name.startswith(".race.partial")]


def test_probing_the_lock_never_writes_it(tmp_path):
    target = tmp_path / "rec.zarr"
    with WriterLock(target):
        before = lock_path(target).read_bytes()
        assert lock_holder(target) is not None
        assert lock_path(target).read_bytes() == before
    (lock_path(target)).write_text("4242 someone else\n")  # a stale file from a killed writer
    assert lock_holder(target) is None and lock_path(target).read_text() == "4242 someone else\n"


def test_overwrite_replaces_only_the_same_kind(tmp_path):
    thesis = tmp_path / "thesis.tif"
    thesis.mkdir()
    (thesis / "chapter1.txt").write_text("years of work")
    with pytest.raises(OutputError, match=r"thesis.tif is a folder; overwriting replaces a file with a file"):
        check_output(thesis, overwrite=True)
    notes = tmp_path / "proj.zarr"
    notes.mkdir()
    (notes / "notes.txt").write_text("x")
    with pytest.raises(OutputError, match=r"proj.zarr is a folder but not a Zarr store"):
        check_output(notes, overwrite=True)
    (tmp_path / "plain").write_text("x")
    with pytest.raises(OutputError, match=r"plain is a file, not a folder"):
        check_output(tmp_path / "plain", overwrite=True, kind="folder")
    (notes / "zarr.json").write_text("{}")
    check_output(notes, overwrite=True)  # a Zarr store may replace a Zarr store
    from flexvox_core.recording import RecordingWriter  # the writer checks it too

    with pytest.raises(OutputError, match=r"thesis.tif ends in .tif; write .*thesis.zarr"):
        RecordingWriter(thesis, height=4, width=4, dtype="float32", attrs={}, overwrite=True)
    assert (thesis / "chapter1.txt").read_text() == "years of work"
    thesis_store = tmp_path / "thesis.zarr"
    thesis_store.mkdir()
    (thesis_store / "chapter1.txt").write_text("years of work")
    with pytest.raises(OutputError, match=r"thesis.zarr is a folder but not a Zarr store"):
        RecordingWriter(thesis_store, height=4, width=4, dtype="float32", attrs={}, overwrite=True)
    assert (thesis_store / "chapter1.txt").read_text() == "years of work"


def test_a_video_never_replaces_a_recording_even_with_overwrite(tmp_path):
    # fv.write_video("run1.zarr", video, overwrite=True) meant for "run1-video.zarr": the camera frames would be lost
    import numpy as np

    import flexvox_core as fv

    code = fv.design_code((2, 2)).code
    sim = fv.simulate_video(fv.render_scene("balls", 8, 8, 8, seed=0), code)
    rec = fv.write_simulation(tmp_path / "run1.zarr", sim)
    video = np.zeros((8, 8, 8), np.float32)
    with pytest.raises(OutputError, match=r"run1.zarr is a recording \(camera frames\); overwriting replaces a "
                                          r"recording only with a recording, never with a video or another file: "
                                          r"choose another path"):
        fv.write_video(rec, video, overwrite=True)
    with pytest.raises(OutputError, match=r"run1.zarr is a recording"):
        check_output(rec, overwrite=True)
    check_output(rec, overwrite=True, kind="store")  # a recording may replace a recording (simulate, capture)
    fv.write_simulation(rec, sim, overwrite=True)
    assert fv.open_recording(rec).n_frames == 2
    fv.write_video(tmp_path / "video.zarr", video)
    fv.write_video(tmp_path / "video.zarr", video, overwrite=True)  # a video replaces a video


def test_a_python_caller_is_told_the_keyword_and_never_a_command_line_flag(tmp_path):
    """``write_video`` onto an existing file names ``overwrite=True``; no refusal from Python names ``--overwrite``."""
    import numpy as np

    from flexvox_core import write_video

    video = np.zeros((2, 4, 4), np.float32)
    write_video(tmp_path / "v.npy", video)
    with pytest.raises(OutputError, match=r"v.npy already exists; choose another path, or pass overwrite=True to "
                                          r"replace it") as refused:
        write_video(tmp_path / "v.npy", video)
    (tmp_path / "d.npy").mkdir()
    with pytest.raises(OutputError, match=r"d.npy is a folder; overwriting replaces a file with a file") as folder:
        write_video(tmp_path / "d.npy", video, overwrite=True)
    assert "--" not in str(refused.value) + str(folder.value)


@pytest.mark.parametrize("overwrite", ["no", "False", 0, None])
def test_overwrite_that_is_not_a_bool_is_refused_and_the_output_kept(tmp_path, overwrite):
    # a string is true: fv.write_video("a.npy", video, overwrite="no") had replaced a.npy
    import numpy as np

    import flexvox_core as fv

    code = fv.design_code("2x2").code
    sim = fv.simulate_video(fv.render_scene("balls", 8, 16, 16, seed=0), code, seed=0)
    video, rec = tmp_path / "a.npy", tmp_path / "s.zarr"
    fv.write_video(video, np.full((4, 8, 8), 0.5, np.float32))
    fv.write_simulation(rec, sim)
    before = {p: sorted((q.relative_to(p), q.stat().st_mtime_ns) for q in p.rglob("*")) if p.is_dir()
              else p.read_bytes() for p in (video, rec)}
    for write in (lambda: fv.write_video(video, np.zeros((4, 8, 8), np.float32), overwrite=overwrite),
                  lambda: fv.write_simulation(rec, sim, overwrite=overwrite),
                  lambda: fv.reconstruct_batch(rec, tmp_path / "b.zarr", "diffusion", overwrite=overwrite)):
        with pytest.raises(TypeError, match=rf"`overwrite` must be True or False; got {overwrite!r}"):
            write()
    after = {p: sorted((q.relative_to(p), q.stat().st_mtime_ns) for q in p.rglob("*")) if p.is_dir()
             else p.read_bytes() for p in (video, rec)}
    assert after == before and not (tmp_path / "b.zarr").exists()
    assert fv.write_video(video, np.zeros((4, 8, 8), np.float32), overwrite=np.bool_(True)) == video
