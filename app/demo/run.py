"""The demo's story on the simulated rig, as an operator walks it at a real one.

Design a code; open the simulated rig (``--rig mock``: a projector finer than the camera behind a
hidden homography, a trigger offset that is not a whole slot); calibrate it
(:func:`flexvox_calibration.pipeline.run_calibration`); hand the result to capture
(:func:`flexvox_calibration.capture_setup.from_run`, what "Use for capture" does); check the shutter with
a strobe in front of the camera (every slot right with the calibration, and how it fails without
it or with the raw phase); record the scene through the capture service; read the recording
back with the one reader (:func:`flexvox_core.capture_reader.read_capture`) and reconstruct it;
report.
"""

from __future__ import annotations

import html
import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from flexvox_app.demo import figures
from flexvox_core.design import design_code
from flexvox_core.divisions import Division
from flexvox_core.methods import Method
from flexvox_core.metrics import psnr
from flexvox_core.motion import motion_aware
from flexvox_core.output_files import OutputError, atomic_output, write_text_atomic
from flexvox_core.reconstruct.diffusion import DEFAULT_TENSOR, DEFAULT_TIME, diffuse
from flexvox_core.reconstruct.rebin import rebin
from flexvox_core.video_api import reconstruct_video
from flexvox_core.video_io import write_video

_logger = logging.getLogger(__name__)

HIGH_SR = (0.05, 0.05, 1.0)
HIGH_TR = (1.0, 1.0, 0.05)
CONTINUUM = [(0.05, 0.05, 1.0), (0.2, 0.2, 1.0), (1.0, 1.0, 1.0), (1.0, 1.0, 0.2), (1.0, 1.0, 0.05)]


@dataclass
class DemoConfig:
    """What the demo runs."""

    out: Path = Path("flexvox-demo")
    quick: bool = False
    scene: str = "drummer"
    tile: tuple[int, int] = (4, 4)
    seed: int = 0
    overwrite: bool = False
    """Whether an earlier report in ``out`` may be replaced."""

    @property
    def size(self) -> tuple[int, int, int]:
        """(frames, height, width) of the capture."""
        return (4, 96, 128) if self.quick else (8, 120, 160)


@dataclass
class DemoResult:
    """Scores and files of a demo run."""

    rows: list[dict] = field(default_factory=list)
    files: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    calibration: dict = field(default_factory=dict)
    shutter_check: list = field(default_factory=list)
    seconds: float = 0.0


STROBE_FRAMES = 17
"""Frames of the shutter check: the strobe visits every slot of K = 16 in 17 frames."""


def _rig(cfg: DemoConfig, scene: str, frames: int):
    """The simulated rig of ``cfg.seed`` with ``scene`` in front of it (virtual clock: runs as fast as it renders)."""
    from rig_drivers.profile import open_rig
    from rig_drivers.simulated_camera import VirtualClock

    _, H, W = cfg.size
    K = cfg.tile[0] * cfg.tile[1]
    return open_rig("mock", scene=scene, camera_size=(H, W), seed=cfg.seed, subframes=frames * K,
                    clock=VirtualClock(), electrons_per_unit=2000.0,
                    effects={"photon_noise": {}, "read_noise": {"sigma": 3.0}})


def _calibrate(cfg: DemoConfig, rig) -> tuple[dict, object]:
    """Calibrate the rig itself (its calibration target in view); its numbers beside the hidden truth, and the
    :class:`~flexvox_calibration.capture_setup.CaptureCalibration` capture uses."""
    from flexvox_calibration.capture_setup import from_run
    from flexvox_calibration.pipeline import run_calibration, truth_comparison
    from flexvox_calibration.session import RigSession

    t0 = time.perf_counter()
    session = RigSession.from_rig(rig)
    outcome = run_calibration(rig, session, tile=cfg.tile)
    rep = outcome.report
    out = {
        "success": outcome.success,
        "rms_px": rep.get("homography", {}).get("rms_px", float("nan")),
        "coverage": rep.get("homography", {}).get("coverage", float("nan")),
        "shutter_slot_accuracy": rep.get("shutter", {}).get("accuracy", float("nan")),
        "phase_found": rep.get("sync", {}).get("phase_slots"),
        "steps": {k: v.get("message", "") if isinstance(v, dict) else str(v) for k, v in rep.items()
                  if k not in ("colocation", "failed")},
    }
    out.update(truth_comparison(rig, outcome, session.camera_size))
    out["seconds"] = time.perf_counter() - t0
    if not outcome.success:
        raise RuntimeError(f"the demo's calibration failed at its {rep.get('failed')} step")
    calibration = from_run(outcome, session.identity, RigSession.from_rig(rig).identity)
    return out, calibration


def _record(cfg: DemoConfig, rig, calibration, path: Path, frames: int):
    """Record ``frames`` frames through the capture service (the one ``flexvox capture`` and the app use)."""
    from flexvox_app.capture import CapturePlan, CaptureService

    plan = CapturePlan(tile=cfg.tile)
    service = CaptureService(rig, plan, path, frames=frames, overwrite=True, calibration=calibration,
                             ground_truth=True,
                             rig_info={"profile": "mock", "demo": True})
    result = service.run(timeout_s=120.0)
    if not result.ok:
        raise RuntimeError(f"the demo capture failed: {result.message}")
    return service


def _shutter_check(cfg: DemoConfig, calibration, folder: Path) -> list[dict]:
    """Record the strobe with the calibration, with the raw phase, and uncalibrated; the slot accuracy of each."""
    from flexvox_calibration.capture_setup import SyncTiming
    from flexvox_core.capture_reader import read_capture
    from flexvox_core.recording import open_recording
    from flexvox_core.slot_check import slot_accuracy

    s = calibration.sync
    raw = calibration.with_sync(SyncTiming(s.raw_phase_slots, s.trigger_delay_us, s.K, s.period_us,
                                           s.raw_phase_slots))
    rows = []
    for name, cal in (("the calibration (phase and trigger delay together)", calibration),
                      ("the raw phase with the delay (the old Capture workspace)", raw),
                      ("no calibration", None)):
        path = folder / f"strobe-{len(rows)}.zarr"
        service = _record(cfg, _rig(cfg, "strobe", STROBE_FRAMES), cal, path, STROBE_FRAMES)
        frames, code = read_capture(path)
        check = slot_accuracy(frames, open_recording(path).ground_truth[:], code)
        rows.append({"with": name, "phase": service.phase_slots, "delay_us": service.trigger_delay_us,
                     "accuracy": check.accuracy, "decidable": check.decidable_fraction})
    return rows


def _capture(cfg: DemoConfig, rig, calibration, path: Path):
    """Record ``cfg.size[0]`` frames of the scene; read them back with the one reader (normalised frames, code,
    ground truth, counters)."""
    from flexvox_core.capture_reader import read_capture
    from flexvox_core.recording import open_recording

    F = cfg.size[0]
    _record(cfg, rig, calibration, path, F)
    frames, code = read_capture(path)
    rec = open_recording(path)
    return frames, code, rec.ground_truth[:], {"rows": rec.n_frames, "drops": int(rec.per_frame("dropped").sum())}


def _timed(fn, *args, **kwargs):
    t0 = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - t0


REPORT_ENTRIES = frozenset({"index.html", "shutter-check", "recording.zarr", "figures", "videos", "bench"})
"""What a demo report folder holds; ``overwrite`` replaces only a folder that holds nothing else."""


def check_report_folder(out, overwrite: bool) -> None:
    """Refuse, before any work, a report folder that may not be replaced (:class:`OutputError`).

    An empty folder is used; a folder of an earlier report needs ``overwrite``; a folder holding anything else is
    never replaced.
    """
    out = Path(out)
    if not out.exists():
        if not out.parent.is_dir():
            raise OutputError(f"cannot write {out}: the folder {out.parent} does not exist")
        return
    if not out.is_dir():
        raise OutputError(f"{out} is a file; --out takes a folder for the report")
    entries = {p.name for p in out.iterdir()}
    if not entries:
        return
    if entries - REPORT_ENTRIES:
        others = ", ".join(sorted(entries - REPORT_ENTRIES)[:3])
        raise OutputError(f"{out} holds other things than a demo report ({others}); --out another folder")
    if not overwrite:
        what = "a demo report" if "index.html" in entries else "part of a demo report"
        raise OutputError(f"{out} already holds {what}; use --overwrite to replace it, or --out another folder")


def run_demo(cfg: DemoConfig, *, step=None) -> DemoResult:
    """Run the demo and write ``cfg.out/index.html``; ``step(name)`` is called before each step.

    The report is built in a hidden sibling of ``cfg.out`` and moved into place when complete
    (:func:`~flexvox_core.output_files.atomic_output`): an interrupted or failed run leaves ``cfg.out`` as it was.
    """
    out = Path(cfg.out)
    check_report_folder(out, cfg.overwrite)
    with atomic_output(out, overwrite=out.exists()) as work:
        work.mkdir()
        res = _run_demo(cfg, work, step or (lambda name: None))
    res.files = [out / Path(f).relative_to(work) for f in res.files]
    return res


def _run_demo(cfg: DemoConfig, out: Path, step) -> DemoResult:
    res = DemoResult()
    t_start = time.perf_counter()
    F, H, W = cfg.size

    step("design")
    design, t = _timed(design_code, cfg.tile)
    K = design.K
    res.notes.append(f"Designed a {cfg.tile[0]}x{cfg.tile[1]} code in {t:.2f} s: {design.message}.")

    step("calibrate")
    rig = _rig(cfg, cfg.scene, F)
    res.calibration, calibration = _calibrate(cfg, rig)
    c = res.calibration
    res.notes.append(
        f"Calibrated the simulated rig (a projector twice as fine as the camera behind a hidden homography, a "
        f"hidden trigger offset; noise, defocus, ambient light on the target) in {c['seconds']:.1f} s: homography "
        f"error {c.get('homography_error_px', float('nan')):.3f} px against the hidden truth (RMS "
        f"{c['rms_px']:.3f} px, coverage {c['coverage']:.1%}), shutter slot accuracy "
        f"{c['shutter_slot_accuracy']:.2%}, phase {c['phase_found']} (true {c['phase_true']}); capture uses phase "
        f"{calibration.phase_slots} with a {calibration.trigger_delay_us:.0f} µs camera trigger delay."
    )

    step("shutter check")
    checks_dir = out / "shutter-check"
    checks_dir.mkdir(exist_ok=True)
    res.shutter_check = _shutter_check(cfg, calibration, checks_dir)
    good, raw, none = (r["accuracy"] for r in res.shutter_check)
    res.notes.append(f"Recorded a strobe ({STROBE_FRAMES} frames) to check which slot every pixel samples: "
                     f"{good:.1%} right with the calibration, {raw:.1%} with the raw phase, {none:.1%} uncalibrated.")

    step("capture")
    rec_path = out / "recording.zarr"
    frames, code, truth, info = _capture(cfg, rig, calibration, rec_path)
    res.notes.append(
        f"Captured the '{cfg.scene}' scene on the calibrated simulated rig through the capture service: "
        f"{info['rows']} frames of {H}x{W} at 15 Hz, K = {K} ({F * K} sub-frames at {15 * K} Hz), photon and read "
        f"noise, {info['drops']} dropped; recording: {rec_path.name}, read back with the one reader."
    )

    step("reconstruct")
    videos: dict[str, np.ndarray] = {}
    timings: dict[str, float] = {}
    by_tr: dict[int, Division] = {}
    for d in sorted(design.supported, key=lambda d: abs(d.a - d.b)):  # squarest block for each TR
        by_tr.setdefault(d.tr, d)
    rebinned = {}
    for tr in sorted(by_tr):
        d = by_tr[tr]
        name = f"re-binning {d.label} [TR {d.tr}, SR {d.sr}]"
        videos[name], timings[name] = _timed(rebin, frames, code, d, interpolate=True)
        rebinned[f"rebin [{d.tr}, {d.sr}]"] = videos[name]
    for label, tensor, n in (("high SR (0.05, 0.05, 1)", HIGH_SR, 3.0), ("high TR (1, 1, 0.05)", HIGH_TR, 2.0),
                             (f"default diffusion {DEFAULT_TENSOR}", DEFAULT_TENSOR, DEFAULT_TIME)):
        videos[label], timings[label] = _timed(diffuse, frames, code, tensor=tensor, time=n)
    gap_it = 10 if cfg.quick else 40
    videos[f"GAP-TV ({gap_it} iterations)"], timings[f"GAP-TV ({gap_it} iterations)"] = _timed(
        reconstruct_video, frames, code, Method("gap-tv", iterations=gap_it), chunk_frames=None)
    ma, t = _timed(motion_aware, frames, code)
    videos["motion-aware"], timings["motion-aware"] = ma.video, t
    for name, v in videos.items():
        res.rows.append({"method": name, "psnr": float(psnr(truth, v)), "seconds": timings[name]})

    step("figures")
    s = F * K // 2 + K // 2
    crop = (H // 3, H // 3 + H // 3, W // 8, W // 8 + W // 3)
    fig_dir = out / "figures"
    fig_dir.mkdir(exist_ok=True)
    res.files += [
        figures.fig1_sampling(fig_dir / "fig1_sampling.png", {"high SR": videos["high SR (0.05, 0.05, 1)"],
                              "high TR": videos["high TR (1, 1, 0.05)"], "motion-aware": ma.video}, s, crop),
        figures.fig3_rebinning(fig_dir / "fig3_rebinning.png", frames[s // K], rebinned, s),
        figures.fig4_continuum(fig_dir / "fig4_continuum.png", {
            f"T = diag{t}": diffuse(frames, code, tensor=t, time=2.0) for t in CONTINUUM}, s),
        figures.fig5_flow(fig_dir / "fig5_flow.png", ma.high_tr[s], ma.flow.flow[s], ma.tr[s], K),
        figures.fig7_panel(fig_dir / "fig7_panel.png", frames, [s - K, s, s + K // 2], {
            "high SR": videos["high SR (0.05, 0.05, 1)"], "high TR": videos["high TR (1, 1, 0.05)"],
            "motion-aware": ma.video}, ma.flow.flow, K),
    ]

    step("videos")
    vid_dir = out / "videos"
    vid_dir.mkdir(exist_ok=True)
    captured_up = np.repeat(frames, K, axis=0)
    for name, v in (("ground_truth", truth), ("captured", captured_up), ("high_sr", videos["high SR (0.05, 0.05, 1)"]),
                    ("high_tr", videos["high TR (1, 1, 0.05)"]), ("motion_aware", ma.video)):
        res.files.append(write_video(vid_dir / f"{name}.mp4", np.clip(v, 0, 1), fps=30, overwrite=True))

    step("accuracy vs time")
    from flexvox_app.accuracy_bench import pareto, run_bench, summary

    bench_rows = run_bench(out / "bench", quick=True, sci=False)
    bench_summary = summary(bench_rows)
    front = {r["method"] for r in pareto(bench_summary)}

    step("report")
    res.seconds = time.perf_counter() - t_start
    write_text_atomic(out / "index.html", _html(cfg, res, bench_summary, front, design))
    res.files.append(out / "index.html")
    return res


def _table(rows, cols) -> str:
    head = "".join(f"<th>{html.escape(c)}</th>" for c, _ in cols)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(fmt(r))}</td>" for _, fmt in cols) + "</tr>" for r in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def _calibration_table(c: dict) -> str:
    if not c:
        return "<p>not run</p>"
    rows = [("homography error over the frame", f"{c.get('homography_error_px', float('nan')):.3f} px"),
            ("RMS reprojection error", f"{c['rms_px']:.3f} px"), ("decoded coverage", f"{c['coverage']:.1%}"),
            ("shutter slot accuracy", f"{c['shutter_slot_accuracy']:.2%}"),
            ("phase found / true", f"{c['phase_found']} / {c['phase_true']}"),
            ("all steps passed", "yes" if c["success"] else "no")]
    rows += [(k, v) for k, v in c.get("steps", {}).items()]
    return _table(rows, [("", lambda r: r[0]), ("", lambda r: str(r[1]))])


def _shutter_table(rows) -> str:
    return _table(rows, [("recorded with", lambda r: r["with"]), ("phase", lambda r: str(r["phase"])),
                         ("camera trigger delay", lambda r: f"{r['delay_us']:.0f} µs"),
                         ("slot accuracy", lambda r: f"{r['accuracy']:.1%}"),
                         ("pixels decided", lambda r: f"{r['decidable']:.0%}")])


def _html(cfg: DemoConfig, res: DemoResult, bench_summary, front, design) -> str:
    order = "<br>".join(" ".join(f"{v:2d}" for v in row) for row in design.order)
    results = _table(sorted(res.rows, key=lambda r: -r["psnr"]),
                     [("method", lambda r: r["method"]), ("PSNR vs ground truth (dB)", lambda r: f"{r['psnr']:.2f}"),
                      ("seconds", lambda r: f"{r['seconds']:.2f}")])
    bench = _table(bench_summary[:15], [("method", lambda r: r["method"]), ("PSNR (dB)", lambda r: f"{r['psnr']:.2f}"),
                                        ("seconds", lambda r: f"{r['seconds']:.4f}"),
                                        ("Pareto", lambda r: "yes" if r["method"] in front else "")])
    notes = "".join(f"<li>{html.escape(n)}</li>" for n in res.notes)
    vids = "".join(f'<figure><video src="videos/{n}.mp4" controls loop muted width="320"></video>'
                   f"<figcaption>{n.replace('_', ' ')}</figcaption></figure>"
                   for n in ("ground_truth", "captured", "high_sr", "high_tr", "motion_aware"))
    return f"""<!doctype html><html><head><meta charset="utf-8"><title>flexvox demo</title>
<style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto;line-height:1.45}}img{{max-width:100%}}
table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:3px 8px;text-align:left}}
figure{{display:inline-block;margin:4px}}code{{background:#f3f3f3}}</style></head><body>
<h1>flexvox demo: flexible voxels on the simulated rig</h1>
<p>A projector co-located with a camera opens each pixel of a {cfg.tile[0]}&times;{cfg.tile[1]} tile in one of
K = {design.K} slots per exposure, so one camera frame holds samples from K instants. After capture we choose,
per location, how to trade spatial for temporal resolution (Gupta et al. 2010, <i>Flexible Voxels for
Motion-Aware Videography</i>: "the paper" below).</p>
<h2>What the demo did</h2><ul>{notes}<li>Total {res.seconds:.1f} s.</li></ul>
<h2>Calibration (simulated rig, against its hidden truth)</h2>{_calibration_table(res.calibration)}
<h2>Shutter check: a strobe, recorded through the capture service</h2>
<p>A strobe flashes once every 17 sub-frames, so 17 frames say which slot every camera pixel sampled.</p>
{_shutter_table(res.shutter_check)}
<h2>The code</h2><p>Firing order (slot of each tile pixel), supporting all {len(design.supported)} divisions:</p>
<pre>{order}</pre>
<h2>Results against the ground truth</h2>{results}
<h2>As in the paper's Fig. 1: high SR, high TR, motion-aware</h2><img src="figures/fig1_sampling.png">
<h2>As in the paper's Fig. 3: re-binning</h2><p>Re-binning the samples at each division trades SR for TR; coded-blur
artifacts show where things move.</p><img src="figures/fig3_rebinning.png">
<h2>As in the paper's Fig. 4: the diffusion continuum</h2><img src="figures/fig4_continuum.png">
<h2>As in the paper's Fig. 5: flow and the tensor field</h2><img src="figures/fig5_flow.png">
<h2>As in the paper's Figs. 7&ndash;8: captured, high SR, high TR, motion-aware, flow</h2>
<img src="figures/fig7_panel.png">
<h2>Videos</h2>{vids}
<h2>What accuracy costs in time (quick benchmark on built-in scenes)</h2>{bench}
<img src="bench/pareto.png"><p>Full run: <code>flexvox bench</code>.</p>
</body></html>"""
