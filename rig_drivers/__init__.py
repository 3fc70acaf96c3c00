"""rig_drivers — device interfaces, the simulated rig and real drivers (projector, camera,
sync box). Qt-free. Filled in by the *Rig drivers* issue."""
