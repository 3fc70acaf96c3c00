"""The GPU filters and resizes against the OpenCV and scipy calls they stand in for."""

import cv2
import numpy as np
import pytest
from scipy.ndimage import uniform_filter1d

from flexvox_core.slopes import slopes


@pytest.fixture
def ws():
    from flexvox_core.gpu.volumes import Workspace

    return Workspace()


def _dev(a):
    from numba import cuda

    return cuda.to_device(np.ascontiguousarray(a))


def _empty(shape, dtype=np.float32):
    from numba import cuda

    return cuda.device_array(shape, dtype)


def _plain_blur(planes, taps_y, taps_x, reflect):
    """The numpy reference of the GPU's blur: float32 sums in OpenCV's order, along x left to right, then along y
    the centre tap first and each pair of rows at ±t added before it is weighed (its column pass)."""
    mode = "symmetric" if reflect else "constant"  # numpy's "symmetric" repeats the edge: BORDER_REFLECT
    out = planes.astype(np.float32)
    if taps_x is not None:
        h = taps_x.size // 2
        p = np.pad(out, ((0, 0), (0, 0), (h, h)), mode=mode)
        acc = np.zeros_like(out)
        for t in range(taps_x.size):
            acc = acc + taps_x[t] * p[:, :, t:t + out.shape[2]]
        out = acc
    if taps_y is not None:
        h = taps_y.size // 2
        p = np.pad(out, ((0, 0), (h, h), (0, 0)), mode=mode)
        rows = out.shape[1]
        acc = taps_y[h] * out
        for t in range(1, h + 1):
            acc = acc + taps_y[h + t] * (p[:, h - t:h - t + rows] + p[:, h + t:h + t + rows])
        out = acc
    return out


@pytest.mark.parametrize("sigma", [0.3, 0.7071, 1.0, 2.5])
@pytest.mark.parametrize("reflect", [True, False])
def test_blur_is_opencvs_gaussian_blur(rng, ws, sigma, reflect):
    """In place, both axes: OpenCV's Gaussian blur within a few units in the last place (2.5 σ reaches past the
    9-row picture: reflected more than once), and the numpy reference of its order."""
    from flexvox_core.gpu.filters import blur, gaussian_taps

    planes = rng.random((2, 9, 11)).astype(np.float32)
    src = _dev(planes)
    taps = gaussian_taps(sigma)
    blur(ws, src, src, taps, taps, reflect=reflect)  # in place
    border = cv2.BORDER_REFLECT if reflect else cv2.BORDER_CONSTANT
    want = [cv2.GaussianBlur(p, (taps.size, taps.size), sigma, borderType=border) for p in planes]
    got = src.copy_to_host()
    np.testing.assert_allclose(got, want, atol=4e-7, rtol=0)
    np.testing.assert_allclose(got, _plain_blur(planes, taps, taps, reflect), atol=2e-7, rtol=0)


@pytest.mark.parametrize("reflect", [True, False])
@pytest.mark.parametrize("axes", ["x", "y", "xy"])
def test_blur_of_a_pair_of_stacks_is_each_stacks_blur(rng, ws, reflect, axes):
    """Two stacks at once (the normalized convolutions' num and den): each is ``cv2.sepFilter2D`` of its planes with
    the taps given per axis (a pass skipped where None), and the reference's sums."""
    from flexvox_core.gpu.filters import blur, gaussian_taps

    a = rng.random((3, 7, 10)).astype(np.float32)
    b = (rng.random((3, 7, 10)) > 0.5).astype(np.float32)
    taps_y = gaussian_taps(1.2) if "y" in axes else None
    taps_x = gaussian_taps(0.8) if "x" in axes else None
    src = (_dev(a), _dev(b))
    out = (_empty(a.shape), _empty(a.shape))
    blur(ws, src, out, taps_y, taps_x, reflect=reflect, tag="pair")
    border = cv2.BORDER_REFLECT if reflect else cv2.BORDER_CONSTANT
    one = np.ones(1, np.float32)
    for planes, d in zip((a, b), out, strict=True):
        got = d.copy_to_host()
        want = [cv2.sepFilter2D(p, -1, one if taps_x is None else taps_x, one if taps_y is None else taps_y,
                                borderType=border) for p in planes]
        np.testing.assert_allclose(got, want, atol=4e-7, rtol=0)
        np.testing.assert_allclose(got, _plain_blur(planes, taps_y, taps_x, reflect), atol=2e-7, rtol=0)
    np.testing.assert_array_equal(src[0].copy_to_host(), a)  # the sources untouched


def test_blur_refuses_taps_it_cannot_sum(ws):
    from flexvox_core.gpu.filters import blur

    src = _dev(np.zeros((1, 4, 4), np.float32))
    with pytest.raises(ValueError, match=r"`taps_x` must be a 1-D kernel of odd length, symmetric about its centre"):
        blur(ws, src, src, None, np.float32([0.2, 0.5, 0.3]))
    with pytest.raises(ValueError, match=r"`taps_y` must be a 1-D kernel of odd length"):
        blur(ws, src, src, np.float32([0.5, 0.5]), None)


def test_dilate_is_opencvs_with_a_square(rng, ws):
    from flexvox_core.gpu.filters import dilate

    mask = (rng.random((2, 10, 12)) > 0.93).astype(np.uint8)
    out = _empty(mask.shape, np.uint8)
    dilate(ws, _dev(mask), out, 2)
    want = [cv2.dilate(m, np.ones((5, 5), np.uint8)) for m in mask]
    np.testing.assert_array_equal(out.copy_to_host(), want)


def test_sobel_slopes_are_the_cpus(rng, ws):
    from flexvox_core.gpu.filters import sobel_slopes

    planes = rng.random((2, 9, 10)).astype(np.float32)
    gx, gy = _empty(planes.shape), _empty(planes.shape)
    sobel_slopes(ws, _dev(planes), gx, gy, 1.0)
    for p, ax, ay in zip(planes, gx.copy_to_host(), gy.copy_to_host(), strict=True):
        wx, wy = slopes(p, 1.0)
        np.testing.assert_allclose(ax, wx, atol=2e-6)
        np.testing.assert_allclose(ay, wy, atol=2e-6)


@pytest.mark.parametrize("size", [4, 5])
def test_box_in_time_is_scipys_uniform_filter(rng, size):
    from flexvox_core.gpu.filters import box_in_time

    v = rng.random((9, 3, 4)).astype(np.float32)
    out = _empty(v.shape)
    box_in_time(_dev(v), out, size)
    np.testing.assert_allclose(out.copy_to_host(), uniform_filter1d(v, size, axis=0, mode="nearest"), atol=1e-6)
    f = rng.random((7, 2, 3, 2)).astype(np.float32)
    out = _empty(f.shape)
    box_in_time(_dev(f), out, size)
    np.testing.assert_allclose(out.copy_to_host(), uniform_filter1d(f, size, axis=0, mode="nearest"), atol=1e-6)


@pytest.mark.parametrize("src, dst", [((12, 18), (4, 6)), ((13, 20), (5, 7)), ((10, 10), (10, 5))])
def test_resize_area_is_opencvs(rng, ws, src, dst):
    from flexvox_core.gpu.resize import resize_area

    planes = rng.random((2, *src)).astype(np.float32)
    out = _empty((2, *dst))
    resize_area(ws, _dev(planes), out)
    want = [cv2.resize(p, dst[::-1], interpolation=cv2.INTER_AREA) for p in planes]
    np.testing.assert_allclose(out.copy_to_host(), want, atol=2e-6)


@pytest.mark.parametrize("src, dst", [((4, 6), (12, 18)), ((5, 7), (13, 20)), ((6, 5), (6, 11))])
def test_resize_linear_is_opencvs(rng, ws, src, dst):
    from flexvox_core.gpu.resize import resize_linear

    planes = rng.random((2, *src)).astype(np.float32)
    out = _empty((2, *dst))
    resize_linear(ws, _dev(planes), out)
    want = [cv2.resize(p, dst[::-1], interpolation=cv2.INTER_LINEAR) for p in planes]
    np.testing.assert_allclose(out.copy_to_host(), want, atol=1e-5)
    flow = rng.normal(size=(2, *src, 2)).astype(np.float32)
    out = _empty((2, *dst, 2))
    resize_linear(ws, _dev(flow), out, scale=(2.0, 3.0))
    want = [cv2.resize(f * np.float32([2, 3]), dst[::-1], interpolation=cv2.INTER_LINEAR) for f in flow]
    np.testing.assert_allclose(out.copy_to_host(), want, atol=1e-5)


def test_to_uint8_is_the_flows(rng):
    from flexvox_core.flow.estimate import to_uint8 as cpu
    from flexvox_core.gpu.resize import to_uint8

    v = (rng.random((2, 5, 6)) * 1.4 - 0.2).astype(np.float32)
    out = _empty(v.shape, np.uint8)
    to_uint8(_dev(v), out)
    np.testing.assert_array_equal(out.copy_to_host(), cpu(v))
