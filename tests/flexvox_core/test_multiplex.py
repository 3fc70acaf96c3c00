import numpy as np
import pytest

from flexvox_core.codes import code_from_order
from flexvox_core.forward import capture
from flexvox_core.multiplex import demultiplex, hadamard, multiplexed_code, noise_gains, s_matrix


@pytest.mark.parametrize("order", [1, 2, 4, 8, 12, 16, 20, 24, 28, 32, 36, 40, 44, 48, 56, 60, 64])
def test_hadamard_constructions(order):
    H = hadamard(order)
    assert H is not None
    assert np.array_equal(H @ H.T, order * np.eye(order, dtype=np.int64))


@pytest.mark.parametrize("K", [3, 7, 11, 15, 19, 23, 27, 31, 35, 63])
def test_s_matrix_properties(K):
    S = s_matrix(K).astype(np.float64)
    assert np.all(S.sum(axis=1) == (K + 1) // 2)
    inv = 2 / (K + 1) * (2 * S.T - 1)
    assert np.allclose(S @ inv, np.eye(K))


@pytest.mark.parametrize("K", [1, 2, 4, 8, 16, 64])
def test_no_s_matrix_unless_k_is_3_mod_4(K):
    with pytest.raises(ValueError, match=rf"no S-matrix exists for K = {K}: S-matrices need K = 3 \(mod 4\)"):
        s_matrix(K)


def test_noise_gains_match_the_known_figures():
    read, photon = noise_gains(s_matrix(15))
    assert read == pytest.approx(16 / (2 * np.sqrt(15)))  # (K+1)/(2 sqrt K)
    assert photon == pytest.approx(0.7303, abs=1e-4)  # a loss under photon noise (docs/architecture.md)


def test_multiplexed_tile_rejects_k_without_s_matrix():
    with pytest.raises(ValueError, match=r"no S-matrix exists for K = 16"):
        multiplexed_code((4, 4))


def test_demultiplex_recovers_slots_of_tile_constant_video(rng):
    mc = multiplexed_code((3, 5))
    F, H, W = 2, 9, 20  # whole tiles
    per_tile = rng.random((F * 15, H // 3, W // 5))
    video = np.repeat(np.repeat(per_tile, 3, axis=1), 5, axis=2)  # constant over each tile
    frames = capture(video, mc.code)
    ident = demultiplex(frames, mc)
    expected = capture(video, code_from_order(mc.placement))
    assert np.allclose(ident, expected, atol=1e-9)


def test_demultiplex_handles_partial_border_tiles(rng):
    mc = multiplexed_code((1, 3))
    video = np.full((6, 4, 7), 0.5)
    out = demultiplex(capture(video, mc.code), mc)
    assert out.shape == (2, 4, 7)
    assert np.allclose(out, 0.5)
