"""The Qt-free models and services of flexvox_app.gui: continuum, expected quality, jobs, capture plan, live stats."""

import json
import math
import re
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from flexvox_app.capture.plan import CapturePlan
from flexvox_app.gui.models.continuum import (
    continuum_division,
    continuum_tensor,
    describe,
    ordered_divisions,
    tensor_position,
)
from flexvox_app.gui.models.expected_quality import BENCH_CSV, TABLE_PATH, build_table, expected, load_table
from flexvox_app.gui.models.jobs import Cancelled, CancelToken, chunk_frames_for, preview_window, run_reconstruction
from flexvox_app.gui.models.live_stats import LiveStats, histogram, saturation_level
from flexvox_core.design import design_code
from flexvox_core.methods import Method
from flexvox_core.reconstruct.rebin import supported_divisions
from rig_drivers.interfaces import Frame

# ---------------------------------------------------------------- continuum


def test_continuum_ends_are_the_seeds_tensors_and_the_middle_is_isotropic():
    assert continuum_tensor(0) == (0.05, 0.05, 1.0)
    assert continuum_tensor(1) == (1.0, 1.0, 0.05)
    assert continuum_tensor(0.5) == (1.0, 1.0, 1.0)
    assert continuum_tensor(0.18) == pytest.approx((0.15, 0.15, 1.0), abs=0.01)  # the default tensor


def test_continuum_moves_monotonically_from_space_to_time_and_inverts():
    ps = np.linspace(0, 1, 41)
    ratios = [continuum_tensor(p)[2] / continuum_tensor(p)[0] for p in ps]
    assert all(a > b for a, b in zip(ratios, ratios[1:], strict=False))
    assert all(max(continuum_tensor(p)) == 1.0 for p in ps)
    for p in ps:
        assert tensor_position(continuum_tensor(p)) == pytest.approx(p, abs=0.01)


def test_continuum_walks_the_divisions_by_tr():
    divs = supported_divisions(design_code((4, 4)).code)
    assert continuum_division(0, divs).label == "1x1x16"
    assert continuum_division(1, divs).label == "4x4x1"
    trs = [continuum_division(p, divs).tr for p in np.linspace(0, 1, 21)]
    assert trs == sorted(trs)
    assert [d.tr for d in ordered_divisions(divs)] == sorted(d.tr for d in divs)


@pytest.mark.parametrize("p", [-0.1, 1.5, float("nan"), True, "0.5"])
def test_continuum_refuses_positions_outside_the_slider(p):
    with pytest.raises(ValueError, match=r"`p` must be a number in \[0, 1\]"):
        continuum_tensor(p)


def test_describe_says_which_way_it_leans():
    assert describe(0).startswith("high SR") and describe(1).startswith("high TR")
    assert describe(0.5).startswith("balanced")


# ---------------------------------------------------------------- expected quality


def test_shipped_table_is_generated_from_the_bench_csv():
    if not BENCH_CSV.exists():
        pytest.skip("docs/bench/results.csv is not in this checkout")
    assert json.loads(TABLE_PATH.read_text()) == json.loads(json.dumps(build_table(BENCH_CSV)))


def _results_csv(path, rows):
    """A results.csv as flexvox bench writes it: each row's method options as JSON text."""
    import csv

    with open(path, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(["case", "K", "family", "method", "psnr", "mse", "ssim", "seconds", "mvoxels_per_s",
                         "device", "options"])
        for case, method, *figures in rows:
            writer.writerow([case, 8, method.name, method.label(), *figures, "cpu", json.dumps(method.as_dict())])
    return path


def test_build_table_takes_psnr_of_the_mean_mse_and_separates_sci(tmp_path):
    gap = Method("gap-tv", iterations=40)
    csv = _results_csv(tmp_path / "r.csv", [
        ("a K=8", gap, 20, 0.01, 0.5, 1.0, 2.0),
        ("b K=8", gap, 30, 0.001, 0.7, 3.0, 1.0),
        ("runner (SCI) K=8", gap, 29.4, 0.001, 0.9, 0.5, 4.0),
    ])
    (e,) = build_table(csv)["entries"]
    assert e["psnr"] == pytest.approx(10 * math.log10(1 / 0.0055), abs=0.01)
    assert (e["ssim"], e["seconds"], e["scenes"], e["sci_psnr"]) == (0.6, 2.0, 2, 29.4)
    assert e["options"] == {"name": "gap-tv", "iterations": 40, "tv_weight": 0.3, "tv_iterations": 4}


def test_rows_are_grouped_and_matched_by_their_options_not_their_labels(tmp_path):
    # Two settings one label cannot tell apart (the label names the iterations only): two entries, and each
    # method finds its own.
    plain, heavy = Method("gap-tv"), Method("gap-tv", tv_weight=1.0)
    assert plain.label() == heavy.label()
    table = build_table(_results_csv(tmp_path / "r.csv", [
        ("a K=8", plain, 20, 0.01, 0.5, 1.0, 2.0),
        ("a K=8", heavy, 25, 0.003, 0.6, 1.0, 2.0),
    ]))
    assert [e["options"]["tv_weight"] for e in table["entries"]] == [0.3, 1.0]
    code = design_code((2, 4)).code
    got = expected(table, heavy, code, voxels=10)
    assert not got.approximate and got.psnr == pytest.approx(25.23, abs=0.01)
    assert expected(table, plain, code, voxels=10).psnr == pytest.approx(20.0)
    other = expected(table, Method("gap-tv", tv_weight=2.0), code, voxels=10)
    assert other.approximate and other.nearest == "gap-tv 40 it"


def test_a_results_file_without_options_is_read_by_the_labels_of_the_methods_the_bench_runs(tmp_path):
    csv = tmp_path / "r.csv"
    csv.write_text(
        "case,K,family,method,psnr,mse,ssim,seconds,mvoxels_per_s\n"
        "a K=8,8,gap-tv,gap-tv 40 it,20,0.01,0.5,1.0,2.0\n"
        "a K=16,16,motion-aware,motion-aware dis n=5 gather-only,30,0.001,0.7,3.0,1.0\n"
        "a K=16,16,rebin,rebin 2x2x4 interp,30,0.001,0.7,3.0,1.0\n"
    )
    gap, ma, rebin = build_table(csv)["entries"]
    assert gap["options"] == Method("gap-tv", iterations=40).as_dict()
    assert ma["options"] == Method("motion-aware", local_choice=False).as_dict()
    assert rebin["options"] == {"name": "rebin", "block": "2x2x4", "interpolate": True}
    csv.write_text(csv.read_text() + "a K=8,8,pnp,pnp-ffdnet,20,0.01,0.5,1.0,2.0\n")
    with pytest.raises(ValueError, match=r"r.csv: row 'pnp-ffdnet' at K=8 has no `options` column and flexvox bench "
                                         r"runs no method of that label"):
        build_table(csv)


def test_expected_matches_exact_rows_and_interpolates_between_times():
    table = load_table()
    code = design_code((4, 4)).code
    vox = 16 * 6 * 96 * 128  # the bench's own size: time = the bench's seconds
    exact = expected(table, Method("diffusion", tensor=(0.15, 0.15, 1.0), time=1.0), code, voxels=vox)
    row = next(e for e in table["entries"] if e["K"] == 16 and e["label"] == "diffusion nc (0.15,0.15,1) n=1")
    assert not exact.approximate and exact.psnr == row["psnr"]
    lo = expected(table, Method("diffusion", tensor=(0.15, 0.15, 1.0), time=1.0), code, voxels=vox)
    hi = expected(table, Method("diffusion", tensor=(0.15, 0.15, 1.0), time=1.5), code, voxels=vox)
    mid = expected(table, Method("diffusion", tensor=(0.15, 0.15, 1.0), time=1.25), code, voxels=vox)
    assert mid.approximate and "interpolated" in mid.basis
    assert min(lo.psnr, hi.psnr) <= mid.psnr <= max(lo.psnr, hi.psnr)
    ma = expected(table, Method("motion-aware", time=4.0), code, voxels=vox)
    assert not ma.approximate and "interpolated" not in ma.basis  # benched at n = 4
    # The bench never ran this slow reach: the figures are the nearest benched setting's, and say so.
    reach = expected(table, Method("motion-aware", time=4.0, slow_reach=2.0), code, voxels=vox)
    assert reach.approximate and reach.nearest == "motion-aware dis n=4"
    gap = expected(table, Method("gap-tv"), code, voxels=vox)
    assert ma.seconds > 10 * exact.seconds and gap.psnr < ma.psnr  # what the bench found
    twice = expected(table, Method("gap-tv"), code, voxels=2 * vox)
    assert twice.seconds == pytest.approx(2 * gap.seconds)
    other_k = expected(table, Method("rebin"), design_code((3, 5)).code, voxels=vox)
    assert other_k.approximate and other_k.basis.startswith("bench K=16")


def test_a_tensor_the_bench_never_measured_is_not_given_another_tensor_s_quality_as_its_own():
    """Point 7: diffusion at (1, 1, 0.21) quoted the quality of (1, 1, 0.05) as its own."""
    table = load_table()
    code = design_code((4, 4)).code
    e = expected(table, Method("diffusion", tensor=(1.0, 1.0, 0.21), time=1.5), code, voxels=16 * 6 * 96 * 128)
    assert e.nearest == "diffusion nc (1,1,0.05) n=1.5"
    assert e.quality_text().startswith("quality not benched at these settings (the nearest benched, diffusion nc "
                                       "(1,1,0.05) n=1.5: ")
    benched = expected(table, Method("diffusion", tensor=(1.0, 1.0, 0.05), time=1.5), code, voxels=16 * 6 * 96 * 128)
    assert benched.nearest == "" and benched.quality_text().endswith("on the built-in scenes")


def test_missing_table_gives_no_expectation(tmp_path, caplog):
    assert load_table(tmp_path / "none.json") is None
    assert "no expected-quality table" in caplog.text
    assert expected(None, Method(), design_code((2, 2)).code, voxels=10) is None


# ---------------------------------------------------------------- jobs


def _capture():
    from flexvox_core.forward import capture
    from flexvox_core.simulate.scenes import render_scene

    code = design_code((2, 4)).code
    truth = render_scene("balls", 6 * 8, 24, 32, seed=0)
    return capture(truth, code), code, truth


def test_run_reconstruction_cancels_between_chunks():
    frames, code, _ = _capture()
    token = CancelToken()
    seen = []

    def progress(done, total):
        seen.append(done)
        token.cancel()  # the user presses Cancel after the first chunk

    with pytest.raises(Cancelled, match="cancelled"):
        run_reconstruction(frames, code, Method("gap-tv", iterations=5), cancel=token, progress=progress,
                           chunk_frames=1)
    assert seen == [1]


def test_run_reconstruction_does_not_depend_on_chunks_and_scores_against_truth():
    frames, code, truth = _capture()
    a = run_reconstruction(frames, code, Method("motion-aware"), chunk_frames=2, truth=truth)
    b = run_reconstruction(frames, code, Method("diffusion"), chunk_frames=2, truth=truth)
    c = run_reconstruction(frames, code, Method("diffusion"), chunk_frames=6, truth=truth)
    np.testing.assert_allclose(b.video, c.video, atol=1e-6)
    assert a.flow.shape == (48, 24, 32, 2) and a.tr.shape == (48, 24, 32)
    assert 1 <= a.tr.min() and a.tr.max() <= 8
    assert b.flow is None and b.psnr > 18 and "dB" in b.label()


def test_motion_aware_in_chunks_matches_one_run_with_slow_voxels():
    # The slow voxels' range weight follows the samples' range: every chunk must use the whole capture's.
    from flexvox_core.forward import capture
    from flexvox_core.motion.pipeline import run_clip
    from flexvox_core.simulate.scenes import render_scene

    code = design_code((2, 4)).code
    frames = capture(render_scene("pan", 10 * 8, 24, 32, seed=0), code)
    method = Method("motion-aware", time=2.0, slow_reach=2.0)
    chunked = run_reconstruction(frames, code, method, chunk_frames=3)
    whole = run_clip(frames, code, method.options)
    np.testing.assert_array_equal(chunked.video, np.clip(whole.video, 0, 1))


def test_chunk_sizes_and_preview_windows():
    assert chunk_frames_for(Method("gap-tv"), 100, 8) == 1
    assert chunk_frames_for(Method("motion-aware", refine_time=0.0), 10, 8) == 8
    assert chunk_frames_for(Method("diffusion"), 200, 8) == 20
    assert preview_window(10, 0) == (0, 3) and preview_window(10, 9) == (7, 10) and preview_window(10, 5) == (4, 7)
    assert preview_window(2, 1) == (0, 2)
    # An end in a gap of dropped frames moves to the captured frame beyond it: bridged from both sides.
    gap = np.zeros(10, bool)
    gap[3:7] = True
    assert preview_window(10, 5, missing=gap) == (2, 8)
    assert preview_window(10, 1, missing=gap) == (0, 3) and preview_window(10, 8, missing=gap) == (7, 10)
    with pytest.raises(ValueError, match="`n_frames` must be >= 1"):
        preview_window(0, 0)


# ---------------------------------------------------------------- capture plan and live stats


def test_capture_plan_timing_of_the_design_example():
    t = CapturePlan((4, 4), camera_hz=15.0).timing()
    assert (t.period_us, t.projector_exposure_us, t.sequence_us) == (4166, 4166, 66656)
    assert t.ok
    drift = next(n for n in t.notes if "drifts one slot every" in n)
    assert "every 26 s" in drift  # docs/architecture.md: 16 x 4166 µs = 66.656 ms at 15 Hz


@pytest.mark.parametrize("plan, message", [
    (CapturePlan((4, 4), camera_hz=15.0, projector_exposure_us=4000), r"at most period - 230 µs = 3936 µs"),
    (CapturePlan((4, 4), camera_hz=1000.0), r"no shorter than 235 µs \(at most 266 Hz at this K\)"),
    (CapturePlan((4, 4), camera_hz=15.0, camera_exposure_us=40_000), r"misses the last 7 of 16 slots"),
    (CapturePlan((4, 4), camera_hz=15.0, camera_exposure_us=70_000), r"longer than the frame period"),
])
def test_capture_plan_timing_errors_name_the_rule(plan, message):
    t = plan.timing()
    assert not t.ok
    assert any(__import__("re").search(message, e) for e in t.errors), t.errors


@pytest.mark.parametrize("given, match", [
    ({"tile": (1, 3), "multiplexed": "no"}, r"`multiplexed` must be True or False; got 'no'"),  # had been multiplexed
    ({"tile": (1, 3), "multiplexed": 0}, r"`multiplexed` must be True or False; got 0"),
    ({"tile": (4, 4.7)}, r"`tile` must be two whole numbers \(m, n\) >= 1; got \(4, 4.7\)"),  # had been (4, 4)
    ({"tile": ("4", "4")}, r"`tile` must be two whole numbers"),
    ({"tile": (True, 4)}, r"`tile` must be two whole numbers"),
    ({"tile": "4x4.5"}, r"tile must be written MxN with two whole numbers, e.g. 4x4; got '4x4.5'"),
    # timed as "misses the last 17 of 16 slots"; NaN refused only when the capture started; 1.5 µs cut to 1
    ({"camera_exposure_us": -1}, r"`camera_exposure_us` must be a finite number of µs above 0, or None .*got -1"),
    ({"camera_exposure_us": float("nan")}, r"`camera_exposure_us` must be a finite number .*got nan"),
    ({"projector_exposure_us": 1.5},
     r"`projector_exposure_us` must be a whole number of µs above 0, or None .*got 1.5"),
    ({"projector_exposure_us": 0}, r"`projector_exposure_us` must be a whole number .*got 0"),
])
def test_capture_plan_refuses_what_it_would_have_read_as_something_else(given, match):
    with pytest.raises(ValueError, match=match):
        CapturePlan(**given)
    assert CapturePlan((4, 4.0), multiplexed=np.bool_(False)) == CapturePlan((4, 4)) == CapturePlan("4x4")


def test_capture_plan_codes_and_resolutions():
    ident = CapturePlan((4, 4))
    assert [(d.tr, str(d.sr)) for d in ident.resolutions()][0] == (1, "1")
    assert len(ident.resolutions()) == 9
    mux = CapturePlan((3, 5), multiplexed=True)
    assert "S-matrix" in mux.code_summary() and mux.code.shape == (3, 5, 15)
    with pytest.raises(ValueError, match=r"no S-matrix exists for K = 16"):
        CapturePlan((4, 4), multiplexed=True).code  # noqa: B018 - the property raises
    pats = ident.patterns((20, 30), (20, 30)).patterns  # uncalibrated: the identity map
    assert pats.shape == (16, 20, 30) and ident.period_us == 4166
    assert np.array_equal(pats.sum(axis=0), np.ones((20, 30)))  # identity: one slot per pixel


def test_live_stats_count_drops_fps_and_saturation():
    s = LiveStats(window=5)
    img = np.zeros((4, 5), np.uint16)
    img[0, :2] = 65535
    for fid, t in ((0, 0.0), (1, 0.1), (4, 0.4), (5, 0.5)):
        s.update(Frame(img, frame_id=fid, timestamp_s=t))
    assert (s.received, s.dropped) == (4, 2)
    assert s.fps == pytest.approx(6.0)  # 3 intervals in 0.5 s: frames received, drops excluded
    assert s.saturated_fraction == pytest.approx(0.1)
    assert "2 dropped" in s.text() and "6.0 fps" in s.text()
    assert saturation_level(np.zeros(2, np.float32)) == 1.0
    counts, edges = histogram(img, bins=4)
    assert counts.sum() == 20 and edges[-1] == 65535


# ---------------------------------------------------------------- Qt stays out of the models

def _qt_free_modules() -> list[str]:
    """Every module of flexvox_app.gui.models (found, not listed by hand), and the flexvox_app.gui package file."""
    import pkgutil

    import flexvox_app.gui.models

    found = [m.name for m in pkgutil.walk_packages(flexvox_app.gui.models.__path__, "flexvox_app.gui.models.")]
    assert len(found) >= 10, found  # the discovery itself must work
    return ["flexvox_app.gui", "flexvox_app.gui.models", *found]


QT_FREE = _qt_free_modules()


def test_models_and_services_import_with_qt_blocked():
    script = textwrap.dedent(f"""
        import importlib, importlib.abc, sys

        class BlockQt(importlib.abc.MetaPathFinder):
            BLOCKED = ("PySide6", "PyQt5", "PyQt6", "shiboken6", "pyqtgraph", "qtpy")

            def find_spec(self, name, path=None, target=None):
                if name.split(".")[0] in self.BLOCKED:
                    raise ImportError("Qt is blocked: " + name)
                return None

        sys.meta_path.insert(0, BlockQt())
        for name in {QT_FREE!r}:
            importlib.import_module(name)
        import flexvox_app.cli.app
        print("ok")
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"



def test_processed_voxels_count_the_overlap_each_chunk_recomputes():
    from flexvox_app.gui.models.machine_speed import processed_voxels
    from flexvox_core.methods import Method

    m = Method("motion-aware", refine_time=0.0)  # overlap 3 frames each side
    assert processed_voxels(m, 8, 16, 10, 20, chunk_frames=8) == 8 * 16 * 200  # one chunk: nothing recomputed
    # 16 frames in chunks of 8: [0, 11) and [5, 16): 22 frames processed
    assert processed_voxels(m, 16, 16, 10, 20, chunk_frames=8) == 22 * 16 * 200


def test_the_speed_model_scales_with_the_recording_and_the_options_and_survives_the_settings():
    from flexvox_app.gui.models.expected_quality import load_table
    from flexvox_app.gui.models.machine_speed import (
        SpeedModel,
        _version,
        estimate_seconds,
        is_current,
        processed_voxels,
    )
    from flexvox_core.design import design_code
    from flexvox_core.methods import Method

    model = SpeedModel("diffusion", 16, c=2e-8, p=1.0, points=((1, 2, 3),), version=_version())
    again = SpeedModel.from_json(model.to_json())
    assert again == model and is_current(again)
    assert not is_current(SpeedModel("diffusion", 16, c=1, p=1, points=(), version="0.0.0-old"))
    assert SpeedModel.from_json("") is None and SpeedModel.from_json('{"method": "x"}') is None
    code, table = design_code((4, 4)).code, load_table()
    base = Method("diffusion")
    t8 = estimate_seconds(model, table, base, code, n_frames=8, H=120, W=160)
    assert t8 == pytest.approx(2e-8 * processed_voxels(base, 8, 16, 120, 160)) and t8 >= 2e-8 * 8 * 16 * 120 * 160
    assert estimate_seconds(model, table, base, code, n_frames=16, H=120, W=160) > 1.9 * t8
    # Other options scale the calibrated time by the bench's relative cost of those options (whatever the
    # shipped table measured: on small captures nc's time is mostly overhead, so the ratio is near 1).
    from flexvox_app.gui.models.expected_quality import expected

    slow = Method("diffusion", time=8.0)
    voxels = processed_voxels(slow, 8, 16, 120, 160)
    ratio = expected(table, slow, code, voxels=voxels).seconds / expected(table, base, code, voxels=voxels).seconds
    assert ratio != 1
    assert estimate_seconds(model, table, slow, code, n_frames=8, H=120, W=160) == pytest.approx(ratio * t8)


def test_calibrate_times_a_method_on_two_clip_sizes():
    from flexvox_app.gui.models.jobs import Cancelled, CancelToken
    from flexvox_app.gui.models.machine_speed import P_RANGE, SIZES, calibrate
    from flexvox_core.design import design_code

    code = design_code((2, 2)).code
    model = calibrate("rebin", code)
    assert model.method == "rebin" and model.K == 4 and len(model.points) == 2
    assert [n for _, n, _ in model.points] == [h * w for h, w in SIZES]
    assert model.c > 0 and P_RANGE[0] <= model.p <= P_RANGE[1]
    token = CancelToken()
    token.cancel()
    with pytest.raises(Cancelled, match="cancelled"):
        calibrate("rebin", code, cancel=token)


def test_file_dialogs_start_in_the_last_folder_used(settings, tmp_path):
    from pathlib import Path

    assert settings.last_folder("review/export_dir") == str(Path.cwd())
    (tmp_path / "runs").mkdir()
    settings.remember_folder(tmp_path / "runs" / "run1.zarr")  # e.g. a recording made in Capture
    assert settings.last_folder("review/export_dir") == str(tmp_path / "runs")  # another dialog starts there
    settings.remember_folder(tmp_path / "x.tif", "review/export_dir")
    settings.remember_folder(tmp_path / "runs" / "cal.json")
    assert settings.last_folder("review/export_dir") == str(tmp_path)  # its own folder first
    assert settings.last_folder() == str(tmp_path / "runs")


def test_messages_from_below_are_said_in_the_window_s_words():
    """Point 8: no driver call, parameter in backticks or command-line flag in what the operator reads."""
    from flexvox_app.capture.rig_setup import delay_refusal
    from flexvox_app.gui.models.operator_words import in_gui_words
    from flexvox_calibration.capture_setup import CaptureCalibration
    from rig_drivers.errors import IncompatibleStateError

    said = {
        "camera gone": "cannot read a frame: call start_acquisition() first",
        "plan": "`plan`: no S-matrix exists for K = 16: S-matrices need K = 3 (mod 4)",
        "closed": str(IncompatibleStateError("cannot read the sensor shape: cam is closed (call open() first)")),
        "no delay": delay_refusal("the camera", 3, 441.0),
        "seed": "cal.json was made for rig 'simulated rig (mock, seed 1)', not 'simulated rig (mock, seed 0)': "
                "calibrate this rig (flexvox calibrate) instead of reusing it (or open the simulated rig with the seed "
                "it was made on: --seed)",
        "sync profile": "x.json is a sync profile (the synchronisation wizard's), not a calibration: it has no "
                        "homography. Give it as a sync profile (flexvox capture --sync-profile; Capture: \"Load sync "
                        "profile…\") and a calibration file as the calibration",
    }
    said |= {f"warning {i}": w for i, w in enumerate(CaptureCalibration().for_plan(16, 1000)[2])}
    for what, message in said.items():
        text = in_gui_words(message)
        assert "`" not in text and "()" not in text and not re.search(r"(^|\s|\()--\w", text), (what, text)
        assert "flexvox calibrate" not in text and "flexvox capture" not in text, (what, text)
    assert in_gui_words(said["camera gone"]) == (
        "the camera is not delivering frames (it was disconnected, switched off or closed): connect it in the Devices "
        "panel and start again")
    assert in_gui_words(said["plan"]) == "no S-matrix exists for K = 16: S-matrices need K = 3 (mod 4)"
    assert in_gui_words(said["sync profile"]).endswith("Give it as a sync profile (“Load sync profile…”) and a "
                                                       "calibration file as the calibration")
    assert "tick \"trigger delay set on the camera\")" in in_gui_words(said["no delay"])


@pytest.mark.parametrize("message", [
    "/d/x.zarr: not a readable Zarr store (GroupNotFoundError: No group found in store /d/x.zarr at path '')",
    "/d/x.zarr: not a flexvox recording (no `flexvox` attributes)",
    "/d/cal.json: not valid JSON (Expecting value at line 1)",
    "/d/code.json: the code's checksum does not match (check it with flexvox design --verify)",
    "/d/code.json: no multiplexed layout (write it again with flexvox design --multiplexed)",
    "no sync profile in use (flexvox capture --sync-profile; Capture: \"Load sync profile…\")",
])
def test_gui_messages_name_no_zarr_store_and_no_command_line_flag(message):
    from flexvox_app.gui.models.operator_words import in_gui_words

    text = in_gui_words(message)
    assert "Zarr store" not in text and " --" not in text and " -o" not in text, text


@pytest.mark.parametrize("message, words, gone", [
    ("/d/x.zarr: not a readable Zarr store (GroupNotFoundError: No group found in store /d/x.zarr at path '')",
     "is not a recording", "GroupNotFoundError"),
    ("/d/cal.json: not valid JSON (Expecting value at line 1)", "not a file flexvox wrote", "Expecting value"),
])
def test_messages_for_programmers_become_words_naming_what_to_open_instead(message, words, gone):
    from flexvox_app.gui.models.operator_words import in_gui_words

    text = in_gui_words(message)
    assert words in text and gone not in text and "open" in text, text


def test_where_it_ran_names_the_gpu_the_simulator_and_why_a_gpu_is_unused(monkeypatch):
    import flexvox_core.gpu.device as device
    from flexvox_app.gui.models import device_words as words

    monkeypatch.setattr(device, "simulator", lambda: False)
    monkeypatch.setattr(words, "gpu_name", lambda: "NVIDIA H200")
    monkeypatch.setattr(words, "gpu_status", lambda: (True, "CUDA", True))
    assert words.where_it_ran("cuda") == "on the GPU (NVIDIA H200)"
    assert words.where_it_ran("cpu", "gap-tv has no GPU path") == "on the CPU (gap-tv has no GPU path)"
    assert words.where_it_ran("cpu") == "on the CPU (the GPU was not asked for)"
    monkeypatch.setattr(words, "gpu_status", lambda: (False, "numba-cuda is not installed (pip install "
                                                             "'flexvox[gpu]')", True))
    assert words.where_it_ran("cpu") == ("on the CPU (a GPU is here but unused: numba-cuda is not installed "
                                         "(pip install 'flexvox[gpu]'))")
    monkeypatch.setattr(words, "gpu_status", lambda: (False, "no NVIDIA driver found (libcuda)", False))
    assert words.where_it_ran("cpu") == "on the CPU"
    monkeypatch.setattr(device, "simulator", lambda: True)
    simulated = words.where_it_ran("cuda")
    assert simulated.startswith("on numba-cuda's simulator (") and "no GPU" in simulated
