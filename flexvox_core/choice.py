"""Choosing a method's knob by the estimated accuracy: the setting whose estimated PSNR is best.

:func:`choose` reconstructs a capture at each candidate value of one knob (diffusion's or motion-aware's
time ``n``, re-binning's division), estimates each result's PSNR from the capture alone
(:func:`flexvox_core.accuracy.estimate_accuracy`: no ground truth) and keeps the best. The estimator is asked
only through its public entry and :func:`~flexvox_core.accuracy.refusal`, so whatever it offers is choosable:
a knob of a method it refuses is refused with its reason (:class:`~flexvox_core.accuracy.NotEstimable`).

**Cost.** Each candidate's reconstruction is handed to the estimate (no run is wasted), which adds its own
probe run (and one for dropped frames): ``k`` candidates cost ``k × (1 + 1)`` reconstructions and the
estimates' bookkeeping; the chosen reconstruction is kept (:attr:`Choice.output`), so using it costs nothing
more. A multiplexed capture is estimated on its demultiplexed capture, so there the reconstructions are the
estimator's own and the chosen one is made again by the caller.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from flexvox_core.accuracy import AccuracyEstimate, NoiseModel, NotEstimable, refusal
from flexvox_core.gaps import as_missing
from flexvox_core.intensity import as_relative

if TYPE_CHECKING:
    import os

    from flexvox_core.methods import Method
    from flexvox_core.multiplex import MultiplexedCode
    from flexvox_core.progress import Progress
    from flexvox_core.recording import Recording

_logger = logging.getLogger(__name__)

TIMES = (1.5, 2.0, 3.0, 4.0, 6.0)
"""The diffusion times ``n`` tried for diffusion's ``time``: from the default 1.5 up to 6, the range over which
nc's accuracy turns from the sample's neighbourhood to the blur (times at or below 1 fill from the nearest sample,
which the estimate cannot score)."""

MOTION_TIMES = (1.5, 3.0, 5.0, 8.0, 12.0)
"""The times tried for motion-aware's ``time``: around its default 5 (on the four built-in moving scenes, noisy,
64×96, the truth's best lay at 1.5 to 12 and the spread over these was at most 0.3 dB)."""

AUTO_KNOBS: dict[str, tuple[str, ...]] = {"diffusion": ("time",), "motion-aware": ("time",), "rebin": ("block",)}
"""The knobs with default candidates (:func:`candidates_for`), by method: what ``auto`` can stand for."""


@dataclass(frozen=True)
class Candidate:
    """One tried value of the knob: its method, its estimate (None: not estimable, ``why`` says why), the seconds
    its reconstruction and estimate took together, the reconstructions they made (0: refused before any) and the
    seconds of its own reconstruction (0 where the estimate made it)."""

    value: Any
    method: Method
    estimate: AccuracyEstimate | None
    seconds: float
    why: str | None = None
    runs: int = 0
    run_seconds: float = 0.0

    def line(self) -> str:
        """``<method>: estimated PSNR NN.NN dB (± ...) in S.SS s``, or why there is no estimate."""
        if self.estimate is None:
            return f"{self.method.label}: estimated PSNR: none ({self.why}) in {self.seconds:.2f} s"
        return f"{self.method.label}: {self.estimate.line()} in {self.seconds:.2f} s"


@dataclass(frozen=True, repr=False)
class Choice:
    """The chosen value of a knob, every candidate's estimate, and what choosing cost.

    Attributes
    ----------
    knob : str
        The option chosen (``time``, ``block``).
    value : object
        The chosen value: the candidate with the best estimated PSNR (the first among equals).
    method : Method
        The method with the chosen value.
    estimate : AccuracyEstimate
        The chosen reconstruction's estimate.
    candidates : tuple of Candidate
        Every candidate, in the order tried; the refused ones keep their reason.
    seconds : float
        What choosing took: every candidate's reconstruction and estimate.
    runs : int
        Reconstructions made (each candidate's, and the estimate's probe and dropped-frame runs).
    output : MethodOutput or None
        The chosen reconstruction (:func:`~flexvox_core.methods.run`'s result), made while choosing; None where it
        could not be kept (a multiplexed capture, or ``keep_video=False``): reconstruct ``method`` then.

    Examples
    --------
    >>> from flexvox_core import capture, render_scene
    >>> from flexvox_core.design import design_code
    >>> code = design_code((2, 2)).code
    >>> choice = choose(capture(render_scene("balls", 16, 24, 32), code), code, "diffusion", "time", (1.5, 4.0))
    >>> choice.value in (1.5, 4.0), len(choice.candidates), choice.runs
    (True, 2, 4)
    """

    knob: str
    value: Any
    method: Method
    estimate: AccuracyEstimate
    candidates: tuple[Candidate, ...]
    seconds: float
    runs: int
    output: Any = field(default=None, compare=False)

    @property
    def video(self) -> np.ndarray | None:
        """The chosen reconstruction's video (:attr:`output`), or None."""
        return None if self.output is None else np.asarray(self.output.video)

    def __repr__(self) -> str:
        return (f"<Choice {self.method.name} {self.knob} = {_shown(self.value)} of {len(self.candidates)} "
                f"candidates: estimated PSNR {self.estimate.psnr:.2f} dB, {self.runs} reconstructions in "
                f"{self.seconds:.2f} s>")

    @property
    def rivals(self) -> tuple[Candidate, ...]:
        """The other candidates whose estimate lies inside the chosen one's interval: the data do not tell them
        apart from the choice."""
        chosen = self.estimate
        return tuple(c for c in self.candidates if c.estimate is not None and c.value != self.value
                     and chosen.low <= c.estimate.psnr <= chosen.high)

    def cost(self) -> str:
        """What choosing cost, in words: candidates, reconstructions, seconds."""
        k = sum(c.runs > 0 for c in self.candidates)
        return (f"choosing cost {self.seconds:.2f} s: {k} candidate{'' if k == 1 else 's'} x (a reconstruction and its "
                f"estimate's probe), "
                f"{self.runs} reconstructions in all")

    def lines(self) -> list[str]:
        """What a front end prints: the choice, each candidate's line, the cost."""
        head = (f"chose {self.knob} {_shown(self.value)} for {self.method.name} by the estimated PSNR "
                f"({self.estimate.psnr:.2f} dB)")
        if self.rivals:
            head += f"; within its interval: {', '.join(_shown(c.value) for c in self.rivals)}"
        return [head, *(f"  {c.line()}" for c in self.candidates), self.cost()]


def _shown(value: Any) -> str:
    label = getattr(value, "label", None)
    if isinstance(label, str):
        return label
    return f"{value:g}" if isinstance(value, float) else str(value)


def candidates_for(method: Method | str, knob: str, code: ArrayLike | MultiplexedCode) -> tuple[Any, ...]:
    """The values :func:`choose` tries for ``knob`` by default.

    ``time``: :data:`TIMES` for diffusion, :data:`MOTION_TIMES` for motion-aware; ``block`` of re-binning: every
    division ``code``
    supports (:func:`~flexvox_core.reconstruct.rebin.supported_divisions`; a multiplexed code's by its placement).

    Raises
    ------
    ValueError
        ``method`` has no option ``knob``, or no default candidates for it (:data:`AUTO_KNOBS`).
    """
    from flexvox_core.methods.runner import as_method

    method = as_method(method)
    if not method.spec.has_option(knob):
        raise ValueError(f"{method.name} has no option {knob!r} (its options: {method.spec.option_list()})")
    if knob not in AUTO_KNOBS.get(method.name, ()):
        offered = "; ".join(f"{m}: {', '.join(k)}" for m, k in AUTO_KNOBS.items())
        raise ValueError(f"{method.name}'s {knob} has no default candidates (they exist for {offered}); give "
                         "`candidates`")
    if knob == "time":
        return MOTION_TIMES if method.name == "motion-aware" else TIMES
    from flexvox_core.codes import code_from_order
    from flexvox_core.multiplex import MultiplexedCode
    from flexvox_core.reconstruct.rebin import supported_divisions

    identity = code_from_order(code.placement) if isinstance(code, MultiplexedCode) else code
    return tuple(supported_divisions(identity))


def _with(method: Method, knob: str, value: Any) -> Method:
    from flexvox_core.methods import Method

    return Method(method.name, **{**dict(method.values), knob: value})


def _refused(method: Method, knob: str, why: str) -> NotEstimable:
    return NotEstimable(f"cannot choose {method.name}'s {knob} by the estimated accuracy: {why}")


def _so_far(progress: Callable[[int, int], object] | None, done: int, total: int) -> Progress | None:
    """A progress callback for the runs of one candidate: it reports the ``done`` candidates of ``total``."""
    if progress is None:
        return None

    def within(_done: int, _total: int) -> None:
        progress(done, total)

    return within


def _choose(method: Method | str, knob: str, candidates: Any, code: Any,
            reconstruct: Callable[[Method, Progress | None], Any],
            estimate: Callable[[Method, Any, Progress | None], AccuracyEstimate], *, reusable: bool,
            keep_video: bool, progress: Callable[[int, int], object] | None) -> Choice:
    """The loop :func:`choose` and :func:`choose_recording` share: ``reconstruct(method, within)`` gives a
    MethodOutput (called only when ``reusable``), ``estimate(method, video or None, within)`` its estimate; both
    call ``within`` between their chunks and runs, which calls ``progress`` with the candidates done so far."""
    from flexvox_core.methods.runner import as_method

    method = as_method(method)
    if not method.spec.has_option(knob):
        raise ValueError(f"{method.name} has no option {knob!r} (its options: {method.spec.option_list()})")
    why = refusal(method)
    if why is not None:
        raise _refused(method, knob, why)
    if candidates is not None and (isinstance(candidates, (str, bytes)) or not hasattr(candidates, "__iter__")):
        raise TypeError(f"`candidates` must be a sequence of {knob} values (e.g. (2.0, 4.0)); got {candidates!r}")
    values = candidates_for(method, knob, code) if candidates is None else tuple(candidates)
    if not values:
        raise ValueError(f"`candidates` for {method.name}'s {knob} must hold at least one value; got none")
    methods = [_with(method, knob, v) for v in values]  # a bad value: Method's own ValueError, before any run
    for i, m in enumerate(methods):  # 2 and 2.0 are one candidate: it would cost its runs twice, and be shown twice
        if m in methods[:i]:
            raise ValueError(f"`candidates` holds {values[methods.index(m)]!r} and {values[i]!r}, the same {knob}: "
                             "give each value once")
    t_start = time.perf_counter()
    tried: list[Candidate] = []
    best: tuple[int, Any] | None = None
    runs = 0
    for i, (value, m) in enumerate(zip(values, methods, strict=True)):
        t0 = time.perf_counter()
        within = _so_far(progress, i, len(values))
        why = refusal(m)
        if why is not None:
            tried.append(Candidate(value, m, None, 0.0, why))
            continue
        out = None
        made = 0
        run_seconds = 0.0
        if reusable:
            out = reconstruct(m, within)
            made = 1
            run_seconds = time.perf_counter() - t0
        try:
            est = estimate(m, None if out is None else out.video, within)
        except NotEstimable as exc:  # refused, before its runs or after them (a method that copies its samples)
            made += exc.runs
            tried.append(Candidate(value, m, None, time.perf_counter() - t0, str(exc), made, run_seconds))
        else:
            made += est.runs
            tried.append(Candidate(value, m, est, time.perf_counter() - t0, None, made, run_seconds))
            chosen = tried[best[0]].estimate if best is not None else None
            if chosen is None or est.psnr > chosen.psnr:
                best = (i, out if keep_video else None)
        runs += made
        _logger.info("%s", tried[-1].line())
        if progress is not None:
            progress(i + 1, len(values))
    seconds = time.perf_counter() - t_start
    if best is None:
        reasons = "; ".join(f"{_shown(c.value)}: {c.why}" for c in tried)
        raise _refused(method, knob, f"no candidate could be estimated ({reasons})")
    c = tried[best[0]]
    assert c.estimate is not None
    choice = Choice(knob, c.value, c.method, c.estimate, tuple(tried), seconds, runs, best[1])
    _logger.info("%s", choice.lines()[0])
    return choice


def choose(frames: ArrayLike, code: ArrayLike | MultiplexedCode, method: Method | str, knob: str,
           candidates: Any = None, *, noise: NoiseModel | None = None, missing: ArrayLike | None = None,
           chunk_frames: int | None = None, device: str = "cpu", seed: int = 0, keep_video: bool = True,
           progress: Callable[[int, int], object] | None = None, white: float | None = None,
           origin: tuple[int, int] | None = None) -> Choice:
    """Reconstruct a capture at each candidate value of ``knob`` and keep the one with the best estimated PSNR.

    Parameters
    ----------
    frames : ndarray (F, H, W)
        The capture: floats in relative units, or integer counts divided by the dtype's largest value unless
        ``white`` gives the white level (as :func:`~flexvox_core.accuracy.estimate_accuracy` takes it).
    code : ndarray (m, n, K) or MultiplexedCode
    method : Method or str
        The method; its other options are kept, ``knob`` is set to each candidate.
    knob : str
        The option to choose: ``time`` (diffusion, motion-aware), ``block`` (re-binning's division), or any
        option of the method when ``candidates`` are given.
    candidates : sequence, optional
        The values to try (default :func:`candidates_for`); each checked by
        :class:`~flexvox_core.methods.Method` before anything runs.
    noise : NoiseModel, optional
        The measurement noise (:func:`~flexvox_core.accuracy.estimate_accuracy`).
    missing : ndarray (F,) bool, optional
        Dropped frames.
    chunk_frames : int, optional
        Passed to :func:`~flexvox_core.methods.run`.
    device : str
        Where the method runs.
    seed : int
        Seeds the estimate's probe (one seed for every candidate).
    keep_video : bool
        Keep the chosen candidate's reconstruction (:attr:`Choice.output`); False holds only the one being made.
    progress : callable(done, total), optional
        Called with the candidates done after each one, and with the count so far between the chunks and runs
        of each (its reconstruction and its estimate): an exception it raises stops the choice there.
    white : float, optional
        The count that stands for white in integer ``frames`` (a 12-bit camera's: 4095).
    origin : (int, int), optional
        For frames cropped from the camera frame: the crop's top-left pixel ``(row, col)`` in the camera frame, as
        :func:`~flexvox_core.reconstruct_video` takes it (the code's phase follows it). Default (0, 0).

    Returns
    -------
    Choice

    Raises
    ------
    NotEstimable
        The estimate refuses the method (:func:`~flexvox_core.accuracy.refusal`, its reason quoted), or no
        candidate could be estimated (each one's reason quoted).
    ValueError
        ``method`` has no option ``knob``, no default candidates for it, or a candidate breaks its rule.
    TypeError
        A recording (its path, a ``Recording``) in ``frames``' place: :func:`choose_recording` takes it.

    Examples
    --------
    >>> from flexvox_core import capture, render_scene
    >>> from flexvox_core.design import design_code
    >>> code = design_code((2, 2)).code
    >>> frames = capture(render_scene("balls", 16, 24, 32), code)
    >>> choose(frames, code, "diffusion", "time", (2.0, 4.0)).method.time in (2.0, 4.0)
    True
    """
    from flexvox_core.accuracy import estimate_accuracy
    from flexvox_core.methods import run
    from flexvox_core.methods.runner import check_counts_within_white, check_origin, code_at_origin
    from flexvox_core.multiplex import MultiplexedCode
    from flexvox_core.numbers import flag
    from flexvox_core.reconstruct._common import refuse_recording

    refuse_recording(frames, "fv.choose", "fv.choose_recording(recording, method, knob)")
    keep_video = flag("`keep_video`", keep_video)
    row, col = check_origin(origin)
    if (row, col) != (0, 0):  # the crop's pixel (y, x) is the camera's (y + row, x + col), as the runner reads it
        if isinstance(code, MultiplexedCode):
            raise ValueError(f"`origin` {origin!r} with a multiplexed code: choose on the whole camera frame, or on a "
                             "crop on its tile grid")
        code = code_at_origin(code, (row, col))
    f32 = np.asarray(as_relative(frames, white=white), np.float32)
    check_counts_within_white(frames, f32, white, code)
    gaps = missing if missing is None or f32.ndim != 3 else as_missing(missing, f32.shape[0])  # checked before any run
    reusable = not isinstance(code, MultiplexedCode)
    if reusable:
        from flexvox_core.codes import is_identity_code, validate_code

        reusable = is_identity_code(validate_code(code))

    def reconstruct(m: Method, within: Progress | None) -> Any:
        return run(f32, code, m, chunk_frames=chunk_frames, missing=gaps, device=device, progress=within)

    def estimate(m: Method, video: Any, within: Progress | None) -> AccuracyEstimate:
        return estimate_accuracy(f32, code, m, noise=noise, missing=gaps, reconstruction=video, seed=seed,
                                 chunk_frames=chunk_frames, device=device, progress=within)

    return _choose(method, knob, candidates, code, reconstruct, estimate, reusable=reusable, keep_video=keep_video,
                   progress=progress)


def choose_recording(recording: str | os.PathLike[str] | Recording, method: Method | str, knob: str,
                     candidates: Any = None, *, noise: NoiseModel | None = None, chunk_frames: int | None = 16,
                     device: str = "cpu", seed: int = 0, keep_video: bool = True,
                     progress: Callable[[int, int], object] | None = None) -> Choice:
    """:func:`choose` on a recording (a path or an open :class:`~flexvox_core.recording.Recording`): each candidate
    reconstructed as every front end does (:meth:`CaptureReader.run
    <flexvox_core.capture_reader.CaptureReader.run>`: its code, its dropped frames) and estimated by
    :func:`~flexvox_core.accuracy.estimate_recording` (the noise it states unless ``noise`` is given). Its ground
    truth, if any, is never read.

    Examples
    --------
    >>> from flexvox_core import render_scene, simulate_video, write_simulation
    >>> from flexvox_core.design import design_code
    >>> sim = simulate_video(render_scene("balls", 16, 24, 32), design_code((2, 2)).code)
    >>> import pathlib, tempfile
    >>> path = write_simulation(pathlib.Path(tempfile.mkdtemp()) / "rec.zarr", sim)
    >>> choose_recording(path, "diffusion", "time", (2.0, 4.0)).video.shape
    (16, 24, 32)
    """
    from flexvox_core.accuracy import estimate_recording
    from flexvox_core.capture_reader import open_capture

    reader = open_capture(recording)
    rec = reader.recording
    reusable = reader.multiplexed is None
    code = reader.multiplexed if reader.multiplexed is not None else reader.code

    def reconstruct(m: Method, within: Progress | None) -> Any:
        return reader.run(m, chunk_frames=chunk_frames, device=device, progress=within)

    def estimate(m: Method, video: Any, within: Progress | None) -> AccuracyEstimate:
        return estimate_recording(rec, m, noise=noise, reconstruction=video, seed=seed, chunk_frames=chunk_frames,
                                  device=device, progress=within)

    return _choose(method, knob, candidates, code, reconstruct, estimate, reusable=reusable, keep_video=keep_video,
                   progress=progress)
