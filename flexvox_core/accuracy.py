"""How good is a reconstruction, from the recording alone: an estimated PSNR with its uncertainty.

The estimate never reads a ground truth. It asks the reconstruction method, through its public entry
point (:func:`flexvox_core.methods.run`), how each probed camera sample would be predicted without that
sample, and compares the prediction with the sample (leave-one-out cross-validation):

1. **Reconstruct** the capture, ``v = f(y)`` (the reconstruction being scored).
2. **Probe**: reconstruct again with a sparse lattice of samples moved by ``±delta`` (Rademacher signs;
   one pixel in ``step × step``, sheared to land on every place of the code's tile (:func:`probe_lattice`),
   shifted by half a step in every other frame, so a probed pixel's next probed sample is two frames away).
   The change at voxel ``u`` over ``delta·b_i`` is its response ``A_u = ∂v_u/∂y_i`` to the nearest-in-time
   sample ``i`` of its pixel.
3. **Take the sample out** by the local linearisation: ``v_u⁻ = (v_u − A_u·y_i) / (1 − A_u)`` is what
   the method gives at ``u`` without sample ``i`` (exact for a linear smoother that renormalises its
   weights, as normalized convolution does; tested against a float64 reference).
4. **Leave-one-out error**: the sample is predicted by the mean of ``v_u⁻`` at its two temporal
   neighbours (the truth's linear change across them cancels); ``L = (pred − y_i)² − σ²``. The
   measurement noise variance ``σ²`` (:class:`NoiseModel`, from the camera model the recording states) is
   subtracted: a sample's noise is independent of a prediction made without it.
5. **From held-out samples to every voxel.** The true PSNR is over all voxels; a held-out voxel has
   lost its own sample, an unsampled voxel at lag ``d`` from its pixel's sample has not. With
   ``v_u = (1 − A)·v_u⁻ + A·y_i`` the error at ``u`` is ``(1 − A)²·L_d + A²·(σ² + V_d) − 2A(1 − A)·C_d``
   (``V_d``: the truth's squared change over the lag, ``C_d``: its covariance with the leave-one-out
   error). The data give ``(v_u⁻ − y_i)² − σ² − L = V_d + 2·C_d`` (taking ``L_d = L``), not the two apart.
   The estimate takes ``C_d = 0`` (the sample's pull counted in full). Two bounds follow: *pessimistic*, the
   voxel no better than one that lost its sample (``L``); *optimistic*, ``C_d`` at its largest,
   Cauchy-Schwarz's ``C_d² ≤ L·V_d`` with ``V_d = e_d − 2C_d ≥ 0`` (``e_d`` what the data give):
   ``C_d = min(e_d/2, −L + √(L² + L·e_d))``, the error ``2·A·C_d`` less. The sampled voxel's own error is Stein's
   unbiased risk estimate ``(v_i − y_i)² − σ² + 2·A_i·σ²``. A method whose temporal neighbours do not
   respond to the sample (each sub-frame reconstructed apart, as GAP-TV's 2-D TV) has every sample held out
   exactly, and its pessimistic end from a k-fold hold-out (:mod:`flexvox_core.accuracy_folds`).
6. The interval spans both bounds, widened by the spread over clusters of probed samples (a normal interval
   of the cluster means) where that reaches further.

Motion-aware is run with its flow held (:mod:`flexvox_core.accuracy_runs`): the probe reuses the first run's
flow and sample range, so the change it sees is the sample's own pull along fixed trajectories.

The cost is one extra reconstruction. The estimate is only offered for methods whose estimates were
checked against the truth (``bench/bench_accuracy.py``); :func:`refusal` says why the others are not.
"""

from __future__ import annotations

import dataclasses
import logging
import math
import os
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from flexvox_core import accuracy_rebin
from flexvox_core.accuracy_folds import FOLDS, held_out_error, independent_rows, masked_run
from flexvox_core.accuracy_runs import HeldRuns, Run, Steps, holds_flow
from flexvox_core.codes import is_identity_code, validate_code
from flexvox_core.forward import tiled_code
from flexvox_core.gaps import as_missing, find_gaps
from flexvox_core.intensity import as_relative
from flexvox_core.numbers import positive_number
from flexvox_core.progress import Progress, progress_callback

if TYPE_CHECKING:
    from flexvox_core.methods import Method
    from flexvox_core.multiplex import MultiplexedCode
    from flexvox_core.recording import Recording

_logger = logging.getLogger(__name__)

PROBE_STEP = 4
"""Probed pixels: one in ``PROBE_STEP × PROBE_STEP``."""
PROBE_DELTA = 0.05
"""How far each probed sample is moved (relative units, 1 = white in one slot)."""
CONFIDENCE = 0.95
"""The confidence of the interval."""
INDEPENDENT = 0.02
"""Below this summed response of a sample's two temporal neighbours, they are taken as independent of it."""
GAP_BLOCKS = 4
"""Captured runs held out per length of a recording's gaps, to score its dropped frames."""
COPIED = 0.9
"""A neighbour's response to a sample at or above which the sample cannot be taken out (``1 − A`` too small)."""
MAX_COPIED = 0.1
"""The largest share of probed samples copied onto a neighbour (:data:`COPIED`) an estimate is made with."""
CLUSTER = 4
"""Probed pixels per cluster side (clusters of ``CLUSTER²`` probed pixels in one camera frame)."""

REFUSED = {
    "motion-aware": ("even with the first run's flow held for the probe (the rest is then nearly linear: the same "
                     "estimate at a move of 0.01 and 0.05), the estimate misses the truth by -3.29 to +3.18 dB (6 of "
                     "12 runs within 1 dB, on the built-in scenes and the SCI clips; bench/bench_accuracy.py), and "
                     "read along the sample's trajectory in the held flow instead of its pixel's column by -0.16 to "
                     "+2.77 dB (8 of 12; at the nearest voxel -1.20 to +1.62 dB, 7 of 12; bench/bench_accuracy.py "
                     "--motion-trajectory): motion-aware carries a sample far (response 0.32 to 0.71 at lags 1 to 8 "
                     "along the trajectory on fan), so the error between samples rests on how the reconstruction's "
                     "error there covaries with the truth's change from the sample, which the probe cannot see (it "
                     "gives their sum alone): on fan that covariance makes the true error up to 1.7 times the "
                     "estimate's"),
    "gap-tv": ("each sample is held out exactly (its temporal neighbours never see it) and a 4-fold hold-out bounds "
               "the error, but the estimate misses the truth by more than 1 dB on 3 of the 4 runs on the SCI clips "
               "(-1.15 to -1.40 dB; within 0.26 dB on the 8 built-in runs; interval covers 9 of 12, "
               "bench/bench_accuracy.py): the neighbours sit at fixed places in the code's tile, where the next slots' "
               "samples lie far, and their errors correlate only partly (0.46 on Runner), so their error is not the "
               "mean unsampled voxel's; scaling the hold-out's error to the unsampled voxels by the truth's increment "
               "over their distance to their sub-frame's nearest sample (a variogram fitted to the sample pairs) "
               "brings Runner within 0.12 dB and the built-in runs within 0.45 dB but runs 1.08 to 1.37 dB high on "
               "Drop (10 of 12 within 1 dB)"),
}
"""Methods the estimate refuses, with why (the figures: ``bench/bench_accuracy.py``)."""

_SOLVERS_HIGH = ("it never moves a sample and fills between them with the samples held, not by a renormalised "
                 "smoother, for which the probe's take-out is exact, and where samples are few (K = 4) the estimate "
                 "runs high; estimate with solver='nc' (within 0.36 dB on the same runs)")
REFUSED_SOLVERS = {
    "explicit": ("the estimate lies within 1 dB of the truth on 34 of 36 runs on the built-in scenes and the SCI "
                 "clips at K = 16 and 8 (n = 0.5, 1.5 and 4; worst +1.19 dB, at n = 0.5; interval covers 36 of 36) "
                 "but is up to 1.86 dB high at a 2x2 code (K = 4; 6 of 8 within 1 dB; bench/bench_accuracy.py): "
                 + _SOLVERS_HIGH),
    "steady": ("the estimate lies within 1 dB of the truth on 12 of 12 runs on the built-in scenes and the SCI clips "
               "at K = 16 and 8 (worst +0.96 dB; interval covers 12 of 12) but is up to 1.99 dB high at a 2x2 code "
               "(K = 4; 6 of 8 within 1 dB; bench/bench_accuracy.py): " + _SOLVERS_HIGH),
}
"""Diffusion's solvers the estimate refuses (every one but ``nc``), with why."""

REFUSED_MULTIPLEXED = ("the estimate of a demultiplexed capture has not met the acceptance: noiseless balls at 60x80, "
                       "diffusion n = 3, a 1x3 tile within 0.75 dB of the truth but a 3x5 tile 4.1 dB low (14.18 "
                       "against 18.28 dB, the interval 12.80-14.52 dB missing it): demultiplexing spreads a sample's "
                       "error over its tile's slots, which the leave-one-out does not take out; estimate_accuracy("
                       "..., unchecked=True) gives the figure, unchecked")
"""Why a multiplexed capture is not estimated (``unchecked=True`` estimates it anyway, saying so)."""


def refusal(method: Method) -> str | None:
    """Why ``method`` (a :class:`~flexvox_core.methods.Method`) cannot be estimated, or None when it can."""
    why = REFUSED.get(method.name)
    if why is None and method.name == "diffusion" and method.solver != "nc":
        why = REFUSED_SOLVERS.get(method.solver, f"diffusion's {method.solver} solver has not been checked against "
                                                 "the truth")
    if why is None and method.name == "rebin":
        why = accuracy_rebin.refusal(bool(method.interpolate))
    if why is None and method.name not in ("diffusion", "rebin", "gap-tv"):
        why = f"{method.name} has not been checked against the truth"
    return why


class NotEstimable(ValueError):
    """The method, or the recording, cannot be estimated; the message says why. ``runs``: the reconstructions made
    before it was refused (0 when it was refused before any ran).

    Examples
    --------
    >>> import numpy as np
    >>> from flexvox_core import Method, estimate_accuracy
    >>> from flexvox_core.design import design_code
    >>> try:
    ...     estimate_accuracy(np.zeros((2, 24, 24)), design_code((2, 2)).code, Method("motion-aware"))
    ... except NotEstimable as exc:
    ...     print(str(exc)[:73])
    cannot estimate the accuracy of motion-aware dis n=5: even with the first
    """

    runs: int = 0


@dataclass(frozen=True)
class NoiseModel:
    """The measurement noise of one sample: variance ``photon·y + floor`` in relative units (1 = white in one
    slot).

    Parameters
    ----------
    photon : float
        Variance per unit of signal (shot noise: ``1 / electrons_per_unit``).
    floor : float
        Variance at zero signal (read noise, dark current, quantisation).
    source : str
        Where the figures came from.

    Examples
    --------
    >>> nm = NoiseModel.from_effects({"photon_noise": {}, "read_noise": {"sigma": 3.0}})
    >>> round(float(nm.variance(0.5)), 7)  # 0.5/1000 + (3/1000)²
    0.000509
    """

    photon: float = 0.0
    floor: float = 0.0
    source: str = "none given"

    def __post_init__(self) -> None:
        from flexvox_core.numbers import checked_number

        for name in ("photon", "floor"):  # a negative variance had been estimated with (6.5 dB for a 20 dB run)
            checked_number(name, getattr(self, name), "a finite number >= 0 (a variance in relative units)",
                           lambda v: v >= 0)

    def variance(self, y: ArrayLike) -> np.ndarray:
        """The noise variance of samples ``y`` (their own values stand in for the unknown signal)."""
        return self.photon * np.maximum(np.asarray(y, np.float64), 0.0) + self.floor

    @classmethod
    def from_effects(cls, effects: dict[str, Any], storage: dict[str, Any] | None = None, *, rate_hz: float = 15.0,
                     electrons_per_unit: float | None = None) -> NoiseModel:
        """The noise a simulated recording states: its ``effects`` (``{name: {param: value}}``) and ``storage``.

        Shot noise gives ``1/e`` per unit, read noise ``(σ/e)²``, dark current ``rate/(hz·e²)`` with shot noise,
        the ADC ``(1/(gain·e))²/12``, where ``e`` is the electrons per unit (the storage's, else the
        simulator's default 1000, which the source then says is assumed). Each effect's parameters follow the
        simulator's rules (a misspelt name or a value out of its range is refused, not read as the default)."""
        from flexvox_core.simulate.effects import EFFECTS

        if not isinstance(effects, dict) or not all(isinstance(v, dict) for v in effects.values()):
            raise TypeError(f"`effects` must be a dict of {{effect name: {{parameter: value}}}} (a recording's "
                            f"effects); got {effects!r}")
        unknown = sorted(set(effects) - set(EFFECTS))
        if unknown:
            raise ValueError(f"`effects` names {', '.join(map(repr, unknown))}, which the simulator does not have "
                             f"(its effects: {', '.join(EFFECTS)}): a misspelt noise would be read as none")
        for name, params in effects.items():  # the simulator's rules: a misspelt parameter, a value out of range
            EFFECTS[name](**params)
        positive_number("`rate_hz`", rate_hz, unit="frames per second")
        if electrons_per_unit is not None:  # 0 had been read as not stated (the default 1000)
            positive_number("`electrons_per_unit`", electrons_per_unit, unit="electrons")
        storage = storage or {}
        stated = electrons_per_unit or storage.get("electrons_per_unit")
        e = float(stated or 1000.0)
        photon = floor = 0.0
        parts = []
        if "photon_noise" in effects:
            photon = 1.0 / e
            parts.append("shot")
            if "dark_current" in effects:
                floor += float(effects["dark_current"].get("rate", 10.0)) / rate_hz / e**2
        if "read_noise" in effects:
            floor += (float(effects["read_noise"].get("sigma", 3.0)) / e) ** 2
            parts.append("read")
        if "adc" in effects:
            gain = float(effects["adc"].get("gain", storage.get("gain", 0.25)))
            floor += (1.0 / (gain * e)) ** 2 / 12.0
            parts.append("quantisation")
        scale = "" if stated or not parts else " at 1000 electrons per unit (the simulator's default: not stated)"
        return cls(photon, floor, "recording's effects: " + (", ".join(parts) or "noiseless") + scale)


@dataclass(frozen=True)
class AccuracyEstimate:
    """An estimated PSNR of a reconstruction, from the recording alone.

    Attributes
    ----------
    psnr : float
        Estimated PSNR over the clip, dB (data range 1: ``10·log10(1 / MSE)``).
    low, high : float
        The confidence interval, dB.
    per_frame : ndarray (F,)
        Estimated PSNR per camera frame (its K sub-frames); NaN for a dropped frame.
    mse : float
        Estimated mean squared error.
    scheme : str
        How it was made.
    samples : int
        Held-out (probed) samples it rests on.
    noise : NoiseModel
    confidence : float
    runs : int
        Reconstructions the estimate made (a reconstruction given to it is not counted).
    caveat : str or None
        Why the estimate may read high (:func:`spill_caveat`), said in :meth:`line` as "an upper bound: ...";
        None when nothing is known against it.

    Examples
    --------
    >>> from flexvox_core import Method, capture, estimate_accuracy, render_scene
    >>> from flexvox_core.design import design_code
    >>> code = design_code((2, 2)).code
    >>> est = estimate_accuracy(capture(render_scene("balls", 16, 24, 32), code), code, Method("diffusion"))
    >>> est.line().startswith("estimated PSNR")
    True
    """

    psnr: float
    low: float
    high: float
    per_frame: np.ndarray = field(repr=False)
    mse: float
    scheme: str
    samples: int
    noise: NoiseModel
    confidence: float = CONFIDENCE
    runs: int = 0
    caveat: str | None = None

    @property
    def half_width(self) -> float:
        """Half the interval's width, dB."""
        return 0.5 * (self.high - self.low)

    def line(self) -> str:
        """``estimated PSNR NN.NN dB (± W.WW dB, 95 % interval LL.LL–HH.HH dB; scheme, N samples)``, and the
        :attr:`caveat` inside the parentheses where there is one."""
        return (f"estimated PSNR {self.psnr:.2f} dB (± {self.half_width:.2f} dB, {self.confidence:.0%} interval "
                f"{self.low:.2f}–{self.high:.2f} dB; {self.scheme}, {self.samples} samples"
                + (f"; an upper bound: {self.caveat}" if self.caveat else "") + ")")

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form."""
        return {"psnr": self.psnr, "low": self.low, "high": self.high, "mse": self.mse,
                "per_frame": [None if not np.isfinite(p) else float(p) for p in self.per_frame],
                "scheme": self.scheme, "samples": self.samples, "confidence": self.confidence,
                "noise": {"photon": self.noise.photon, "floor": self.noise.floor, "source": self.noise.source},
                "caveat": self.caveat}


def db(mse: float) -> float:
    """PSNR (data range 1) of a mean squared error; 100 dB for an error at or below 1e-10."""
    return 10.0 * math.log10(1.0 / max(mse, 1e-10))


def _z(confidence: float) -> float:
    from statistics import NormalDist

    return NormalDist().inv_cdf(0.5 + confidence / 2)


def estimate_accuracy(frames: ArrayLike, code: ArrayLike | MultiplexedCode, method: Method | str, *,
                      noise: NoiseModel | None = None, missing: ArrayLike | None = None,
                      reconstruction: ArrayLike | None = None, step: int = PROBE_STEP,
                      delta: float = PROBE_DELTA, seed: int = 0,
                      confidence: float = CONFIDENCE, chunk_frames: int | None = None,
                      device: str = "cpu", unchecked: bool = False,
                      progress: bool | Progress | None = None, white: float | None = None,
                      origin: tuple[int, int] | None = None) -> AccuracyEstimate:
    """Estimate the PSNR of ``method``'s reconstruction of a capture without its ground truth.

    Parameters
    ----------
    frames : ndarray (F, H, W)
        The capture: floats in relative units (white = 1; :meth:`Recording.normalised_frames
        <flexvox_core.recording.Recording.normalised_frames>`), or integer counts, divided by the dtype's largest
        value (uint8: 255, uint16: 65535) unless ``white`` gives the white level, as
        :func:`~flexvox_core.methods.run` reads them. The noise model is in the same relative units.
    code : ndarray (m, n, K) or MultiplexedCode
        The capture's code. A multiplexed capture is refused (:data:`REFUSED_MULTIPLEXED`); with ``unchecked``
        it is demultiplexed per tile first (the noise carried through the demultiplexing) and the estimate is of
        the method's reconstruction of that identity capture.
    method : Method or str
    noise : NoiseModel, optional
        The measurement noise; none: taken as zero, so the estimate includes the noise (low when it is not).
    missing : ndarray (F,) bool, optional
        Dropped frames. They hold no samples; their voxels' error is that of captured runs of the same length
        held out as if dropped (one more reconstruction; up to :data:`GAP_BLOCKS` per length), which needs a
        captured run of that length clear of the gaps and the clip's ends, else they are not scored (the
        scheme says so, their per-frame estimate is NaN and the clip's covers the captured frames).
    reconstruction : ndarray (F·K, H, W), optional
        ``method``'s reconstruction of ``frames``, when already made (saves one run).
    step : int
        One probed pixel in ``step × step``.
    delta : float
        How far each probed sample is moved.
    seed : int
        Seeds the probe's signs.
    confidence : float
        Of the interval.
    chunk_frames : int, optional
        Passed to :func:`~flexvox_core.methods.run`.
    device : str
        Where the method runs (:func:`~flexvox_core.methods.run`).
    unchecked : bool
        Estimate a method :func:`refusal` refuses, a multiplexed capture (:data:`REFUSED_MULTIPLEXED`), or a
        method that copies its samples onto their neighbours, all the same (benchmarks that measure how far off it
        is); the scheme then says ``unchecked``.
    progress : bool or callable(done_frames, total_frames), optional
        As :func:`~flexvox_core.methods.run`'s (:mod:`flexvox_core.progress`), over the estimate's
        reconstructions (``total`` counts each run's camera frames, and grows when a run is found needed): a
        callable is called after each chunk of a run and after each run, and an exception it raises stops the
        estimate there (Review's Cancel).
    white : float, optional
        The count that stands for white in integer ``frames`` (a 12-bit camera's: 4095), as
        :func:`~flexvox_core.methods.run`'s.
    origin : (int, int), optional
        For frames cropped from the camera frame: the crop's top-left pixel ``(row, col)`` in the camera frame, as
        :func:`~flexvox_core.methods.run` takes it (the code's phase follows it). Default (0, 0).

    Returns
    -------
    AccuracyEstimate

    Raises
    ------
    NotEstimable
        A method the estimate cannot serve (:func:`refusal`), or a capture too small to probe.
    TypeError
        A recording (its path, a ``Recording``) in ``frames``' place: :func:`estimate_recording` takes it.

    Examples
    --------
    >>> from flexvox_core import Method, capture, render_scene
    >>> from flexvox_core.design import design_code
    >>> code = design_code((2, 2)).code
    >>> truth = render_scene("balls", 16, 24, 32)
    >>> est = estimate_accuracy(capture(truth, code), code, Method("diffusion"))
    >>> est.samples > 0, est.low <= est.psnr <= est.high
    (True, True)
    """
    from flexvox_core.methods.runner import check_counts_within_white, check_origin, code_at_origin
    from flexvox_core.multiplex import MultiplexedCode
    from flexvox_core.reconstruct._common import refuse_recording

    refuse_recording(frames, "fv.estimate_accuracy", "fv.estimate_recording(recording, method)")
    if check_origin(origin) != (0, 0):
        if isinstance(code, MultiplexedCode):
            raise ValueError(f"`origin` {origin!r} with a multiplexed code: estimate on the whole camera frame, or on "
                             "a crop on its tile grid")
        code = code_at_origin(code, origin)
    counts, frames = frames, as_relative(frames, white=white)
    check_counts_within_white(counts, frames, white, code)
    with progress_callback(progress, desc="accuracy estimate", unit="frame") as report:
        return _estimate(frames, code, method, noise=noise, missing=missing, reconstruction=reconstruction,
                         step=step, delta=delta, seed=seed, confidence=confidence, chunk_frames=chunk_frames,
                         device=device, unchecked=unchecked, report=report)


def _estimate(frames: ArrayLike, code: ArrayLike | MultiplexedCode, method: Method | str, *,
              noise: NoiseModel | None, missing: ArrayLike | None, reconstruction: ArrayLike | None, step: int,
              delta: float, seed: int, confidence: float, chunk_frames: int | None, device: str, unchecked: bool,
              report: Progress | None) -> AccuracyEstimate:
    """:func:`estimate_accuracy`, its progress a callback or None."""
    from flexvox_core.methods.runner import as_method
    from flexvox_core.multiplex import MultiplexedCode

    method = as_method(method)  # a method's name too; anything else a TypeError naming fv.Method
    if noise is not None and not isinstance(noise, NoiseModel):
        raise TypeError(f"`noise` must be a NoiseModel (NoiseModel(photon=..., floor=...), or "
                        f"NoiseModel.from_effects({{'read_noise': {{'sigma': 3.0}}}})); got {noise!r}")
    why = refusal(method)
    if why and not unchecked:
        raise NotEstimable(f"cannot estimate the accuracy of {method.label}: {why}")
    noise = noise or NoiseModel()
    frames = np.asarray(frames)
    scheme = "leave-one-out by probe" + (", unchecked" if unchecked else "")
    variance_map = None
    if isinstance(code, MultiplexedCode) or not is_identity_code(validate_code(getattr(code, "code", code))):
        if not unchecked:
            raise NotEstimable(f"cannot estimate the accuracy of {method.label} on a multiplexed capture: "
                               f"{REFUSED_MULTIPLEXED}")
        frames, code, variance_map = _demultiplexed(frames, code, noise)
        scheme += ", multiplexed capture demultiplexed per tile"
        reconstruction = None
    code = validate_code(code)
    if frames.ndim != 3:
        raise ValueError(f"`frames` must have shape (F, H, W); got {frames.shape}")
    F, H, W = frames.shape
    K = code.shape[2]
    S = F * K
    probe_lattice(0, 0, step)  # `step` checked before anything runs (a whole number >= 1)
    if min(H, W) < 3 * step or F < 1:
        raise NotEstimable(f"a capture of {F}x{H}x{W} is too small to probe one pixel in {step}x{step} "
                           f"(needs {3 * step} pixels a side)")
    if not 0 < confidence < 1:
        raise ValueError(f"`confidence` must lie in (0, 1); got {confidence}")
    checked = as_missing(missing, F)  # the shape and the rule, in words
    dropped = np.zeros(F, bool) if checked is None else checked
    gaps = checked
    f32 = frames.astype(np.float32)
    if method.name == "rebin" and not (unchecked and dropped.any()):
        return _rebin_closed_form(f32, code, method, dropped, variance_map, noise, confidence, scheme, reconstruction,
                                  unchecked)
    steps = Steps(report, F, int(reconstruction is None) + 1 + int(dropped.any()))
    try:
        run_method = _runs(f32, code, method, gaps, chunk_frames, device, steps)
        if reconstruction is None:
            reconstruction = run_method(f32)
            steps.finished()
        elif isinstance(run_method, HeldRuns):
            run_method.flow_only(f32)  # the flow the given reconstruction was made with, held for the probe
        v0 = np.asarray(reconstruction, np.float32)  # read in float64 where used (the probe's columns)
        if v0.shape != (S, H, W):
            raise ValueError(f"`reconstruction` must have shape {(S, H, W)}; got {v0.shape}")
        # alternate frames probe lattices offset by half a step: a pixel is probed every other frame
        lattices = [probe_lattice(H, W, step, shift) for shift in (0, step // 2)]
        rng = np.random.default_rng(seed)
        signs = rng.choice(np.array([-1.0, 1.0]), size=(F, H, W)) * np.stack([lattices[f % 2] for f in range(F)])
        signs[dropped] = 0.0
        probed = f32 + np.float32(delta) * signs.astype(np.float32)
        v1 = np.asarray(run_method(probed), np.float32)
        steps.finished()
        probe = _Probe(v0, v1, frames, dropped, np.argmax(tiled_code(code, H, W), axis=0), K, delta)
        rows: list[np.ndarray] = []  # per probed sample: frame, cluster, MSE bounds, voxels, response, copied
        for f in range(F):
            if dropped[f]:
                continue
            ys, xs = np.nonzero(lattices[f % 2])
            var = variance_map[f, ys, xs] if variance_map is not None else noise.variance(frames[f, ys, xs])
            cl = (ys // (step * CLUSTER)) * (W // (step * CLUSTER) + 1) + xs // (step * CLUSTER)
            rows.append(probe.frame_rows(f, ys, xs, signs[f, ys, xs], var, cl))
        arr = np.concatenate(rows, axis=0) if rows else np.zeros((0, 8))
        if arr.shape[0] < 8:
            raise NotEstimable(f"only {arr.shape[0]} probed samples could be held out (too few frames or pixels)")
        fr, clus, mlo, mhi, w, pull, copied, mop = arr.T
        _logger.debug("%s: %.1f %% of the probed samples copied onto a neighbour", method.label, 100 * np.mean(copied))
        if np.mean(copied) > MAX_COPIED and not unchecked:
            raise NotEstimable(f"cannot estimate the accuracy of {method.label}: it copies {np.mean(copied):.0%} of "
                               f"the probed samples onto a temporal neighbour (response >= {COPIED}; at most "
                               f"{MAX_COPIED:.0%} can be taken out), so what it predicts without them is not known (a "
                               "nearest-sample fill, as nc's at short diffusion times)")
        samples = int(arr.shape[0])
        if np.mean(pull) < INDEPENDENT:
            # The temporal neighbours do not respond to the sample (each sub-frame is reconstructed from its own
            # samples, as GAP-TV's 2-D TV does): every sample is held out exactly (flexvox_core.accuracy_folds).
            m_opt = None
            mse, m_hi, se, per_frame, samples, how = _independent(v0, v1, f32, code, method, dropped, signs, delta,
                                                                    variance_map, noise, steps)
            scheme = scheme.replace("leave-one-out by probe", how)
        else:
            sum_w = float(np.sum(w))
            m_lo, m_hi = float(np.sum(mlo) / sum_w), float(np.sum(mhi) / sum_w)
            mse = m_lo  # the estimate: errors uncorrelated with the truth's change; the other bound is the worst case
            m_opt = float(np.sum(mop) / sum_w)  # the best case the data allow
            se = _cluster_se(fr * 1e6 + clus, mlo, w)
            per_frame = np.full(F, np.nan)
            for f in np.unique(fr).astype(int):
                sel = fr == f
                per_frame[f] = db(float(np.sum(mlo[sel]) / np.sum(w[sel])))
        z = _z(confidence)
        if dropped.any():
            held_out = _gap_errors(f32, code, method, dropped, variance_map, noise, chunk_frames, device, steps)
            if held_out is None:
                scheme += ", dropped frames not scored (no captured run long enough to hold out like them)"
            else:
                # Voxels of dropped frames hold no sample: their error is that of captured frames held out the same way.
                share = float(np.mean(dropped))
                gap_mse = sum(held_out[g.frames][0] * g.frames for g in find_gaps(dropped)) / max(int(dropped.sum()), 1)
                gap_var = sum((held_out[g.frames][1] * g.frames) ** 2 for g in find_gaps(dropped)) / max(
                    int(dropped.sum()), 1) ** 2
                for g in find_gaps(dropped):
                    per_frame[g.start:g.stop] = db(held_out[g.frames][0])
                mse = (1 - share) * mse + share * gap_mse
                m_hi = (1 - share) * m_hi + share * gap_mse
                m_opt = None if m_opt is None else (1 - share) * m_opt + share * gap_mse
                se = math.sqrt(((1 - share) * se) ** 2 + share**2 * gap_var)
                scheme += ", dropped frames scored by captured runs held out like them"
        if not mse > 1e-10 and noise.photon == 0 and noise.floor == 0:  # no noise taken out: nothing to measure
            raise NotEstimable(
                f"the held-out samples are predicted exactly (their error is {mse:.3g}, and no noise is stated): a "
                "capture without change, or a code whose every voxel holds its own sample, leaves the estimate no "
                "error to measure, so it gives no PSNR")
        if not mse > 1e-10:  # db() would say 100 dB: the noise taken out exceeds the error the samples show
            raise NotEstimable(
                f"the held-out samples' error less the noise the capture states (photon {noise.photon:g}, floor "
                f"{noise.floor:g}: {noise.source}) is {mse:.3g}, not above zero: the stated noise is larger than the "
                "samples' own error; estimate with the noise measured on this camera, or with none (the estimate then "
                "includes the noise)")
        lo_mse = mse - z * se if m_opt is None else min(mse - z * se, m_opt)  # up to the optimistic bound
        hi_mse = max(m_hi, mse + z * se)  # down to the pessimistic bound
        est = AccuracyEstimate(psnr=db(mse), low=db(hi_mse), high=db(max(lo_mse, 1e-10)), per_frame=per_frame,
                               mse=max(mse, 0.0), scheme=scheme, samples=samples, noise=noise,
                               confidence=confidence, runs=steps.done)
        _logger.info("%s: %s", method.label, est.line())
        return est
    except NotEstimable as exc:  # refused after some runs: say how many (fv.choose counts them)
        exc.runs = steps.done
        raise


def probe_lattice(H: int, W: int, step: int, shift: int = 0) -> np.ndarray:
    """The probed pixels (H, W) bool: one in ``step × step``, sheared so that they land on every place of a code's
    tile. Cell ``(i, j)`` probes row ``1 + shift + step·i + (j mod step)`` and column ``1 + shift + step·j +
    (i mod step)`` (the border rows and columns left out): a lattice of step ``step`` would land on one place of a
    tile whose sides divide it, and the estimate would rest on that place's neighbours alone (on the 16 origins of
    such a lattice, diffusion's estimate ranged from 1.4 dB low to 3.9 dB high). Neighbouring probed pixels lie
    about ``step`` pixels apart, a few diagonal neighbours where the shear wraps (their random signs keep their
    pulls on each other out of the mean); for a step of 4 or more the lattices of ``shift`` 0 and ``step // 2``
    (alternate frames) share no pixel.

    Raises
    ------
    ValueError
        ``step`` not a whole number >= 1, or ``shift`` not a whole number >= 0, or ``H``, ``W`` negative.
    """
    for name, value, least in (("step", step, 1), ("shift", shift, 0), ("H", H, 0), ("W", W, 0)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise ValueError(f"`{name}` must be a whole number >= {least}; got {value!r}")
    lat = np.zeros((H, W), bool)
    ii, jj = np.mgrid[0:H // step + 1, 0:W // step + 1]
    yy = 1 + shift + step * ii + jj % step
    xx = 1 + shift + step * jj + ii % step
    ok = (yy < H - 1) & (xx < W - 1)
    lat[yy[ok], xx[ok]] = True
    return lat


def _largest_covariance(loo: np.ndarray, e: np.ndarray) -> np.ndarray:
    """The largest ``C`` (``≥ 0``) the data allow, of the covariance of a voxel's leave-one-out error (mean square
    ``L``) with the truth's change from the sample (mean square ``V``), given ``e = V + 2C``: Cauchy-Schwarz,
    ``C² ≤ L·V = L·(e − 2C)``, so ``C ≤ −L + √(L² + L·e)``, and ``V ≥ 0`` gives ``C ≤ e/2``."""
    lp = np.maximum(loo, 0.0)
    disc = lp * lp + lp * e
    bound = np.minimum(np.maximum(e, 0.0) / 2.0, -lp + np.sqrt(np.maximum(disc, 0.0)))
    out: np.ndarray = np.where(disc > 0, np.maximum(bound, 0.0), 0.0)
    return out


def _cluster_se(keys: np.ndarray, values: np.ndarray, weights: np.ndarray) -> float:
    """The standard error of the weighted mean of ``values`` from the spread of its clusters' means (``keys``)."""
    groups = np.unique(keys)
    if groups.size < 2:
        return 0.0
    total = float(np.sum(weights))
    sums = np.array([[values[keys == g].sum(), weights[keys == g].sum()] for g in groups])
    means = sums[:, 0] / sums[:, 1]
    share = sums[:, 1] / total
    centre = float(np.sum(share * means))
    return math.sqrt(np.sum(share**2 * (means - centre) ** 2) * groups.size / (groups.size - 1))


def _independent(v0: np.ndarray, v1: np.ndarray, frames: np.ndarray, code: np.ndarray, method: Method,
                 dropped: np.ndarray, signs: np.ndarray, delta: float, variance_map: np.ndarray | None,
                 noise: NoiseModel, steps: Steps) -> tuple[float, float, float, np.ndarray, int, str]:
    """(MSE, pessimistic MSE, standard error, per-frame PSNR, samples, scheme) of a method whose sub-frames are
    reconstructed apart (:mod:`flexvox_core.accuracy_folds`)."""
    F, H, W = frames.shape
    K = code.shape[2]
    variance = variance_map if variance_map is not None else noise.variance(frames)
    t0 = np.arange(F)[:, None, None] * K + np.argmax(tiled_code(code, H, W), axis=0)[None]
    fi, yi, xi = np.nonzero(signs)
    tt = t0[fi, yi, xi]
    a_self = float(np.mean(signs[fi, yi, xi] * (v1[tt, yi, xi].astype(np.float64) - v0[tt, yi, xi]) / delta))
    rows = independent_rows(v0, frames, code, dropped, variance, float(np.clip(a_self, 0.0, 1.0)))
    if rows.shape[0] < 8:
        raise NotEstimable(f"only {rows.shape[0]} samples could be held out (too few frames or pixels)")
    fr, clus, vals, loo = rows.T
    ones = np.ones(vals.size)
    mse = float(np.mean(vals))
    masked = masked_run(method)
    if masked is not None:
        steps.more(FOLDS)
        held = held_out_error(frames, code, masked, dropped, variance, between=steps.finished)
        m_hi = mse + (K - 1) / K * (held - float(np.mean(loo)))
        how = (f"exact leave-one-out of every sample by its temporal neighbours (sub-frames independent), "
               f"interval to a {FOLDS}-fold hold-out")
    else:
        m_hi = mse + (K - 1) / K * float(np.mean(loo))  # the neighbours' errors independent: twice L
        how = "exact leave-one-out of every sample by its temporal neighbours (sub-frames independent)"
    per_frame = np.full(F, np.nan)
    for f in np.unique(fr).astype(int):
        per_frame[f] = db(float(np.mean(vals[fr == f])))
    return mse, max(m_hi, mse), _cluster_se(fr * 1e6 + clus, vals, ones), per_frame, int(vals.size), how


def _rebin_closed_form(frames: np.ndarray, code: np.ndarray, method: Method, dropped: np.ndarray,
                       variance_map: np.ndarray | None, noise: NoiseModel, confidence: float, scheme: str,
                       reconstruction: ArrayLike | None, unchecked: bool) -> AccuracyEstimate:
    """Interpolated re-binning's estimate in closed form, no run (:mod:`flexvox_core.accuracy_rebin`); checked at
    the code's default division only (another is refused unless ``unchecked``)."""
    from flexvox_core.reconstruct.rebin import default_block

    F, H, W = frames.shape
    K = code.shape[2]
    if dropped.any():
        raise NotEstimable(f"cannot estimate the accuracy of {method.label}: {accuracy_rebin.DROPPED}")
    if reconstruction is not None and np.shape(reconstruction) != (F * K, H, W):
        raise ValueError(f"`reconstruction` must have shape {(F * K, H, W)}; got {np.shape(reconstruction)}")
    division = method.block or default_block(code)
    if division != default_block(code) and not unchecked:
        raise NotEstimable(f"cannot estimate the accuracy of {method.label}: {accuracy_rebin.OTHER_DIVISIONS}")
    variance = variance_map if variance_map is not None else noise.variance(frames)
    try:
        r = accuracy_rebin.rebin_error(frames.astype(np.float64), code, division, variance,
                                       interpolate=bool(method.interpolate), z=_z(confidence))
    except accuracy_rebin.TooFewLags as exc:  # a division of 1x1 or 1-slot blocks: its lags are never spanned
        at = "" if method.block else f" (its default division {division.label})"
        raise NotEstimable(f"cannot estimate the accuracy of {method.label}{at}: {exc}") from None
    if not r.mse > 1e-10:
        raise NotEstimable(f"the error the samples' increments show less the noise the capture states (photon "
                           f"{noise.photon:g}, floor {noise.floor:g}: {noise.source}) is {r.mse:.3g}, not above zero: "
                           "the stated noise is larger than the samples' own error")
    how = (f"closed form: re-binning's weights and the samples' increments, a variogram (beta {r.beta:.2f}) for the "
           f"lags no pair spans ({r.unspanned:.0%} of the error)")
    per_frame = np.array([db(m) if np.isfinite(m) else np.nan for m in r.per_frame])
    est = AccuracyEstimate(psnr=db(r.mse), low=db(r.high), high=db(max(r.low, 1e-10)), per_frame=per_frame,
                           mse=r.mse, scheme=scheme.replace("leave-one-out by probe", how), samples=r.samples,
                           noise=noise, confidence=confidence, runs=0)
    _logger.info("%s: %s", method.label, est.line())
    return est


def _runs(frames: np.ndarray, code: np.ndarray, method: Method, missing: np.ndarray | None,
          chunk_frames: int | None, device: str, steps: Steps) -> Run:
    """How ``method`` is run on the capture and its probe: with the first run's flow held for motion-aware
    (:class:`~flexvox_core.accuracy_runs.HeldRuns`), else through :func:`~flexvox_core.methods.run` (its
    progress the estimate's, ``steps``)."""
    if holds_flow(method):
        return HeldRuns(frames, code, method, missing=missing, device=device)

    def plain(f: np.ndarray) -> np.ndarray:
        from flexvox_core.methods import run

        return np.asarray(run(f, code, method, chunk_frames=chunk_frames, missing=missing, device=device,
                              progress=steps.during()).video)

    return plain


def _gap_errors(frames: np.ndarray, code: np.ndarray, method: Method, dropped: np.ndarray,
                variance_map: np.ndarray | None, noise: NoiseModel, chunk_frames: int | None,
                device: str, steps: Steps) -> dict[int, tuple[float, float]] | None:
    """{gap length: (MSE, its standard error)} of captured runs of that length held out as if dropped (one more
    reconstruction), or None when no captured run can be held out without touching a gap or the clip's ends."""
    from flexvox_core.methods import run

    F = frames.shape[0]
    K = code.shape[2]
    held = np.zeros(F, bool)
    blocks: list[tuple[int, int]] = []
    for g in sorted({gap.frames for gap in find_gaps(dropped)}):
        found = 0
        f = 1
        while f + g < F and found < GAP_BLOCKS:
            # the run, and one captured frame on each side, clear of every gap and held run
            if not (dropped[f - 1:f + g + 1].any() or held[max(0, f - 2):f + g + 2].any()):
                held[f:f + g] = True
                blocks.append((f, g))
                found += 1
                f += g + 2
            else:
                f += 1
        if not found:
            steps.more(-1)  # the run planned for the gaps is not made
            return None
    v = run(frames, code, method, chunk_frames=chunk_frames, missing=dropped | held, device=device,
            progress=steps.during()).video
    steps.finished()
    _, H, W = frames.shape
    slot = np.argmax(tiled_code(code, H, W), axis=0)
    yy, xx = np.mgrid[0:H, 0:W]
    out: dict[int, list[float]] = {}
    for f0, g in blocks:
        for f in range(f0, f0 + g):
            y = frames[f].astype(np.float64)
            s2 = variance_map[f] if variance_map is not None else noise.variance(y)
            pred = v[f * K + slot, yy, xx].astype(np.float64)
            out.setdefault(g, []).append(float(np.mean((pred - y) ** 2 - s2)))
    result = {}
    for g, errs in out.items():
        e = np.asarray(errs)
        se = float(np.std(e, ddof=1) / math.sqrt(e.size)) if e.size > 1 else float(e[0])
        result[g] = (max(float(np.mean(e)), 1e-10), se)
    return result


class _Probe:
    """The two runs (``v0`` the reconstruction, ``v1`` the probed one) read along probed pixels' columns."""

    def __init__(self, v0: np.ndarray, v1: np.ndarray, frames: np.ndarray, dropped: np.ndarray, slot: np.ndarray,
                 K: int, delta: float):
        self.v0, self.v1, self.frames, self.dropped, self.slot = v0, v1, frames, dropped, slot
        self.K, self.delta, self.S = K, delta, v0.shape[0]

    def removed(self, t: np.ndarray, ys: np.ndarray, xs: np.ndarray, y: np.ndarray, b: np.ndarray
                ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """At voxels ``(t, ys, xs)``: the value without the sample ``y`` (moved by ``b·delta`` in the probe), the
        voxels' response to it, and their value with it."""
        tc = np.clip(t, 0, self.S - 1)
        u0, u1 = self.v0[tc, ys, xs].astype(np.float64), self.v1[tc, ys, xs].astype(np.float64)
        a = b * (u1 - u0) / self.delta
        ac = np.clip(a, 0.0, 0.9)
        return (u0 - ac * y) / (1.0 - ac), a, u0

    def usable(self, t: np.ndarray) -> np.ndarray:
        """Voxels inside the clip and outside dropped frames."""
        ok: np.ndarray = (t >= 0) & (t < self.S) & ~self.dropped[np.clip(t, 0, self.S - 1) // self.K]
        return ok

    def frame_rows(self, f: int, ys: np.ndarray, xs: np.ndarray, b: np.ndarray, s2: np.ndarray,
                   cluster: np.ndarray) -> np.ndarray:
        """Rows (frame, cluster, MSE with C_d = 0, MSE no better than held out, voxels, response of the two
        temporal neighbours, copied, MSE with C_d at its Cauchy-Schwarz bound) of frame ``f``'s probed samples."""
        K = self.K
        t0 = f * K + self.slot[ys, xs]
        y = self.frames[f, ys, xs].astype(np.float64)
        inside = self.usable(t0 - 1) & self.usable(t0 + 1)
        before, a_before, _ = self.removed(t0 - 1, ys, xs, y, b)
        after, a_after, _ = self.removed(t0 + 1, ys, xs, y, b)
        loo = (0.5 * (before + after) - y) ** 2 - s2  # the held-out sample's error, its noise taken out
        _, a_self, v_self = self.removed(t0, ys, xs, y, b)
        sampled = (v_self - y) ** 2 - s2 + 2.0 * np.clip(a_self, 0.0, 1.0) * s2  # SURE at the sample's voxel
        lo = np.zeros(ys.size)
        hi = np.zeros(ys.size)
        count = np.zeros(ys.size)
        op = np.zeros(ys.size)
        for d in range(-(K // 2), K - K // 2):  # the voxels of the pixel's column nearest to this sample
            ok = self.usable(t0 + d)
            if d == 0:
                lo_d = hi_d = op_d = sampled
            else:
                vm, a, _ = self.removed(t0 + d, ys, xs, y, b)
                a = np.clip(a, 0.0, 0.9)
                e_d = (vm - y) ** 2 - s2 - loo  # = V_d + 2 C_d
                lo_d = (1 - a) ** 2 * loo + a**2 * (s2 + e_d)  # C_d = 0: the sample's pull counted in full
                hi_d = loo  # the voxel no better than one that lost its sample
                op_d = lo_d - 2.0 * a * _largest_covariance(loo, e_d)  # C_d at its Cauchy-Schwarz bound
            lo += np.where(ok, lo_d, 0.0)
            hi += np.where(ok, hi_d, 0.0)
            op += np.where(ok, op_d, 0.0)
            count += ok
        keep = inside & (count > 0)
        copied = np.maximum(a_before, a_after) >= COPIED  # a neighbour that takes the sample's value: no way back
        out = np.stack([np.full(ys.size, f, np.float64), cluster, lo, hi, count, a_before + a_after, copied, op],
                       axis=1)
        kept: np.ndarray = out[keep]
        return kept


def _demultiplexed(frames: ArrayLike, code: object, noise: NoiseModel) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(identity frames, identity code, per-sample noise variance) of a multiplexed capture."""
    from flexvox_core.multiplex import MultiplexedCode, demultiplex

    if not isinstance(code, MultiplexedCode):
        raise NotEstimable("a multiplexed capture needs its MultiplexedCode (the S-matrix and placement) to be "
                           "estimated")
    f64 = np.asarray(frames, np.float64)
    out = demultiplex(f64, code)
    m, n = code.tile
    K = m * n
    F, H, W = f64.shape
    Hp, Wp = -(-H // m) * m, -(-W // n) * n
    var = noise.variance(np.pad(f64, ((0, 0), (0, Hp - H), (0, Wp - W)),
                                mode="symmetric"))
    tiles = var.reshape(F, Hp // m, m, Wp // n, n).transpose(0, 1, 3, 2, 4).reshape(F, Hp // m, Wp // n, K)
    slots = tiles @ (np.asarray(code.demux, np.float64) ** 2).T  # independent samples: variances add, squared
    placed = slots[..., code.placement.ravel()]
    v = placed.reshape(F, Hp // m, Wp // n, m, n).transpose(0, 1, 3, 2, 4).reshape(F, Hp, Wp)[:, :H, :W]
    from flexvox_core.codes import code_from_order

    return out, code_from_order(code.placement), v


def noise_of(recording: Recording) -> NoiseModel:
    """The noise a recording states (a simulated one's effects; a captured one states none: zero)."""
    attrs = recording.attrs
    effects = attrs.get("effects") or {}
    if not effects:
        return NoiseModel(source="the recording states no noise")
    rate = float((attrs.get("rates") or {}).get("camera_hz", 15.0))
    return NoiseModel.from_effects(effects, attrs.get("storage"), rate_hz=rate)


def estimate_recording(recording: str | os.PathLike[str] | Recording, method: Method, *,
                       noise: NoiseModel | None = None, reconstruction: ArrayLike | None = None,
                       **options: Any) -> AccuracyEstimate:
    """:func:`estimate_accuracy` of a recording (a path or an open :class:`~flexvox_core.recording.Recording`):
    its normalised frames, its code (a multiplexed one demultiplexed), its dropped frames and the noise it states
    (:func:`noise_of`, unless ``noise`` is given). Its ground truth, if any, is never read.

    Other keywords go to :func:`estimate_accuracy`.

    Examples
    --------
    >>> from flexvox_core import Method, render_scene, simulate_video, write_simulation
    >>> from flexvox_core.design import design_code
    >>> sim = simulate_video(render_scene("balls", 16, 24, 32), design_code((2, 2)).code)
    >>> import pathlib, tempfile
    >>> path = write_simulation(pathlib.Path(tempfile.mkdtemp()) / "rec.zarr", sim)
    >>> estimate_recording(path, Method("diffusion")).samples > 0
    True
    """
    from flexvox_core.capture_reader import open_capture

    reader = open_capture(recording)
    rec = reader.recording
    frames = rec.normalised_frames()
    code = reader.multiplexed if reader.multiplexed is not None else reader.code
    est = estimate_accuracy(frames, code, method, noise=noise or noise_of(rec), missing=reader.missing,
                            reconstruction=reconstruction if reader.multiplexed is None else None, **options)
    caveat = spill_caveat(rec.attrs)
    if caveat is not None:
        _logger.info("%s: %s", rec.path, caveat)
        est = dataclasses.replace(est, caveat=caveat)
    return est


SPILL_EFFECTS = ("pattern_blur", "misregistration")
"""Effects that carry a slot's light onto neighbouring pixels: the leave-one-out probe's neighbours then hold some of
the held-out sample's light, and the estimate reads high (docs/reconstruction.md, "Accuracy without ground truth")."""


def spill_caveat(attrs: dict[str, Any]) -> str | None:
    """Why an estimate of the recording with attributes ``attrs`` may read high, or None: it states an effect of
    :data:`SPILL_EFFECTS`, or it was captured on a rig (whose projector blurs and registers its code to within the
    calibration's error). Measured: drummer 48×64, 4×4 code, nc: +2.6 dB with pattern blur's defaults and +2.0 dB
    with misregistration's, the truth below the interval (+0.7 dB and inside it with neither); the mock rig's
    calibrated captures +1.6 to +2.4 dB (bench/bench_accuracy.py does not yet cover either)."""
    if not isinstance(attrs, dict):
        raise TypeError(f"`attrs` must be a recording's attribute dict (`recording.attrs`); got {type(attrs).__name__}")
    stated = [name for name in SPILL_EFFECTS if name in (attrs.get("effects") or {})]
    if stated:
        why = f"the recording states {' and '.join(stated)}"
    elif attrs.get("kind") == "captured":
        why = "a rig's projector blurs its code onto neighbouring pixels"
    else:
        return None
    return (f"{why}, so a slot's light spills onto the pixels that predict its sample and the estimate reads high "
            "(1.6 to 2.6 dB where measured, the truth below the interval)")
