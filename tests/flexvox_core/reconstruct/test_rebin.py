import numpy as np
import pytest

from flexvox_core.codes import code_from_order
from flexvox_core.divisions import Division, enumerate_divisions
from flexvox_core.forward import capture
from flexvox_core.multiplex import multiplexed_code
from flexvox_core.reconstruct import as_identity_capture, rebin, rebin_blocks, supported_divisions

from .conftest import smooth_video


@pytest.mark.parametrize("shape", [(8, 12), (7, 9), (1, 3), (3, 1)])
def test_blocks_hold_their_one_sample(code24, rng, shape):
    H, W = shape
    F, K = 2, 8
    video = rng.random((F * K, H, W)).astype(np.float32)
    frames = capture(video, code24)
    order = code24.argmax(axis=2)
    for d in enumerate_divisions((2, 4)):
        blocks = rebin_blocks(frames, code24, d)
        assert blocks.shape == (F * d.tr, -(-H // d.a), -(-W // d.b))
        # every full block equals the sample of the one pixel that fires inside it
        for t in range(blocks.shape[0]):
            for i in range(H // d.a):
                for j in range(W // d.b):
                    f, s0 = divmod(t * d.c, K)
                    ys, xs = np.mgrid[i * d.a:(i + 1) * d.a, j * d.b:(j + 1) * d.b]
                    slots = order[ys % 2, xs % 4]
                    hit = (slots >= s0) & (slots < s0 + d.c)
                    assert hit.sum() == 1
                    assert blocks[t, i, j] == frames[f, ys[hit][0], xs[hit][0]]


def test_full_grid_fills_each_block_and_is_exact_for_block_constant_videos(code24, rng):
    for d in enumerate_divisions((2, 4)):
        coarse = rng.random((2 * d.tr, 8 // d.a, 12 // d.b)).astype(np.float32)
        video = coarse.repeat(d.c, 0).repeat(d.a, 1).repeat(d.b, 2)
        frames = capture(video, code24)
        assert np.array_equal(rebin_blocks(frames, code24, d), coarse)
        assert np.array_equal(rebin(frames, code24, d), video)


def test_interpolation_is_linear_between_block_centres(code24):
    # A video linear in t, y, x and constant within blocks' sample offsets is not
    # reproduced exactly; but blocks that are themselves linear are: check on the block grid.
    d = Division(2, 2, 2)  # [4, 1/4]
    F, H, W = 2, 8, 12
    frames = capture(np.zeros((F * 8, H, W), np.float32), code24)
    blocks_val = rebin_blocks(frames, code24, d)
    assert np.all(blocks_val == 0)
    # linear in block index -> interpolation reproduces the linear ramp at block centres
    coarse = (np.arange(F * d.tr)[:, None, None] + 2.0 * np.arange(H // 2)[None, :, None]
              + 3.0 * np.arange(W // 2)[None, None, :]).astype(np.float32)
    video = coarse.repeat(d.c, 0).repeat(d.a, 1).repeat(d.b, 2)
    out = rebin(capture(video, code24), code24, d, interpolate=True)
    t = (np.arange(F * 8) - 0.5) / 2
    y = (np.arange(H) - 0.5) / 2
    x = (np.arange(W) - 0.5) / 2
    want = (np.clip(t, 0, F * d.tr - 1)[:, None, None] + 2 * np.clip(y, 0, H // 2 - 1)[None, :, None]
            + 3 * np.clip(x, 0, W // 2 - 1)[None, None, :])
    np.testing.assert_allclose(out, want, atol=1e-5)


def test_output_stays_within_sample_range(code24, rng):
    video = smooth_video(rng, 16, 9, 13)
    frames = capture(video, code24)
    for d in supported_divisions(code24):
        for interp in (False, True):
            out = rebin(frames, code24, d, interpolate=interp)
            assert out.shape == video.shape and out.dtype == np.float32
            assert out.min() >= frames.min() and out.max() <= frames.max()


def test_unsupported_division_is_refused(seq22):
    assert Division(1, 1, 4) in supported_divisions(seq22)
    frames = np.zeros((1, 4, 4), np.float32)
    with pytest.raises(ValueError, match=r"`division` 1x2x2 is not supported by this code.*supports: "):
        rebin(frames, seq22, "1x2x2")
    with pytest.raises(ValueError, match=r"does not divide a 2x2 tile"):
        rebin(frames, seq22, (3, 1, 1))
    with pytest.raises(ValueError, match=r"`division` must be a Division"):
        rebin(frames, seq22, 5)


def test_k1_and_border_tiles(rng):
    one = code_from_order([[0]])
    frames = rng.random((3, 5, 4)).astype(np.float32)
    assert np.array_equal(rebin(frames, one, "1x1x1"), frames)
    code = code_from_order([[0, 3], [2, 1]])
    frames = rng.random((1, 5, 5)).astype(np.float32)  # partial tiles at both borders
    out = rebin(frames, code, "2x2x1")
    assert out.shape == (4, 5, 5) and np.isfinite(out).all()
    assert out.min() >= frames.min() and out.max() <= frames.max()


def test_prepare_demultiplexes_and_rejects_misuse(rng):
    mc = multiplexed_code((1, 3))
    video = np.full((6, 4, 6), 0.4, np.float32)
    f, c = as_identity_capture(capture(video, mc.code), mc)
    np.testing.assert_allclose(rebin(f, c, "1x3x1"), video, atol=1e-5)
    with pytest.raises(ValueError, match=r"`code` must be an identity code"):
        rebin(capture(video, mc.code), mc.code, "1x1x3")
    with pytest.raises(ValueError, match=r"`code` is a MultiplexedCode"):
        rebin(f, mc, "1x1x3")
    bad = np.zeros((2, 4, 6), np.float32)
    bad[1, 0, 0] = np.nan
    with pytest.raises(ValueError, match=r"`frames` camera frame 1 holds NaN"):
        rebin(bad, c, "1x1x3")
    with pytest.raises(ValueError, match=r"`dtype` must be float32 or float64"):
        rebin(f, c, "1x1x3", dtype=np.int32)
