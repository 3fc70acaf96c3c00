"""Accuracy without ground truth: the estimate (:mod:`flexvox_core.accuracy`) against the truth.

On the built-in moving scenes (4×4 designed code, K = 16, 64×96, 4 frames), clean and with photon and
read noise (1000 e⁻ per unit, 3 e⁻ read noise), and on the SCI clips Runner and Drop (2×4 code, K = 8)
when ``../shared/data/sci_benchmark`` (or ``$FLEXVOX_DATA``) holds them, for diffusion (its nc, explicit and
steady solvers), GAP-TV, re-binning at the default division (2×2×4 at K = 16; interpolated, its default, and
without interpolation) and motion-aware (and diffusion's
nc and explicit solvers at times 0.5 and 4, for the order check among the settings the API estimates), prints
per run: the estimate, its interval, the true PSNR of the clip (``10·log10(1/MSE)``, what the estimate
estimates; read only after the estimate), the error, whether the interval covers the truth, the time of the
estimate with its reconstruction over the reconstruction's alone, and the mean of the sub-frames' PSNRs
(``flexvox_core.metrics.psnr``, what ``flexvox bench`` reports) for reference. A method the API refuses is
estimated all the same here (``unchecked=True``) and marked, as the evidence for the refusal.
Then per method: runs within 1 dB, the interval's coverage; and the order by estimate against the order
by truth wherever the truths differ by more than 1 dB (methods the API estimates). Then diffusion's three
solvers at a 2×2 code (K = 4), and last, diffusion on captures with two dropped frames.

Figures only, never pass/fail. Usage: ``python bench/bench_accuracy.py [--quick]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from flexvox_core import metrics
from flexvox_core.accuracy import NoiseModel, NotEstimable, db, estimate_accuracy
from flexvox_core.design import design_code
from flexvox_core.forward import capture
from flexvox_core.methods import Method, run
from flexvox_core.metrics import psnr
from flexvox_core.reconstruct.rebin import default_block
from flexvox_core.simulate import render_scene, simulate_video

NOISE = {"photon_noise": {}, "read_noise": {"sigma": 3.0}}


def cases(quick: bool):
    """(name, truth, frames, code, noise model) of every run."""
    H, W, F = (48, 64, 4) if quick else (64, 96, 4)
    code = design_code((4, 4)).code
    scenes = ("balls", "fan") if quick else ("balls", "fan", "drummer", "pan")
    out = []
    for scene in scenes:
        truth = render_scene(scene, F * 16, H, W, seed=0)
        out.append((f"{scene} clean", truth, capture(truth, code), code, NoiseModel()))
        sim = simulate_video(truth, code, effects=NOISE, seed=1)
        out.append((f"{scene} noisy", truth, sim.frames, code, NoiseModel.from_effects(NOISE)))
    from flexvox_app.accuracy_bench import sci_data_dir

    folder = sci_data_dir()
    if folder is not None:
        from flexvox_core.simulate.sources import load_video

        code8 = design_code((2, 4)).code
        for name in ("runner",) if quick else ("runner", "drop"):
            truth = load_video(folder / f"{name}40_cacti.mat")[:8 if quick else 16]
            out.append((f"{name} (SCI) clean", truth, capture(truth, code8), code8, NoiseModel()))
            sim = simulate_video(truth, code8, effects=NOISE, seed=1)
            out.append((f"{name} (SCI) noisy", truth, sim.frames, code8, NoiseModel.from_effects(NOISE)))
    return out


def clip_psnr(truth, video) -> float:
    """The PSNR the estimate estimates: of the clip's mean squared error (:func:`flexvox_core.metrics.clip_psnr`;
    ``flexvox_core.metrics.psnr`` is the mean of the sub-frames' PSNRs, printed beside it as "frames mean")."""
    return metrics.clip_psnr(truth, video)


def methods(code):
    return [Method("diffusion"), Method("diffusion", time=0.5), Method("diffusion", time=4.0),
            Method("diffusion", solver="explicit"), Method("diffusion", solver="explicit", time=0.5),
            Method("diffusion", solver="explicit", time=4.0), Method("diffusion", solver="steady"), Method("gap-tv"),
            Method("rebin", block=default_block(code), interpolate=True),
            Method("rebin", block=default_block(code), interpolate=False), Method("motion-aware")]


def key(method: Method) -> str:
    """The method's name in ``--methods`` and the summary: its name, diffusion's other solvers as
    ``diffusion:SOLVER``, re-binning without interpolation as ``rebin:nearest``."""
    if method.name == "diffusion" and method.solver != "nc":
        return f"diffusion:{method.solver}"
    if method.name == "rebin" and not method.interpolate:
        return "rebin:nearest"
    return method.name


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="two scenes, smaller frames, Runner only")
    ap.add_argument("--methods", default=None,
                    help="comma-separated method names to run (default: all), e.g. gap-tv,rebin; diffusion's "
                         "other solvers as diffusion:explicit, diffusion:steady")
    ap.add_argument("--no-dropped", action="store_true", help="skip the dropped-frames runs")
    args = ap.parse_args()
    chosen = None if args.methods is None else set(args.methods.split(","))
    solvers = chosen is None or any(c == "diffusion" or c.startswith("diffusion:") for c in chosen)
    rows = []
    refused = {}
    print(f"{'case':22s} {'method':34s} {'estimate':>9s} {'interval':>15s} {'truth':>7s} {'error':>6s} cover "
          f"{'cost (runs)':>11s} {'frames mean':>11s}")
    for name, truth, frames, code, noise in cases(args.quick):
        for method in methods(code):
            if chosen is not None and key(method) not in chosen:
                continue
            t0 = time.perf_counter()
            video = run(frames, code, method, chunk_frames=None).video
            t_rec = time.perf_counter() - t0
            why = None
            t0 = time.perf_counter()
            try:
                est = estimate_accuracy(frames, code, method, noise=noise, reconstruction=video)
            except NotEstimable as exc:  # what the API says; then the same estimate unchecked, as the evidence
                why = refused[method.label] = str(exc)
                t0 = time.perf_counter()
                est = estimate_accuracy(frames, code, method, noise=noise, reconstruction=video, unchecked=True)
            t_est = time.perf_counter() - t0 + t_rec  # the probe and the reconstruction it needs
            true = clip_psnr(truth, video)  # the truth, read only now, for the comparison
            frames_mean = float(psnr(truth, video))
            err = est.psnr - true
            cover = est.low <= true <= est.high
            rows.append((name, key(method), est.psnr, true, err, cover, bool(why)))
            flag = " (refused by the API)" if why else ""
            print(f"{name:22s} {method.label:34s} {est.psnr:9.2f} {est.low:7.2f}-{est.high:<7.2f} {true:7.2f} "
                  f"{err:+6.2f} {'yes' if cover else 'NO ':5s} {t_est / max(t_rec, 1e-9):11.2f} "
                  f"{frames_mean:11.2f}{flag}", flush=True)
    print()
    for m in sorted({(r[1], r[6]) for r in rows}):
        errs = np.array([r[4] for r in rows if (r[1], r[6]) == m])
        cov = np.mean([r[5] for r in rows if (r[1], r[6]) == m])
        name = m[0] + (" (refused)" if m[1] else "")
        print(f"{name:24s} runs {errs.size:3d}  within 1 dB {np.mean(np.abs(errs) <= 1):5.0%}  "
              f"mean error {errs.mean():+.2f}  worst {errs[np.argmax(np.abs(errs))]:+.2f}  interval covers {cov:5.0%}")
    groups = (("methods the API estimates", lambda r: not r[6]),
              ("those and GAP-TV and re-binning, unchecked", lambda r: not r[6] or r[1] in ("gap-tv", "rebin",
                                                                                        "rebin:nearest")),
              ("every method, unchecked included", lambda r: True))
    for label, chosen in groups:
        pairs = agree = 0
        for case in sorted({r[0] for r in rows}):
            rs = [r for r in rows if r[0] == case and chosen(r)]
            for i in range(len(rs)):
                for j in range(i + 1, len(rs)):
                    if abs(rs[i][3] - rs[j][3]) > 1.0:
                        pairs += 1
                        agree += (rs[i][2] > rs[j][2]) == (rs[i][3] > rs[j][3])
        print(f"order ({label}): {agree} of {pairs} pairs whose truths differ by more than 1 dB are in the "
              "truth's order")
    for why in dict.fromkeys(refused.values()):
        print(f"refused: {why}")
    if args.methods is None or "gap-tv" in args.methods.split(","):
        gap_tv_spacing(args.quick)
    if args.methods is None or "rebin" in args.methods.split(","):
        rebin_divisions(args.quick)
    if solvers:
        solvers_at_k4(args.quick)
    if not args.no_dropped:
        dropped_frames(args.quick)


def gap_tv_spacing(quick: bool) -> None:
    """GAP-TV's estimate with the 4-fold hold-out's error scaled to the unsampled voxels by the truth's increment over
    the distance to the nearest sample (:func:`flexvox_core.accuracy_folds.spacing_ratio`), against the estimate's
    own (the neighbours' exact leave-one-out) and the hold-out's alone: the candidate correction, not used."""
    from flexvox_core.accuracy_folds import held_out_error, independent_rows, masked_run, spacing_ratio

    print("\nGAP-TV: the 4-fold hold-out scaled by the fitted variogram to the unsampled voxels' spacing (not used):")
    method = Method("gap-tv")
    for name, truth, frames, code, noise in cases(quick):
        F = frames.shape[0]
        K = code.shape[2]
        video = np.asarray(run(frames, code, method, chunk_frames=None).video)
        est = estimate_accuracy(frames, code, method, noise=noise, reconstruction=video, unchecked=True)
        var = noise.variance(frames)
        none = np.zeros(F, bool)
        loo = float(np.mean(independent_rows(video, frames, code, none, var, 0.0)[:, 3]))
        sure = K * est.mse - (K - 1) * loo  # the sampled voxels' share, as the estimate has it
        held = held_out_error(np.asarray(frames, np.float32), code, masked_run(method), none, var)
        ratio = spacing_ratio(np.asarray(frames), code, var)
        scaled = ((K - 1) * held * ratio + sure) / K
        true = clip_psnr(truth, video)
        print(f"  {name:22s} truth {true:6.2f}  estimate {est.psnr - true:+.2f}  hold-out alone "
              f"{db((K - 1) / K * held + sure / K) - true:+.2f}  scaled {db(scaled) - true:+.2f} (ratio {ratio:.2f})",
              flush=True)


def rebin_divisions(quick: bool) -> None:
    """Interpolated re-binning's estimate at every division the code supports (unchecked: the API estimates the
    code's default division only), against the truth: what ``--block auto`` would choose from."""
    from flexvox_core.reconstruct.rebin import supported_divisions

    print("\ninterpolated re-binning at every supported division (error, '!' where the interval misses):")
    errors = []
    covered = refused = 0
    for name, truth, frames, code, noise in cases(quick):
        cells = []
        for division in supported_divisions(code):
            method = Method("rebin", block=division)
            video = run(frames, code, method, chunk_frames=None).video
            true = clip_psnr(truth, video)
            try:
                est = estimate_accuracy(frames, code, method, noise=noise, unchecked=True)
            except NotEstimable:
                cells.append(f"{division.label} refused")
                refused += 1
                continue
            cover = est.low <= true <= est.high
            if division != default_block(code):
                errors.append(est.psnr - true)
                covered += cover
            cells.append(f"{division.label} {est.psnr - true:+.2f}{'' if cover else '!'}")
        print(f"  {name:22s} " + "  ".join(cells), flush=True)
    e = np.array(errors)
    if e.size:
        print(f"  other than the default: {e.size} runs, within 1 dB {int(np.sum(np.abs(e) <= 1))}, "
              f"{e.min():+.2f} to {e.max():+.2f} dB, interval covers {covered}; {refused} refused (too few lags)")


def solvers_at_k4(quick: bool) -> None:
    """Diffusion's three solvers at a 2×2 code (K = 4, 16 frames: the same 64 sub-frames), clean and noisy: where
    the explicit and steady solvers' estimates run high."""
    print("\ndiffusion's solvers at a 2x2 code (K = 4):")
    code = design_code((2, 2)).code
    H, W = (48, 64) if quick else (64, 96)
    errors: dict[str, list[float]] = {}
    for scene in ("balls", "fan") if quick else ("balls", "fan", "drummer", "pan"):
        truth = render_scene(scene, 16 * 4, H, W, seed=0)
        sim = simulate_video(truth, code, effects=NOISE, seed=1)
        for label, frames, noise in (("clean", capture(truth, code), NoiseModel()),
                                     ("noisy", sim.frames, NoiseModel.from_effects(NOISE))):
            for solver in ("nc", "explicit", "steady"):
                method = Method("diffusion", solver=solver)
                video = run(frames, code, method, chunk_frames=None).video
                est = estimate_accuracy(frames, code, method, noise=noise, reconstruction=video, unchecked=True)
                true = clip_psnr(truth, video)
                errors.setdefault(solver, []).append(est.psnr - true)
                print(f"  {scene:8s} {label} {solver:9s} estimate {est.psnr:6.2f} ({est.low:.2f}-{est.high:.2f})  "
                      f"truth {true:6.2f}  error {est.psnr - true:+.2f}  covers "
                      f"{'yes' if est.low <= true <= est.high else 'NO'}", flush=True)
    for solver, errs in errors.items():
        e = np.array(errs)
        worst = e[np.argmax(np.abs(e))]
        print(f"  {solver:9s} within 1 dB {int(np.sum(np.abs(e) <= 1))} of {e.size}, worst {worst:+.2f}")


def dropped_frames(quick: bool) -> None:
    """Diffusion on captures with frames 3 and 7 of 12 dropped (their rows zero): the dropped frames are scored by
    captured frames held out like them."""
    print("\ndropped frames 3 and 7 of 12 (diffusion, clean):")
    code = design_code((4, 4)).code
    H, W = (48, 64) if quick else (64, 96)
    for scene in ("balls", "fan") if quick else ("balls", "fan", "drummer", "pan"):
        truth = render_scene(scene, 12 * 16, H, W, seed=0)
        frames = capture(truth, code)
        missing = np.zeros(12, bool)
        missing[[3, 7]] = True
        frames[missing] = 0
        method = Method("diffusion")
        video = run(frames, code, method, chunk_frames=None, missing=missing).video
        est = estimate_accuracy(frames, code, method, missing=missing, reconstruction=video)
        true = clip_psnr(truth, video)
        print(f"  {scene:8s} estimate {est.psnr:6.2f} ({est.low:.2f}-{est.high:.2f})  truth {true:6.2f}  error "
              f"{est.psnr - true:+.2f}  covers {'yes' if est.low <= true <= est.high else 'NO'}  (frames' mean "
              f"{float(psnr(truth, video)):.2f})", flush=True)


if __name__ == "__main__":
    main()
