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

``--motion-trajectory`` prints instead why motion-aware's estimate is refused: per run, the error of the estimate
(which reads the probe along the sample's pixel's column) and of the same estimate read along the sample's
trajectory in the held flow (voxels ``p + d·u`` at ``t0 + d``, bilinear, or at the nearest voxel), and how far the
true error of the voxels that reading scores lies from the clip's; then, on fan, the terms of the error along
the trajectory per lag, from the truth (the data give ``V + 2C`` alone).

Figures only, never pass/fail. Usage: ``python bench/bench_accuracy.py [--quick] [--motion-trajectory]``.
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
    ap.add_argument("--motion-trajectory", action="store_true",
                    help="only motion-aware's estimate read along the held flow's trajectories, against the truth")
    args = ap.parse_args()
    if args.motion_trajectory:
        motion_trajectory(args.quick)
        return
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


def _bilinear(volume, t, y, x):
    """``volume`` (S, H, W[, 2]) at sub-frames ``t`` and positions ``(y, x)`` (clamped to the frame), bilinear."""
    S, H, W = volume.shape[:3]
    t = np.clip(t, 0, S - 1)
    y, x = np.clip(y, 0, H - 1.001), np.clip(x, 0, W - 1.001)
    y0, x0 = np.floor(y).astype(int), np.floor(x).astype(int)
    fy, fx = (y - y0).reshape(y.shape + (1,) * (volume.ndim - 3)), (x - x0).reshape(x.shape + (1,) * (volume.ndim - 3))
    at = lambda a, b: volume[t, a, b].astype(np.float64)  # noqa: E731
    return ((1 - fy) * (1 - fx) * at(y0, x0) + (1 - fy) * fx * at(y0, x0 + 1) + fy * (1 - fx) * at(y0 + 1, x0)
            + fy * fx * at(y0 + 1, x0 + 1))


def _trajectories(flow, t0, ys, xs, K):
    """{lag d: (t0 + d, y, x)} for d in -K..K: the positions along each sample's trajectory, the held flow
    integrated a sub-frame at a time from the sample's voxel (bilinear)."""
    pos = {0: (t0, ys.astype(float), xs.astype(float))}
    for sign in (1, -1):
        y, x = ys.astype(float), xs.astype(float)
        for k in range(1, K + 1):
            u = _bilinear(flow, t0 + sign * (k - 1), y, x)
            x, y = x + sign * u[:, 0], y + sign * u[:, 1]
            pos[sign * k] = (t0 + sign * k, y.copy(), x.copy())
    return pos


def motion_trajectory(quick: bool) -> None:
    """Motion-aware's estimate (the API's, reading the probe along the pixel's column) against the same estimate
    read along the sample's trajectory in the held flow, and what the truth says of the terms it cannot see."""
    from flexvox_core.accuracy import PROBE_DELTA, PROBE_STEP, db, probe_lattice
    from flexvox_core.accuracy_runs import HeldRuns
    from flexvox_core.forward import tiled_code

    method = Method("motion-aware")
    print("motion-aware, the probe read along the held flow's trajectories (errors: estimate - clip's truth, dB)")
    print(f"{'case':22s} {'truth':>6s} {'column':>7s} {'traj bilinear':>13s} {'traj nearest':>12s}  truth of the "
          "voxels the trajectory scores (bilinear, nearest)")
    errors = {"column": [], "bilinear": [], "nearest": []}
    fan = None
    for name, truth, frames, code, noise in cases(quick):
        f32 = np.asarray(frames, np.float32)
        F, H, W = f32.shape
        K = code.shape[2]
        held = HeldRuns(f32, code, method)
        v0 = held(f32)
        # the probe as estimate_accuracy makes it (seed 0)
        lattices = [probe_lattice(H, W, PROBE_STEP, shift) for shift in (0, PROBE_STEP // 2)]
        signs = np.random.default_rng(0).choice(np.array([-1.0, 1.0]), size=(F, H, W)) * np.stack(
            [lattices[f % 2] for f in range(F)])
        v1 = held(f32 + np.float32(PROBE_DELTA) * signs.astype(np.float32))
        flow = held.flows[-1].flow
        column = estimate_accuracy(f32, code, method, noise=noise, reconstruction=v0, unchecked=True).psnr
        slot = np.argmax(tiled_code(code, H, W), axis=0)
        S = F * K
        x = np.asarray(truth, np.float64)  # for the comparison only
        sums = {k: [0.0, 0] for k in ("bilinear", "nearest", "truth bilinear", "truth nearest")}
        for f in range(F):
            ys, xs = np.nonzero(signs[f])
            t0, b, y = f * K + slot[ys, xs], signs[f, ys, xs], f32[f, ys, xs].astype(np.float64)
            s2 = noise.variance(y)
            pos = _trajectories(flow, t0, ys, xs, K)
            inside = (t0 >= 1) & (t0 < S - 1)
            for how in ("bilinear", "nearest"):
                near = how == "nearest"
                loo = (0.5 * (_removed(v0, v1, x, pos[-1], b, y, near)[0]
                              + _removed(v0, v1, x, pos[1], b, y, near)[0]) - y) ** 2 - s2
                for d in range(-(K // 2), K - K // 2):
                    ok = inside & (t0 + d >= 0) & (t0 + d < S)
                    vm, a, u0, xu = _removed(v0, v1, x, pos[d], b, y, near)
                    if d == 0:
                        est = (u0 - y) ** 2 - s2 + 2 * a * s2
                    else:
                        est = (1 - a) ** 2 * loo + a**2 * (s2 + (vm - y) ** 2 - s2 - loo)
                    for key_, val in ((how, est), ("truth " + how, (u0 - xu) ** 2)):
                        sums[key_][0] += float(np.sum(val[ok]))
                        sums[key_][1] += int(np.sum(ok))
        true = clip_psnr(truth, v0)
        err = {k: db(total / count) - true for k, (total, count) in sums.items()}
        errors["column"].append(column - true)
        errors["bilinear"].append(err["bilinear"])
        errors["nearest"].append(err["nearest"])
        print(f"{name:22s} {true:6.2f} {column - true:+7.2f} {err['bilinear']:+13.2f} {err['nearest']:+12.2f}  "
              f"{err['truth bilinear']:+.2f}, {err['truth nearest']:+.2f}", flush=True)
        if name == "fan clean":
            fan = (v0, v1, flow, x, f32, signs, slot, K, noise)
    for k, e in errors.items():
        e = np.array(e)
        print(f"  {k:9s} within 1 dB {int(np.sum(np.abs(e) <= 1))} of {e.size}, from {e.min():+.2f} to "
              f"{e.max():+.2f} dB")
    if fan is not None:
        _fan_terms(*fan)


def _removed(v0, v1, x, position, b, y, nearest=False):
    """At ``position`` (t, y, x) along the trajectories: the value without the sample ``y`` (moved by ``b·delta`` in
    the probe ``v1``), the response to it, the value with it and the truth ``x`` there (bilinear, or at the nearest
    voxel)."""
    from flexvox_core.accuracy import PROBE_DELTA

    t, py, px = position
    if nearest:
        H, W = v0.shape[1:]
        py, px = np.clip(np.round(py), 0, H - 1), np.clip(np.round(px), 0, W - 1)
    u0, u1 = _bilinear(v0, t, py, px), _bilinear(v1, t, py, px)
    a = np.clip(b * (u1 - u0) / PROBE_DELTA, 0.0, 0.9)
    return (u0 - a * y) / (1 - a), a, u0, _bilinear(x, t, py, px)


def _fan_terms(v0, v1, flow, x, frames, signs, slot, K, noise) -> None:
    """Per lag along the trajectory on fan (clean): the response, what the data give (V + 2C), and from the
    truth the error without the sample L_d, the truth's change V_d, the covariance C_d and the voxel's error."""
    F = frames.shape[0]
    S = F * K
    rows = {d: [] for d in range(-(K // 2), K - K // 2)}
    loos = []
    for f in range(F):
        ys, xs = np.nonzero(signs[f])
        t0, b, y = f * K + slot[ys, xs], signs[f, ys, xs], frames[f, ys, xs].astype(np.float64)
        pos = _trajectories(flow, t0, ys, xs, K)
        inside = (t0 >= 1) & (t0 < S - 1)

        loo = (0.5 * (_removed(v0, v1, x, pos[-1], b, y)[0] + _removed(v0, v1, x, pos[1], b, y)[0]) - y) ** 2
        loos.append(loo[inside])
        xi = x[t0, ys, xs]
        for d in rows:
            if d == 0:
                continue
            vm, a, u0, xu = _removed(v0, v1, x, pos[d], b, y)
            ok = inside & (t0 + d >= 0) & (t0 + d < S)
            rows[d].append(np.stack([a, (vm - y) ** 2 - loo, (vm - xu) ** 2, (xu - xi) ** 2, (vm - xu) * (xu - xi),
                                     (1 - a) ** 2 * loo + a**2 * ((vm - y) ** 2 - loo), (u0 - xu) ** 2], 1)[ok])
    print(f"\nfan, clean: along the trajectory, x 1e-3 (L = {1e3 * np.mean(np.concatenate(loos)):.2f}, the held-out "
          "sample's error)")
    print("  lag  response  V+2C (data)  L_d (truth)  V_d (truth)  C_d (truth)  estimate (C = 0)  error (truth)")
    for d, r in rows.items():
        if not r:
            continue
        m = np.concatenate(r).mean(axis=0)
        print(f"  {d:3d}  {m[0]:8.2f}  {1e3 * m[1]:11.2f}  {1e3 * m[2]:11.2f}  {1e3 * m[3]:11.2f}  {1e3 * m[4]:11.2f}  "
              f"{1e3 * m[5]:16.2f}  {1e3 * m[6]:13.2f}")


if __name__ == "__main__":
    main()
