"""A recording is created only under a name ending in .zarr, by every writer of recordings (a folder named run1.npy
would be taken for an array by every command that reads it)."""

import numpy as np
import pytest

import flexvox_core as fv
from flexvox_core.output_files import OutputError, check_output
from flexvox_core.recording import RecordingWriter


def _sim():
    code = fv.design_code((2, 2)).code
    return fv.simulate_video(fv.render_scene("balls", 8, 8, 8, seed=0), code)


@pytest.mark.parametrize("name, got, suggested", [("run1.npy", "ends in .npy", "run1.zarr"),
                                                   ("run1", "has no suffix", "run1.zarr")])
def test_a_recording_under_another_name_is_refused_and_nothing_is_made(tmp_path, name, got, suggested):
    with pytest.raises(OutputError, match=rf"a recording \(a Zarr store\) is a folder whose name ends in .zarr: "
                                             rf".*{name} {got}; write .*{suggested}$"):
        fv.write_simulation(tmp_path / name, _sim())
    with pytest.raises(OutputError, match=r"whose name ends in .zarr"):
        RecordingWriter(tmp_path / name, height=8, width=8, dtype="float32", attrs={})
    assert list(tmp_path.iterdir()) == []  # no store, no lock, no partial sibling


def test_check_output_of_a_store_names_the_suffix_rule_and_a_zarr_name_passes(tmp_path):
    with pytest.raises(OutputError, match=r"run1.npy ends in .npy; write .*run1.zarr"):
        check_output(tmp_path / "run1.npy", kind="store")
    assert check_output(tmp_path / "run1.ZARR", kind="store") == tmp_path / "run1.ZARR"  # any case, as output_kind
    assert fv.open_recording(fv.write_simulation(tmp_path / "run1.zarr", _sim())).n_frames == 2
    assert np.isfinite(fv.open_recording(tmp_path / "run1.zarr").frames[:]).all()
