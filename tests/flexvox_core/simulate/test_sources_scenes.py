import cv2
import numpy as np
import pytest
import scipy.io
import tifffile

from flexvox_core.simulate.scene_file import load_scene, scene_from_mapping
from flexvox_core.simulate.scenes import SCENES, render_scene
from flexvox_core.simulate.simulator import simulate
from flexvox_core.simulate.sources import TrimWarning, load_video, trim_to_frames


@pytest.mark.parametrize("name", list(SCENES))
def test_builtin_scenes_are_deterministic_in_range_and_detailed(name):
    a = render_scene(name, 16, 40, 48, seed=1)
    b = render_scene(name, 16, 40, 48, seed=1)
    assert a.shape == (16, 40, 48) and a.dtype == np.float32
    assert np.array_equal(a, b)
    assert a.min() >= 0 and a.max() <= 1
    # Real high-frequency detail: the pixel-to-pixel differences carry energy.
    assert np.abs(np.diff(a[0], axis=1)).mean() > 0.03


@pytest.mark.parametrize(
    "name, moves", [("static", False), ("fan", True), ("balls", True), ("drummer", True), ("pan", True)]
)
def test_scenes_move_as_described(name, moves):
    v = render_scene(name, 16, 40, 48)
    assert bool(np.abs(np.diff(v, axis=0)).max() > 0.1) == moves


def test_render_scene_rejects_unknown_names():
    with pytest.raises(ValueError, match=r"unknown scene 'fann'; built-in scenes: fan, balls, drummer, pan, static"):
        render_scene("fann", 8, 16, 16)
    with pytest.raises(ValueError, match=r"`height` must be a whole number >= 8; got 4"):
        render_scene("fan", 8, 4, 16)


def test_npy_tiff_video_and_mat_sources(tmp_path, rng):
    v8 = (rng.random((6, 16, 24)) * 255).astype(np.uint8)
    np.save(tmp_path / "v.npy", v8)
    tifffile.imwrite(tmp_path / "v.tif", v8)
    scipy.io.savemat(tmp_path / "v.mat", {"orig": v8.transpose(1, 2, 0)})
    for name in ("v.npy", "v.tif", "v.mat"):
        got = load_video(tmp_path / name)
        assert got.dtype == np.float32 and got.shape == (6, 16, 24)
        assert np.allclose(got, v8 / 255.0)
    writer = cv2.VideoWriter(str(tmp_path / "v.avi"), cv2.VideoWriter_fourcc(*"MJPG"), 10, (24, 16), False)
    for frame in v8:
        writer.write(np.full((16, 24), frame.mean(), np.uint8))
    writer.release()
    got = load_video(tmp_path / "v.avi")
    assert got.shape == (6, 16, 24)


@pytest.mark.parametrize(("dtype", "value", "expected"), [
    (np.uint8, 1, 1 / 255), (np.uint8, 255, 1.0), (np.uint16, 65535, 1.0), (np.uint16, 257, 257 / 65535),
    (np.float32, 0.25, 0.25),
])
def test_colour_videos_are_grey_on_their_types_own_scale(tmp_path, dtype, value, expected):
    # A dark 8-bit colour video stays dark (it was not divided by 255 when its values were small), and floats
    # are never rescaled by a guess.
    np.save(tmp_path / "c.npy", np.full((4, 6, 8, 3), value, dtype))
    got = load_video(tmp_path / "c.npy")
    assert got.shape == (4, 6, 8) and got.dtype == np.float32
    np.testing.assert_allclose(got, expected, rtol=1e-5)
    assert got.max() <= 1.0


@pytest.mark.parametrize("dtype", [">u2", ">f4", ">f8"])
def test_big_endian_videos_read_as_their_values(tmp_path, dtype):
    values, scale = (np.array([0, 257, 65535]), 65535) if dtype == ">u2" else (np.array([0, 0.5, 1.0]), 1)
    np.save(tmp_path / "b.npy", np.resize(values, (4, 6, 8)).astype(dtype))
    got = load_video(tmp_path / "b.npy")
    np.testing.assert_allclose(got, np.resize(values / scale, (4, 6, 8)), atol=1e-6)


def test_a_colour_float_video_beyond_one_is_refused_as_a_grey_one_is(tmp_path):
    np.save(tmp_path / "c.npy", np.full((4, 6, 8, 3), 1.05, np.float32))
    with pytest.raises(ValueError, match=r"c.npy: float video values must lie in \[0, 1\]; found 1.05"):
        load_video(tmp_path / "c.npy")


def test_npy_is_never_unpickled(tmp_path):
    np.save(tmp_path / "obj.npy", np.array([{"a": 1}], dtype=object), allow_pickle=True)
    with pytest.raises(ValueError, match=r"obj.npy: cannot read: .*allow_pickle"):
        load_video(tmp_path / "obj.npy")


def _truncated_tiff(folder):
    import tifffile

    tifffile.imwrite(folder / "x.tif", np.zeros((12, 16, 24), np.float32), imagej=True)
    data = (folder / "x.tif").read_bytes()
    (folder / "x.tif").write_bytes(data[: len(data) // 3])  # a copy that stopped a third of the way


def _truncated_npy(folder):
    np.save(folder / "x.npy", np.zeros((4, 4, 4)))
    data = (folder / "x.npy").read_bytes()
    (folder / "x.npy").write_bytes(data[:-100])  # a copy that stopped short


@pytest.mark.parametrize(
    "make, match",
    [
        (lambda p: np.save(p / "x.npy", np.zeros((4, 4))), r"must have 3 dimensions \(S, H, W\); got 2"),
        (_truncated_npy, r"x.npy: a damaged .npy: its header declares 4x4x4 float64 \(512 bytes\) but the file "
                         r"holds 412 bytes after it; it may be truncated"),
        (lambda p: (p / "x.tif").write_bytes(np.random.default_rng(0).bytes(3000)),
         r"x.tif: not a readable TIFF \(not a TIFF file.*\); it is damaged or another format"),
        (lambda p: np.save(p / "x.npy", np.full((2, 4, 4), 2.0)), r"must lie in \[0, 1\]; found 2 .. 2"),
        (lambda p: (p / "x.npy").write_bytes(b"garbage"), r"x.npy: not a NumPy .npy file \(no .npy header\)"),
        (lambda p: (p / "x.tif").write_bytes(b"garbage" * 20), r"x.tif: not a readable TIFF \(not a TIFF file"),
        (_truncated_tiff, r"x.tif: a damaged TIFF \(.*\); it may be truncated"),
        (lambda p: (p / "x.mp4").write_bytes(b"garbage"), r"x.mp4: OpenCV cannot open|holds no readable frame"),
        (lambda p: scipy.io.savemat(p / "x.mat", {"meas": np.zeros((4, 4, 2))}), r"no variable `orig`"),
        (lambda p: (p / "x.gif").write_bytes(b"x"), r"unknown video type '.gif'"),
        (lambda p: (p / "x.mat").write_bytes(b""), r"x.mat: cannot read it as a MATLAB file \(.*\); it is empty"),
        (lambda p: (p / "x.npy").mkdir(), r"x.npy: cannot read: Is a directory"),
    ],
)
def test_bad_sources(tmp_path, make, match):
    make(tmp_path)
    path = next(tmp_path.iterdir())
    with pytest.raises(ValueError, match=match):
        load_video(path)


def test_video_shape_reads_the_header_only(tmp_path, rng, monkeypatch):
    import tifffile

    from flexvox_core.simulate.sources import video_shape

    np.save(tmp_path / "v.npy", rng.random((6, 16, 24), dtype=np.float32))
    np.save(tmp_path / "rgb.npy", np.zeros((5, 16, 24, 3), np.uint8))
    tifffile.imwrite(tmp_path / "v.tif", np.zeros((7, 16, 24), np.uint16))
    (tmp_path / "bad.tif").write_bytes(b"garbage" * 20)
    monkeypatch.setattr(np, "load", lambda *a, **k: pytest.fail("video_shape read the pixels"))
    assert video_shape(tmp_path / "v.npy") == (6, 16, 24)
    assert video_shape(tmp_path / "rgb.npy") == (5, 16, 24)
    assert video_shape(tmp_path / "v.tif") == (7, 16, 24)
    assert video_shape(tmp_path / "bad.tif") is None  # load_video names the damage
    assert video_shape(tmp_path / "missing.npy") is None


def test_missing_file():
    with pytest.raises(ValueError, match=r"nope.npy: no such file"):
        load_video("nope.npy")


def test_trim_to_whole_frames_warns():
    v = np.zeros((37, 4, 4), np.float32)
    message = r"37 sub-frames is not a multiple of K = 16; using the first 32 \(2 camera frames\), dropping 5"
    with pytest.warns(TrimWarning, match=message):
        out = trim_to_frames(v, 16, source="clip")
    assert out.shape[0] == 32
    with pytest.raises(ValueError, match=r"fewer than one camera frame"):
        trim_to_frames(v[:10], 16)


def test_scene_file_round_trip(tmp_path):
    (tmp_path / "s.toml").write_text(
        """
seed = 3
[source]
builtin = "balls"
height = 24
width = 32
frames = 2
[camera]
rate_hz = 30
[code]
tile = "2x4"
[effects.read_noise]
sigma = 1.5
[effects.photon_noise]
"""
    )
    spec = load_scene(tmp_path / "s.toml")
    assert spec.builtin == "balls" and spec.tile == (2, 4) and spec.seed == 3 and spec.rate_hz == 30
    assert [e.name for e in spec.effects] == ["photon_noise", "read_noise"]
    result = simulate(spec)
    assert result.frames.shape == (2, 24, 32) and result.ground_truth.shape == (16, 24, 32)
    assert result.effects["read_noise"] == {"sigma": 1.5}


@pytest.mark.parametrize(
    "data, match",
    [
        ({"source": {"builtin": "nope"}}, r"unknown scene 'nope'; built-in scenes: fan"),
        ({"source": {"builtin": "fan", "file": "x.npy"}}, r"give either `builtin` or `file`"),
        ({"source": {"colour": 1}}, r"\[source\]: unknown key 'colour'"),
        ({"camera": {"rate_hz": -1}}, r"rate_hz must be >= 0.001; got -1"),
        ({"code": {"tile": "0x4"}}, r"\[code\]: `tile` side m must be between 1 and 8; got 0"),
        ({"effects": {"sparkle": {}}}, r"\[effects\]: unknown effect 'sparkle'"),
        ({"effects": {"read_noise": {"sigma": -3}}}, r"read_noise.sigma must be between 0 and"),
        ({"seed": -1}, r"seed must be >= 0; got -1"),
        # tables of the wrong type, strings that are not, booleans that are strings, conflicting code keys, and
        # numbers too large to be a camera's (each was a traceback, or silently something else)
        ({"source": 5}, r"scene: `source` must be a table \(\[source\] with its keys\); got 5"),
        ({"source": "fan"}, r"scene: `source` must be a table \(\[source\] with its keys\); got 'fan'"),
        ({"camera": 1}, r"scene: `camera` must be a table"),
        ({"code": [1, 2]}, r"scene: `code` must be a table"),
        ({"source": {"builtin": ["fan"]}}, r"\[source\] builtin must be a string; got \['fan'\]"),
        ({"source": {"file": 5}}, r"\[source\] file must be a string; got 5"),
        ({"code": {"multiplexed": "false"}}, r"\[code\] multiplexed must be true or false; got 'false'"),
        ({"code": {"multiplexed": True, "order": [[0, 1], [2, 3]]}}, r"`order` places an identity code's slots"),
        ({"code": {"tile": "4x4", "order": [[0, 1], [2, 3]]}}, r"`order` has 2x2 slots but `tile` is 4x4"),
        ({"code": {"order": [[0, 1], [2]]}}, r"order must be m rows of n slot numbers each; got \[\[0, 1\], \[2\]\]"),
        ({"camera": {"rate_hz": 1e308}}, r"rate_hz must be at most 10000; got 1e\+308"),
        ({"source": {"duration_s": 1e308}}, r"duration_s must be at most 86400; got 1e\+308"),
        ({"camera": {"electrons_per_unit": 1e20}}, r"electrons_per_unit must be at most 1e\+09; got 1e\+20"),
        ({"source": {"file": "v.npy", "height": 32}}, r"`height` sets the size of a built-in scene; a `file` is"),
    ],
)
def test_bad_scene_files(data, match):
    with pytest.raises(ValueError, match=match):
        scene_from_mapping(data)


def test_unreadable_scene_files(tmp_path):
    (tmp_path / "bad.toml").write_text("seed = = 3")
    with pytest.raises(ValueError, match=r"bad.toml: not valid TOML"):
        load_scene(tmp_path / "bad.toml")
    with pytest.raises(ValueError, match=r"missing.toml: no such scene file"):
        load_scene(tmp_path / "missing.toml")


def test_the_strobe_lights_one_sub_frame_in_17():
    from flexvox_core.simulate.scenes import STROBE_PERIOD

    v = render_scene("strobe", 40, 16, 16, seed=2)
    lit = v.reshape(40, -1).max(axis=1) > 0
    assert STROBE_PERIOD == 17 and np.flatnonzero(lit).tolist() == [0, 17, 34]
    np.testing.assert_array_equal(v[17], v[0])  # the same wall every flash


def test_counts_of_a_12_bit_camera_are_read_with_their_white_or_warned_of(tmp_path):
    from flexvox_core.intensity import CountsWarning

    counts = np.round(render_scene("balls", 16, 16, 16) * 4095).astype(np.uint16)
    np.save(tmp_path / "c.npy", counts)
    with pytest.warns(CountsWarning, match=r"c\.npy: uint16 counts none above \d+: read as 16-bit counts .* "
                                           r"`white = 4095` in the scene file's \[source\], or --white 4095"):
        dim = load_video(tmp_path / "c.npy")
    np.testing.assert_allclose(dim, counts / 65535, rtol=1e-6)
    np.testing.assert_allclose(load_video(tmp_path / "c.npy", white=4095), counts / 4095, rtol=1e-6)
    with pytest.raises(ValueError, match=r"counts up to \d+ lie above white = 1000"):
        load_video(tmp_path / "c.npy", white=1000)
    np.save(tmp_path / "f.npy", counts / np.float32(4095))
    with pytest.raises(ValueError, match=r"`white` divides integer counts .* this video holds float"):
        load_video(tmp_path / "f.npy", white=4095)


def test_a_scene_file_gives_its_file_s_white(tmp_path):
    counts = np.round(render_scene("balls", 32, 16, 16) * 4095).astype(np.uint16)
    np.save(tmp_path / "c.npy", counts)
    spec = scene_from_mapping({"source": {"file": "c.npy", "white": 4095}, "code": {"tile": "2x2"}},
                              base_dir=tmp_path)
    assert spec.white == 4095
    np.testing.assert_allclose(simulate(spec).ground_truth, counts[:32] / 4095, rtol=1e-6)
    with pytest.raises(ValueError, match=r"`white` is the count that stands for white in a `file` of counts; a "
                                         r"built-in scene has none"):
        scene_from_mapping({"source": {"builtin": "balls", "white": 4095}})
