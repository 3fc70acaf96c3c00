"""The plugin's napari-free half: the reader's layer tuples and the cancellable reconstruction steps.

These run without napari installed (napari's reader contract is plain Python), so they also hold in
``pip install flexvox`` environments and guard the plugin's logic where napari cannot run.
"""

import threading

import numpy as np
import pytest
import zarr

from flexvox_app.napari_plugin import layers
from flexvox_core.methods import Method
from flexvox_core.recording import open_recording
from flexvox_core.video_api import reconstruct_video
from flexvox_core.video_io import write_video

pytestmark = pytest.mark.recording("fan", size=(24, 32), tile=(2, 2), scene_seed=3, noise_seed=1)


def test_a_recording_opens_as_coded_frames_and_ground_truth_with_time_in_seconds(recording):
    assert layers.get_reader(str(recording)) is layers.read and layers.get_reader([str(recording)]) is layers.read
    (frames, fk, ft), (truth, tk, tt) = layers.read(str(recording))
    assert ft == tt == "image"
    assert fk["name"] == "rec: coded frames" and tk["name"] == "rec: ground truth"
    assert fk["scale"] == pytest.approx((1 / 15, 1, 1)) and tk["scale"] == pytest.approx((1 / 60, 1, 1))
    # a coded frame sits at its exposure's centre: (K - 1) / 2 sub-frames after its start
    assert fk["translate"] == pytest.approx((1.5 / 60, 0, 0))
    rec = open_recording(recording)
    assert frames.shape == (6, 24, 32) and truth.shape == (24, 24, 32)
    np.testing.assert_array_equal(np.asarray(frames[2]), rec.frames[2])
    np.testing.assert_array_equal(np.asarray(truth[5]), rec.ground_truth[5:6][0])
    assert fk["metadata"]["flexvox"]["recording"] == str(rec.path) and fk["metadata"]["flexvox"]["K"] == 4
    assert layers.recording_of(fk["metadata"]) == str(rec.path) and layers.recording_of({}) is None


def test_the_frames_layer_reads_through_the_checksums(recording):
    (frames, _, _), _ = layers.read(str(recording))
    changed = zarr.open_group(str(recording), mode="r+")["frames"]
    changed[3] = changed[3] + 1  # the chunk is valid Zarr, but no longer what was recorded
    np.asarray(frames[2])  # the other rows still read
    with pytest.raises(ValueError, match=r"row.* 3"):
        np.asarray(frames[3])


def test_a_reconstruction_opens_with_its_sub_frame_period_and_method(recording, tmp_path):
    video = np.linspace(0, 1, 24 * 24 * 32, dtype=np.float32).reshape(24, 24, 32)
    method = Method("rebin")
    write_video(tmp_path / "v.zarr", video, time_step=1 / 60, attrs={"source": str(recording),
                                                                     "method": method.as_dict()})
    assert layers.get_reader(str(tmp_path / "v.zarr")) is layers.read
    ((data, kwargs, kind),) = layers.read(str(tmp_path / "v.zarr"))
    assert kind == "image" and kwargs["name"] == f"v: {method.label()}" and not kwargs["multiscale"]
    assert kwargs["scale"] == pytest.approx((1 / 60, 1, 1)) and kwargs["contrast_limits"] == (0.0, 1.0)
    np.testing.assert_array_equal(data[:], video)


def test_a_pyramid_opens_as_napari_multiscale(tmp_path):
    write_video(tmp_path / "p.zarr", np.zeros((3, 16, 16)), time_step=0.01, pyramid=2)
    ((data, kwargs, _),) = layers.read(str(tmp_path / "p.zarr"))
    assert kwargs["multiscale"] and [d.shape for d in data] == [(3, 16, 16), (3, 8, 8), (3, 4, 4)]


def test_a_store_from_before_ngff_opens_with_its_recordings_time_step(recording, tmp_path):
    group = zarr.open_group(str(tmp_path / "old.zarr"), mode="w-", zarr_format=3)
    group.create_array("video", shape=(24, 24, 32), chunks=(1, 24, 32), dtype="float32")
    group.attrs["flexvox"] = {"source": str(recording), "method": {"name": "no-longer-registered"}}
    ((_, kwargs, _),) = layers.read(str(tmp_path / "old.zarr"))
    assert kwargs["name"] == "old: no-longer-registered" and kwargs["scale"] == pytest.approx((1 / 60, 1, 1))


def test_other_paths_are_not_ours(tmp_path):
    zarr.open_group(str(tmp_path / "plain.zarr"), mode="w-", zarr_format=3).create_array("x", shape=(2,),
                                                                                          dtype="int8")
    (tmp_path / "folder").mkdir()
    for path in (tmp_path / "plain.zarr", tmp_path / "folder", tmp_path / "missing.zarr"):
        assert layers.get_reader(str(path)) is None and layers.what_is(path) is None
    assert layers.get_reader([str(tmp_path / "a.zarr"), str(tmp_path / "b.zarr")]) is None
    with pytest.raises(ValueError, match=r"plain.zarr: not a flexvox recording or reconstruction"):
        layers.read(str(tmp_path / "plain.zarr"))


def _drain(steps):
    done = []
    try:
        while True:
            done.append(next(steps))
    except StopIteration as stop:
        return done, stop.value


def test_the_steps_yield_after_each_chunk_and_return_the_runners_result(recording):
    method = Method("diffusion")
    done, out = _drain(layers.reconstruction_steps(str(recording), method, chunk_frames=2))
    assert done == [2, 2, 2]  # camera frames per chunk, 6 frames in chunks of 2
    rec = open_recording(recording)
    np.testing.assert_allclose(out.video, reconstruct_video(rec.normalised_frames(), rec.code, method, chunk_frames=2),
                               atol=1e-6)


def test_the_steps_run_on_the_gpu_asked_for_and_the_result_says_so(tmp_path):
    from flexvox_core.design import design_code
    from flexvox_core.recording import write_simulation
    from flexvox_core.simulate.scenes import render_scene
    from flexvox_core.simulate.simulator import simulate_video

    video = render_scene("fan", 2 * 4, 8, 8, seed=3)  # tiny: the tests' simulator runs every GPU thread as Python
    tiny = write_simulation(tmp_path / "tiny.zarr", simulate_video(video, design_code((2, 2)).code, seed=1))
    method = Method("diffusion")
    _, on_gpu = _drain(layers.reconstruction_steps(str(tiny), method, device="cuda"))
    _, by_default = _drain(layers.reconstruction_steps(str(tiny), method))
    assert on_gpu.device == "cuda" and by_default.device == "cpu"  # auto never takes the tests' simulator
    np.testing.assert_allclose(on_gpu.video, by_default.video, atol=2e-6)


def test_cancel_stops_at_the_next_chunk_boundary(recording):
    cancel = threading.Event()
    steps = layers.reconstruction_steps(str(recording), Method("diffusion"), chunk_frames=1, cancel=cancel)
    assert next(steps) == 1  # the runner now waits for the consumer: no chunk runs ahead
    cancel.set()
    with pytest.raises(layers.Cancelled, match="the reconstruction was cancelled"):
        next(steps)


def test_closing_the_steps_stops_the_runner(recording):
    steps = layers.reconstruction_steps(str(recording), Method("diffusion"), chunk_frames=1)
    next(steps)
    before = {t for t in threading.enumerate() if t.name == "flexvox-napari-reconstruction"}
    assert before
    steps.close()
    assert not any(t.is_alive() for t in before)


def test_dropped_frames_are_bridged_not_read_as_black(tmp_path):
    # The plugin reconstructs through the reader, which hands the runner the recording's dropped frames.
    from flexvox_core.design import design_code
    from flexvox_core.recording import write_simulation
    from flexvox_core.simulate.simulator import simulate_video

    result = simulate_video(np.full((6 * 4, 12, 16), 0.5, np.float32), design_code((2, 2)).code)
    result.frames[3] = 0
    result.dropped[3] = True
    path = write_simulation(tmp_path / "d.zarr", result)
    method = Method("diffusion")
    _, out = _drain(layers.reconstruction_steps(str(path), method, chunk_frames=2))
    np.testing.assert_allclose(out.video, 0.5, atol=1e-5)  # the zero row is no sample: the gap is bridged
    video = layers.result_layers(out, method=method, recording=str(path), subframe_hz=60.0, K=4)[0]
    assert video[1]["metadata"]["flexvox"]["interpolated_subframes"] == [12, 13, 14, 15]


def test_a_recording_that_cannot_be_reconstructed_says_why(tmp_path):
    with pytest.raises(ValueError, match="missing.zarr"):
        next(layers.reconstruction_steps(str(tmp_path / "missing.zarr"), Method()))


@pytest.mark.recording(frames=3, size=(32, 40), tile=(4, 4), scene_seed=2, noise_seed=1, name="moving.zarr")
def test_motion_aware_results_become_video_flow_wheel_and_tr_map_layers(recording):
    method = Method("motion-aware")
    _, out = _drain(layers.reconstruction_steps(str(recording), method, extras=True, chunk_frames=8))
    video, flow, tr = layers.result_layers(out, method=method, recording=str(recording), subframe_hz=240.0, K=16)
    assert video[0].shape == (48, 32, 40) and video[1]["name"] == f"moving: {method.label()}"
    assert flow[0].shape == (48, 32, 40, 3) and flow[0].dtype == np.uint8 and flow[1]["rgb"]
    assert flow[1]["name"].startswith("moving: flow (colour wheel, full = ")
    assert flow[1]["metadata"]["flexvox"]["max_px_per_subframe"] > 0
    assert tr[1]["name"] == "moving: TR map (1 = high SR, 16 = high TR; SR = 1/TR)"
    assert tr[1]["contrast_limits"] == (1.0, 16.0) and 1 <= tr[0].min() <= tr[0].max() <= 16
    for _, kwargs, kind in (video, flow, tr):
        assert kind == "image" and kwargs["scale"] == pytest.approx((1 / 240, 1, 1))


def test_a_method_without_extras_gives_only_the_video(recording):
    method = Method("rebin")
    _, out = _drain(layers.reconstruction_steps(str(recording), method))
    assert [k["name"] for _, k, _ in layers.result_layers(out, method=method, recording=str(recording),
                                                       subframe_hz=60.0, K=4)] == [f"rec: {method.label()}"]
