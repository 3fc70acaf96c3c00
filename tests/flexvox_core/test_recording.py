import json

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
    assert np.array_equal(rec.ground_truth(), sim.ground_truth)
    assert rec.per_frame("frame_id").tolist() == [0, 1, 2]
    assert rec.attrs["schema_version"] == SCHEMA_VERSION and rec.attrs["seed"] == 7
    assert rec.attrs["order"] == design_code((4, 4)).order.tolist()
    assert rec.attrs["rates"] == {"camera_hz": 15.0, "subframe_hz": 240.0}
    # Readable by plain zarr, no flexvox needed.
    g = zarr.open_group(str(path), mode="r")
    assert g["frames"].shape == (3, 12, 20)


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
    with pytest.raises(RecordingError, match=r"already exists"):
        write_simulation(tmp_path / "r.zarr", sim)
    write_simulation(tmp_path / "r.zarr", sim, overwrite=True)


def _edit_attrs(path, fn):
    meta = json.loads((path / "zarr.json").read_text())
    fn(meta["attributes"]["flexvox"])
    (path / "zarr.json").write_text(json.dumps(meta))


def test_schema_missing_or_newer(tmp_path, sim):
    path = write_simulation(tmp_path / "r.zarr", sim)
    _edit_attrs(path, lambda a: a.update(schema_version=SCHEMA_VERSION + 1))
    with pytest.raises(RecordingError, match=r"schema version 2 is newer than this software reads \(1\)"):
        open_recording(path)
    _edit_attrs(path, lambda a: a.pop("schema_version"))
    with pytest.raises(RecordingError, match=r"has no schema_version"):
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
