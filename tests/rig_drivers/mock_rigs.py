"""The simulated rig as tests build it: the one ``--rig mock`` rig, set up for a test.

:func:`calibration_rig` is the rig with its calibration target in view (what calibration images);
:func:`ideal_rig` is the textbook rig (projector = camera, identity map, no trigger offset) for
tests of the capture path itself. Both run on a virtual clock by default (nothing sleeps).
"""

from rig_drivers.profile import open_rig
from rig_drivers.simulated_camera import VirtualClock


def calibration_rig(seed: int = 0, *, camera_size=(120, 160), projector_size=None, homography=None, effects=None,
                    phase_slots=None, delay_us=None, baseline=(0.0, 0.0, 0.0), depth: float = 1.0, video=None,
                    albedo=(0.35, 0.95), shadow=None, camera_line=None, electrons_per_unit=None, clock=None,
                    scene="static"):
    """The simulated rig of ``seed`` (not opened) with the calibration target in view at ``depth``.

    ``effects`` are the effects met with the target (default the rig's
    :data:`~rig_drivers.simulated_target.TARGET_EFFECTS`; ``{}`` for none); ``video`` replaces the
    target; the other options are :meth:`~rig_drivers.simulated_rig.SimulatedRig.create`'s.
    """
    options = dict(scene=scene, camera_size=tuple(camera_size), projector_size=projector_size, homography=homography,
                   seed=int(seed), phase_slots=phase_slots, delay_us=delay_us, baseline=baseline,
                   target_effects=effects, subframes=16, clock=clock or VirtualClock())
    if camera_line is not None:
        options["camera_line"] = camera_line
    if electrons_per_unit is not None:
        options["electrons_per_unit"] = electrons_per_unit
    rig = open_rig("mock", **options)
    rig.simulated.show_target(depth=depth, albedo=albedo, shadow=shadow, video=video)
    return rig


def ideal_rig(scene="balls", **kw):
    """The textbook simulated rig (not opened): projector = camera, identity homography, no trigger offset."""
    kw.setdefault("clock", VirtualClock())
    return open_rig("mock", scene=scene, ideal=True, **kw)
