"""The capture tests' small code and plan, and the textbook simulated rig they capture from."""

from flexvox_app.capture import CapturePlan
from flexvox_core.design import design_code
from rig_drivers.simulated_camera import VirtualClock
from rig_drivers.simulated_rig import SimulatedRig

CODE = design_code((2, 2)).code  # K = 4: small and fast
PLAN = CapturePlan.from_code(CODE)
PERIOD = PLAN.period_us  # 16666 µs at 15 Hz


def make_rig(**kw):
    """The textbook rig (projector = camera, identity map, no trigger offset): these tests are about the capture
    path's mechanics; tests/app/capture/test_one_chain.py captures through a calibration of the real one."""
    kw.setdefault("camera_size", (16, 24))
    kw.setdefault("subframes", 32)
    kw.setdefault("ideal", True)
    kw.setdefault("clock", VirtualClock())
    return SimulatedRig.create(kw.pop("scene", "balls"), **kw)
