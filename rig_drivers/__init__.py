"""rig_drivers — device interfaces, the simulated rig and real drivers (projector, camera,
sync box). Qt-free.

- :mod:`rig_drivers.errors`: the exception hierarchy
- :mod:`rig_drivers.interfaces`: Device lifecycle, Projector, Camera, SyncController, settings, and
  the Rig protocol every rig implements
- :mod:`rig_drivers.simulated`: SimulatedProjector, SimulatedSyncController
- :mod:`rig_drivers.simulated_camera`: SimulatedCamera and the simulation clocks
- :mod:`rig_drivers.simulated_rig`: SimulatedRig, the coupled projector/camera/sync box + truth
- :mod:`rig_drivers.simulated_rig_spec`: SimulatedRigSpec, what a simulated rig is built from
- :mod:`rig_drivers.genicam`: GenICam cameras through harvesters (optional extra ``genicam``)
- :mod:`rig_drivers.uvc`: UVC webcams through OpenCV (preview and alignment only)
- :mod:`rig_drivers.profile`: rig profiles (``--rig mock`` or ``--rig FILE.toml``), ``open_rig`` and
  the ProfileRig it returns
- :mod:`rig_drivers.dlpc350`: TI DLP LightCrafter 4500 over USB HID (+ a fake transport)
- :mod:`rig_drivers.syncbox`: the serial sync box (+ a fake serial port)

From Python (docs/python.md): ``from rig_drivers import open_rig``; each name below is imported when first used.
"""

import importlib

__all__ = ["DeviceError", "open_rig", "Rig", "SimulatedRigSpec", "VirtualClock"]

_WHERE = {"DeviceError": "rig_drivers.errors", "Rig": "rig_drivers.interfaces", "open_rig": "rig_drivers.profile",
          "SimulatedRigSpec": "rig_drivers.simulated_rig_spec", "VirtualClock": "rig_drivers.simulated_camera"}


def __getattr__(name: str):
    if name in _WHERE:
        return getattr(importlib.import_module(_WHERE[name]), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(__all__))
