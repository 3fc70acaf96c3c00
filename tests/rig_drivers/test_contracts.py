"""Run the interface contracts against every implementation."""

import pytest

from rig_drivers.dlpc350 import DLPC350, FakeDLPC350Transport
from rig_drivers.profile import open_rig
from rig_drivers.simulated import SimulatedProjector, SimulatedSyncController
from rig_drivers.simulated_camera import VirtualClock
from rig_drivers.simulated_rig import SimulatedRig
from rig_drivers.syncbox import FakeSyncBoxSerial, SyncBox

from .contract_projector import ProjectorContract
from .contract_rig import RigContract
from .contract_sync import SyncControllerContract
from .display_rig import display_rig


class Clock:
    """A hand-advanced µs clock."""

    def __init__(self):
        self.now = 0

    def __call__(self):
        return self.now

    def advance(self, us):
        self.now += us


class TestSimulatedProjector(ProjectorContract):
    @pytest.fixture
    def projector(self):
        return SimulatedProjector(clock_us=Clock())

    @pytest.fixture
    def device_running(self):
        return lambda p: p.current_slot() is not None and p.run_state.value == "running"


class TestDLPC350OverFakeTransport(ProjectorContract):
    @pytest.fixture
    def fake(self):
        return FakeDLPC350Transport()

    @pytest.fixture
    def projector(self, fake):
        return DLPC350(fake, poll_interval_s=0)

    @pytest.fixture
    def device_running(self, fake):
        return lambda p: fake.running


class TestSimulatedSyncController(SyncControllerContract):
    @pytest.fixture
    def clock(self):
        return Clock()

    @pytest.fixture
    def sync(self, clock):
        return SimulatedSyncController(clock_us=clock)

    @pytest.fixture
    def advance(self, clock):
        return clock.advance


class TestSyncBoxOverFakeSerial(SyncControllerContract):
    @pytest.fixture
    def port(self):
        return FakeSyncBoxSerial()

    @pytest.fixture
    def sync(self, port):
        return SyncBox(port, timeout_s=0.05)

    @pytest.fixture
    def advance(self, port):
        return port.advance_us


class TestSimulatedRig(RigContract):
    @pytest.fixture
    def rig(self):
        return SimulatedRig.create("balls", camera_size=(16, 24), subframes=8, clock=VirtualClock())


class TestProfileRigOfMock(RigContract):
    @pytest.fixture
    def rig(self):
        return open_rig("mock", scene="balls", camera_size=(16, 24), subframes=8, clock=VirtualClock())


class TestProfileRigOfADLPC350(RigContract):
    """A real-rig profile: a DLPC350 (fake USB) fed on its video port, TRIG_OUT_2 to the camera, no sync box."""

    @pytest.fixture
    def rig(self):
        return display_rig()
