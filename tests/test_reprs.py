"""Every public object prints as a few lines of facts (shape, dtype, key fields): never an array's values, never a
memory address; the ones a notebook shows as a table have ``_repr_html_``."""

from __future__ import annotations

import re

import numpy as np
import pytest

import flexvox_core as fv
from flexvox_app.capture import CapturePlan, CaptureService
from flexvox_calibration import CaptureCalibration
from flexvox_core.flow import FlowField
from flexvox_core.motion.result import MotionAwareResult
from flexvox_core.reprs import describe_array, html_table
from rig_drivers import open_rig
from rig_drivers.simulated_camera import MonotonicClock, VirtualClock
from rig_drivers.simulated_rig_spec import SimulatedRigSpec

CODE = fv.design_code((2, 2))


@pytest.fixture(scope="module")
def objects(tmp_path_factory):
    """One of each public object, at tiny sizes, by name."""
    tmp = tmp_path_factory.mktemp("reprs")
    sim = fv.simulate_video(fv.render_scene("balls", 16, 16, 16, seed=0), CODE.code)
    rec_path = fv.write_simulation(tmp / "r.zarr", sim)
    out = fv.run(sim.frames, CODE.code, fv.Method("diffusion"))
    fv.write_video(tmp / "v.zarr", out.video, time_step=0.01)
    S, H, W = out.video.shape
    flow = FlowField(np.zeros((S, H, W, 2), np.float32), np.ones((S, H, W), np.float32))
    motion = MotionAwareResult(out.video, out.video, flow, 4, seconds={"high_tr": 0.5, "flow": 0.25, "diffusion": 1.0})
    rig = open_rig("mock", clock=VirtualClock(), camera_size=(16, 24), subframes=32)
    service = CaptureService(rig, CapturePlan.from_code(CODE.code), tmp / "c.zarr", frames=4)
    before = repr(service)
    result = service.run(timeout_s=60)
    return {
        "DesignResult": CODE, "SimulationResult": sim, "Recording": fv.open_recording(rec_path),
        "MethodOutput": out, "MotionAwareResult": motion, "CaptureReader": fv.open_capture(rec_path),
        "VideoStore": fv.open_video_store(tmp / "v.zarr"), "MultiplexedCode": fv.multiplexed_code((1, 3)),
        "ProfileRig": rig, "SimulatedRig": rig.simulated, "SimulatedCamera": rig.camera,
        "SimulatedRigSpec": SimulatedRigSpec(np.zeros((8, 16, 16), np.float32), seed=3),
        "VirtualClock": VirtualClock(5), "MonotonicClock": MonotonicClock(),
        "CaptureService (idle)": before, "CaptureService": service, "CaptureResult": result,
        "CaptureStats": result.stats, "CaptureCalibration": CaptureCalibration(),
    }


EXPECTED = {
    "DesignResult": r"<DesignResult tile 2x2 \(K = 4\), 4 divisions supported, separation 1, \d+\.\d\d s>",
    "MethodOutput": r"<MethodOutput video 16×16×16 float32, interpolated 0 sub-frames, on cpu>",
    "MotionAwareResult": r"<MotionAwareResult video 16×16×16 float32, K = 4, on cpu, 1.75 s>",
    "CaptureReader": r"<CaptureReader r.zarr: 4 frames of 16x16, tile 2x2 \(K = 4\), 0 missing>",
    "VideoStore": r"<VideoStore v.zarr: 16×16×16 float32, time step 0.01 s>",
    "MultiplexedCode": r"<MultiplexedCode tile 1x3 \(K = 3\), throughput 0.67, SNR gain 1.15 under read noise, "
                       r"0.82 under photon noise>",
    "ProfileRig": r"<ProfileRig 'simulated rig \(mock, seed 0\)'\n"
                  r"  projector: <RigProjector 'simulated projector' \(projector\): closed>\n"
                  r"  camera: <SimulatedCamera 'simulated camera' \(camera\): closed>\n"
                  r"  sync: <SimulatedSyncController 'simulated sync box' \(sync box\): closed>>",
    "SimulatedRig": r"<SimulatedRig 'simulated rig \(seed 0\)'\n(  \w+: <.*>\n){3}  clock: <VirtualClock at \d+ µs>>",
    "SimulatedCamera": r"<SimulatedCamera 'simulated camera' \(camera\): closed>",
    "SimulatedRigSpec": r"SimulatedRigSpec\(scene=array 8×16×16 float32, seed=3\)",
    "VirtualClock": r"<VirtualClock at 5 µs>",
    "MonotonicClock": r"<MonotonicClock: real time>",
    "CaptureService (idle)": r"\"<CaptureService idle: 4 frames of tile 2x2 \(K = 4\) at 15 Hz into c.zarr, rig "
                             r"'simulated rig \(mock, seed 0\)'>\"",
    "CaptureService": r"<CaptureService done: 4 frames of tile 2x2 .*; done: 4 rows written \(0 dropped\)>",
    "CaptureResult": r"<CaptureResult done: captured 4 frames: 0 dropped \(0 by the queue\); .*c.zarr holds 4 "
                     r"frame\(s\) and opens cleanly>",
    "CaptureStats": r"<CaptureStats done: 4 rows written \(0 dropped, 0 by the queue\), 4 frames received, camera "
                    r"\d+\.\d Hz, writing \d+\.\d Hz, \d+\.\d s>",
    "CaptureCalibration": r"<CaptureCalibration identity \(uncalibrated\) · RMS — · no sync>",
    "SimulationResult": r"<SimulationResult: 4 frames of 16x16 \(float32\), tile 2x2 \(K = 4\), 0 dropped, "
                        r"effects: none>",
    "Recording": r"<Recording r.zarr: 4 frames of 16x16, tile 2x2 \(K = 4\), 15 Hz, 0 dropped, ground truth>",
}


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_a_public_objects_repr_is_a_few_lines_of_facts(objects, name):
    text = repr(objects[name])
    assert re.fullmatch(EXPECTED[name], text, flags=re.DOTALL), text
    assert len(text.splitlines()) <= 5 and len(text) <= 300
    assert not re.search(r"0x[0-9a-f]{6,}|array\(\[|\[\[", text)  # no address, no values


@pytest.mark.parametrize("name", ["DesignResult", "MethodOutput", "MotionAwareResult", "VideoStore", "Recording",
                                  "CaptureStats"])
def test_a_notebook_shows_a_table(objects, name):
    table = objects[name]._repr_html_()
    assert table.startswith(f"<table><caption>{name}</caption><tr><th") and table.endswith("</table>")
    assert "[[" not in table and table.count("<tr>") >= 3


def test_a_design_that_found_no_code_says_why():
    result = fv.design_code((4, 4), separation=5)
    assert re.fullmatch(r"<DesignResult tile 4x4 \(K = 16\), no code \(status 2\): .+>", repr(result)), repr(result)


def test_the_helpers_describe_without_reading_values():
    class Lazy:  # a zarr or dask array stands in: shape and dtype, values never read
        shape, dtype = (3, 4), np.dtype("uint16")

        def __array__(self, *args, **kwargs):
            raise AssertionError("read")

    assert describe_array(Lazy()) == "3×4 uint16" and describe_array([1, 2]) == "list"
    assert html_table("<x>", [("a&b", "<1>")]) == ("<table><caption>&lt;x&gt;</caption><tr><th style='text-align:"
                                                   "left'>a&amp;b</th><td>&lt;1&gt;</td></tr></table>")
