"""``flexvox calibrate`` on the simulated rig, through a parser built with ``register()``."""

import json

import numpy as np
import pytest

from flexvox_app.cli import calibrate
from flexvox_app.cli.errors import CliError, OneLineParser
from flexvox_calibration.files import load_calibration


def parse(*argv):
    parser = OneLineParser(prog="flexvox")
    sub = parser.add_subparsers(dest="command", parser_class=OneLineParser)
    calibrate.register(sub)
    return parser.parse_args(["calibrate", *argv])


def run(capsys, *argv):
    args = parse(*argv)
    code = args.func(args)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_json_meets_the_targets_against_the_hidden_truth(capsys, tmp_path):
    cal = tmp_path / "cal.json"
    code, out, _ = run(capsys, "--rig", "mock", "--seed", "7", "--json", "-o", str(cal))

    def refuse(constant):  # strict JSON (JSON.parse, jq): no NaN, no Infinity
        raise AssertionError(f"not strict JSON: {constant}")

    d = json.loads(out, parse_constant=refuse)
    json.loads(cal.read_text(), parse_constant=refuse)
    # what no step measured, or an infinite slip time (no drift), is null in both, and the file loads back
    assert d["steps"]["sync"]["residual_leakage"] is None and d["steps"]["frames"]["seconds_per_slot_slip"] is None
    from flexvox_calibration.capture_setup import load_for_capture
    from flexvox_calibration.session import RigIdentity

    rig = load_calibration(cal)["rig"]
    identity = RigIdentity(rig["name"], rig["camera"], rig["projector"], tuple(rig["camera_size"]),
                           tuple(rig["projector_size"]), rig["pixel_layout"])
    assert load_for_capture(cal, identity).phase_slots in range(16)
    assert code == 0 and d["success"] is True
    for key in ("homography_error_px", "rms_px", "coverage", "shutter_slot_accuracy", "phase_found", "phase_true"):
        assert key in d
    assert d["homography_error_px"] <= 0.25 and d["rms_px"] < 0.3 and d["coverage"] > 0.99
    assert d["shutter_slot_accuracy"] >= 0.999 and d["phase_found"] == d["phase_true"]
    assert d["steps"]["colocation"]["parallax"]["status"] == "ok"
    assert d["steps"]["frames"]["status"] == "ok"
    saved = load_calibration(cal)
    assert saved["sync"]["phase_slots"] == d["phase_found"] and saved["H"].shape == (3, 3)
    assert np.isfinite(saved["H"]).all()


def test_text_output_and_a_rig_that_is_not_co_located(capsys, tmp_path):
    code, out, err = run(capsys, "--seed", "1", "--mock-baseline", "0.02,0,0", "-o", str(tmp_path / "c.json"))
    assert code == 1
    assert "parallax:    NOT co-located" in out and "image moves left" in out
    assert "the colocation step failed" in err
    assert not (tmp_path / "c.json").exists()  # a bad calibration is never written


@pytest.mark.parametrize("argv, message", [
    (["--seed", "-3"], "--seed must be a whole number >= 0; got '-3'"),
    (["--mock-baseline", "1,2"], "--mock-baseline must be three numbers BX,BY,BZ"),
    (["--tile", "0x4"], "`tile` side m must be between 1 and 8; got 0"),
    (["--tile", "1x1"], "a 1x1 tile (K = 1) has nothing to shutter: its one slot is open all the time, so there is "
                        "no shutter to verify and no phase to measure"),
])
def test_bad_options_exit_2_with_one_line(capsys, argv, message):
    with pytest.raises(SystemExit) as exc:
        parse(*argv)
    err = capsys.readouterr().err
    assert exc.value.code == 2 and len(err.strip().splitlines()) == 1 and message in err


def test_a_missing_rig_profile_is_a_cli_error(tmp_path):
    args = parse("--rig", str(tmp_path / "nope.toml"))
    with pytest.raises(CliError, match=r"no rig profile .*nope.toml: a rig is \"mock\" \(the simulated rig\) or "
                                       r"the path"):
        args.func(args)


def test_an_output_folder_that_does_not_exist_is_refused_before_calibrating(tmp_path, capsys):
    from flexvox_app.cli.main import main

    assert main(["calibrate", "--rig", "mock", "-o", str(tmp_path / "nope" / "cal.json")]) == 2
    err = capsys.readouterr().err
    assert "the folder" in err and "does not exist (checked before calibrating" in err
