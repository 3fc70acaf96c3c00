"""The Camera contract against every camera, and what each camera does beyond it."""

import enum
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from rig_drivers.errors import DeviceNotFoundError, DeviceTimeoutError, SettingError
from rig_drivers.genicam import GenICamCamera, simulated_producer
from rig_drivers.interfaces import CameraSettings, TriggerActivation, TriggerConfig, TriggerSource
from rig_drivers.simulated_camera import SimulatedCamera, VirtualClock
from rig_drivers.simulated_rig import SimulatedRig
from rig_drivers.uvc import UvcCamera

from .contract_camera import CameraContract

# --------------------------------------------------------------------------- fakes


class FakeTime:
    """A host clock in seconds whose sleep advances it (no real waiting)."""

    def __init__(self):
        self.now = 100.0
        self.slept = 0.0

    def __call__(self):
        return self.now

    def sleep(self, s):
        self.slept += s
        self.now += max(s, 1e-4)


class FakeCapture:
    """cv2.VideoCapture stand-in: serves BGR frames, or fails every read when `frames` is empty."""

    def __init__(self, frames, *, opened=True, accept=True):
        self.frames = list(frames)
        self.opened = opened
        self.accept = accept
        self.released = False
        self.set_calls = {}

    def isOpened(self):  # noqa: N802 - OpenCV's name
        return self.opened

    def read(self):
        if not self.frames:
            return False, None
        return True, self.frames.pop(0) if len(self.frames) > 1 else self.frames[0]

    def get(self, prop):
        import cv2

        shape = self.frames[0].shape if self.frames else (0, 0)
        return {cv2.CAP_PROP_FRAME_HEIGHT: shape[0], cv2.CAP_PROP_FRAME_WIDTH: shape[1]}.get(prop, 0.0)

    def set(self, prop, value):
        self.set_calls[prop] = value
        return self.accept

    def release(self):
        self.released = True


def bgr_frames(n=3, shape=(6, 8)):
    rng = np.random.default_rng(1)
    return [rng.integers(0, 255, shape + (3,), dtype=np.uint8) for _ in range(n)]


def viky_or_skip():
    """The genicam wheel's simulated producer, or skip (with the reason) where it is absent."""
    pytest.importorskip("harvesters.core", reason="harvesters is not installed (pip install -e '.[genicam]')",
                        exc_type=ImportError)
    cti = simulated_producer()
    if cti is None:
        pytest.skip("the genicam wheel (with viky.cti) is not installed (pip install -e '.[genicam]')")
    return cti


# --------------------------------------------------------------------------- contract runs


class TestSimulatedCameraContract(CameraContract):
    @pytest.fixture
    def camera(self):
        video = np.random.default_rng(0).random((32, 12, 16), dtype=np.float32)
        return SimulatedCamera(video, clock=VirtualClock())


class TestRigCameraContract(CameraContract):
    @pytest.fixture
    def camera(self):
        return SimulatedRig.create("static", camera_size=(16, 24), subframes=16, clock=VirtualClock()).camera


class TestUvcCameraOverFakeCapture(CameraContract):
    @pytest.fixture
    def camera(self):
        clock = FakeTime()
        return UvcCamera(0, capture_factory=lambda i: FakeCapture(bgr_frames()), clock_s=clock, sleep_s=clock.sleep)


class TestGenICamOverViky(CameraContract):
    """The real driver against the simulated GenTL producer of the `genicam` wheel."""

    @pytest.fixture
    def camera(self):
        return GenICamCamera(viky_or_skip(), serial="0")


# --------------------------------------------------------------------------- simulated camera


def test_simulated_camera_alone_is_dark_and_times_out_on_a_line():
    clock = VirtualClock()
    video = np.ones((8, 4, 5), np.float32)
    with SimulatedCamera(video, clock=clock, default_slots=4) as cam:
        cam.configure(CameraSettings(exposure_us=1000, trigger=TriggerConfig(source=TriggerSource.LINE1)))
        cam.enable()
        cam.start_acquisition()
        with pytest.raises(DeviceTimeoutError,
                           match=r"no frame within 0.05 s \(trigger source Line1: is the projector"):
            cam.read_frame(timeout_s=0.05)
        assert clock.now == 50_000  # the wait used the (virtual) timeout, no more


def test_software_trigger_delivers_one_frame_per_trigger():
    clock = VirtualClock()
    with SimulatedCamera(np.zeros((8, 4, 5), np.float32), clock=clock) as cam:
        cam.configure(CameraSettings(exposure_us=2000, trigger=TriggerConfig(source=TriggerSource.SOFTWARE)))
        cam.enable()
        cam.start_acquisition()
        with pytest.raises(DeviceTimeoutError, match=r"call trigger_software\(\) for each frame"):
            cam.read_frame(timeout_s=0.01)
        cam.trigger_software()
        frame = cam.read_frame(timeout_s=0.01)
        assert frame.frame_id == 0 and frame.timestamp_s == pytest.approx(0.01)
        assert clock.now == 12_000


def test_slow_consumer_loses_frames_as_id_gaps():
    clock = VirtualClock()
    with SimulatedCamera(np.zeros((8, 4, 5), np.float32), clock=clock, buffer_frames=2) as cam:
        cam.configure(CameraSettings(exposure_us=1000))
        cam.enable()
        cam.start_acquisition()
        assert cam.read_frame(0.01).frame_id == 0
        clock.advance(10_000)  # 10 more exposures complete; the camera holds 2
        assert cam.read_frame(0.01).frame_id == 9
        assert cam.dropped_ids == list(range(1, 9))


# --------------------------------------------------------------------------- UVC


def test_uvc_is_marked_unable_to_shutter_and_synthesises_ids():
    clock = FakeTime()
    cam = UvcCamera(2, capture_factory=lambda i: FakeCapture(bgr_frames()), clock_s=clock, sleep_s=clock.sleep)
    caps = cam.capabilities
    assert not caps.hardware_trigger and not caps.frame_ids and not caps.device_timestamps
    assert UvcCamera.synthesised_ids is True
    with cam:
        with pytest.raises(SettingError, match="has no hardware trigger: it cannot shutter in sync with the projector"):
            cam.configure(CameraSettings(exposure_us=1000, trigger=TriggerConfig(source=TriggerSource.LINE0)))
        with pytest.raises(SettingError, match="can only run free .* no Software trigger"):
            cam.configure(CameraSettings(exposure_us=1000, trigger=TriggerConfig(source=TriggerSource.SOFTWARE)))
        cam.configure(CameraSettings(exposure_us=1000))
        cam.enable()
        cam.start_acquisition()
        frames = [cam.read_frame(0.1) for _ in range(3)]
    assert [f.frame_id for f in frames] == [0, 1, 2]
    assert frames[0].image.shape == (6, 8) and frames[0].image.dtype == np.uint8  # grey


def test_uvc_read_times_out_quickly_and_missing_camera_is_explained():
    clock = FakeTime()
    cap = FakeCapture(bgr_frames(1))
    cam = UvcCamera(0, capture_factory=lambda i: cap, clock_s=clock, sleep_s=clock.sleep)
    with cam:
        cam.configure(CameraSettings(exposure_us=1000))
        cam.enable()
        cam.start_acquisition()
        cap.frames.clear()
        with pytest.raises(DeviceTimeoutError, match=r"UVC camera 0: no frame within 0.05 s"):
            cam.read_frame(timeout_s=0.05)
        assert 0.04 <= clock.slept <= 0.06
    assert cap.released
    absent = UvcCamera(3, capture_factory=lambda i: FakeCapture([], opened=False))
    with pytest.raises(DeviceNotFoundError, match=r"no UVC camera at index 3: is it plugged in"):
        absent.open()


def test_uvc_backend_refusing_exposure_is_recorded():
    clock = FakeTime()
    cam = UvcCamera(0, capture_factory=lambda i: FakeCapture(bgr_frames(), accept=False), clock_s=clock,
                    sleep_s=clock.sleep)
    with cam:
        cam.configure(CameraSettings(exposure_us=1000))
        assert cam.unapplied == ["auto exposure off", "exposure", "gain"]


# --------------------------------------------------------------------------- GenICam over a fake harvesters


class FakeNode:
    def __init__(self, value, symbolics=None, lo=None, hi=None):
        self.value = value
        if symbolics is not None:
            self.symbolics = tuple(symbolics)
        if lo is not None:
            self.min, self.max = lo, hi
        self.executed = 0

    def execute(self):
        self.executed += 1


class FakeNodeMap:
    def __init__(self, **nodes):
        self.__dict__.update(nodes)

    def has_node(self, name):
        return name in self.__dict__


class FakeCallback:
    def emit(self, context=None):
        raise NotImplementedError


class FakeAcquirer:
    class Events(enum.IntEnum):
        INCOMPLETE_BUFFER = 4

    def __init__(self, node_map, script):
        self.remote_device = SimpleNamespace(node_map=node_map)
        self.script = list(script)
        self.callbacks = {}
        self.started = self.destroyed = False

    def add_callback(self, event, callback):
        self.callbacks[event] = callback

    def start(self):
        self.started = True

    def stop(self):
        self.started = False

    def destroy(self):
        self.destroyed = True

    def try_fetch(self, *, timeout):
        item = self.script.pop(0) if self.script else None
        if item == "incomplete":
            self.callbacks[self.Events.INCOMPLETE_BUFFER].emit(context=self)
            return None
        return item


class FakeBuffer:
    def __init__(self, frame_id, image, timestamp_ns=None):
        self.module = SimpleNamespace(frame_id=frame_id)
        self._ts = timestamp_ns
        h, w = image.shape
        self.payload = SimpleNamespace(components=[SimpleNamespace(data=image.ravel(), width=w, height=h)])

    @property
    def timestamp_ns(self):
        if self._ts is None:
            raise RuntimeError("timestamps not supported by the device")
        return self._ts

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return None


def fake_harvesters(node_map, script, devices=({"serial_number": "7", "model": "M", "vendor": "V"},)):
    acquirer = FakeAcquirer(node_map, script)

    class Harvester:
        def __init__(self):
            self.files = []
            self.device_info_list = []

        def add_file(self, path):
            self.files.append(path)

        def update(self):
            self.device_info_list = [SimpleNamespace(property_dict=d) for d in devices]

        def create(self, index):
            return acquirer

        def reset(self):
            self.device_info_list = []

    return SimpleNamespace(Harvester=Harvester, Callback=FakeCallback), acquirer


def trigger_nodes():
    return FakeNodeMap(
        Width=FakeNode(8), Height=FakeNode(6), PixelFormat=FakeNode("Mono8", ["Mono8", "Mono12"]),
        TriggerSelector=FakeNode("AcquisitionStart", ["AcquisitionStart", "FrameStart"]),
        TriggerMode=FakeNode("Off", ["Off", "On"]),
        TriggerSource=FakeNode("Software", ["Software", "Line0", "Line1"]),
        TriggerActivation=FakeNode("RisingEdge", ["RisingEdge", "FallingEdge"]),
        TriggerSoftware=FakeNode(None), ExposureAuto=FakeNode("Continuous", ["Off", "Continuous"]),
        ExposureTime=FakeNode(1000.0, lo=20.0, hi=1e6), Gain=FakeNode(0.0, lo=0.0, hi=24.0))


@pytest.fixture
def cti(tmp_path):
    path = tmp_path / "producer.cti"
    path.write_bytes(b"")
    return path


def test_genicam_writes_frame_start_trigger_on_a_line(cti):
    nodes = trigger_nodes()
    module, acquirer = fake_harvesters(nodes, [])
    cam = GenICamCamera(cti, serial="7", harvesters_module=module)
    with cam:
        assert cam.capabilities.hardware_trigger and cam.sensor_shape == (6, 8)
        cam.configure(CameraSettings(exposure_us=4000, gain_db=3, trigger=TriggerConfig(
            source=TriggerSource.LINE1, activation=TriggerActivation.FALLING_EDGE)))
    assert (nodes.TriggerSelector.value, nodes.TriggerMode.value, nodes.TriggerSource.value,
            nodes.TriggerActivation.value) == ("FrameStart", "On", "Line1", "FallingEdge")
    assert (nodes.ExposureAuto.value, nodes.ExposureTime.value, nodes.Gain.value) == ("Off", 4000.0, 3.0)
    assert acquirer.destroyed


def test_genicam_trigger_delay_is_a_capability_and_is_written_or_refused(cti):
    nodes = trigger_nodes()
    nodes.TriggerDelay = FakeNode(500.0, lo=0.0, hi=1e6)
    module, _ = fake_harvesters(nodes, [])
    line = dict(exposure_us=4000)
    with GenICamCamera(cti, harvesters_module=module) as cam:
        assert cam.capabilities.trigger_delay
        cam.configure(CameraSettings(**line, trigger=TriggerConfig(source=TriggerSource.LINE0, delay_us=964.0)))
        assert nodes.TriggerDelay.value == 964.0
        cam.configure(CameraSettings(**line, trigger=TriggerConfig(source=TriggerSource.LINE0)))
        assert nodes.TriggerDelay.value == 0.0  # no delay asked: an earlier one is undone
    plain = trigger_nodes()
    module, _ = fake_harvesters(plain, [])
    with GenICamCamera(cti, harvesters_module=module) as cam:
        assert not cam.capabilities.trigger_delay
        cam.configure(CameraSettings(**line, trigger=TriggerConfig(source=TriggerSource.LINE0)))  # no delay: fine
        with pytest.raises(SettingError, match=r"has no TriggerDelay feature: it cannot do this setting"):
            cam.configure(CameraSettings(**line, trigger=TriggerConfig(source=TriggerSource.LINE0, delay_us=964.0)))


def test_genicam_refuses_out_of_range_exposure_and_missing_lines(cti):
    nodes = trigger_nodes()
    module, _ = fake_harvesters(nodes, [])
    with GenICamCamera(cti, harvesters_module=module) as cam:
        with pytest.raises(SettingError, match="ExposureTime must be between 20 and 1e\\+06; got 2e\\+06"):
            cam.configure(CameraSettings(exposure_us=2e6))
        with pytest.raises(SettingError, match="has no trigger source Line3; it has Software, Line0, Line1"):
            cam.configure(CameraSettings(exposure_us=1000, trigger=TriggerConfig(source=TriggerSource.LINE3)))


def test_genicam_counts_incomplete_buffers_and_id_gaps(cti):
    img = np.arange(48, dtype=np.uint8).reshape(6, 8)
    script = [FakeBuffer(1, img, 5_000_000_000), "incomplete", FakeBuffer(3, img, 6_000_000_000),
              FakeBuffer(6, img, 7_000_000_000)]
    module, _ = fake_harvesters(trigger_nodes(), script)
    clock = FakeTime()
    with GenICamCamera(cti, harvesters_module=module, clock_s=clock) as cam:
        cam.configure(CameraSettings(exposure_us=1000))
        cam.enable()
        cam.start_acquisition()
        frames = [cam.read_frame(0.5) for _ in range(3)]
        assert [f.frame_id for f in frames] == [1, 3, 6]
        assert [f.timestamp_s for f in frames] == [5.0, 6.0, 7.0] and cam.capabilities.device_timestamps
        assert np.array_equal(frames[0].image, img)
        assert cam.incomplete_buffers == 1 and cam.dropped_frames == 3  # 2 (incomplete) + 4, 5 (gap)


def test_genicam_unknown_serial_lists_what_was_found(cti):
    module, _ = fake_harvesters(trigger_nodes(), [])
    with pytest.raises(DeviceNotFoundError, match=r"no camera with serial 9 .*; found: V M \(serial 7\)"):
        GenICamCamera(cti, serial="9", harvesters_module=module).open()


def test_genicam_without_harvesters_says_how_to_install(cti, monkeypatch):
    monkeypatch.setitem(sys.modules, "harvesters", None)
    monkeypatch.setitem(sys.modules, "harvesters.core", None)
    cam = GenICamCamera(cti)
    with pytest.raises(DeviceNotFoundError,
                       match=r"harvesters package, which is not installed: .*pip install -e \"\.\[genicam\]\""):
        cam.open()
    assert cam.state.value == "closed"


def test_genicam_missing_producer_file_is_explained(tmp_path):
    module, _ = fake_harvesters(trigger_nodes(), [])
    with pytest.raises(DeviceNotFoundError, match=r"no GenTL producer at .*nope.cti"):
        GenICamCamera(tmp_path / "nope.cti", harvesters_module=module).open()


def test_genicam_viky_times_out_quickly_and_has_no_trigger():
    with GenICamCamera(viky_or_skip(), serial="1") as cam:
        assert not cam.capabilities.hardware_trigger
        cam.configure(CameraSettings(exposure_us=2e5))  # free run at 5 frames per second
        assert "ExposureTime" in cam.unapplied
        cam.enable()
        cam.start_acquisition()
        first = cam.read_frame(timeout_s=2.0)
        with pytest.raises(DeviceTimeoutError, match=r"no complete frame within 0.05 s"):
            cam.read_frame(timeout_s=0.05)
        assert first.image.shape == cam.sensor_shape
