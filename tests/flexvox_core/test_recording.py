import json
import re
from pathlib import Path

import numpy as np
import pytest
import zarr

from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.recording import SCHEMA_VERSION, RecordingError, open_recording, write_simulation
from flexvox_core.simulate.effects import parse_effects
from flexvox_core.simulate.simulator import simulate_video


@pytest.fixture
def sim(rng):
    v = rng.random((3 * 16, 12, 20)).astype(np.float32)
    return simulate_video(v, design_code((4, 4)).code, seed=7)


def test_round_trip_float(tmp_path, sim):
    path = write_simulation(tmp_path / "r.zarr", sim)
    rec = open_recording(path)
    assert rec.n_frames == 3 and rec.K == 16
    assert rec.frames.dtype == np.float32 and rec.frames.chunks == (1, 12, 20)
    assert np.array_equal(rec.frames[:], capture(sim.ground_truth, rec.code))
    assert np.array_equal(rec.ground_truth[:], sim.ground_truth)
    assert rec.per_frame("frame_id").tolist() == [0, 1, 2]
    assert rec.attrs["schema_version"] == SCHEMA_VERSION and rec.attrs["seed"] == 7
    assert rec.attrs["order"] == design_code((4, 4)).order.tolist()
    assert rec.attrs["rates"] == {"camera_hz": 15.0, "subframe_hz": 240.0}
    # Readable by plain zarr, no flexvox needed.
    g = zarr.open_group(str(path), mode="r")
    assert g["frames"].shape == (3, 12, 20)
    # The truth is compressed as the reconstructions are: Blosc LZ4, which every PSNR reads 3x faster than Zstd.
    (codec,) = g["ground_truth"].compressors
    assert codec.to_dict()["configuration"]["cname"] == "lz4"


def test_a_ground_truth_stored_with_zstd_still_reads_and_checks(tmp_path, sim):
    # Recordings simulated before the truth took Blosc LZ4 hold it with zarr's default Zstd: they read as before,
    # each sub-frame checked against its CRC, and a damaged one is still caught.
    path = write_simulation(tmp_path / "z.zarr", sim)
    g = zarr.open_group(str(path), mode="r+")
    truth = g["ground_truth"][:]
    del g["ground_truth"]
    g.create_array("ground_truth", data=truth, chunks=(1, *truth.shape[1:]), compressors=zarr.codecs.ZstdCodec())
    rec = open_recording(path)
    assert np.array_equal(rec.ground_truth[:], sim.ground_truth)
    g["ground_truth"][5] = truth[5] + 1
    with pytest.raises(RecordingError, match="ground_truth.*5"):
        open_recording(path).ground_truth[:]


def test_counts_and_effects_metadata(tmp_path, rng):
    v = rng.random((16, 8, 8)).astype(np.float32)
    eff = parse_effects({"photon_noise": {}, "adc": {"bits": 10, "gain": 0.5, "black_level": 32}})
    r = simulate_video(v, design_code((4, 4)).code, effects=eff, seed=2)
    rec = open_recording(write_simulation(tmp_path / "c.zarr", r))
    assert rec.frames.dtype == np.uint16
    assert rec.attrs["effects"] == {"photon_noise": {}, "adc": {"bits": 10, "gain": 0.5, "black_level": 32}}
    assert rec.attrs["storage"]["kind"] == "counts"
    assert np.allclose(rec.normalised_frames(), r.normalised(), atol=0)


def test_refuses_to_overwrite(tmp_path, sim):
    write_simulation(tmp_path / "r.zarr", sim)
    with pytest.raises(RecordingError, match=r"r.zarr already exists; choose another path, or pass overwrite=True"):
        write_simulation(tmp_path / "r.zarr", sim)
    write_simulation(tmp_path / "r.zarr", sim, overwrite=True)


def _edit_attrs(path, fn):
    meta = json.loads((path / "zarr.json").read_text())
    fn(meta["attributes"]["flexvox"])
    (path / "zarr.json").write_text(json.dumps(meta))


def test_schema_missing_or_newer(tmp_path, sim):
    path = write_simulation(tmp_path / "r.zarr", sim)
    _edit_attrs(path, lambda a: a.update(schema_version=SCHEMA_VERSION + 1))
    with pytest.raises(RecordingError, match=r"schema version 3 is newer than this software reads \(2\)"):
        open_recording(path)
    _edit_attrs(path, lambda a: a.pop("schema_version"))
    with pytest.raises(RecordingError, match=r"has no schema_version"):
        open_recording(path)


@pytest.mark.parametrize("version", ["2", 0, 1.5, True])
def test_a_schema_version_that_is_no_whole_number_is_damage_not_the_future(tmp_path, sim, version):
    path = write_simulation(tmp_path / "r.zarr", sim)
    _edit_attrs(path, lambda a: a.update(schema_version=version))
    with pytest.raises(RecordingError, match=rf"schema version {re.escape(repr(version))} is not a whole number >= 1"):
        open_recording(path)


@pytest.mark.parametrize(("rates", "message"), [
    ({}, r"rate `camera_hz` must be a finite number of Hz above 0; got None; rate `subframe_hz` must be"),
    ({"camera_hz": 0, "subframe_hz": 240.0}, r"rate `camera_hz` must be a finite number of Hz above 0; got 0"),
    ({"camera_hz": -15.0, "subframe_hz": 240.0}, r"rate `camera_hz` must be a finite number of Hz above 0; got -15.0"),
    ({"camera_hz": 15.0, "subframe_hz": "240"}, r"rate `subframe_hz` must be a finite number of Hz above 0; got '240'"),
    ({"camera_hz": 15.0, "subframe_hz": 200.0}, r"rate `subframe_hz` 200 is not K = 16 times `camera_hz` 15"),
    ([15.0, 60.0], r"the `rates` attribute must be a mapping of camera_hz and subframe_hz; got \[15.0, 60.0\]"),
])
def test_rates_that_no_time_step_can_come_from_are_damage(tmp_path, sim, rates, message):
    # Every time step (a reconstruction's, a TIFF's frame interval) is read from them: refused when opened.
    path = write_simulation(tmp_path / "r.zarr", sim)
    _edit_attrs(path, lambda a: a.update(rates=rates))
    with pytest.raises(RecordingError, match=message):
        open_recording(path)


def test_a_frame_holding_nan_is_named_by_its_row_when_checked_and_when_read(tmp_path, rng, capsys):
    # Stored as written (its checksum matches): info lists the row, and a chunked reconstruction names the
    # same row, not its place within a chunk.
    from flexvox_app.cli.main import main
    from flexvox_core.recording import values_crc

    v = rng.random((8 * 4, 8, 12)).astype(np.float32)
    path = write_simulation(tmp_path / "r.zarr", simulate_video(v, design_code((2, 2)).code, seed=1))
    g = zarr.open_group(str(path), mode="r+")
    frame = g["frames"][7]
    frame[3, 4] = np.nan
    g["frames"][7] = frame
    g["frame_crc"][7] = values_crc(frame)
    lines = open_recording(path).verify()
    assert lines == ["frames row 7: it holds NaN or infinite values (no reconstruction can use them)"]
    assert main(["reconstruct", str(path), "--method", "diffusion", "--chunk", "3",
                 "-o", str(tmp_path / "o.npy")]) == 2
    assert "frames row 7 is damaged: it holds NaN or infinite values" in capsys.readouterr().err
    assert not (tmp_path / "o.npy").exists()


def test_a_code_that_is_no_identity_code_in_a_recording_not_marked_multiplexed_is_damage(tmp_path, sim):
    path = write_simulation(tmp_path / "r.zarr", sim)

    def two_slots(a):
        a["code"][0][0] = [1] * 8 + [0] * 8  # pixel (0, 0) open in eight slots

    _edit_attrs(path, two_slots)
    with pytest.raises(RecordingError, match=r"the code opens pixels in more than one slot .*not marked `multiplexed`"):
        open_recording(path)


def test_damaged_recordings(tmp_path, sim):
    path = write_simulation(tmp_path / "r.zarr", sim)
    g = zarr.open_group(str(path), mode="r+")
    g["dropped"].resize((2,))
    with pytest.raises(RecordingError, match=r"`dropped` has 2 entries for 3 frames"):
        open_recording(path)
    with pytest.raises(RecordingError, match=r"no such recording"):
        open_recording(tmp_path / "none.zarr")
    (tmp_path / "junk.zarr").mkdir()
    with pytest.raises(RecordingError, match=r"junk.zarr: not a"):
        open_recording(tmp_path / "junk.zarr")


# --------------------------------------------------------------------------- crash safety

from flexvox_core.output_errors import OutputBusyError  # noqa: E402
from flexvox_core.recording import (  # noqa: E402
    JOURNAL,
    RecordingWriter,
    RowsView,
    read_journal,
    recording_attrs,
    recover_recording,
)
from tests.killed_writer import kill as _kill  # noqa: E402


def _writer(path, **kw):
    attrs = recording_attrs(design_code((2, 2)).code, rate_hz=30.0, kind="captured", storage={"kind": "float"})
    return RecordingWriter(path, height=4, width=5, dtype="float32", attrs=attrs, **kw)


def _fill(w, n, start=0):
    for i in range(start, start + n):
        w.append(np.full((4, 5), i + 1, np.float32), frame_id=i, timestamp=i / 30, dropped=False)


def test_interrupted_writer_opens_with_the_true_count(tmp_path):
    path = tmp_path / "i.zarr"
    w = _writer(path, block_frames=8)
    _fill(w, 11)  # capacity 16, count 11; never closed (a kill)
    assert zarr.open_group(str(path), mode="r")["frames"].shape == (16, 4, 5)
    rec = open_recording(path)
    assert rec.interrupted and rec.n_frames == 11
    assert isinstance(rec.frames, RowsView) and rec.frames.shape == (11, 4, 5) and len(rec.frames) == 11
    assert rec.frames[:].shape == (11, 4, 5) and rec.frames[-1][0, 0] == 11 and rec.frames[2:4, 0, 0].tolist() == [3, 4]
    assert np.asarray(rec.frames).shape == (11, 4, 5) and rec.normalised_frames(9).shape == (2, 4, 5)
    with pytest.raises(IndexError, match=r"row 11 is out of range for 11 rows"):
        rec.frames[11]
    assert rec.per_frame("frame_id").tolist() == list(range(11))
    # The per-frame arrays lag a block behind (flushed when the arrays grew): the journal rules.
    assert zarr.open_group(str(path), mode="r")["frame_id"][:8].tolist() == list(range(8))


def test_rows_by_a_list_or_a_mask_as_numpy_and_a_fraction_refused(tmp_path):
    # rec.frames[1.5] had been row 1; rec.frames[[0, 2]] had raised a TypeError from int()
    path = tmp_path / "r.zarr"
    w = _writer(path, block_frames=8)
    _fill(w, 11)
    w.close()
    rows = open_recording(path).frames
    whole = rows[:]
    np.testing.assert_array_equal(rows[[0, 2, -1]], whole[[0, 2, -1]])
    np.testing.assert_array_equal(rows[np.array([4, 3])], whole[[4, 3]])
    np.testing.assert_array_equal(rows[np.arange(11) % 3 == 0, 1:3], whole[np.arange(11) % 3 == 0, 1:3])
    assert rows[[]].shape == rows[np.zeros(11, bool)].shape == (0, 4, 5)
    for key in (1.5, "1", [0.5], True):
        with pytest.raises(IndexError, match=r"frames rows are indexed by a whole number, a slice, a list of whole "
                                             r"numbers or 11 booleans; got "):
            rows[key]
    with pytest.raises(IndexError, match=r"row 11 is out of range for 11 rows"):
        rows[[0, 11]]


def test_torn_or_corrupt_journal_records_are_ignored(tmp_path):
    path = tmp_path / "t.zarr"
    w = _writer(path)
    _fill(w, 5)
    _kill(w)
    journal = path / JOURNAL
    with open(journal, "ab") as f:
        f.write(b"\x01" * 10)  # a record torn by the kill
    assert open_recording(path).n_frames == 5
    data = bytearray(journal.read_bytes())
    last = bytearray(data)
    last[16 + 4 * 28] ^= 0xFF  # the last complete record fails its CRC: torn by the kill, ignored
    journal.write_bytes(bytes(last))
    assert open_recording(path).n_frames == 4 and read_journal(journal)["frame_id"].tolist() == [0, 1, 2, 3]
    data[16 + 2 * 28] ^= 0xFF  # record 2 fails with complete records after it: damage, refused
    journal.write_bytes(bytes(data))
    with pytest.raises(RecordingError, match=r"the capture journal is damaged: record 2 of 5 fails its checksum "
                                             r"and 2 complete record\(s\) follow it"):
        open_recording(path)
    with pytest.raises(RecordingError, match=r"journal is damaged"):
        recover_recording(path)  # nothing is trimmed away
    assert zarr.open_group(str(path), mode="r")["frames"].shape[0] >= 5
    journal.write_bytes(b"garbage")
    with pytest.raises(RecordingError, match=r"not a flexvox capture journal"):
        open_recording(path)


def test_arrays_of_different_lengths_after_a_kill_mid_resize_still_open(tmp_path):
    path = tmp_path / "k.zarr"
    w = _writer(path, block_frames=4)
    _fill(w, 6)
    zarr.open_group(str(path), mode="r+")["dropped"].resize((4,))  # killed between two resizes
    rec = open_recording(path)
    assert rec.n_frames == 6 and rec.per_frame("dropped").tolist() == [False] * 6


def test_close_trims_and_recover_finalises(tmp_path):
    w = _writer(tmp_path / "c.zarr", block_frames=8)
    _fill(w, 3)
    w.append(None, frame_id=3, timestamp=0.1, dropped=True)
    w.close(attrs_update={"capture": {"rows": 4}})
    w.close()  # idempotent
    g = zarr.open_group(str(tmp_path / "c.zarr"), mode="r")
    assert g["frames"].shape == (4, 4, 5) and g["dropped"][:].tolist() == [False] * 3 + [True]
    assert not (tmp_path / "c.zarr" / JOURNAL).exists()
    rec = open_recording(tmp_path / "c.zarr")
    assert not rec.interrupted and rec.attrs["capture"] == {"rows": 4} and not rec.frames[3].any()
    with pytest.raises(RecordingError, match=r"the writer is closed"):
        _fill(w, 1)
    w2 = _writer(tmp_path / "r.zarr", block_frames=8)
    _fill(w2, 10)
    with pytest.raises(OutputBusyError, match=r"r.zarr is being written by process \d+"):
        recover_recording(tmp_path / "r.zarr")  # a running capture is not finalised under its writer
    _kill(w2)
    assert recover_recording(tmp_path / "r.zarr") == 10
    rec = open_recording(tmp_path / "r.zarr")
    assert not rec.interrupted and rec.frames.shape == (10, 4, 5) and "recovered_utc" in rec.attrs
    assert rec.per_frame("frame_id").tolist() == list(range(10))
    assert recover_recording(tmp_path / "r.zarr") == 10  # a finished recording is left as it is


def test_full_disk_and_vanished_folder_raise_oserror(tmp_path, monkeypatch):
    import errno
    import os
    import shutil

    import flexvox_core.recording.writer as recording_writer

    w = _writer(tmp_path / "f.zarr")
    _fill(w, 2)
    real_write = os.write
    monkeypatch.setattr(recording_writer.os, "write", lambda fd, data: real_write(fd, data[:5]))
    with pytest.raises(OSError, match=r"short write") as info:
        _fill(w, 1, start=2)
    assert info.value.errno == errno.ENOSPC
    monkeypatch.undo()
    assert open_recording(tmp_path / "f.zarr").n_frames == 2  # the torn record does not count
    v = _writer(tmp_path / "v.zarr")
    _fill(v, 1)
    shutil.rmtree(tmp_path / "v.zarr")
    with pytest.raises(FileNotFoundError, match=r"the recording folder .* vanished"):
        _fill(v, 1, start=1)
    with pytest.raises(FileNotFoundError, match=r"vanished"):
        v.close()
    with pytest.raises(RecordingError, match=r"`block_frames` must be a whole number 1..65536; got 0"):
        _writer(tmp_path / "b.zarr", block_frames=0)


def test_a_writer_that_cannot_write_its_first_metadata_leaves_nothing(tmp_path, monkeypatch):
    """Under a file-size limit the group's first ``zarr.json`` is refused (EFBIG) after its folder was made: the
    writer raises the OS error and removes the folder, which would otherwise read as a damaged recording."""
    import errno

    def refused(store, **kw):
        Path(store).mkdir()
        raise OSError(errno.EFBIG, "File too large")

    monkeypatch.setattr(zarr, "open_group", refused)
    with pytest.raises(OSError, match=r"File too large") as info:
        _writer(tmp_path / "new.zarr")
    assert info.value.errno == errno.EFBIG
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # neither the folder nor its lock file
    monkeypatch.undo()
    old = _writer(tmp_path / "old.zarr")
    _fill(old, 3)
    old.close()
    monkeypatch.setattr(zarr, "open_group", refused)
    with pytest.raises(OSError, match=r"File too large"):
        _writer(tmp_path / "old.zarr", overwrite=True)
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.zarr"]
    assert open_recording(tmp_path / "old.zarr").n_frames == 3  # the recording it was to replace is back


def test_opening_never_lists_the_folder(tmp_path, sim):
    # A capture writing beside a reader renames zarr's temporary metadata files into place (and one killed at
    # that moment leaves one behind): a reader that listed the folder met them (a warning, or a failure when
    # one vanished under it). Each array is looked up by name instead.
    path = write_simulation(tmp_path / "r.zarr", sim)
    (path / "zarr.0123456789abcdef.partial").write_text("{")
    (path / "frames" / "zarr.fedcba9876543210.partial").write_text("{")
    rec = open_recording(path)  # warnings are errors under pytest here
    assert rec.n_frames == 3 and rec.has_ground_truth


class _LookingGroup:
    """A recording's group as a reader sees it while ``moves`` happen between its looks: call k of
    ``group["frames"]`` first runs ``moves[k]`` (if any)."""

    def __init__(self, group, moves):
        self.group, self.moves, self.looks = group, moves, 0

    def __getitem__(self, name):
        move = self.moves.get(self.looks)
        self.looks += 1
        if move:
            move()
        return self.group[name]


def test_a_capture_starting_while_it_is_opened_is_seen_with_its_journal(tmp_path):
    # The reader looked for the journal before the writer made it, and at the frames after their first block
    # was added: that block's empty rows must not pass for frames of a finished recording.
    from flexvox_core.recording.reader import _journal_snapshot

    path = tmp_path / "r.zarr"
    w = _writer(path)
    for i in range(3):
        w.append(np.full((4, 5), 0.5, np.float32), frame_id=i, timestamp=i / 30)
    hidden = tmp_path / "journal.hidden"
    (path / JOURNAL).rename(hidden)  # not made yet when the reader first looks
    group = zarr.open_group(str(path), mode="r")
    shrunk = zarr.open_array(str(path / "frames"), mode="r+")
    shrunk.resize((0, 4, 5))  # nor the first block

    def writer_starts():
        shrunk.resize((64, 4, 5))
        hidden.rename(path / JOURNAL)

    journal, rows = _journal_snapshot(path, _LookingGroup(group, {1: writer_starts}))
    assert journal is not None and len(journal["frame_id"]) == 3 and rows is None
    assert open_recording(path).n_frames == 3
    w.close()


def test_a_recording_that_keeps_changing_while_it_is_opened_is_refused(tmp_path, sim):
    from flexvox_core.recording import SNAPSHOT_TRIES
    from flexvox_core.recording.reader import _journal_snapshot

    path = write_simulation(tmp_path / "r.zarr", sim)
    group = zarr.open_group(str(path), mode="r")
    grown = zarr.open_array(str(path / "frames"), mode="r+")

    def grow():
        grown.resize((grown.shape[0] + 1, *grown.shape[1:]))

    moves = {k: grow for k in range(1, 2 * SNAPSHOT_TRIES, 2)}
    with pytest.raises(RecordingError, match=r"the recording changed while it was opened 5 times \(a capture "
                                              r"starting or finishing in it\); open it again"):
        _journal_snapshot(path, _LookingGroup(group, moves))


def test_a_recording_opened_before_its_capture_grows_keeps_the_rows_it_was_opened_with(tmp_path):
    # Opened between the writer making its arrays and its journal: no frames. Rows added after the opening
    # (the first block of a capture starting) are not frames of that finished-looking recording.
    path = tmp_path / "r.zarr"
    w = _writer(path)
    (path / JOURNAL).rename(tmp_path / "journal.hidden")
    rec = open_recording(path)
    assert not rec.interrupted and rec.n_frames == 0
    zarr.open_array(str(path / "frames"), mode="r+").resize((64, 4, 5))
    assert rec.n_frames == 0 and rec.frames.shape == (0, 4, 5)
    (tmp_path / "journal.hidden").rename(path / JOURNAL)
    w.close()


def test_a_capture_starting_between_the_snapshot_and_the_checks_is_looked_at_again(tmp_path, monkeypatch):
    # Seen without a journal and with no rows; by the time the per-frame arrays are checked the capture has
    # started (its journal made, its arrays grown): the recording is looked at again, not called damaged.
    import flexvox_core.recording.reader as recording_reader

    path = tmp_path / "r.zarr"
    w = _writer(path)
    w.append(np.full((4, 5), 0.5, np.float32), frame_id=0, timestamp=0.0)
    w._flush_per_frame()
    hidden = tmp_path / "journal.hidden"
    (path / JOURNAL).rename(hidden)
    real = recording_reader._journal_snapshot
    calls = []

    def snapshot(p, group):
        calls.append(1)
        if len(calls) == 1:
            got = (None, 0)  # as seen before the capture grew anything
            hidden.rename(path / JOURNAL)  # ... which it does right after
            return got
        return real(p, group)

    monkeypatch.setattr(recording_reader, "_journal_snapshot", snapshot)
    rec = open_recording(path)
    assert len(calls) == 2 and rec.interrupted and rec.n_frames == 1
    w.close()


@pytest.mark.parametrize("calibrated, said", [(False, ", uncalibrated>"), (True, ", calibrated>")])
def test_a_captures_repr_says_calibrated_only_when_it_was(tmp_path, calibrated, said):
    attrs = recording_attrs(np.eye(4, dtype=bool).reshape(2, 2, 4), rate_hz=30.0, kind="captured",
                            storage={"kind": "float"}, calibration={"calibrated": calibrated, "source": "x"})
    with RecordingWriter(tmp_path / "c.zarr", height=4, width=4, dtype="float32", attrs=attrs) as w:
        w.append(np.ones((4, 4), np.float32), frame_id=0, timestamp=0.0)
    rec = open_recording(tmp_path / "c.zarr")
    assert rec.calibration["calibrated"] is calibrated  # a capture always records its calibration, as a dict
    assert repr(rec).endswith(said)


def test_recording_names_say_what_they_hold_and_old_names_warn(tmp_path):
    from flexvox_core import code_from_order, render_scene, sequential_order
    from flexvox_core.recording import GroundTruthRows

    sim = simulate_video(render_scene("balls", 12, 16, 20, seed=3), code_from_order(sequential_order((2, 2))))
    path = write_simulation(tmp_path / "r.zarr", sim)
    rec = open_recording(path)
    assert isinstance(rec.ground_truth, GroundTruthRows)
    np.testing.assert_array_equal(rec.ground_truth[:2], sim.ground_truth[:2])  # an array-like: slices
    np.testing.assert_array_equal(np.asarray(rec.ground_truth), sim.ground_truth)
    assert rec.n_frames == 3 and rec.tile == (2, 2) and rec.shape == (3, 16, 20) and rec.camera_hz == 15.0
    assert rec.dropped.dtype == bool and rec.dropped.shape == (3,) and rec.calibration is None
    assert repr(rec).startswith("<Recording r.zarr: 3 frames of 16x20, tile 2x2 (K = 4), 15 Hz, 0 dropped, ground")
    assert "<th style='text-align:left'>tile</th><td>2×2 (K = 4)</td>" in rec._repr_html_()
    assert "ground truth: 12x16x20 float32" in repr(rec.ground_truth)
    with pytest.warns(DeprecationWarning, match=r"calling it is deprecated .*rec\.ground_truth\[start:stop\]"):
        old = rec.ground_truth(1, 3)
    np.testing.assert_array_equal(old, sim.ground_truth[1:3])
    with pytest.warns(DeprecationWarning, match=r"`Recording\.ground_truth_rows` is deprecated .*use `ground_truth`"):
        assert rec.ground_truth_rows.shape == (12, 16, 20)
    with pytest.warns(DeprecationWarning, match=r"`Recording\.rows` is deprecated .*use `n_frames`"):
        assert rec.rows == 3
