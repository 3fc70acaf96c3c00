import json
import subprocess
import sys

import numpy as np
import pytest

from flexvox_app.cli.main import main
from flexvox_core.codes import code_from_order, sequential_order

from ..flexvox_core.independent import supports_all_slow


def run_cli(capsys, *argv):
    with pytest.raises(SystemExit) as exc:
        raise SystemExit(main(list(argv)))
    out = capsys.readouterr()
    return exc.value.code, out.out, out.err


@pytest.mark.parametrize("tile", ["2x2", "2x3", "2x4", "3x3", "4x4", "4x8", "8x8"])
def test_design_json_codes_support_every_division(capsys, tile):
    code, out, err = run_cli(capsys, "design", "--tile", tile, "--json")
    assert code == 0, err
    payload = json.loads(out)
    m, n = map(int, tile.split("x"))
    assert payload["tile"] == [m, n] and payload["K"] == m * n
    assert supports_all_slow(payload["order"])  # independent check
    assert np.array_equal(np.asarray(payload["code"], dtype=bool), code_from_order(payload["order"]))
    assert {tuple(r["block"]) for r in payload["resolutions"]} >= {(1, 1, m * n), (m, n, 1)}
    assert all(r["TR"] * r["SR"] == pytest.approx(1) for r in payload["resolutions"])


def test_design_text_output_shows_grid_and_resolutions(capsys):
    code, out, _ = run_cli(capsys, "design", "--tile", "2x2")
    assert code == 0
    assert "firing order" in out and "0 2" in out and "3 1" in out
    assert "2x2x1" in out and "1/4" in out


@pytest.mark.parametrize(
    "tile, message",
    [
        ("0x4", "`tile` side m must be between 1 and 8; got 0"),
        ("4", "tile must be written MxN"),
        ("ax4", "tile must be written MxN"),
        ("-2x2", "`tile` side m must be between 1 and 8; got -2"),
        ("9x8", "`tile` side m must be between 1 and 8; got 9"),
    ],
)
def test_bad_tiles_exit_2_with_one_line(capsys, tile, message):
    with pytest.raises(SystemExit) as exc:
        main(["design", "--tile", tile])
    err = capsys.readouterr().err
    assert exc.value.code == 2
    assert len(err.strip().splitlines()) == 1
    assert message in err and "Traceback" not in err


def test_console_script_reports_bad_tile_without_traceback():
    out = subprocess.run(
        [sys.executable, "-m", "flexvox_app.cli.main", "design", "--tile", "ax4"], capture_output=True, text=True
    )
    assert out.returncode == 2
    assert out.stderr.strip().splitlines() == [
        "flexvox design: error: argument --tile: tile must be written MxN with two whole numbers, e.g. 4x4; got 'ax4'"
    ]


def test_write_then_verify_round_trip(capsys, tmp_path):
    path = tmp_path / "code.json"
    code, _, _ = run_cli(capsys, "design", "--tile", "4x4", "-o", str(path))
    assert code == 0 and path.exists()
    code, out, _ = run_cli(capsys, "design", "--verify", str(path))
    assert code == 0 and "supports all 9 divisions" in out


def test_verify_sequential_code_fails_with_exit_1(capsys, tmp_path):
    path = tmp_path / "seq.json"
    path.write_text(json.dumps({"order": sequential_order((4, 4)).tolist()}))
    code, out, _ = run_cli(capsys, "design", "--verify", str(path), "--json")
    assert code == 1
    payload = json.loads(out)
    assert [2, 2, 4] in [r["block"] for r in payload["unsupported"]]


@pytest.mark.parametrize(
    "content, message",
    [
        ("{not json", "not valid JSON"),
        ('{"tile": [2, 2]}', "a code file needs an `order`"),
        ('{"order": [[0, 0], [1, 2]]}', "each slot 0..3 exactly once"),
        ("[" * 100000 + "]" * 100000, "its JSON is nested too deeply to read"),  # was a RecursionError traceback
        ('{"order": ' + "9" * 5000 + "}", "not valid JSON (Exceeds the limit"),
    ],
)
def test_verify_rejects_bad_files(capsys, tmp_path, content, message):
    path = tmp_path / "bad.json"
    path.write_text(content)
    code, _, err = run_cli(capsys, "design", "--verify", str(path))
    assert code == 2 and message in err and len(err.strip().splitlines()) == 1


def test_verify_says_what_capture_says_of_a_code_file(capsys, tmp_path):
    # A multiplexed file from design is verified through its demultiplexed slots and passes, as capture uses it;
    # an order and a code that disagree, or a tile that is not the code's, fail, as capture refuses them.
    mux = tmp_path / "m13.json"
    assert run_cli(capsys, "design", "--tile", "1x3", "--multiplexed", "-o", str(mux))[0] == 0
    code, out, _ = run_cli(capsys, "design", "--verify", str(mux))
    assert code == 0 and "an S-matrix multiplexed code" in out and "supports all 2 divisions" in out
    order = [[0, 2], [3, 1]]
    other = code_from_order([[1, 2], [3, 0]]).astype(int).tolist()
    for name, payload, why in [
        ("disagree.json", {"order": order, "code": other}, "its `order` and its `code` disagree"),
        ("tile.json", {"order": order, "tile": [4, 4]}, "its `tile` [4, 4] disagrees with its code's 2x2"),
        ("order.json", {"order": [[0, 2], [2, 1]], "code": code_from_order(order).astype(int).tolist()},
         "its `order`: `order` of a 2x2 tile must hold each slot 0..3 exactly once"),
    ]:
        path = tmp_path / name
        path.write_text(json.dumps(payload))
        code, out, _ = run_cli(capsys, "design", "--verify", str(path))
        assert code == 1 and f"capture cannot use it: {path}: {why}" in out
        code, out, _ = run_cli(capsys, "design", "--verify", str(path), "--json")
        result = json.loads(out)
        assert code == 1 and result["capture_ready"] is False and why in result["problem"]


def test_a_file_too_large_for_a_code_is_refused_before_it_is_parsed(capsys, tmp_path, monkeypatch):
    import flexvox_core.json_file

    monkeypatch.setattr(flexvox_core.json_file, "MAX_BYTES", 100)  # /dev/zero would never end
    path = tmp_path / "big.json"
    path.write_text(json.dumps({"order": [[0, 1], [2, 3]], "pad": "x" * 200}))
    code, _, err = run_cli(capsys, "design", "--verify", str(path))
    assert code == 2 and f"{path}: more than 0 MiB; not a code or calibration file" in err


def test_verify_names_a_folder_or_a_binary_file_for_what_it_is(capsys, tmp_path):
    # they had said "cannot read: [Errno 21] Is a directory" and "cannot read: 'utf-8' codec can't decode byte 0x93"
    import numpy as np

    folder, array = tmp_path / "rec.zarr", tmp_path / "v.npy"
    folder.mkdir()
    np.save(array, np.zeros(3))
    for path, message in ((folder, "rec.zarr is a folder, not a code or calibration file (a JSON file)"),
                          (array, "v.npy: not a code or calibration file: a binary file, where those are JSON text")):
        code, _, err = run_cli(capsys, "design", "--verify", str(path))
        assert code == 2 and message in err and len(err.strip().splitlines()) == 1, err


def test_verify_missing_file(capsys, tmp_path):
    code, _, err = run_cli(capsys, "design", "--verify", str(tmp_path / "nope.json"))
    assert code == 2 and "no such file" in err


def test_multiplexed(capsys):
    code, out, _ = run_cli(capsys, "design", "--tile", "3x5", "--multiplexed", "--json")
    assert code == 0
    payload = json.loads(out)
    assert payload["multiplexed"] and payload["snr_gain_read_noise"] == pytest.approx(2.0656, abs=1e-3)
    assert np.asarray(payload["code"]).sum(axis=2).tolist() == [[8] * 5] * 3
    code, _, err = run_cli(capsys, "design", "--tile", "4x4", "--multiplexed")
    assert code == 2 and "no S-matrix exists for K = 16" in err


def test_divisions_option(capsys):
    code, out, _ = run_cli(capsys, "design", "--tile", "4x4", "--divisions", "2x2x4,4x4x1", "--json")
    assert code == 0
    assert json.loads(out)["divisions_requested"] == ["1x1x16", "2x2x4", "4x4x1"]
    code, _, err = run_cli(capsys, "design", "--tile", "4x4", "--divisions", "3x3x3")
    assert code == 2 and "division 3x3x3 does not divide a 4x4 tile" in err


def test_separation_option_validation(capsys):
    code, _, err = run_cli(capsys, "design", "--tile", "4x4", "--separation", "lots")
    assert code == 2 and "--separation must be 'auto' or a whole number" in err
    code, out, err = run_cli(capsys, "design", "--tile", "4x4", "--separation", "8", "--json")
    assert code == 1 and json.loads(out)["status"] == 2  # possible in principle, infeasible here
    code, _, err = run_cli(capsys, "design", "--tile", "4x4", "--separation", "8")
    assert code == 1 and "no 4x4 code has a 4-neighbour gap >= 8" in err
    assert "ask for a smaller neighbour gap, or fewer divisions (--separation N for the gap, --divisions" in err
    # beyond any code (two of 16 slots are at most 8 apart): refused before the solver, which tried to build a
    # constraint matrix for it (10^21: a traceback; 2*10^7 on 2x2: more than 2 GB)
    code, _, err = run_cli(capsys, "design", "--tile", "4x4", "--separation", "1000000000000000000000")
    assert code == 2 and "`separation` 1000000000000000000000 is more than any 4x4 code can have" in err
    assert "ask for at most 8" in err
    code, _, err = run_cli(capsys, "design", "--tile", "2x2", "--divisions", ",")
    assert code == 2 and "--divisions must name at least one division AxBxC" in err


def test_no_command_prints_help_and_exits_2(capsys):
    code, out, _ = run_cli(capsys)
    assert code == 2 and "design" in out


def test_a_tile_with_no_code_at_any_gap_points_to_the_divisions_only(capsys, monkeypatch):
    from flexvox_core import design

    monkeypatch.setattr(design, "_solve", lambda m, n, A, gap, limit: (design.STATUS_INFEASIBLE, None))
    code, _, err = run_cli(capsys, "design", "--tile", "4x4")
    assert code == 1 and "infeasible; ask for fewer divisions" in err
    assert "--divisions AxBxC,... for the divisions" in err and "--separation" not in err
