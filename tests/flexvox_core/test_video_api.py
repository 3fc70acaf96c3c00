"""``fv.reconstruct_video`` and ``fv.run`` from Python: camera counts, crops off the tile grid, codes that are
no code, recordings with their drops, methods by name, progress."""

import numpy as np
import pytest

import flexvox_core as fv

NC = fv.Method("diffusion")  # normalized convolution: linear, fast


@pytest.fixture(scope="module")
def scene():
    code = fv.design_code((2, 4)).code
    video = fv.render_scene("balls", 6 * 8, 24, 32, seed=0)
    return video, code, fv.capture(video, code)


@pytest.mark.parametrize("dtype", [np.uint8, np.uint16])
def test_integer_counts_are_divided_by_their_dtype_s_largest_value(scene, dtype):
    video, code, frames = scene
    white = np.iinfo(dtype).max
    counts = np.round(frames * white).astype(dtype)
    got = fv.reconstruct_video(counts, code, NC)
    np.testing.assert_allclose(got, fv.reconstruct_video(counts / np.float32(white), code, NC), atol=1e-6)
    assert fv.psnr(video, got) > 20


def test_white_gives_the_white_level_of_counts(scene):
    video, code, frames = scene
    counts = np.round(frames * 4095).astype(np.uint16)  # a 12-bit camera's counts in uint16
    got = fv.run(counts, code, NC, white=4095).video
    np.testing.assert_allclose(got, fv.reconstruct_video(counts / np.float32(4095), code, NC), atol=1e-6)
    with pytest.raises(ValueError, match=r"`white` must be a positive finite number of counts; got 0"):
        fv.reconstruct_video(counts, code, NC, white=0)
    with pytest.raises(ValueError, match=r"`frames` must hold real numbers .*; got dtype <U1"):
        fv.reconstruct_video(np.full((1, 4, 4), "a"), code, NC)


def test_counts_held_as_floats_are_refused_naming_white_not_clipped_to_white(scene):
    _, code, frames = scene
    counts = np.round(frames * 4095)  # float64 counts: read as relative units they were 4095 times too bright
    with pytest.raises(ValueError, match=r"`frames` are floats reaching \d+, more than twice the light of all 8 "
                                         r"slots open on white \(white = 1\): counts held as floats\? give `white=`"):
        fv.reconstruct_video(counts, code, NC)
    got = fv.reconstruct_video(counts, code, NC, white=4095)  # said so, they are read right
    np.testing.assert_allclose(got, fv.reconstruct_video(counts / 4095, code, NC), atol=1e-6)
    assert fv.reconstruct_video(frames * 1.3, code, NC).shape == (6 * 8, 24, 32)  # highlights up to 1.3: kept
    assert fv.reconstruct_video(frames + 9.0, code, NC).shape == (6 * 8, 24, 32)  # ambient light over K slots: kept
    with pytest.raises(ValueError, match=r"counts held as floats"):
        fv.reconstruct_video(frames * 20, code, NC)  # 8-bit-like counts (up to 255 at K = 8)


def test_counts_far_above_white_are_refused_not_clipped_to_white(scene):
    # a 12-bit camera's counts in the high bits of a uint16 (x 16) at white=4095 had been reconstructed white
    # everywhere, clipped, without a word
    _, code, frames = scene
    counts = np.round(frames * 4095).astype(np.uint16) * np.uint16(16)
    with pytest.raises(ValueError, match=r"`frames` reach \d+ counts, 1\d.\d times `white` = 4095, where the code "
                                         r"lets in at most 1 slot\(s\) of white: `white` is not these counts' white"):
        fv.reconstruct_video(counts, code, NC, white=4095)
    for call in (lambda: fv.estimate_accuracy(counts, code, NC, white=4095),
                 lambda: fv.choose(counts, code, "diffusion", "time", (2.0,), white=4095)):
        with pytest.raises(ValueError, match=r"`white` is not these counts' white"):
            call()
    noisy = np.round(np.clip(frames * 1.3, 0, None) * 4095).astype(np.uint16)  # highlights up to 1.3 white: kept
    assert fv.reconstruct_video(noisy, code, NC, white=4095).shape == (6 * 8, 24, 32)
    mc = fv.multiplexed_code((1, 3))  # an S-matrix pixel sums 2 slots: up to 2 whites is its light
    sums = np.round(fv.capture(np.ones((2 * 3, 6, 6), np.float32), mc.code) * 4095).astype(np.uint16)
    assert sums.max() == 2 * 4095
    assert fv.reconstruct_video(sums, mc.code, NC, white=4095).shape == (6, 6, 6)


def test_a_crop_off_the_tile_grid_follows_the_code_phase_given_by_origin(scene):
    _, code, frames = scene
    whole = fv.reconstruct_video(frames, code, NC)
    row, col, h, w = 5, 7, 14, 20  # off the 2x4 tile grid in both directions
    crop = frames[:, row:row + h, col:col + w]
    inner = (slice(None), slice(3, h - 3), slice(3, w - 3))  # away from the crop's borders
    region = whole[:, row:row + h, col:col + w][inner]
    np.testing.assert_allclose(fv.reconstruct_video(crop, code, NC, origin=(row, col))[inner], region, atol=1e-5)
    assert fv.psnr(region, fv.reconstruct_video(crop, code, NC)[inner]) < 30  # the wrong phase
    on_grid = fv.reconstruct_video(frames[:, 4:4 + h, 8:8 + w], code, NC, origin=(4, 8))
    np.testing.assert_allclose(on_grid[inner], whole[:, 4:4 + h, 8:8 + w][inner], atol=1e-5)
    with pytest.raises(ValueError, match=r"`origin` must be two whole numbers >= 0 \(row, col\).*; got \(-1, 2\)"):
        fv.reconstruct_video(crop, code, NC, origin=(-1, 2))


def test_a_code_that_is_neither_an_identity_nor_a_multiplexed_code_is_refused(scene):
    _, code, frames = scene
    with pytest.raises(ValueError, match=r"`code` is neither an identity code \(each tile pixel open in exactly one "
                                         r"slot.*nor a multiplexed one \(the tile's 8x8 pixel-by-slot matrix "
                                         r"invertible.*opens its pixels in 8 to 8 of 8 slots.*rank 1 of 8"):
        fv.reconstruct_video(frames, np.ones_like(code), NC)
    mc = fv.multiplexed_code((1, 3))  # a multiplexed code is still taken
    assert fv.codes.check_reconstructable(mc.code) and not fv.codes.check_reconstructable(code)
    mux = fv.capture(np.full((6, 4, 6), 0.5, np.float32), mc.code)
    assert fv.reconstruct_video(mux, mc.code, "gap-tv", iterations=3).shape == (6, 4, 6)


@pytest.fixture(scope="module")
def dropped(tmp_path_factory):
    code = fv.design_code((2, 2)).code
    video = fv.render_scene("balls", 16 * 4, 16, 24, seed=0)
    sim = fv.simulate_video(video, code, effects={"dropped_frames": {"probability": 0.2}}, seed=3)
    assert 0 < sim.dropped.sum() < 8
    return fv.write_simulation(tmp_path_factory.mktemp("rec") / "d.zarr", sim)


def test_a_recording_in_place_of_frames_and_code_brings_its_dropped_frames(dropped):
    rec = fv.open_recording(dropped)
    frames, code = fv.read_capture(dropped)
    expected = fv.reconstruct_video(frames, code, NC, missing=rec.dropped)
    np.testing.assert_array_equal(fv.reconstruct_video(rec, NC), expected)
    np.testing.assert_array_equal(fv.reconstruct_video(rec, "diffusion"), expected)
    np.testing.assert_array_equal(fv.open_capture(rec).run(NC).video, expected)
    assert not np.array_equal(fv.reconstruct_video(frames, code, NC), expected)  # drops forgotten: another answer
    with pytest.raises(TypeError, match=r"a Recording carries its code: .*got `code` as well"):
        fv.reconstruct_video(rec, code, NC)
    with pytest.raises(TypeError, match=r"a Recording carries its dropped frames: .*got `missing` as well"):
        fv.reconstruct_video(rec, NC, missing=rec.dropped)


def test_a_recording_s_path_in_place_of_frames_is_the_recording(dropped):
    # as fv.reconstruct_batch, fv.estimate_recording and fv.choose_recording take it; it was read as an array of
    # one string ("`frames` must hold real numbers ...; got dtype <U..")
    expected = fv.reconstruct_video(fv.open_recording(dropped), NC)
    np.testing.assert_array_equal(fv.reconstruct_video(dropped, NC), expected)
    np.testing.assert_array_equal(fv.reconstruct_video(str(dropped), "diffusion"), expected)
    with pytest.raises(TypeError, match=r"`frames` is a path \(.*d.zarr\): a recording goes to "
                                        r"fv.reconstruct_video\(path, method\), which reads its code and dropped "
                                        r"frames; fv.run takes frames \(F, H, W\) and a code"):
        fv.run(str(dropped), np.ones((2, 2, 4), bool), NC)


def test_a_recording_given_to_run_says_where_it_goes(dropped):
    # read as an array it was "`frames` must hold real numbers ...; got dtype object"
    rec = fv.open_recording(dropped)
    for given in (rec, fv.open_capture(rec)):
        with pytest.raises(TypeError, match=r"`frames` is a (Recording|CaptureReader): a recording goes to "
                                            r"fv.reconstruct_video\(recording, method\), which reads its code"):
            fv.run(given, NC)
        with pytest.raises(TypeError, match=r"`frames` is a (Recording|CaptureReader): a recording goes to"):
            fv.run(given, fv.read_capture(dropped)[1], "diffusion")


def test_a_method_by_name_takes_its_options_as_keywords(scene):
    _, code, frames = scene
    by_name = fv.reconstruct_video(frames, code, "gap-tv", iterations=3)
    np.testing.assert_array_equal(by_name, fv.reconstruct_video(frames, code, fv.Method("gap-tv", iterations=3)))
    np.testing.assert_array_equal(fv.run(frames, code, "diffusion", time=2).video,
                                  fv.reconstruct_video(frames, code, fv.Method("diffusion", time=2)))
    with pytest.raises(TypeError, match=r"`method` must be an fv\.Method .* or a method's name \(rebin, diffusion, "
                                        r"gap-tv, motion-aware.*; got int 3"):
        fv.reconstruct_video(frames, code, 3)
    with pytest.raises(TypeError, match=r"options \(iterations=\.\.\.\) go into the method: "
                                        r"fv\.Method\('gap-tv', iterations=\.\.\.\)"):
        fv.reconstruct_video(frames, code, fv.Method("gap-tv"), iterations=3)
    with pytest.raises(ValueError, match=r"`method` must be one of rebin, diffusion, gap-tv, motion-aware.*'gaptv'"):
        fv.reconstruct_video(frames, code, "gaptv")


@pytest.mark.parametrize("call", [fv.reconstruct_video, fv.run], ids=["reconstruct_video", "run"])
def test_progress_is_true_false_none_or_a_callable(scene, call, capsys):
    _, code, frames = scene
    expected = fv.reconstruct_video(frames, code, NC)
    for progress in (True, False, None):
        out = call(frames, code, NC, progress=progress, chunk_frames=2)
        np.testing.assert_array_equal(getattr(out, "video", out), expected)
    seen = []
    call(frames, code, NC, progress=lambda done, total: seen.append((done, total)), chunk_frames=4)
    assert seen == [(4, 6), (6, 6)]
    with pytest.raises(TypeError, match=r"`progress` must be True \(a bar\), False or None \(nothing\), or a "
                                        r"callable progress\(done, total\); got str 'yes'"):
        call(frames, code, NC, progress="yes")


@pytest.mark.parametrize("call", ["motion_aware", "diffuse", "gap_tv"])
def test_a_recording_given_to_a_methods_function_names_reconstruct_video(call, tmp_path):
    """``fv.motion_aware(rec, code)`` said "got 0 dimensions ()"; every method's function now names the call that
    takes a recording."""
    code = fv.design_code((2, 2)).code
    path = fv.write_simulation(tmp_path / "r.zarr", fv.simulate_video(fv.render_scene("balls", 8, 8, 8, seed=0), code))
    from flexvox_core.reconstruct import diffuse, gap_tv

    function = {"motion_aware": fv.motion_aware, "diffuse": diffuse, "gap_tv": gap_tv}[call]
    for given, what in ((fv.open_recording(path), r"a Recording"), (path, r"a path \(.*r.zarr\)"),
                        (str(path), r"a path \(.*r.zarr\)")):
        with pytest.raises(TypeError, match=rf"`frames` is {what}: a recording goes to "
                                            rf"fv.reconstruct_video\(recording, method\), which reads its code"):
            function(given, code)


def test_a_flag_given_as_text_is_refused_not_read_as_true():
    """``extras="no"`` computed the extras and ``keep_video="no"`` kept the video: a string is true to Python."""
    code = fv.design_code((2, 2)).code
    frames = fv.capture(fv.render_scene("balls", 8, 8, 8, seed=0), code)
    with pytest.raises(TypeError, match=r"`extras` must be True or False; got 'no'"):
        fv.run(frames, code, "diffusion", extras="no")
    with pytest.raises(TypeError, match=r"`keep_video` must be True or False; got 'no'"):
        fv.choose(frames, code, "diffusion", "time", (2.0, 4.0), keep_video="no")
    assert fv.run(frames, code, "diffusion", extras=np.bool_(False)).video.shape == (8, 8, 8)


def test_a_crop_smaller_than_the_tile_is_refused_naming_the_unsampled_slots():
    """A 2×2 crop of a 4×4-tile capture sees 4 of 16 slots: the other 12 sub-frames would be made up."""
    code = fv.design_code((4, 4)).code
    frames = fv.capture(fv.render_scene("balls", 32, 8, 8, seed=0), code)
    with pytest.raises(ValueError, match=r"`frames` of 2x2 pixels hold less than one 4x4 tile: 12 of the code's "
                                         r"K = 16 slots are sampled by no pixel.*"
                                         r"at least one whole tile \(4x4 pixels\)"):
        fv.run(frames[:, :2, :2], code, "diffusion")
    with pytest.raises(ValueError, match=r"`frames` of 8x3 pixels hold less than one 4x4 tile: 4 of"):
        fv.reconstruct_video(frames[:, :, :3], code, "diffusion")
    assert fv.run(frames[:, :5, 3:7], code, "diffusion", origin=(0, 3)).video.shape == (32, 5, 4)  # a whole tile
