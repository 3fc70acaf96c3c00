"""The coupled simulated rig: forward model, truth, determinism, geometry, effects, timing."""

import time

import numpy as np
import pytest

from flexvox_core.design import design_code
from flexvox_core.forward import capture, tiled_code
from flexvox_core.simulate.effects import parse_effects
from flexvox_core.simulate.scene_file import scene_from_mapping
from rig_drivers.errors import DeviceTimeoutError, IncompatibleStateError, SettingError
from rig_drivers.interfaces import CameraSettings, PatternSequence, TriggerConfig, TriggerSource
from rig_drivers.simulated_camera import VirtualClock
from rig_drivers.simulated_rig import SimulatedRig, warp_patterns
from rig_drivers.simulated_target import coarse_homography, fine_homography, hidden_timing

PERIOD = 4166
LINE0 = CameraSettings(exposure_us=16 * PERIOD - 300, trigger=TriggerConfig(source=TriggerSource.LINE0))


def make_rig(**kw):
    """The textbook rig by default (these tests look at the rig's physics with camera-sized patterns)."""
    kw.setdefault("camera_size", (24, 32))
    kw.setdefault("subframes", 48)
    kw.setdefault("clock", VirtualClock())
    kw.setdefault("ideal", True)
    return SimulatedRig.create(kw.pop("scene", "drummer"), **kw)


def grab(rig, patterns, n, *, settings=LINE0, timeout_s=0.5, start_projector=True):
    seq = PatternSequence(patterns, PERIOD, PERIOD)
    rig.projector.open()
    rig.projector.enable()
    rig.projector.load_sequence(seq)
    if start_projector:
        rig.projector.start()
    rig.camera.open()
    rig.camera.configure(settings)
    rig.camera.enable()
    rig.camera.start_acquisition()
    return [rig.camera.read_frame(timeout_s) for _ in range(n)]


def test_show_identity_rig_without_effects_matches_the_forward_model():
    code = design_code((4, 4)).code
    rig = make_rig(homography=np.eye(3))
    frames = grab(rig, tiled_code(code, 24, 32), 5)
    expected = capture(rig.truth.video, code)  # 48 sub-frames = 3 camera frames; the scene loops
    assert [f.frame_id for f in frames] == [0, 1, 2, 3, 4]
    for f in frames:
        np.testing.assert_allclose(f.image, expected[f.frame_id % 3], atol=1e-6)
    assert [f.timestamp_s for f in frames] == pytest.approx([i * 16 * PERIOD / 1e6 for i in range(5)])


def test_truth_record_and_the_coarse_homography_is_mild():
    rig = make_rig(seed=5, phase_slots=3, delay_us=40, homography=coarse_homography((24, 32), (24, 32), 5))
    t = rig.truth
    assert (t.phase_slots, t.delay_us, t.seed, t.video.shape) == (3, 40, 5, (48, 24, 32))
    np.testing.assert_array_equal(t.homography, coarse_homography((24, 32), (24, 32), 5))
    a, b = t.homography[0, 0], t.homography[1, 0]
    assert 1.05 <= np.hypot(a, b) <= 1.10 and abs(np.degrees(np.arctan2(b, a))) <= 0.5
    corners = t.projector_to_camera([[0, 0], [31, 23]])
    assert np.all(corners[0] < 0) and np.all(corners[1] > [31, 23])  # covers the camera
    assert not np.array_equal(t.homography, coarse_homography((24, 32), (24, 32), 6))


def test_the_default_rig_is_built_as_a_real_one():
    """A finer projector behind a hidden homography that is not the identity, a trigger offset that is not a
    whole slot: what calibration must find (the same rig for `flexvox calibrate`, `capture` and the app)."""
    rig = SimulatedRig.create("drummer", camera_size=(24, 32), subframes=48, seed=5, clock=VirtualClock())
    t = rig.truth
    assert rig.projector.size == (48, 64)
    np.testing.assert_array_equal(t.homography, fine_homography((24, 32), (48, 64), 5))
    a, b = t.homography[0, 0], t.homography[1, 0]
    assert 0.55 <= np.hypot(a, b) <= 0.70 and not np.allclose(t.homography, np.eye(3))
    assert (t.phase_slots, t.delay_us) == hidden_timing(5)
    assert 0.15 * 4166 <= t.delay_us <= 0.85 * 4166
    other = SimulatedRig.create("drummer", camera_size=(24, 32), subframes=48, seed=6, clock=VirtualClock()).truth
    assert not np.array_equal(other.homography, t.homography)


def test_the_calibration_target_comes_into_view_and_goes():
    rig = SimulatedRig.create("drummer", camera_size=(24, 32), subframes=48, seed=2, clock=VirtualClock(),
                              baseline=(0.3, 0.0, 0.0))
    pats = np.ones((16, 48, 64), bool)
    scene = grab(rig, pats, 1)[0].image
    rig.show_target()
    assert rig.viewing == "target"
    target = rig.camera.read_frame(0.5).image
    assert not np.allclose(scene, target)
    rig.move_target(2.0)  # with a baseline the projector's image moves with the target's depth
    np.testing.assert_allclose(rig.truth.homography_at(1.0), rig.truth.homography)
    assert not np.allclose(rig.truth.homography_at(2.0), rig.truth.homography)
    rig.show_scene()
    assert rig.viewing == "scene"
    with pytest.raises(SettingError, match=r"the calibration target is not in view: show_target\(\) first"):
        rig.move_target(1.0)


def test_same_seed_same_frames_other_seed_other_noise():
    effects = {"photon_noise": {}, "read_noise": {"sigma": 5.0}}
    pats = tiled_code(design_code((4, 4)).code, 24, 32)
    a = grab(make_rig(seed=1, effects=effects), pats, 3)
    b = grab(make_rig(seed=1, effects=effects), pats, 3)
    c = grab(make_rig(seed=2, effects=effects, homography=make_rig(seed=1).truth.homography), pats, 3)
    for fa, fb in zip(a, b, strict=True):
        np.testing.assert_array_equal(fa.image, fb.image)
    assert not np.array_equal(a[0].image, c[0].image)
    assert not np.array_equal(a[0].image, a[1].image)  # each exposure draws its own noise


def test_dropped_frames_show_as_frame_id_gaps():
    rig = make_rig(seed=3, effects={"dropped_frames": {"probability": 0.4}}, homography=np.eye(3))
    code = design_code((4, 4)).code
    frames = grab(rig, tiled_code(code, 24, 32), 10)
    ids = [f.frame_id for f in frames]
    assert ids == sorted(ids) and ids[-1] > 9  # gaps: the ids of dropped frames are skipped
    assert set(rig.camera.dropped_ids) == set(range(ids[-1] + 1)) - set(ids)
    expected = capture(rig.truth.video, code)
    for f in frames:  # a delivered frame is the exposure its id names, never a zeroed one
        np.testing.assert_allclose(f.image, expected[f.frame_id % 3], atol=1e-6)


def test_single_bright_projector_pixel_lands_where_the_homography_says():
    # A white wall: the frame is the projected light itself.
    rig = make_rig(scene=np.ones((16, 40, 48), np.float32), seed=4, camera_size=None, projector_size=(44, 56))
    pats = np.zeros((16, 44, 56), bool)
    pats[:, 20, 30] = True  # projector pixel x=30, y=20 in every slot
    frame = grab(rig, pats, 1)[0].image
    ys, xs = np.mgrid[: frame.shape[0], : frame.shape[1]]
    centroid = np.array([(xs * frame).sum(), (ys * frame).sum()]) / frame.sum()
    expected = rig.truth.projector_to_camera([[30, 20]])[0]
    np.testing.assert_allclose(centroid, expected, atol=0.15)
    # Area-correct: a 6x6 block of mirrors lights its area in camera pixels (to the warp's
    # 1/4-pixel sub-sampling), not a whole number of camera pixels.
    block = np.zeros((1, 44, 56), bool)
    block[0, 17:23, 27:33] = True
    area = 36 * abs(np.linalg.det(rig.truth.homography[:2, :2]))
    assert warp_patterns(block, rig.truth.homography, (40, 48)).sum() == pytest.approx(area, rel=0.02)


def test_outside_the_projector_only_ambient():
    h = np.array([[1.0, 0, 8], [0, 1, 0], [0, 0, 1]])  # projector shifted 8 px right: columns 0..7 unlit
    rig = make_rig(scene="static", homography=h, effects={"ambient": {"level": 0.05}})
    frame = grab(rig, np.ones((16, 24, 32), bool), 1)[0].image
    video = rig.truth.video[:16]
    np.testing.assert_allclose(frame[:, :8], 0.05 * video[:, :, :8].sum(axis=0), rtol=1e-5)
    np.testing.assert_allclose(frame[:, 8:], 1.05 * video[:, :, 8:].sum(axis=0), rtol=1e-5)


def test_effects_apply_only_when_declared():
    pats = tiled_code(design_code((4, 4)).code, 24, 32)
    plain = grab(make_rig(seed=1), pats, 1)[0].image
    h = make_rig(seed=1).truth.homography
    leaky = grab(make_rig(seed=1, effects={"leakage": {"alpha": 0.1}}), pats, 1)[0].image
    assert plain.dtype == np.float32 and not np.array_equal(plain, leaky)
    assert np.all(leaky >= plain - 1e-6)
    spec = scene_from_mapping({"source": {"builtin": "drummer", "height": 24, "width": 32},
                               "effects": {"adc": {"bits": 12}}})
    counted = grab(SimulatedRig.create(spec, clock=VirtualClock(), homography=h, seed=1, subframes=48, ideal=True),
                   pats, 1)
    assert counted[0].image.dtype == np.uint16
    again = grab(SimulatedRig.create("drummer", camera_size=(24, 32), subframes=48, clock=VirtualClock(),
                                     homography=h, seed=1, effects=parse_effects({}), ideal=True), pats, 1)[0].image
    np.testing.assert_array_equal(again, plain)


def test_phase_slots_relabels_the_slots():
    K = 16
    pats = np.zeros((K, 24, 32), bool)
    for k in range(K):
        pats[k, k] = True  # pattern k lights row k
    ramp = np.broadcast_to(np.arange(48, dtype=np.float32)[:, None, None] / 48, (48, 24, 32))
    rig = make_rig(scene=np.ascontiguousarray(ramp), camera_size=None, homography=np.eye(3), phase_slots=5)
    frame = grab(rig, pats, 1)[0].image
    # exposure slot t sees pattern (t + 5) mod K: row r is lit in slot (r - 5) mod K
    lit_slot = (np.arange(K) - 5) % K
    np.testing.assert_allclose(frame[:K, 0], lit_slot / 48, atol=1e-6)


def test_grab_waits_at_most_its_timeout():
    clock = VirtualClock()
    rig = make_rig(clock=clock)
    t0 = time.perf_counter()
    with pytest.raises(DeviceTimeoutError,
                       match=r"no frame within 0.02 s \(trigger source Line0: is the projector running"):
        grab(rig, np.ones((16, 24, 32), bool), 1, timeout_s=0.02, start_projector=False)
    assert clock.now == 20_000 and time.perf_counter() - t0 < 1.0
    with pytest.raises(IncompatibleStateError, match=r"call start_acquisition\(\) first"):
        rig.camera.stop_acquisition()
        rig.camera.read_frame(timeout_s=0.01)


def test_wrong_line_and_syncbox_wiring_need_their_trigger():
    pats = np.ones((16, 24, 32), bool)
    rig = make_rig(camera_line=TriggerSource.LINE2)
    with pytest.raises(DeviceTimeoutError, match="no frame within"):
        grab(rig, pats, 1, timeout_s=0.1)
    rig = make_rig(wiring="syncbox")
    with pytest.raises(DeviceTimeoutError, match="no frame within"):
        grab(rig, pats, 1, timeout_s=0.1)
    from rig_drivers.interfaces import SyncSettings

    with rig.sync:
        rig.sync.configure(SyncSettings(period_us=PERIOD, pulses_per_frame=16))
        rig.sync.enable()
        rig.sync.start()
        assert rig.camera.read_frame(0.1).frame_id == 0  # the sync box triggers the first exposure


def test_free_run_integrates_one_sequence_and_a_stopped_projector_is_dark():
    pats = np.zeros((16, 24, 32), bool)
    pats[0] = True  # only slot 0 lit
    rig = make_rig(scene=np.ones((48, 24, 32), np.float32), camera_size=None, homography=np.eye(3))
    free = CameraSettings(exposure_us=16 * PERIOD + PERIOD // 2)  # half a slot longer than a sequence
    frames = grab(rig, pats, 3, settings=free)
    levels = [float(f.image.mean()) for f in frames]
    assert levels[0] == pytest.approx(1.0) and levels[1] == pytest.approx(1.0)  # one slot's worth, spread
    rig.projector.stop()
    assert float(rig.camera.read_frame(0.5).image.max()) == 0.0


def test_projector_refuses_patterns_of_another_size_and_bad_arguments():
    rig = make_rig(projector_size=(30, 40))
    with rig.projector:
        with pytest.raises(SettingError, match=r"`patterns` must be 30x40 projector pixels \(H x W\) .*; got 24x32"):
            rig.projector.load_sequence(PatternSequence(np.ones((4, 24, 32), bool), PERIOD, PERIOD))
    with pytest.raises(SettingError, match="unknown scene 'nope'; built-in scenes: fan, balls"):
        SimulatedRig.create("nope")
    with pytest.raises(SettingError, match="`wiring` must be one of projector, syncbox"):
        SimulatedRig.create("static", wiring="usb")
    with pytest.raises(SettingError, match="`homography` must be invertible"):
        SimulatedRig.create("static", homography=np.zeros((3, 3)))


def test_warp_is_exact_for_the_identity_and_keeps_light_in_range():
    rng = np.random.default_rng(0)
    pats = rng.random((3, 10, 12)) < 0.5
    np.testing.assert_array_equal(warp_patterns(pats, np.eye(3), (10, 12)), pats.astype(np.float32))
    h = coarse_homography((10, 12), (10, 12), 3)
    w = warp_patterns(pats, h, (10, 12))
    assert w.min() >= 0 and w.max() <= 1 and len(np.unique(w)) > 2  # grey where a pixel straddles mirrors


def test_a_real_clock_never_repeats_an_exposure():
    """With a real clock, time moves between the camera's reading and the projector's (about 0.7 s)."""
    from rig_drivers.simulated_camera import MonotonicClock

    code = design_code((4, 4)).code
    rig = make_rig(homography=np.eye(3), clock=MonotonicClock())
    frames = grab(rig, tiled_code(code, 24, 32), 10, timeout_s=1.0)
    stamps = np.array([f.timestamp_s for f in frames])
    assert np.all(np.diff(stamps) > 0.5 * 16 * PERIOD / 1e6), np.diff(stamps)  # one exposure per period
