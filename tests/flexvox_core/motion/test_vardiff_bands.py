"""The variable-tensor diffusion a band of sub-frames at a time: the bits of stepping the whole volume."""

import numpy as np
import pytest

from flexvox_core.motion.vardiff import explicit_steps, variable_tensor_diffusion
from flexvox_core.motion.vardiff_kernel import vardiff_step
from tests.flexvox_core.motion.band_volumes import Counted
from tests.flexvox_core.motion.vardiff_reference import variable_tensor_diffusion_reference

C = (0.95, 0.05, 0.05)  # every term of the step: along λ, ψ and the Laplacian


def time_of(steps: int) -> float:
    """A diffusion time of exactly ``steps`` explicit steps at C."""
    t = steps * 0.47
    assert explicit_steps(t, C) == steps
    return t


def whole_volume(init, mask, flow, *, time, keep_samples=True, sharp=None):
    """Each explicit step over the whole volume into a new one (the diffusion before it ran in bands)."""
    c1, c2, c3 = C
    steps = explicit_steps(time, C)
    dt = time / steps if steps else 0.0
    src = np.ascontiguousarray(init, np.float32)
    sh = np.zeros((1, 1, 1), bool) if sharp is None else np.ascontiguousarray(sharp)
    for _ in range(steps):
        dst = np.empty_like(src)
        vardiff_step(src, dst, flow, mask, keep_samples, c1, c2, c3, dt, sh, sharp is not None, 0, len(src))
        src = dst
    return src


def case(S, seed=3, H=9, W=11):
    rng = np.random.default_rng(seed)
    init = rng.uniform(0.2, 0.8, (S, H, W)).astype(np.float32)
    mask = rng.random(init.shape) < 0.2
    flow = rng.normal(0, 1.5, (*init.shape, 2)).astype(np.float32)
    flow[0, 0, 0, 0] = np.nan  # an unmeasured vector counts as no motion
    sharp = rng.random(init.shape) < 0.5
    return init, mask, flow, sharp


@pytest.mark.parametrize("S", [1, 2, 7, 13])
@pytest.mark.parametrize("steps", [1, 2, 3, 4])
@pytest.mark.parametrize("band", [1, 3, 5, None])  # None: the default, longer than S
@pytest.mark.parametrize("use_sharp", [False, True])
def test_bands_give_the_whole_volumes_bits(S, steps, band, use_sharp):
    init, mask, flow, sharp = case(S)
    sharp = sharp if use_sharp else None
    time = time_of(steps)
    for keep in (True, False):
        expected = whole_volume(init, mask, flow, time=time, keep_samples=keep, sharp=sharp)
        got = variable_tensor_diffusion(init, mask, flow, c=C, time=time, keep_samples=keep, sharp=sharp, band=band)
        assert np.array_equal(got, expected)
        same = init.copy()  # in place: the input a later band's halo reads is kept before it is written
        assert variable_tensor_diffusion(same, mask, flow, c=C, time=time, keep_samples=keep, sharp=sharp,
                                         band=band, out=same) is same
        assert np.array_equal(same, expected)
        other = np.full_like(init, -1.0)
        variable_tensor_diffusion(init, mask, flow, c=C, time=time, keep_samples=keep, sharp=sharp, band=band,
                                  out=other)
        assert np.array_equal(other, expected)
    reference = variable_tensor_diffusion_reference(init, mask, flow, c=C, time=time, keep_samples=False,
                                                    sharp=sharp)
    np.testing.assert_allclose(got, reference, atol=2e-6)  # keep_samples False, the loop's last
    assert not np.array_equal(got, init)


@pytest.mark.parametrize("band", [1, 4, 6])
@pytest.mark.parametrize("steps", [1, 3])
def test_mask_flow_and_sharp_are_read_a_band_at_a_time(band, steps):
    init, mask, flow, sharp = case(11, seed=4)
    time = time_of(steps)
    expected = whole_volume(init, mask, flow, time=time, sharp=sharp)
    volumes = [Counted(v, band) for v in (mask, flow, sharp)]  # a band's own sub-frames, no halo
    got = variable_tensor_diffusion(init, volumes[0], volumes[1], c=C, time=time, sharp=volumes[2], band=band)
    assert np.array_equal(got, expected)
    for v in volumes:  # each sub-frame once: the planes a later band reads are carried to it
        assert v.handed == 11 and v.calls == -(-11 // band)


class Into(Counted):
    """A :class:`Counted` volume that makes a band in the caller's buffer (as ``ScaledFlow.band_into``)."""

    def band_into(self, t0, t1, out):
        out[...] = self.band(t0, t1)
        self.into = getattr(self, "into", 0) + 1


def test_a_volume_with_band_into_is_read_into_the_buffers():
    init, mask, flow, sharp = case(9, seed=6)
    time = time_of(2)
    flows = Into(flow, 3)
    got = variable_tensor_diffusion(init, mask, flows, c=C, time=time, sharp=sharp, band=3)
    assert np.array_equal(got, whole_volume(init, mask, flow, time=time, sharp=sharp))
    assert flows.into == 3 and flows.handed == 9


def test_start_reads_the_sub_frames_of_longer_volumes():
    # What the refinement does on the gathered sub-frames [g0, g1) of a window: their ends are the ends of time.
    init, mask, flow, sharp = case(17, seed=5)
    g0, g1 = 4, 13
    time = time_of(2)
    expected = whole_volume(init[g0:g1], mask[g0:g1], flow[g0:g1], time=time, sharp=sharp[g0:g1])
    video = init.copy()
    variable_tensor_diffusion(video[g0:g1], Counted(mask, 99), Counted(flow, 99), c=C, time=time,
                              sharp=Counted(sharp, 99), start=g0, band=3, out=video[g0:g1])
    assert np.array_equal(video[g0:g1], expected)
    assert np.array_equal(video[:g0], init[:g0]) and np.array_equal(video[g1:], init[g1:])
    with pytest.raises(ValueError, match=r"`mask` \(17, 9, 11\) and `flow` \(17, 9, 11, 2\) must match `init` "
                                         r"\(9, 9, 11\) .* from sub-frame `start` = 9 on"):
        variable_tensor_diffusion(init[g0:g1], mask, flow, time=time, start=9)
    with pytest.raises(ValueError, match=r"`mask` \(9, 9, 11\) and `flow` \(9, 9, 11, 2\) must match `init` "
                                         r"\(17, 9, 11\) \(flow with a last axis of 2\)$"):
        variable_tensor_diffusion(init, mask[g0:g1], flow[g0:g1], time=time)
    # From sub-frame 0 of longer volumes: the first sub-frames' bits.
    assert np.array_equal(variable_tensor_diffusion(init[:g1], mask, flow, c=C, time=time, sharp=sharp),
                          whole_volume(init[:g1], mask[:g1], flow[:g1], time=time, sharp=sharp[:g1]))
    with pytest.raises(ValueError, match=r"`sharp` \(9, 9, 11\) must match `init` \(9, 9, 11\) from sub-frame "
                                         r"`start` = 4 on"):
        variable_tensor_diffusion(init[g0:g1], mask, flow, time=time, sharp=sharp[g0:g1], start=g0)


def test_out_is_init_or_apart_from_it():
    init, mask, flow, _ = case(6)
    video = np.concatenate([init, init[:1]])
    with pytest.raises(ValueError, match=r"`out` must be `init` itself or share no memory with it"):
        variable_tensor_diffusion(video[:6], mask, flow, time=1.0, out=video[1:])
    with pytest.raises(ValueError, match=r"`band` must be a whole number of sub-frames >= 1; got 0"):
        variable_tensor_diffusion(init, mask, flow, time=1.0, band=0)


def test_a_scratch_volume_is_deprecated_and_ignored():
    init, mask, flow, _ = case(6)
    expected = variable_tensor_diffusion(init, mask, flow, time=1.0)
    scratch = np.full_like(init, -5.0)
    with pytest.warns(DeprecationWarning, match=r"`scratch` of variable_tensor_diffusion is deprecated and will "
                                                r"be removed in the next release"):
        got = variable_tensor_diffusion(init, mask, flow, time=1.0, scratch=scratch)
    assert np.array_equal(got, expected)
    assert (scratch == -5.0).all()
    with pytest.raises(TypeError, match=r"unexpected keyword arguments \['scrach'\]"):
        variable_tensor_diffusion(init, mask, flow, time=1.0, scrach=scratch)


@pytest.mark.parametrize("band", [2, None])
def test_voxels_slower_than_the_still_speed_are_taken_as_still(band):
    init, mask, flow, sharp = case(8, seed=7)
    flow[1:3] *= 0.01  # tiny speeds, as the flow made full-size from a smaller scale gives still voxels
    still = 0.05
    finite = np.where(np.isfinite(flow), flow, np.float32(0))  # NaN counts as 0 (its voxel's speed is |v|)
    speed2 = finite[..., 0].astype(np.float64) ** 2 + finite[..., 1].astype(np.float64) ** 2
    zeroed = np.where((speed2 < still**2)[..., None], np.float32(0), finite)
    assert 0 < (zeroed == 0).all(-1).mean() < 0.5
    time = time_of(2)
    got = variable_tensor_diffusion(init, mask, flow, c=C, time=time, sharp=sharp, band=band, still_speed=still)
    assert np.array_equal(got, variable_tensor_diffusion(init, mask, zeroed, c=C, time=time, sharp=sharp, band=band))
    assert not np.array_equal(got, variable_tensor_diffusion(init, mask, flow, c=C, time=time, sharp=sharp))
    reference = variable_tensor_diffusion_reference(init, mask, flow, c=C, time=time, sharp=sharp, still_speed=still)
    np.testing.assert_allclose(got, reference, atol=2e-6)
    assert np.array_equal(variable_tensor_diffusion(init, mask, flow, c=C, time=time, still_speed=0),
                          variable_tensor_diffusion(init, mask, flow, c=C, time=time))
    with pytest.raises(ValueError, match=r"`still_speed` must be a finite number >= 0 or None; got -1"):
        variable_tensor_diffusion(init, mask, flow, time=time, still_speed=-1)


@pytest.mark.parametrize("steps", [1, 2, 3])
def test_an_init_read_through_a_buffer_gives_the_same_bits(steps):
    # The first step reads a C-contiguous `init` itself, any other through a buffer: the same bits either way.
    init, mask, flow, sharp = case(7, seed=8)
    time = time_of(steps)
    expected = whole_volume(init, mask, flow, time=time, sharp=sharp)
    strided = np.zeros((7, 9, 22), np.float32)
    strided[:, :, ::2] = init
    view = strided[:, :, ::2]  # not C-contiguous
    assert not view.flags.c_contiguous
    for out in (None, np.full_like(init, -1.0)):
        got = variable_tensor_diffusion(view, mask, flow, c=C, time=time, sharp=sharp, band=3, out=out)
        np.testing.assert_array_equal(got, expected)
    np.testing.assert_array_equal(strided[:, :, 1::2], 0)  # the input's neighbours untouched


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("where", [0, 6, 12, 20])
def test_a_nan_or_inf_anywhere_in_init_is_refused(bad, where):
    # The check sums chunks of sub-frames on the threads: each chunk's sub-frames are read, the last one's too.
    init, mask, flow, _ = case(21, seed=8)
    init[where, 4, 7] = bad
    with pytest.raises(ValueError, match=r"`init` holds NaN or infinite values"):
        variable_tensor_diffusion(init, mask, flow, c=C, time=time_of(2))


def test_the_largest_finite_values_pass_the_check():
    # A float64 sum of float32 values cannot overflow: a volume whose float32 sum would (1e38 a voxel) is not refused.
    init, mask, flow, _ = case(21, seed=8)
    big = np.full_like(init, 1e38)
    got = variable_tensor_diffusion(big, mask, flow, c=C, time=time_of(1))
    np.testing.assert_allclose(got, big, rtol=1e-6)  # a constant stays itself, to float32 rounding
