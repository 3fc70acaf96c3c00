"""Recordings prove their integrity: a missing, truncated or changed chunk is never read as data."""

import os
import shutil

import numpy as np
import pytest
import zarr

from flexvox_core.capture_reader import NotReconstructableError, read_capture
from flexvox_core.design import design_code
from flexvox_core.recording import (
    DamagedRecordingError,
    RecordingWriter,
    open_recording,
    recording_attrs,
    values_crc,
    write_simulation,
)
from flexvox_core.simulate.simulator import simulate_video
from tests.killed_writer import kill


@pytest.fixture
def rec_path(tmp_path, rng):
    v = rng.random((6 * 4, 8, 10)).astype(np.float32)
    return write_simulation(tmp_path / "r.zarr", simulate_video(v, design_code((2, 2)).code, seed=3))


def _chunk(path, row, array="frames"):
    return path / array / "c" / str(row) / "0" / "0"


def test_every_frame_carries_its_crc(rec_path):
    rec = open_recording(rec_path)
    crcs = rec.per_frame("frame_crc")
    raw = np.asarray(zarr.open_group(str(rec_path), mode="r")["frames"][:])
    assert crcs.dtype == np.uint32 and crcs.tolist() == [values_crc(f) for f in raw]
    assert rec.has_checksums and rec.verify() == []
    assert values_crc(np.ones(3, ">f4")) == values_crc(np.ones(3, "<f4"))  # bytes as stored: little-endian


def test_a_deleted_chunk_is_refused_by_every_reader(rec_path, tmp_path):
    from flexvox_core.batch import reconstruct_batch

    _chunk(rec_path, 2).unlink()
    rec = open_recording(rec_path)  # the structure is sound ...
    with pytest.raises(DamagedRecordingError, match=r"frames row 2 is damaged: its chunk file is missing") as info:
        rec.frames[:]
    assert info.value.rows == [2]
    np.testing.assert_array_equal(rec.frames[1], np.asarray(zarr.open_group(str(rec_path))["frames"][1]))
    with pytest.raises(DamagedRecordingError, match=r"row 2 is damaged"):
        read_capture(rec_path)
    with pytest.raises(DamagedRecordingError, match=r"row 2 is damaged"):
        reconstruct_batch(rec_path, tmp_path / "b.zarr", chunk_frames=2)
    assert not (tmp_path / "b.zarr").exists() and not list(tmp_path.glob(".b.*"))
    assert rec.verify() == ["frames row 2: its chunk file is missing"]


def test_truncated_garbled_and_changed_chunks(rec_path):
    data = _chunk(rec_path, 1).read_bytes()
    _chunk(rec_path, 1).write_bytes(data[: len(data) // 2])  # truncated: the codec fails
    g = zarr.open_group(str(rec_path), mode="r+")
    g["frames"][4] = np.asarray(g["frames"][4]) + 0.5  # a valid chunk with other values
    garbled = bytearray(_chunk(rec_path, 3).read_bytes())
    garbled[len(garbled) // 2] ^= 0xFF
    _chunk(rec_path, 3).write_bytes(bytes(garbled))
    rec = open_recording(rec_path)
    problems = rec.verify()
    assert problems[0] == "frames row 1: its chunk cannot be decoded (truncated or garbled)"
    assert problems[-1] == "frames row 4: its checksum does not match (the chunk was changed or damaged)"
    assert len(problems) == 3 and problems[1].startswith("frames row 3: its ")
    with pytest.raises(DamagedRecordingError, match=r"row 1 is damaged: its chunk cannot be decoded"):
        rec.normalised_frames(0, 2)
    with pytest.raises(DamagedRecordingError, match=r"row 4 is damaged: its checksum does not match"):
        rec.frames[4]


def test_a_damaged_ground_truth_chunk_is_found(rec_path):
    _chunk(rec_path, 5, "ground_truth").unlink()
    rec = open_recording(rec_path)
    assert rec.verify() == ["ground truth row 5: its chunk file is missing"]
    with pytest.raises(DamagedRecordingError, match=r"ground truth row 5 is damaged"):
        rec.ground_truth[:]
    assert rec.ground_truth[0:4].shape == (4, 8, 10)


def test_frame_ids_must_increase_by_one_before_reconstruction(rec_path):
    g = zarr.open_group(str(rec_path), mode="r+")
    g["frame_id"][3] = 1
    with pytest.raises(NotReconstructableError, match=r"frame ids do not increase at row 3 \(2 then 1\)"):
        read_capture(rec_path)
    g["frame_id"][:] = [0, 1, 2, 5, 6, 7]
    with pytest.raises(NotReconstructableError, match=r"frame ids skip 2 id\(s\) without a dropped row at row 3"):
        read_capture(rec_path)


def test_schema_1_recordings_still_read_and_missing_chunks_are_still_refused(rec_path):
    g = zarr.open_group(str(rec_path), mode="r+")
    del g["frame_crc"]
    del g["ground_truth_crc"]
    g.attrs["flexvox"] = {**g.attrs["flexvox"], "schema_version": 1}
    rec = open_recording(rec_path)
    assert not rec.has_checksums and read_capture(rec)[0].shape == (6, 8, 10)
    assert rec.verify() == ["no checksums (schema 1): missing chunks were checked, changed values cannot be"]
    _chunk(rec_path, 0).unlink()
    with pytest.raises(DamagedRecordingError, match=r"row 0 is damaged: its chunk file is missing"):
        read_capture(rec_path)


def test_a_failed_simulation_write_leaves_the_old_recording(rec_path, rng, monkeypatch):
    before = {p.relative_to(rec_path): p.read_bytes() for p in rec_path.rglob("*") if p.is_file()}
    sim = simulate_video(rng.random((4 * 4, 8, 10)).astype(np.float32), design_code((2, 2)).code, seed=4)
    calls = []

    def full_disk(self, frame, **kw):
        calls.append(1)
        if len(calls) == 3:
            raise OSError(28, "No space left on device")
        return original(self, frame, **kw)

    original = RecordingWriter.append
    monkeypatch.setattr(RecordingWriter, "append", full_disk)
    with pytest.raises(OSError, match="No space left"):
        write_simulation(rec_path, sim, overwrite=True)
    after = {p.relative_to(rec_path): p.read_bytes() for p in rec_path.rglob("*") if p.is_file()}
    assert after == before
    assert sorted(p.name for p in rec_path.parent.iterdir() if p.name.startswith(".")) == []
    monkeypatch.setattr(RecordingWriter, "append", original)
    write_simulation(rec_path, sim, overwrite=True)
    assert open_recording(rec_path).n_frames == 4


def _writer(path, **kw):
    attrs = recording_attrs(design_code((2, 2)).code, rate_hz=30.0, kind="captured", storage={"kind": "float"})
    return RecordingWriter(path, height=4, width=5, dtype="float32", attrs=attrs, **kw)


def test_a_capture_that_overwrites_keeps_the_old_recording_until_it_has_frames(rec_path):
    old = open_recording(rec_path).frames[:]
    w = _writer(rec_path, overwrite=True)
    hidden = [p for p in rec_path.parent.iterdir() if p.name.startswith(".r.replaced-")]
    assert len(hidden) == 1  # the old one is aside while the new one is written
    w.close()  # no frame: the old one comes back
    np.testing.assert_array_equal(open_recording(rec_path).frames[:], old)
    w = _writer(rec_path, overwrite=True)
    w.append(np.ones((4, 5), np.float32), frame_id=0, timestamp=0.0)
    w.close()
    assert open_recording(rec_path).n_frames == 1
    assert [p.name for p in rec_path.parent.iterdir() if p.name.startswith(".")] == []


def _hidden(folder):
    return sorted(p.name for p in folder.iterdir() if p.name.startswith(".") and not p.name.endswith(".lock"))


def test_repair_puts_back_the_recording_an_overwriting_capture_killed_before_its_first_frame_moved_aside(rec_path):
    from flexvox_core.leftovers import find_leftovers
    from flexvox_core.recording import repair_recording

    old = open_recording(rec_path).frames[:]
    kill(_writer(rec_path, overwrite=True))  # killed after moving the old one aside, before its first frame
    [aside] = _hidden(rec_path.parent)
    assert open_recording(rec_path).interrupted and open_recording(rec_path).n_frames == 0
    [item] = [i for i in find_leftovers(rec_path.parent) if i.kind == "replaced"]
    assert not item.removable and item.writer is None  # the only copy: never offered for removal
    assert item.why.endswith(f"r.zarr holds no frame (that capture stopped before its first frame), so this is the "
                             f"only copy; `flexvox info --repair {rec_path}` puts it back")
    repair = repair_recording(rec_path)
    assert repair.restored == (aside,) and not repair.finalised and repair.frames == 6
    assert repair.describe() == (f"put back {aside}, the earlier r.zarr that an overwriting capture killed before "
                                 "its first frame had moved aside; 6 frames")
    np.testing.assert_array_equal(open_recording(rec_path).frames[:], old)
    assert _hidden(rec_path.parent) == [] and not open_recording(rec_path).interrupted


def test_repair_puts_back_the_first_recording_after_two_overwrites_killed_before_their_first_frame(rec_path,
                                                                                                   monkeypatch):
    from flexvox_core.recording import repair_recording

    old = open_recording(rec_path).frames[:]
    monkeypatch.setattr(os, "getpid", lambda: 999991)  # two capture processes, one after the other
    kill(_writer(rec_path, overwrite=True))
    first = _hidden(rec_path.parent)
    monkeypatch.setattr(os, "getpid", lambda: 999992)
    kill(_writer(rec_path, overwrite=True))  # it moves the first one's empty store aside in turn
    monkeypatch.undo()
    assert len(_hidden(rec_path.parent)) == 2
    repair = repair_recording(rec_path)
    assert len(repair.restored) == 2 and repair.restored[-1] == first[0] and repair.frames == 6
    np.testing.assert_array_equal(open_recording(rec_path).frames[:], old)
    assert _hidden(rec_path.parent) == []


def test_a_killed_overwrite_with_committed_frames_is_finalised_and_the_old_recording_may_go(rec_path):
    from flexvox_core.leftovers import find_leftovers
    from flexvox_core.recording import repair_recording

    w = _writer(rec_path, overwrite=True)
    for i in range(2):
        w.append(np.full((4, 5), i + 1, np.float32), frame_id=i, timestamp=i / 30)
    kill(w)
    [aside] = _hidden(rec_path.parent)
    [item] = [i for i in find_leftovers(rec_path.parent) if i.kind == "replaced"]
    assert item.removable and item.why.startswith("the earlier r.zarr, moved aside by process")  # as before
    repair = repair_recording(rec_path)
    assert (repair.frames, repair.finalised, repair.restored) == (2, True, ())
    assert repair.describe() == "finalised, 2 frames"
    assert open_recording(rec_path).n_frames == 2 and _hidden(rec_path.parent) == [aside]  # kept for clean


def test_an_earlier_recording_beside_one_that_holds_no_frame_or_is_unreadable_is_never_removable(rec_path):
    from flexvox_core.leftovers import find_leftovers
    from flexvox_core.recording.repair import _finalise

    kill(_writer(rec_path, overwrite=True))
    _finalise(open_recording(rec_path))  # what --repair made of it before: a finished recording of 0 frames
    [item] = [i for i in find_leftovers(rec_path.parent) if i.kind == "replaced"]
    assert not item.removable and item.why.endswith(
        "r.zarr holds no frame (that capture stopped before its first frame), so this is the only copy; to keep it, "
        "delete r.zarr and rename this back to r.zarr")
    shutil.rmtree(rec_path)
    rec_path.mkdir()  # killed while it made its new store: not a recording yet
    [item] = [i for i in find_leftovers(rec_path.parent) if i.kind == "replaced"]
    assert not item.removable and "r.zarr is not a readable recording (that capture stopped" in item.why


def test_durable_writes_flush_every_frame(tmp_path, monkeypatch):
    synced = []
    real = os.fsync
    monkeypatch.setattr(os, "fsync", lambda fd: (synced.append(fd), real(fd)))
    w = _writer(tmp_path / "d.zarr", fsync=True, block_frames=2)
    w.append(np.ones((4, 5), np.float32), frame_id=0, timestamp=0.0)  # (the first also flushes the metadata)
    before = len(synced)
    w.append(np.ones((4, 5), np.float32), frame_id=1, timestamp=0.1)
    per_frame = len(synced) - before
    w.close()
    assert per_frame == 6  # the chunk, the four folders that name it (c/1/0, c/1, c, frames), the journal
    assert open_recording(tmp_path / "d.zarr").verify() == []
    synced.clear()
    w = _writer(tmp_path / "n.zarr")
    w.append(np.ones((4, 5), np.float32), frame_id=0, timestamp=0.0)
    w.close()
    assert synced == []
    shutil.rmtree(tmp_path / "n.zarr")


def test_a_missing_per_frame_chunk_is_named_not_blamed_on_the_frames(rec_path):
    (rec_path / "frame_crc" / "c" / "0").unlink()
    problems = open_recording(rec_path).verify()
    assert problems[0] == "per-frame array `frame_crc` rows 0..5: its chunk file is missing (it reads as zeros)"
    assert "or the checksum itself is missing (it reads 0" in problems[1]
