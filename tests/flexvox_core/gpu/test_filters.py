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


@pytest.mark.parametrize("sigma", [0.3, 0.7071, 1.0])
@pytest.mark.parametrize("reflect", [True, False])
def test_blur_is_opencvs_gaussian_blur(rng, ws, sigma, reflect):
    from flexvox_core.gpu.filters import blur, gaussian_taps

    planes = rng.random((2, 9, 11)).astype(np.float32)
    src = _dev(planes)
    taps = gaussian_taps(sigma)
    blur(ws, src, src, taps, taps, reflect=reflect)  # in place
    border = cv2.BORDER_REFLECT if reflect else cv2.BORDER_CONSTANT
    want = [cv2.GaussianBlur(p, (taps.size, taps.size), sigma, borderType=border) for p in planes]
    np.testing.assert_allclose(src.copy_to_host(), want, atol=2e-6)


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
