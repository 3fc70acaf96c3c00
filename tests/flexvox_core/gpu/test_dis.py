"""DIS optical flow on the GPU (flexvox_core.gpu.dis): the kernels under numba-cuda's simulator against the
numpy reference (dis_reference.py), the reference against OpenCV's DIS, the parameters' validation, the
deviceless compile, and (marked gpu) the real kernels at full size against OpenCV."""

from pathlib import Path

import numpy as np
import pytest

from flexvox_core.gpu import dis as gdis
from flexvox_core.gpu.dis import DisParams, DisWorkspace, dis_pairs, level_shapes, scales
from tests.flexvox_core.gpu import dis_reference as ref
from tests.flexvox_core.gpu.dis_cases import affine_case, cases, epe, opencv_dis, texture

ROOT = Path(__file__).resolve().parents[3]

# Few Gauss-Newton and SOR iterations: the simulator runs every thread as Python.
SIM = DisParams(gradient_descent_iterations=6, variational_iterations=1, sor_iterations=2)


def _clip(rng, h, w, shifts):
    """uint8 (1 + len(shifts), h, w): a texture and the texture moved by each (dx, dy)."""
    import cv2

    T = texture(rng, h, w)
    out = [T[40:40 + h, 40:40 + w]]
    for dx, dy in shifts:
        M = np.float32([[1, 0, dx], [0, 1, dy]])
        out.append(cv2.warpAffine(T, M, T.shape[::-1], flags=cv2.INTER_CUBIC)[40:40 + h, 40:40 + w])
    return np.clip(np.rint(np.stack(out)), 0, 255).astype(np.uint8)


# ------------------------------------------------------------------------------------- kernels = reference

# The kernels and the reference do the same float32 operations in the same order, and the simulator runs
# the kernels' arithmetic as numpy float32 scalars: they agree to the bit (measured: 0.0 everywhere). The
# tolerance, 1e-5 px, only leaves room for a last-bit difference in a library sqrt or division; a wrong
# index, border or order shows as a difference of 1e-3 px or more (a discrete choice of the search flips).
TOL = 1e-5


@pytest.mark.parametrize(("h", "w", "shifts", "a", "b", "params"), [
    # one level at full size (the small-image rule), one pair
    (16, 16, [(0.8, -0.5)], [0], [1], SIM),
    # two pairs sharing an image, one reversed; a pair of an image with itself
    (24, 32, [(1.2, 0.7), (-0.6, 1.5)], [0, 2, 1], [1, 0, 1], SIM),
    # two levels (0 and 1): upsampling between them; no propagation, plain SSD, no refinement
    (16, 40, [(2.5, -0.4)], [0], [1], DisParams(gradient_descent_iterations=3, variational_iterations=0,
                                                use_spatial_propagation=False, use_mean_normalization=False)),
    # stripes of two patch rows (11 rows of patches): the anti-diagonal sweep, propagation from the row above
    # and below; 18 stripes in two blocks of the simulator
    (24, 24, [(1.4, -0.9), (-0.3, 2.2), (0.6, 0.6)], [0, 1, 3], [1, 2, 0],
     DisParams(patch_size=4, patch_stride=2, finest_scale=0, gradient_descent_iterations=4, variational_iterations=0)),
    # finest scale 1: the fractional INTER_AREA level (47 -> 23 rows) and the final upsampling
    (47, 50, [(1.7, 1.1)], [0], [1], DisParams(gradient_descent_iterations=4, variational_iterations=1,
                                               sor_iterations=1)),
])
def test_kernels_equal_the_reference(rng, h, w, shifts, a, b, params):
    images = _clip(rng, h, w, shifts)
    got = dis_pairs(images, np.array(a), np.array(b), params).copy_to_host()
    want = ref.dis_pairs(images, a, b, params)
    assert got.shape == (len(a), h, w, 2) and got.dtype == np.float32
    np.testing.assert_allclose(got, want, rtol=0, atol=TOL)
    assert np.abs(want).max() > 0.3  # the pairs move: a zero flow would not test much


def test_workspace_is_reused_and_out_is_written(rng):
    images = _clip(rng, 16, 16, [(0.5, 0.5)])
    p = DisParams(gradient_descent_iterations=2, variational_iterations=0)
    first = dis_pairs(images, [0], [1], p).copy_to_host()
    from flexvox_core.gpu.volumes import Workspace

    held = Workspace()
    ws = held.held("dis", lambda d: d.fits(2, 1, 16, 16, p), lambda: DisWorkspace(2, 1, 16, 16, p))
    assert held.held("dis", lambda d: d.fits(1, 1, 16, 16, p), lambda: DisWorkspace(1, 1, 16, 16, p)) is ws
    assert held.nbytes == ws.nbytes > 0  # the DIS buffers count in the workspace's memory
    out = gdis.cuda.device_array((1, 16, 16, 2), np.float32)
    back = dis_pairs(images, gdis.cuda.to_device(np.array([0], np.int64)), (1,), p, out=out, workspace=ws)
    assert back is out
    np.testing.assert_array_equal(out.copy_to_host(), first)


# ------------------------------------------------------------------------------------- reference = OpenCV


def test_pyramid_levels_follow_opencv():
    p = DisParams()
    assert level_shapes(160, 213, p) == [(80, 106), (40, 53), (20, 26)]
    assert level_shapes(80, 107, p) == [(40, 53), (20, 26)]
    assert scales(16, 16, p) == (0, 0) and scales(16, 40, p) == (0, 1) and scales(46, 46, p) == (1, 1)
    for h in range(16, 200, 7):
        for w in range(16, 260, 11):
            assert scales(h, w, p) == ref.scales(h, w, p)


@pytest.mark.parametrize("case", cases(), ids=lambda c: c.name)
def test_reference_matches_opencv(case):
    """The numpy reference is OpenCV's DIS but for float rounding: a mean end-point error to OpenCV's flow
    below 1e-4 px (measured 1e-7 to 1e-6), and the same error to the true flow within 0.002 px."""
    p = DisParams()
    got, ocv = ref.dis(case.I0, case.I1, p), opencv_dis(case.I0, case.I1, p)
    e = epe(got, ocv)
    assert e.mean() < 1e-4
    assert (e > 0.01).mean() < 0.002
    mine, theirs = epe(got, case.truth)[case.mask].mean(), epe(ocv, case.truth)[case.mask].mean()
    assert mine <= theirs + 0.002
    assert mine < 0.15  # and both are good flows (measured 0.03 to 0.13 px)


@pytest.mark.parametrize("preset", ["ultrafast", "fast", "medium"])
def test_reference_matches_opencv_presets(preset):
    import cv2

    c = affine_case("translation", np.random.default_rng(3), 96, 128, shift=(2.2, -1.4))
    p = DisParams.from_preset(preset)
    want = cv2.DISOpticalFlow_create({"ultrafast": 0, "fast": 1, "medium": 2}[preset]).calc(c.I0, c.I1, None)
    assert epe(ref.dis(c.I0, c.I1, p), want).mean() < 1e-4


@pytest.mark.parametrize("params", [
    DisParams(patch_size=4, patch_stride=2, finest_scale=0),
    DisParams(use_mean_normalization=False),
    DisParams(use_spatial_propagation=False),
    DisParams(patch_size=12, patch_stride=5, variational_iterations=3, alpha=5.0, delta=1.0, gamma=0.0, epsilon=0.05),
    DisParams(finest_scale=2, gradient_descent_iterations=7),
], ids=["patch4-stride2-scale0", "no-mean-normalization", "no-propagation", "patch12-refinement-weights", "scale2"])
def test_reference_matches_opencv_params(params):
    c = affine_case("rotation and translation", np.random.default_rng(4), 96, 128, shift=(2.2, -1.4), angle_deg=1.0)
    assert epe(ref.dis(c.I0, c.I1, params), opencv_dis(c.I0, c.I1, params)).mean() < 1e-4


def test_reference_pieces_match_opencv(rng):
    import cv2

    img = rng.integers(0, 256, (53, 71), dtype=np.uint8)
    for h, w in [(26, 35), (27, 36)]:
        np.testing.assert_array_equal(ref.area_resize(img, h, w), cv2.resize(img, (w, h), interpolation=cv2.INTER_AREA))
    gx, gy = ref.sobel(img)
    np.testing.assert_array_equal(gx, cv2.Sobel(img, cv2.CV_16S, 1, 0, ksize=3))
    np.testing.assert_array_equal(gy, cv2.Sobel(img, cv2.CV_16S, 0, 1, ksize=3))
    flow = rng.standard_normal((26, 35)).astype(np.float32)
    np.testing.assert_allclose(ref.resize_linear(flow, 53, 71), cv2.resize(flow, (71, 53)), atol=2e-6)


# ------------------------------------------------------------------------------------- validation


@pytest.mark.parametrize(("kwargs", "match"), [
    ({"patch_size": 1}, r"DisParams.patch_size must be an integer from 2 to 16; got 1"),
    ({"patch_size": 8.0}, r"DisParams.patch_size must be an integer"),
    ({"patch_stride": 9}, r"DisParams.patch_stride must be an integer from 1 to 8; got 9"),
    ({"gradient_descent_iterations": 0}, r"gradient_descent_iterations must be an integer from 1"),
    ({"variational_iterations": -1}, r"variational_iterations must be an integer from 0"),
    ({"alpha": float("nan")}, r"DisParams.alpha must be a finite number >= 0; got nan"),
    ({"gamma": -1.0}, r"DisParams.gamma must be a finite number >= 0; got -1.0"),
    ({"epsilon": 0.0}, r"DisParams.epsilon must be a finite number > 0; got 0.0"),
    ({"use_spatial_propagation": 1}, r"DisParams.use_spatial_propagation must be True or False; got 1"),
])
def test_params_are_validated(kwargs, match):
    with pytest.raises(ValueError, match=match):
        DisParams(**kwargs)


def test_preset_names_and_overrides_are_validated():
    assert DisParams.from_preset("fast", variational_iterations=2).patch_stride == 4
    with pytest.raises(ValueError, match=r"DIS preset must be one of ultrafast, fast, medium; got 'slow'"):
        DisParams.from_preset("slow")
    with pytest.raises(ValueError, match=r"DisParams has no field 'iterations'"):
        DisParams.from_preset("medium", iterations=3)


@pytest.mark.parametrize(("images", "a", "b", "match"), [
    (np.zeros((2, 16, 16), np.float32), [0], [1], r"images must be \(N, H, W\) uint8; got dtype float32"),
    (np.zeros((2, 6, 16), np.uint8), [0], [1], r"each image side must be at least patch_size 8; got 6x16"),
    (np.zeros((2, 16, 16), np.uint8), [0], [2], r"b must index the 2 images \(0 to 1\); got values from 2 to 2"),
    (np.zeros((2, 16, 16), np.uint8), [], [], r"a must be a non-empty 1-D integer array"),
    (np.zeros((2, 16, 16), np.uint8), [0.0], [1], r"a must be a non-empty 1-D integer array; got dtype float64"),
    (np.zeros((2, 16, 16), np.uint8), [0, 1], [1], r"a and b must have the same length; got 2 and 1"),
])
def test_inputs_are_validated(images, a, b, match):
    with pytest.raises(ValueError, match=match):
        dis_pairs(images, a, b)


def test_out_and_workspace_are_validated():
    images = np.zeros((2, 16, 16), np.uint8)
    with pytest.raises(ValueError, match=r"out must be a C-contiguous \(1, 16, 16, 2\) float32 array; got dtype "
                                         r"float32, shape \(1, 16, 16\)"):
        dis_pairs(images, [0], [1], out=gdis.cuda.device_array((1, 16, 16), np.float32))
    ws = DisWorkspace(2, 1, 16, 16, DisParams())
    with pytest.raises(ValueError, match=r"the workspace holds 2 images, 1 pairs of 16x16; got 2 images, 2 pairs"):
        dis_pairs(images, [0, 1], [1, 0], workspace=ws)


# ------------------------------------------------------------------------------------- compile for a GPU

# ------------------------------------------------------------------------------------- on a real GPU


@pytest.mark.gpu
@pytest.mark.parametrize(("h", "w"), [(160, 213), (80, 107)])
def test_gpu_matches_opencv_at_full_size(h, w):
    """64 pairs in one call against OpenCV pair by pair. The GPU may fuse multiply-adds where OpenCV rounds
    twice, which can flip a few of the search's choices: a mean end-point error to OpenCV below 0.02 px, and
    the error to the true flow within 0.01 px of OpenCV's."""
    rng = np.random.default_rng(64)
    shifts = [(rng.uniform(-4, 4), rng.uniform(-3, 3)) for _ in range(64)]
    images = _clip(rng, h, w, shifts)
    p = DisParams()
    got = dis_pairs(images, np.zeros(64, int), np.arange(1, 65), p).copy_to_host()
    ocv = np.stack([opencv_dis(images[0], images[q + 1], p) for q in range(64)])
    assert epe(got, ocv).mean() < 0.02
    truth = np.broadcast_to(np.float32(shifts)[:, None, None, :], got.shape)
    inner = (slice(None), slice(8, h - 8), slice(8, w - 8))
    assert epe(got, truth)[inner].mean() <= epe(ocv, truth)[inner].mean() + 0.01


def test_the_reference_follows_opencv_on_a_built_in_scenes_high_tr_pairs():
    """What motion-aware's flow measures: successive high-TR sub-frames of the balls at the flow's size."""
    from flexvox_core.gpu.dis import DisParams
    from tests.flexvox_core.gpu.dis_cases import epe, opencv_dis, scene_pairs
    from tests.flexvox_core.gpu.dis_reference import dis

    p = DisParams()
    for a, b in scene_pairs("balls", h=80, w=107, pairs=2):
        e = epe(dis(a, b, p), opencv_dis(a, b, p))
        assert e.mean() < 1e-3 and np.percentile(e, 99.9) < 0.05
