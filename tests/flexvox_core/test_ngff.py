"""OME-Zarr (NGFF 0.5) images: every image flexvox writes validates against ome-zarr-models' NGFF models,
with axes t, y, x and the right time step; older stores and recordings still read; Fiji's TIFF carries
the frame interval."""

import json
import subprocess
import sys

import numpy as np
import pytest
import tifffile
import zarr

from flexvox_app.cli.main import main
from flexvox_core import ngff
from flexvox_core.batch import reconstruct_batch
from flexvox_core.design import design_code
from flexvox_core.methods import Method
from flexvox_core.recording import RecordingWriter, open_recording, recording_attrs, write_simulation
from flexvox_core.simulate.simulator import simulate_video
from flexvox_core.video_io import open_video_store, write_video


def _multiscale(path):
    """The validated model's one multiscale (validate_image raises when NGFF refuses the store)."""
    model = ngff.validate_image(path)
    (multiscale,) = model.ome_attributes.multiscales
    return multiscale


def _scales(multiscale):
    return [list(d.coordinateTransformations[0].scale) for d in multiscale.datasets]


def _axes(multiscale):
    return [(a.name, a.type, a.unit) for a in multiscale.axes]


def _attrs_through_the_models(dataset, *, time_step, levels=0, name=None):
    """The ``ome`` block built through ome-zarr-models' pydantic models, which refuse what NGFF does not allow."""
    from ome_zarr_models.v05.axes import Axis
    from ome_zarr_models.v05.image import ImageAttrs
    from ome_zarr_models.v05.multiscales import Dataset, Multiscale

    axes = [Axis(name="t", type="time", unit="second" if time_step is not None else None),
            Axis(name="y", type="space"), Axis(name="x", type="space")]
    datasets = [Dataset.build(path=ngff.level_path(dataset, i), scale=[time_step or 1.0, 2.0 ** i, 2.0 ** i],
                              translation=[0.0, (2 ** i - 1) / 2, (2 ** i - 1) / 2] if i else None)
                for i in range(levels + 1)]
    multiscale = Multiscale(axes=axes, datasets=datasets, name=name or dataset, type="local_mean" if levels else None)
    return ImageAttrs(version=ngff.NGFF_VERSION, multiscales=[multiscale]).model_dump(mode="json", exclude_none=True)


@pytest.mark.parametrize("dataset, time_step, levels, name", [
    ("video", 1 / 240, 0, None), ("video", 1 / 240, 3, None), ("video", None, 0, None), ("video", None, 2, "v"),
    ("frames", 1 / 15, 0, "frames"), ("frames", None, 0, "frames"), ("video", 0.5, np.int64(1), None)])
def test_the_ome_block_equals_what_ome_zarr_models_builds(dataset, time_step, levels, name):
    """Writing builds the block as a plain dict (no pydantic at run time): it must be the models' own, every form."""
    from ome_zarr_models.v05.image import ImageAttrs

    ours = ngff.image_attrs(dataset, time_step=time_step, levels=levels, name=name)
    assert ours == _attrs_through_the_models(dataset, time_step=time_step, levels=int(levels), name=name)
    # and on its own terms: the models take the dict as it is and give it back unchanged
    assert ImageAttrs.model_validate(ours).model_dump(mode="json", exclude_none=True) == ours
    assert json.loads(json.dumps(ours)) == ours  # plain JSON types only


@pytest.mark.parametrize("levels", [-1, True, 1.5, "2"])
def test_the_ome_block_refuses_bad_levels(levels):
    with pytest.raises(ValueError, match=r"the pyramid levels must be a whole number >= 0; got"):
        ngff.image_attrs("video", time_step=None, levels=levels)


def test_the_validator_without_ome_zarr_models_says_what_to_install(tmp_path, monkeypatch):
    write_video(tmp_path / "v.zarr", np.zeros((2, 4, 4), np.float32))
    monkeypatch.setitem(sys.modules, "ome_zarr_models.v05.image", None)  # as if it were not installed
    with pytest.raises(ImportError, match=r"needs ome-zarr-models .*pip install 'flexvox\[test\]'"):
        ngff.validate_image(tmp_path / "v.zarr")


def test_writing_an_image_does_not_import_pydantic(tmp_path):
    """The models are for checking (the tests, ``validate_image``); a writer never loads them."""
    code = ("import sys, numpy as np\n"
            "from flexvox_core.video_io import write_video\n"
            f"write_video({str(tmp_path / 'v.zarr')!r}, np.zeros((2, 4, 4), np.float32), time_step=0.01, pyramid=1)\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in ('pydantic', 'ome_zarr_models')))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"
    ngff.validate_image(tmp_path / "v.zarr")


@pytest.fixture
def rec_path(tmp_path, rng):
    v = rng.random((6 * 4, 12, 16)).astype(np.float32)
    sim = simulate_video(v, design_code((2, 2)).code, seed=1)
    return write_simulation(tmp_path / "r.zarr", sim)


def test_write_video_zarr_is_a_valid_ngff_image_with_the_time_step(tmp_path, rng):
    v = rng.random((5, 9, 12)).astype(np.float32)
    write_video(tmp_path / "v.zarr", v, time_step=1 / 240, attrs={"method": {"name": "rebin"}})
    ms = _multiscale(tmp_path / "v.zarr")
    assert _axes(ms) == [("t", "time", "second"), ("y", "space", None), ("x", "space", None)]
    assert [d.path for d in ms.datasets] == ["video"] and _scales(ms) == [[1 / 240, 1.0, 1.0]]
    group = zarr.open_group(str(tmp_path / "v.zarr"), mode="r")
    assert sorted(group.array_keys()) == ["video"]  # no pyramid unless asked for
    assert group["video"].metadata.dimension_names == ("t", "y", "x") and group["video"].chunks == (1, 9, 12)
    np.testing.assert_array_equal(group["video"][:], v)
    meta = group.attrs["flexvox"]
    assert meta["method"] == {"name": "rebin"} and meta["time_step_s"] == 1 / 240 and meta["software_version"]


def test_a_pyramid_is_valid_and_each_level_is_the_2x2_mean(tmp_path, rng):
    v = rng.random((3, 9, 13)).astype(np.float32)
    write_video(tmp_path / "p.zarr", v, time_step=0.01, pyramid=2)
    ms = _multiscale(tmp_path / "p.zarr")
    assert [d.path for d in ms.datasets] == ["video", "video_1", "video_2"]
    assert _scales(ms) == [[0.01, 1.0, 1.0], [0.01, 2.0, 2.0], [0.01, 4.0, 4.0]]
    assert list(ms.datasets[2].coordinateTransformations[1].translation) == [0.0, 1.5, 1.5]
    store = open_video_store(tmp_path / "p.zarr")
    assert [a.shape for a in store.levels] == [(3, 9, 13), (3, 4, 6), (3, 2, 3)]
    level1 = v[:, :8, :12].reshape(3, 4, 2, 6, 2).mean(axis=(2, 4))
    np.testing.assert_allclose(store.levels[1][:], level1, rtol=1e-6)
    np.testing.assert_allclose(store.levels[2][:], level1[:, :, :].reshape(3, 2, 2, 3, 2).mean(axis=(2, 4)),
                               rtol=1e-6)


@pytest.mark.parametrize("kwargs, match", [
    ({"pyramid": 4}, r"pyramid levels must be a whole number from 0 to 3 \(each level halves the 9x13 image"),
    ({"pyramid": -1}, r"from 0 to 3 .*got -1"),
    ({"time_step": 0.0}, r"the time step must be a positive finite number of seconds; got 0.0"),
    ({"time_step": float("nan")}, r"the time step must be a positive finite number of seconds; got nan"),
])
def test_bad_pyramid_or_time_step_is_refused_before_writing(tmp_path, kwargs, match):
    with pytest.raises(ValueError, match=match):
        write_video(tmp_path / "v.zarr", np.zeros((2, 9, 13)), **kwargs)
    assert not (tmp_path / "v.zarr").exists()


def test_a_pyramid_goes_only_into_zarr(tmp_path):
    with pytest.raises(ValueError, match=r"a pyramid is written only into a .zarr store; got .*v.tif with pyramid=1"):
        write_video(tmp_path / "v.tif", np.zeros((2, 8, 8)), pyramid=1)


def test_the_validator_refuses_a_store_flexvox_wrote_before(tmp_path, rng):
    # The earlier layout (array `video`, no `ome`, no dimension_names): not NGFF, but still read.
    v = rng.random((4, 6, 8)).astype(np.float32)
    group = zarr.open_group(str(tmp_path / "old.zarr"), mode="w-", zarr_format=3)
    group.create_array("video", shape=v.shape, chunks=(1, 6, 8), dtype="float32")[:] = v
    group.attrs["flexvox"] = {"source": "gone.zarr", "method": {"name": "rebin"}}
    with pytest.raises(ValueError, match=r"old.zarr is not a valid OME-Zarr 0.5 image: .*'ome'"):
        ngff.validate_image(tmp_path / "old.zarr")
    store = open_video_store(tmp_path / "old.zarr")
    np.testing.assert_array_equal(store.array[:], v)
    assert store.time_step is None and store.attrs["method"] == {"name": "rebin"} and len(store.levels) == 1


def test_an_old_store_takes_its_time_step_from_its_recording_when_it_is_there(tmp_path, rec_path):
    group = zarr.open_group(str(tmp_path / "old.zarr"), mode="w-", zarr_format=3)
    group.create_array("video", shape=(24, 12, 16), chunks=(1, 12, 16), dtype="float32")
    group.attrs["flexvox"] = {"source": str(rec_path)}
    rate = open_recording(rec_path).attrs["rates"]["subframe_hz"]
    assert open_video_store(tmp_path / "old.zarr").time_step == pytest.approx(1 / rate)


def test_open_video_store_names_what_is_not_a_reconstruction(tmp_path, rec_path):
    with pytest.raises(ValueError, match=r"r.zarr: no `video` array: a recording \(camera frames\): fv.open_recording "
                                         r"opens it"):
        open_video_store(rec_path)
    zarr.open_group(str(tmp_path / "other.zarr"), mode="w", zarr_format=3)
    with pytest.raises(ValueError, match=r"other.zarr: no `video` array: not a flexvox reconstruction"):
        open_video_store(tmp_path / "other.zarr")


def test_a_recordings_frames_are_a_valid_ngff_image_one_camera_frame_per_step(rec_path):
    rec = open_recording(rec_path)
    ms = _multiscale(rec_path)
    assert [d.path for d in ms.datasets] == ["frames"] and ms.name == "frames"
    assert _scales(ms) == [[1 / rec.attrs["rates"]["camera_hz"], 1.0, 1.0]]
    assert _axes(ms)[0] == ("t", "time", "second")
    group = zarr.open_group(str(rec_path), mode="r")
    assert group["frames"].metadata.dimension_names == ("t", "y", "x")
    assert rec.attrs["schema_version"] == 2  # the layout is unchanged: no schema bump
    assert rec.verify() == []


def test_a_captured_recording_is_valid_ngff_while_written_and_when_closed(tmp_path):
    code = design_code((2, 2)).code
    attrs = recording_attrs(code, rate_hz=15.0, kind="captured", storage={"kind": "counts", "black_level": 0,
                                                                          "gain": 1, "electrons_per_unit": 1})
    with RecordingWriter(tmp_path / "c.zarr", height=8, width=10, dtype="uint16", attrs=attrs, block_frames=4) as w:
        w.append(np.ones((8, 10), np.uint16), frame_id=0, timestamp=0.0)
        assert _scales(_multiscale(tmp_path / "c.zarr")) == [[1 / 15, 1.0, 1.0]]
        for i in range(1, 6):
            w.append(np.full((8, 10), i, np.uint16), frame_id=i, timestamp=i / 15)
    ms = _multiscale(tmp_path / "c.zarr")
    assert ms.datasets[0].path == "frames"
    rec = open_recording(tmp_path / "c.zarr")
    assert rec.n_frames == 6 and rec.verify() == []
    assert zarr.open_group(str(tmp_path / "c.zarr"))["frames"].metadata.dimension_names == ("t", "y", "x")


def test_a_recording_written_before_ngff_still_reads(tmp_path, rec_path):
    # Strip what this change added (the `ome` block, dimension_names): the recording reads as before.
    meta = json.loads((rec_path / "zarr.json").read_text())
    del meta["attributes"]["ome"]
    (rec_path / "zarr.json").write_text(json.dumps(meta))
    frames_meta = json.loads((rec_path / "frames" / "zarr.json").read_text())
    frames_meta.pop("dimension_names", None)
    (rec_path / "frames" / "zarr.json").write_text(json.dumps(frames_meta))
    with pytest.raises(ValueError, match="not a valid OME-Zarr 0.5 image"):
        ngff.validate_image(rec_path)
    rec = open_recording(rec_path)
    assert rec.n_frames == 6 and rec.verify() == [] and rec.frames[:].shape == (6, 12, 16)


def test_reconstruct_export_and_batch_write_valid_ngff_images(tmp_path, rec_path, capsys):
    rates = open_recording(rec_path).attrs["rates"]
    sub, cam = 1 / rates["subframe_hz"], 1 / rates["camera_hz"]
    out = tmp_path
    assert main(["reconstruct", str(rec_path), "--method", "rebin", "-o", str(out / "rec.zarr")]) == 0
    assert main(["export", str(rec_path), "--what", "reconstruction", "--method", "rebin", "-o",
                 str(out / "exp.zarr"), "--pyramid", "1"]) == 0
    assert main(["export", str(rec_path), "--what", "frames", "-o", str(out / "frames.zarr")]) == 0
    assert main(["export", str(rec_path), "--what", "ground-truth", "-o", str(out / "truth.zarr")]) == 0
    assert main(["batch", str(rec_path), "--method", "rebin", "--chunk", "2", "-o", str(out / "b.zarr"),
                 "--pyramid", "2"]) == 0
    expected = {"rec.zarr": (sub, 1), "exp.zarr": (sub, 2), "frames.zarr": (cam, 1), "truth.zarr": (sub, 1),
                "b.zarr": (sub, 3)}
    for name, (step, n_levels) in expected.items():
        ms = _multiscale(out / name)
        assert _axes(ms)[0] == ("t", "time", "second"), name
        assert [s[0] for s in _scales(ms)] == [pytest.approx(step)] * n_levels, name
        assert open_video_store(out / name).time_step == pytest.approx(step)
    batch = open_video_store(out / "b.zarr")
    assert batch.attrs["batch"] is True and batch.attrs["method"]["name"] == "rebin"
    np.testing.assert_allclose(batch.array[:], open_video_store(out / "rec.zarr").array[:], atol=1e-6)
    np.testing.assert_allclose(batch.levels[1][:], ngff.downsample(batch.array[:]), rtol=1e-6)


def test_batch_writes_a_pyramid_with_the_same_values_as_write_video(tmp_path, rec_path):
    reconstruct_batch(rec_path, tmp_path / "b.zarr", Method("rebin"), chunk_frames=2, pyramid=1)
    store = open_video_store(tmp_path / "b.zarr")
    write_video(tmp_path / "w.zarr", store.array[:], time_step=store.time_step, pyramid=1)
    np.testing.assert_allclose(store.levels[1][:], open_video_store(tmp_path / "w.zarr").levels[1][:], rtol=1e-6)


def test_cli_pyramid_errors_are_one_line(tmp_path, rec_path, capsys):
    assert main(["export", str(rec_path), "-o", str(tmp_path / "f.tif"), "--pyramid", "1"]) == 2
    assert "--pyramid goes with a .zarr output (an OME-Zarr image); got -o" in capsys.readouterr().err
    assert main(["export", str(rec_path), "-o", str(tmp_path / "f.zarr"), "--pyramid", "9"]) == 2
    assert "--pyramid: the pyramid levels must be a whole number from 0 to 3" in capsys.readouterr().err
    assert main(["batch", str(rec_path), "-o", str(tmp_path / "b.zarr"), "--pyramid", "9"]) == 2
    assert "the pyramid levels must be a whole number from 0 to 3" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        main(["batch", str(rec_path), "-o", str(tmp_path / "b.zarr"), "--pyramid", "x"])
    assert exit_.value.code == 2
    assert "--pyramid must be a whole number of levels >= 0; got 'x'" in capsys.readouterr().err
    assert not (tmp_path / "f.zarr").exists() and not (tmp_path / "b.zarr").exists()


# --------------------------------------------------------------------------- Fiji


def test_the_tiff_of_a_reconstruction_carries_the_frame_interval_in_seconds(tmp_path, rng):
    write_video(tmp_path / "v.tif", rng.random((4, 6, 8)), time_step=1 / 240)
    with tifffile.TiffFile(tmp_path / "v.tif") as tif:
        meta = tif.imagej_metadata
        assert tif.series[0].axes == "TYX" and tif.series[0].shape == (4, 6, 8)
    assert meta["finterval"] == pytest.approx(1 / 240) and meta["tunit"] == "sec" and meta["unit"] == "pixel"


def test_the_tiff_export_carries_the_frame_interval_in_seconds(tmp_path, rec_path):
    rates = open_recording(rec_path).attrs["rates"]
    assert main(["export", str(rec_path), "--what", "frames", "-o", str(tmp_path / "f.tif")]) == 0
    assert main(["reconstruct", str(rec_path), "--method", "rebin", "-o", str(tmp_path / "v.tif")]) == 0
    with tifffile.TiffFile(tmp_path / "f.tif") as tif:
        frames = tif.imagej_metadata
    with tifffile.TiffFile(tmp_path / "v.tif") as tif:
        video = tif.imagej_metadata
        assert tif.series[0].shape[0] == 24
    assert frames["finterval"] == pytest.approx(1 / rates["camera_hz"]) and frames["tunit"] == "sec"
    assert video["finterval"] == pytest.approx(1 / rates["subframe_hz"]) and video["tunit"] == "sec"
