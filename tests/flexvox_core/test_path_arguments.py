"""A path argument that is no path (bytes, an array, a result object, a number) is refused in words, naming the
call's order where the arguments look swapped, before anything is written."""

import numpy as np
import pytest

import flexvox_core as fv
from flexvox_core.output_files import check_path


def test_check_path_takes_text_and_paths_and_names_what_it_got(tmp_path):
    assert check_path(str(tmp_path / "v.npy")) == tmp_path / "v.npy"
    assert check_path(tmp_path / "v.npy") == tmp_path / "v.npy"
    with pytest.raises(TypeError, match=r"`path` must be a file path \(str or pathlib.Path\); got bytes b'v.npy': "
                                        r"give the path as text, 'v.npy'"):
        check_path(b"v.npy")
    with pytest.raises(TypeError, match=r"`out` must be a file path .*; got int 5$"):
        check_path(5, "out")
    with pytest.raises(TypeError, match=r"got NoneType None \(fv.read_video\(path\) takes a path\)"):
        check_path(None, call="fv.read_video(path)")


def test_videos_refuse_swapped_arguments_and_bytes(tmp_path):
    video = np.zeros((3, 8, 8), np.float32)
    with pytest.raises(TypeError, match=r"got ndarray of shape \(3, 8, 8\): the path comes first, "
                                        r"fv.write_video\(path, video\)"):
        fv.write_video(video, str(tmp_path / "v.npy"))
    with pytest.raises(TypeError, match=r"got bytes b'.*v.npy': give the path as text"):
        fv.write_video(str(tmp_path / "v.npy").encode(), video)
    assert not list(tmp_path.iterdir())
    fv.write_video(tmp_path / "v.npy", video)
    with pytest.raises(TypeError, match=r"`path` must be a file path .*got bytes"):
        fv.read_video(str(tmp_path / "v.npy").encode())
    with pytest.raises(TypeError, match=r"`path` must be a file path .*got bytes"):
        fv.open_video_store(b"v.zarr")


def test_a_simulation_and_a_batch_refuse_swapped_arguments(tmp_path):
    code = fv.design_code((2, 2)).code
    sim = fv.simulate_video(fv.render_scene("balls", 8, 16, 16), code)
    with pytest.raises(TypeError, match=r"got SimulationResult: the path comes first, "
                                        r"fv.write_simulation\(path, result\)"):
        fv.write_simulation(sim, str(tmp_path / "s.zarr"))
    with pytest.raises(TypeError, match=r"`result` must be a SimulationResult \(fv.simulate_video\(video, code\)\); "
                                        r"got ndarray"):
        fv.write_simulation(tmp_path / "s.zarr", sim.frames)
    assert not list(tmp_path.iterdir())
    rec = fv.write_simulation(tmp_path / "s.zarr", sim)
    with pytest.raises(TypeError, match=r"`output` must be a file path .*got int 5: the path comes first, "
                                        r"fv.reconstruct_batch\(recording, output, method\)"):
        fv.reconstruct_batch(rec, 5, "rebin")
