"""``flexvox capture`` (parser built with register(); the mock rig on a virtual clock)."""

import pytest

from flexvox_app.cli import capture
from flexvox_app.cli.errors import CliError, OneLineParser
from flexvox_core.recording import open_recording


def cli(argv):
    parser = OneLineParser(prog="flexvox")
    sub = parser.add_subparsers(dest="command", parser_class=OneLineParser)
    capture.register(sub)
    args = parser.parse_args(argv)
    return args.func(args)


def test_capture_mock_writes_a_recording_with_counters(tmp_path, capsys):
    out = tmp_path / "r.zarr"
    assert cli(["capture", "--rig", "mock", "--frames", "6", "-o", str(out), "--tile", "2x2", "--size", "16x24",
                "--scene", "balls", "--clock", "virtual", "--ground-truth"]) == 0
    text = capsys.readouterr().out
    assert "capturing to" in text and "6 written, 0 dropped, queue" in text
    assert "captured 6 frames: 0 dropped (0 by the queue)" in text and "holds 6 frame(s)" in text
    rec = open_recording(out)
    assert rec.n_frames == 6 and rec.K == 4 and rec.has_ground_truth and rec.attrs["rig"]["profile"] == "mock"


@pytest.mark.parametrize("argv, message", [
    (["--frames", "0"], r"--frames must be >= 1; got 0"),
    (["--frames", "2", "--scene", "nope"], r"unknown scene 'nope'"),
    (["--frames", "2", "--rate", "5000"], r"the projector's shortest is 235 µs"),
    (["--frames", "2", "--rig", "missing.toml"], r"no rig profile missing.toml"),
])
def test_capture_bad_options(tmp_path, argv, message):
    with pytest.raises(CliError, match=message):
        cli(["capture", "-o", str(tmp_path / "r.zarr"), "--clock", "virtual", "--size", "16x16", *argv])


def test_capture_refuses_an_existing_output_and_bad_sizes(tmp_path, capsys):
    (tmp_path / "r.zarr").mkdir()
    with pytest.raises(CliError, match=r"already exists"):
        cli(["capture", "--frames", "1", "-o", str(tmp_path / "r.zarr")])
    with pytest.raises(SystemExit) as info:
        cli(["capture", "--frames", "1", "-o", str(tmp_path / "s.zarr"), "--size", "4x4"])
    assert info.value.code == 2 and "H, W >= 8" in capsys.readouterr().err


def test_capture_error_exits_1_with_the_count(tmp_path, capsys, monkeypatch):
    from rig_drivers.errors import DeviceError
    from rig_drivers.simulated_camera import SimulatedCamera

    real = SimulatedCamera._do_read_frame
    state = {"n": 0}

    def flaky(self, timeout_s):
        state["n"] += 1
        if state["n"] > 3:
            raise DeviceError("cable pulled")
        return real(self, timeout_s)

    monkeypatch.setattr(SimulatedCamera, "_do_read_frame", flaky)
    assert cli(["capture", "--frames", "50", "-o", str(tmp_path / "r.zarr"), "--size", "16x16",
                "--tile", "2x2", "--clock", "virtual"]) == 1
    err = capsys.readouterr().err
    assert "the camera failed (unplugged?): cable pulled" in err and "holds 3 frame(s)" in err
    assert open_recording(tmp_path / "r.zarr").n_frames == 3


def _calibration_file(path, *, camera_size=(24, 32), phase=3):
    """A calibration file for the mock capture rig of the given size (as `flexvox calibrate -o` writes)."""
    import numpy as np

    from flexvox_calibration.files import CALIBRATION_FORMAT, CALIBRATION_VERSION, write_versioned
    from flexvox_calibration.session import RigSession
    from rig_drivers.profile import open_rig

    rig = open_rig("mock", camera_size=camera_size)
    identity = RigSession.from_rig(rig).identity
    h = np.array([[1.0, 0, 1.0], [0, 1.0, 0], [0, 0, 1.0]])
    sync = {"status": "ok", "K": 16, "period_us": 4166, "phase_slots": phase - 1, "delay_us": 1000.0,
            "recommended_camera_delay_us": 3166.0, "effective_phase_slots": phase}
    body = {"homography": {"projector_to_camera": h.tolist(), "camera_to_projector": np.linalg.inv(h).tolist()},
            "quality": {}, "sync": sync}
    return write_versioned(path, CALIBRATION_FORMAT, CALIBRATION_VERSION, identity, body)


def test_capture_uses_a_calibration_file(tmp_path, capsys):
    cal = _calibration_file(tmp_path / "cal.json")
    out = tmp_path / "r.zarr"
    assert cli(["capture", "--frames", "2", "--size", "24x32", "--clock", "virtual", "--calibration", str(cal),
                "-o", str(out)]) == 0
    stored = open_recording(out).attrs["calibration"]
    assert stored["phase_slots"] == 3 and "cal.json" in stored["source"]
    assert stored["homography"][0][2] == 1.0
    assert stored["trigger_delay_us"] == 3166.0
    assert open_recording(out).attrs["rig"]["trigger_delay_set_by"] == "camera"


def test_capture_refuses_a_calibration_for_another_resolution(tmp_path, capsys):
    cal = _calibration_file(tmp_path / "cal.json", camera_size=(24, 32))
    with pytest.raises(CliError, match=r"was made for a camera resolution of 24x32, this rig's is 48x64"):
        cli(["capture", "--frames", "2", "--size", "48x64", "--clock", "virtual", "--calibration", str(cal),
             "-o", str(tmp_path / "r.zarr")])
    assert not (tmp_path / "r.zarr").exists()


def test_capture_takes_a_design_file(tmp_path, capsys):
    import json

    from flexvox_core.multiplex import multiplexed_code

    code = tmp_path / "code.json"
    code.write_text(json.dumps(multiplexed_code((1, 3)).as_dict()))
    out = tmp_path / "r.zarr"
    assert cli(["capture", "--frames", "2", "--size", "16x24", "--clock", "virtual", "--code", str(code),
                "-o", str(out)]) == 0
    rec = open_recording(out)
    assert rec.K == 3 and rec.attrs["multiplexed"] and rec.attrs["placement_order"] is not None
    assert "S-matrix multiplexed from code.json" in capsys.readouterr().out
    bad = tmp_path / "bad.json"
    bad.write_text('{"code": [[[1, 1], [0, 0]]]}')
    with pytest.raises(CliError, match=r"bad.json: not an identity code .* and not marked multiplexed"):
        cli(["capture", "--frames", "1", "--clock", "virtual", "--code", str(bad), "-o", str(tmp_path / "b.zarr")])
    with pytest.raises(CliError, match=r"--multiplexed goes with --tile"):
        cli(["capture", "--frames", "1", "--clock", "virtual", "--code", str(code), "--multiplexed",
             "-o", str(tmp_path / "c.zarr")])


def test_capture_refuses_a_rate_of_zero_in_its_own_words(tmp_path):
    with pytest.raises(CliError, match=r"--rate must be a camera rate above 0 and at most 10000 Hz; got 0"):
        cli(["capture", "--frames", "1", "--rate", "0", "--clock", "virtual", "-o", str(tmp_path / "r.zarr")])


def test_a_stopped_ground_truth_capture_is_given_the_time_its_truth_takes():
    # Ctrl-C after 3,675 frames with --ground-truth: 30 s were not enough to write its 58,800 truth sub-frames
    # (about 1,330 a second here), and the recording was left damaged. The wait now grows with the truth.
    from flexvox_app.cli.capture import GROUND_TRUTH_RATE, stop_timeout

    assert stop_timeout(3675, 16, ground_truth=False) == 30.0
    assert stop_timeout(3675, 16, ground_truth=True) == 30.0 + 3675 * 16 / GROUND_TRUTH_RATE
    assert stop_timeout(3675, 16, ground_truth=True) > 3675 * 16 / 1330 * 2  # twice the measured rate's need


def test_ctrl_c_and_sigterm_during_a_capture_are_noted_not_raised():
    """A KeyboardInterrupt raised inside a lock's critical section left the lock held and hung the capture's stop
    (the second-capture refusal test, under load): during a capture the signals are only counted."""
    import os
    import signal
    import threading

    from flexvox_app.cli.capture import StopRequests

    before = {sig: signal.getsignal(sig) for sig in StopRequests.SIGNALS}
    pause = threading.Event()
    with StopRequests() as requests:
        os.kill(os.getpid(), signal.SIGINT)
        pause.wait(0.05)
        os.kill(os.getpid(), signal.SIGTERM)
        pause.wait(0.05)
        assert requests.count == 2
    assert {sig: signal.getsignal(sig) for sig in StopRequests.SIGNALS} == before
