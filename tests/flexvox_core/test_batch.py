"""Batch reconstruction with dask equals the in-memory reconstruction."""

import numpy as np
import pytest
import zarr

from flexvox_core.batch import _chunks, batch_video, reconstruct_batch
from flexvox_core.design import design_code
from flexvox_core.methods import Method
from flexvox_core.recording import open_recording, write_simulation
from flexvox_core.simulate.simulator import simulate_video
from flexvox_core.video_api import reconstruct_video


@pytest.fixture
def rec_path(tmp_path, rng):
    v = rng.random((11 * 4, 12, 16)).astype(np.float32)
    return write_simulation(tmp_path / "r.zarr", simulate_video(v, design_code((2, 2)).code, seed=1))


METHODS = [Method(), Method("rebin"), Method("diffusion", solver="explicit"), Method("gap-tv", iterations=5)]


@pytest.mark.parametrize("method", METHODS, ids=lambda m: m.label())
def test_batch_equals_in_memory(rec_path, tmp_path, method):
    rec = open_recording(rec_path)
    expected = reconstruct_video(rec.normalised_frames(), rec.code, method, chunk_frames=None)
    done = []
    result = reconstruct_batch(rec_path, tmp_path / "o.zarr", method, chunk_frames=3,
                               progress=lambda d, t: done.append((d, t)))
    out = zarr.open_group(str(tmp_path / "o.zarr"), mode="r")["video"]
    assert out.chunks == (1, 12, 16) and result.shape == (44, 12, 16)
    np.testing.assert_allclose(out[:], expected, atol=1e-5)
    assert done[-1][0] == done[-1][1] >= 1 and [d for d, _ in done] == sorted(d for d, _ in done)


def test_motion_aware_batch_equals_in_memory_with_slow_voxels(tmp_path):
    # A slow pan: the slow voxels' gather weighs samples by a range scaled to the whole recording's.
    from flexvox_core.simulate.scenes import render_scene

    code = design_code((2, 4)).code
    path = write_simulation(tmp_path / "pan.zarr", simulate_video(render_scene("pan", 10 * 8, 24, 32), code, seed=1))
    rec = open_recording(path)
    method = Method("motion-aware", time=2.0)
    expected = reconstruct_video(rec.normalised_frames(), rec.code, method, chunk_frames=None)
    reconstruct_batch(path, tmp_path / "o.zarr", method, chunk_frames=3)
    np.testing.assert_array_equal(zarr.open_group(str(tmp_path / "o.zarr"), mode="r")["video"][:], expected)


def test_batch_on_a_distributed_cluster(rec_path, tmp_path):
    from distributed import LocalCluster

    rec = open_recording(rec_path)
    expected = reconstruct_video(rec.normalised_frames(), rec.code, Method(), chunk_frames=None)
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        result = reconstruct_batch(rec_path, tmp_path / "d.zarr", Method(), chunk_frames=4,
                                   scheduler=cluster.scheduler_address)
    assert result.scheduler == cluster.scheduler_address
    np.testing.assert_allclose(zarr.open_group(str(tmp_path / "d.zarr"), mode="r")["video"][:], expected, atol=1e-5)


def test_chunks_and_refusals(rec_path, tmp_path):
    assert _chunks(10, 4, 1) == (4, 4, 2) and _chunks(9, 4, 2) == (4, 5) and _chunks(3, 8, 1) == (3,)
    rec = open_recording(rec_path)
    with pytest.raises(ValueError, match=r"global solve and cannot run in chunks"):
        batch_video(rec, Method("diffusion", solver="steady"))
    video, ov = batch_video(rec, Method("diffusion", solver="explicit"), chunk_frames=1)
    assert ov > 1 and video.chunks[0][0] >= ov * 4  # chunks raised to the overlap
    with pytest.raises(ValueError, match=r"`chunk_frames` must be a whole number >= 1; got 0"):
        batch_video(rec, Method(), chunk_frames=0)
    with pytest.raises(ValueError, match=r"is the input .*: an output never replaces its input, whatever the flags"):
        reconstruct_batch(rec_path, rec_path, Method(), overwrite=True)
    (tmp_path / "old.zarr").mkdir()
    with pytest.raises(ValueError, match=r"old.zarr already exists; choose another path, or pass overwrite=True"):
        reconstruct_batch(rec_path, tmp_path / "old.zarr", Method())


def test_batch_takes_a_distributed_client_and_a_cluster(rec_path, tmp_path):
    from distributed import Client, LocalCluster

    rec = open_recording(rec_path)
    method = Method("diffusion")
    expected = reconstruct_video(rec.normalised_frames(), rec.code, method, chunk_frames=None)
    seen = []
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None) as cluster:
        with Client(cluster) as client:
            result = reconstruct_batch(rec_path, tmp_path / "c.zarr", method, chunk_frames=4, scheduler=client,
                                       progress=lambda d, t: seen.append((d, t)))
            assert client.status == "running"  # the caller's client is left open
        assert result.scheduler == cluster.scheduler_address
        reconstruct_batch(rec_path, tmp_path / "l.zarr", method, chunk_frames=4, scheduler=cluster)
    assert seen == [(0, 3), (3, 3)]
    for name in ("c.zarr", "l.zarr"):
        np.testing.assert_allclose(zarr.open_group(str(tmp_path / name), mode="r")["video"][:], expected, atol=1e-5)


def test_batch_takes_a_method_by_name_and_progress_true_false_or_a_callable(rec_path, tmp_path):
    import inspect

    from flexvox_core.methods.registry import DEFAULT

    rec = open_recording(rec_path)
    expected = reconstruct_video(rec.normalised_frames(), rec.code, Method("diffusion", time=2), chunk_frames=None)
    for i, progress in enumerate((True, False, None)):
        reconstruct_batch(rec, tmp_path / f"{i}.zarr", "diffusion", time=2, chunk_frames=4, progress=progress)
        np.testing.assert_array_equal(zarr.open_group(str(tmp_path / f"{i}.zarr"), mode="r")["video"][:], expected)
    with pytest.raises(TypeError, match=r"`progress` must be True \(a bar\), False or None \(nothing\), or a "
                                        r"callable progress\(done, total\); got int 1"):
        reconstruct_batch(rec_path, tmp_path / "x.zarr", "diffusion", progress=1)
    with pytest.raises(TypeError, match=r"`method` must be an fv\.Method .*; got float 1.5"):
        reconstruct_batch(rec_path, tmp_path / "x.zarr", 1.5)
    # The default method is the one the docstring names.
    assert DEFAULT == "motion-aware" and "Default: motion-aware" in inspect.getdoc(reconstruct_batch)
