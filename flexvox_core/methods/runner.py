"""The one chunked runner every reconstruction goes through.

A capture ``(F, H, W)`` is cut into chunks of camera frames (:func:`chunk_plan`); each chunk is
reconstructed with the overlap its method needs on each side (:meth:`Method.overlap
<flexvox_core.methods.method.Method.overlap>`) and trimmed back to its own sub-frames by
:func:`run_chunk`, the per-chunk function that ``flexvox reconstruct``, ``flexvox export``, the
Review workspace's jobs and the dask batch (:mod:`flexvox_core.batch`) all call. Methods that
need the sample range get the whole capture's in every chunk; so the result does not depend on
the chunking. Progress is reported after every chunk (a callback that raises stops the run
there: the Review workspace's cancel).

Dropped camera frames (``missing``) are handled here for every method (:mod:`flexvox_core.gaps`):
a gap longer than the method bridges is refused before any work; chunks read the longest gap and
one frame more of context on each side; a method that takes ``missing`` leaves the dropped frames
out of its samples and fills them itself, and any other (and every multiplexed capture) gets them
interpolated from their neighbours and its result's gap sub-frames bridged from both sides.

A multiplexed capture (a non-identity code) goes only to methods that take it
(:meth:`~flexvox_core.methods.spec.MethodSpec.takes_multiplexed`); the reader demultiplexes per tile
for the others (:meth:`flexvox_core.capture_reader.CaptureReader.input`). The result says which
sub-frames were interpolated (:attr:`MethodOutput.interpolated`).
"""

from __future__ import annotations

import inspect
import logging
import os
import warnings
from numbers import Integral
from typing import Any, NamedTuple

import numpy as np

from flexvox_core.codes import check_reconstructable, validate_code
from flexvox_core.deprecations import renamed_keyword, warn_renamed
from flexvox_core.gaps import (
    as_missing,
    bridge,
    captured,
    check_reach,
    context,
    fill_frames,
    interpolated_subframes,
)
from flexvox_core.intensity import as_relative
from flexvox_core.memory_budget import check_fits, reconstruction_bytes
from flexvox_core.methods.method import Method
from flexvox_core.methods.spec import MethodOutput
from flexvox_core.numbers import flag
from flexvox_core.progress import Progress, progress_callback
from flexvox_core.reconstruct._common import refuse_recording

_logger = logging.getLogger(__name__)


class Chunk(NamedTuple):
    """Camera frames ``[start, stop)`` of the result, reconstructed from frames ``[lo, hi)``."""

    start: int
    stop: int
    lo: int
    hi: int


def chunk_plan(n_frames: int, chunk_frames: int | None, overlap: int | None) -> list[Chunk]:
    """The chunks of a run over ``n_frames`` camera frames.

    Parameters
    ----------
    n_frames : int
    chunk_frames : int or None
        Camera frames per chunk (None: one chunk).
    overlap : int or None
        Frames of context on each side (None: the method cannot be chunked, one chunk).

    Returns
    -------
    list of Chunk
        Consecutive ``[start, stop)`` covering ``[0, n_frames)``, each read from
        ``[max(0, start - overlap), min(n_frames, stop + overlap))``.
    """
    if chunk_frames is None or overlap is None or n_frames <= chunk_frames:
        return [Chunk(0, n_frames, 0, n_frames)]
    return [Chunk(s, min(n_frames, s + chunk_frames), max(0, s - overlap), min(n_frames, s + chunk_frames + overlap))
            for s in range(0, n_frames, chunk_frames)]


def check_method_reach(missing, method: Method, K: int) -> None:
    """Refuse a run of dropped frames longer than ``method`` bridges, naming the registered method
    whose default options reach furthest when one does reach it (:func:`flexvox_core.gaps.check_reach`)."""
    from flexvox_core.methods.registry import names

    reach = method.max_gap(K)
    best, name = max((Method(n).max_gap(K), n) for n in names())
    advice = (f"At its defaults {name} bridges {best} (a method's reach is twice the context it reads on each "
              "side; more diffusion or refinement time reaches further)" if best > reach else
              "No method bridges it at its defaults: reconstruct with longer diffusion or refinement times")
    check_reach(missing, reach, method.name, K, advice)


def sample_range(frames, missing=None) -> tuple[float, float]:
    """Smallest and largest sample of ``frames`` (what :attr:`needs_sample_range` methods take),
    leaving out the ``missing`` (dropped) frames' zero rows."""
    f = captured(np.asarray(frames), missing)
    return float(np.min(f)), float(np.max(f))


def _range_keyword(spec) -> str:
    """The keyword ``spec.run`` takes the sample range by: ``sample_range``, or (warned) its deprecated name."""
    params = inspect.signature(spec.run).parameters
    if "sample_range" in params or "value_range" not in params:
        return "sample_range"
    warn_renamed(f"the `value_range` keyword of {type(spec).__name__}.run", "it `sample_range`", stacklevel=4)
    return "value_range"


def check_code_for(code, method: Method) -> bool:
    """True for a multiplexed ``code``, which ``method`` must take
    (:meth:`Method.takes_multiplexed <flexvox_core.methods.method.Method.takes_multiplexed>`), False for an identity
    code; ``ValueError`` for a multiplexed code ``method`` does not take (saying to demultiplex) and for a code that
    is neither (:func:`flexvox_core.codes.check_reconstructable`)."""
    if not check_reconstructable(code):
        return False
    if not method.takes_multiplexed():
        raise ValueError(f"{method.label} takes identity-code captures only; demultiplex this multiplexed capture "
                         "first (flexvox_core.reconstruct.as_identity_capture; CaptureReader.input does it for such "
                         "methods)")
    return True


def device_for(method: Method, code, device: str = "cpu") -> tuple[str, str | None]:
    """(where ``method`` runs, why not on the GPU): ``device`` (``auto``, ``cpu`` or ``cuda``) resolved
    (:func:`flexvox_core.gpu.resolve_device`; ``cuda`` without a usable GPU raises
    :class:`~flexvox_core.gpu.DeviceUnavailable`), then the CPU for a method, values or code without a GPU path
    (:meth:`~flexvox_core.methods.spec.MethodSpec.cpu_only`), with that reason; ``auto`` that falls back to the CPU
    because numba-cuda and numpy do not work together (:func:`flexvox_core.gpu.device.broken_stack`) says so too."""
    if device == "cpu":
        return "cpu", None
    from flexvox_core.gpu.device import broken_stack, resolve_device

    if resolve_device(device) == "cpu":
        return "cpu", broken_stack()  # auto beside a GPU whose stack is broken says why; None where there is no GPU
    why = method.cpu_only(np.asarray(code, bool))
    return ("cpu", why) if why else ("cuda", None)


GPU_MEMORY_SHARE = 0.8
"""The share of the card's free memory a chunk may take."""


def gpu_chunk_frames(method: Method, K: int, H: int, W: int, n_frames: int, chunk_frames: int | None) -> int | None:
    """``chunk_frames`` shortened so that a chunk and its context fit the GPU's free memory (at most
    :data:`GPU_MEMORY_SHARE` of it, :meth:`~flexvox_core.methods.method.Method.gpu_voxel_bytes`); unchanged
    when it fits or the free memory is not known. ``ValueError`` when not even one frame with its context fits."""
    from flexvox_core.gpu.device import free_memory

    free = free_memory()
    per_voxel = method.gpu_voxel_bytes(K, H, W)
    if free is None or not per_voxel:
        return chunk_frames
    overlap = method.overlap(K) or 0
    fit = int(GPU_MEMORY_SHARE * free // (per_voxel * K * H * W)) - 2 * overlap
    wanted = n_frames if chunk_frames is None else chunk_frames
    if fit < 1:
        raise ValueError(f"{method.label} needs about {per_voxel * K * H * W * (1 + 2 * overlap) / 2**30:.1f} GiB "
                         f"of GPU memory for one {H}x{W} frame and its context; {free / 2**30:.1f} GiB are free: "
                         "reconstruct on the CPU")
    if fit < wanted:
        _logger.info("GPU: chunks of %d camera frames to fit %.1f GiB free", fit, free / 2**30)
        return fit
    return chunk_frames


def run_chunk(frames, code, method: Method, *, left: int = 0, count: int | None = None, sample_range=None,
              extras: bool = False, missing=None, device: str = "cpu", **deprecated: Any) -> MethodOutput:
    """Reconstruct one chunk with its context and keep the chunk's own sub-frames.

    Parameters
    ----------
    frames : ndarray (F, H, W)
        The chunk's camera frames with ``left`` frames of context before them and any after.
    code : ndarray (m, n, K), identity code, or a multiplexed one for a method that takes it
        (:func:`check_code_for`)
    method : Method
    left : int
        Frames of context before the chunk.
    count : int or None
        Camera frames of the chunk (None: all after ``left``).
    sample_range : (lo, hi) or None
        The whole recording's sample range, for methods that need it (``value_range``, its deprecated name, still
        works for one release).
    extras : bool
        Also return the method's extras (trimmed like the video).
    missing : ndarray (F,) bool or None
        The chunk's dropped frames (context included); they must not be all of its frames.
    device : {"cpu", "cuda", "auto"}
        Where it runs (:func:`device_for`).

    Returns
    -------
    MethodOutput
        ``video`` (count·K, H, W) float32 clipped to [0, 1], the extras, which sub-frames
        were interpolated across dropped frames, and where it ran.
    """
    sample_range = renamed_keyword(deprecated, "value_range", "sample_range", sample_range, "run_chunk")
    if deprecated:
        raise TypeError(f"run_chunk() got unexpected keywords {', '.join(deprecated)}")
    K = code.shape[2]
    count = frames.shape[0] - left if count is None else count
    m = as_missing(missing, frames.shape[0])
    spec, options = method.spec, method.options
    on: dict[str, Any] = {_range_keyword(spec): sample_range}
    multiplexed = check_code_for(code, method)
    device, note = device_for(method, code, device)
    on.update({"device": device} if device == "cuda" else {})  # only a method with a GPU path takes `device`
    if m is None:
        out = spec.run(frames, code, options, extras=extras, **on)
    elif spec.takes_missing and not multiplexed:
        out = spec.run(frames, code, options, extras=extras, missing=m, **on)
    else:
        out = spec.run(fill_frames(frames, m), code, options, extras=extras, **on)
        bridge(out.video, m, K)
    a, b = left * K, (left + count) * K
    whole = out.video
    if (isinstance(whole, np.ndarray) and whole.dtype == np.float32 and whole.flags.writeable
            and (a, b) == (0, len(whole))
            and not any(np.may_share_memory(whole, other) for other in (frames, *out.extras.values()))):
        # The method's own float32 result, all of it kept (one chunk): clipped in place (a fresh copy of a 1-s
        # VGA clip cost 0.3-0.5 s of page faults); never an input's or an extra's memory. A chunk with context
        # is copied, so that the context's sub-frames are not held while the chunk waits to be stored.
        video = np.clip(whole, 0, 1, out=whole)
    else:
        video = np.clip(whole[a:b], 0, 1).astype(np.float32, copy=False)
    interpolated = None if m is None else interpolated_subframes(m, K)[a:b]
    return MethodOutput(video, {k: v[a:b] for k, v in out.extras.items()}, interpolated, out.device, note)


def as_method(method=None, options: dict | None = None) -> Method:
    """The :class:`Method` that ``method`` and ``options`` name.

    Parameters
    ----------
    method : Method, str or None
        A :class:`Method`; a registered method's name (``"gap-tv"``); None: the default method
        (:data:`~flexvox_core.methods.registry.DEFAULT`).
    options : dict, optional
        The method's options, with a name or None (``as_method("diffusion", {"time": 3})``).

    Raises
    ------
    TypeError
        ``method`` of another type, or options given beside a :class:`Method` (which holds its own).
    ValueError
        An unknown name or option, or a value that breaks its option's rule (:class:`Method`).
    """
    options = options or {}
    if isinstance(method, Method):
        if options:
            given = ", ".join(f"{k}=..." for k in options)
            raise TypeError(f"options ({given}) go into the method: fv.Method({method.name!r}, {given}), or name it "
                            f"with its options as keywords: ({method.name!r}, {given}); got them beside {method!r}")
        return method
    if method is None:
        return Method(**options)
    if isinstance(method, str):
        return Method(method, **options)
    from flexvox_core.methods.registry import names

    raise TypeError(f"`method` must be an fv.Method (fv.Method('gap-tv', iterations=40)) or a method's name "
                    f"({', '.join(names())}) with its options as keywords; got {type(method).__name__} {method!r}")


def code_at_origin(code, origin) -> np.ndarray:
    """``code`` (checked) as frames cropped at ``origin`` = (row, col) of the camera frame see it: the crop's pixel
    (y, x) is the camera's (y + row, x + col), so the tile is rolled by (−row, −col)."""
    row, col = check_origin(origin)
    code = validate_code(code)
    if (row, col) != (0, 0):
        code = np.ascontiguousarray(np.roll(code, (-row, -col), axis=(0, 1)))
    return code


def check_origin(origin) -> tuple[int, int]:
    """``origin`` as (row, col): two whole numbers >= 0 (None: (0, 0)); ``ValueError`` otherwise."""
    if origin is None:
        return 0, 0
    try:
        row, col = origin
    except (TypeError, ValueError):
        raise ValueError(f"`origin` must be (row, col), the crop's top-left pixel in the camera frame; got "
                         f"{origin!r}") from None
    for v in (row, col):
        if isinstance(v, bool) or not isinstance(v, Integral) or v < 0:
            raise ValueError(f"`origin` must be two whole numbers >= 0 (row, col), the crop's top-left pixel in the "
                             f"camera frame; got {origin!r}")
    return int(row), int(col)


def run(frames, code, method: Method | str | None = None, *, chunk_frames: int | None = 16,
        progress: bool | Progress | None = None, extras: bool = False, missing=None, device: str = "cpu",
        origin: tuple[int, int] | None = None, white: float | None = None, **options: Any) -> MethodOutput:
    """Reconstruct the full video ``(F·K, H, W)`` float32 in [0, 1] of a capture.

    Parameters
    ----------
    frames : ndarray (F, H, W)
        The camera frames: floats in relative units (white = 1), or integer counts, divided by the dtype's
        largest value (uint8: 255, uint16: 65535) unless ``white`` gives the white level
        (:mod:`flexvox_core.intensity`). A recording: :meth:`flexvox_core.capture_reader.CaptureReader.run`, or
        :func:`flexvox_core.reconstruct_video` with the recording in place of frames and code.
    code : ndarray (m, n, K)
        An identity code, or a multiplexed one (the frames then multiplexed, each value a sum of its open slots)
        for a method that :meth:`~flexvox_core.methods.method.Method.takes_multiplexed`; any other code is
        refused (:func:`flexvox_core.codes.check_reconstructable`).
    method : Method or str, optional
        A :class:`Method`, or a method's name (``"gap-tv"``) with its options as keywords (``**options``).
        Default: motion-aware.
    chunk_frames : int or None
        Camera frames per chunk (None: all at once). Chunks overlap by the method's
        :meth:`~flexvox_core.methods.method.Method.overlap`, so the result does not depend on it.
    progress : bool or callable(done_frames, total_frames), optional
        True: a ``tqdm.auto`` bar; False or None: nothing; a callable is called after each chunk (an exception it
        raises stops the run) (:mod:`flexvox_core.progress`).
    extras : bool
        Also return the method's extras (:attr:`~flexvox_core.methods.spec.MethodSpec.extras`),
        e.g. motion-aware's flow and per-voxel TR, assembled like the video.
    missing : ndarray (F,) bool, optional
        Frames the camera dropped (zero rows): bridged from both sides, or refused
        (:class:`~flexvox_core.gaps.GapTooLongError`) when a gap is longer than the method's
        :meth:`~flexvox_core.methods.method.Method.max_gap`.
    device : {"cpu", "cuda", "auto"}
        Where it runs (:func:`device_for`): ``auto`` takes the GPU when one is usable and the method has a GPU
        path; the result's ``device`` and ``device_note`` say where it ran and why not on the GPU.
    origin : (int, int), optional
        For frames cropped from the camera frame: the crop's top-left pixel ``(row, col)`` in the camera frame.
        The code's phase follows it: pixel ``(y, x)`` of the crop uses ``code[(y + row) % m, (x + col) % n]``.
        Default (0, 0), a crop on the tile grid.
    white : float, optional
        The count that stands for white in integer ``frames`` (a 12-bit camera's: 4095); with float frames, the
        value they are divided by.
    **options
        The method's options when ``method`` is a name or None (``Method(name).spec.option_specs``).

    Returns
    -------
    MethodOutput

    Raises
    ------
    TypeError
        A ``method`` that is neither a :class:`Method` nor a name, options beside a :class:`Method`, a
        ``progress`` that is not a bool or a callable, or a recording (its path, a ``Recording``, a
        ``CaptureReader``) in ``frames``' place.
    ValueError
        Frames, a code, an origin or options that break their rules (the message names the value and the rule).
    """
    method = as_method(method, options)
    extras = flag("`extras`", extras)
    if isinstance(frames, str | os.PathLike):
        raise TypeError(f"`frames` is a path ({frames}): a recording goes to fv.reconstruct_video(path, method), "
                        "which reads its code and dropped frames; fv.run takes frames (F, H, W) and a code "
                        "(fv.read_capture(path)), or fv.open_capture(path).run(method) gives the result object")
    _refuse_recording(frames)
    if code is None:
        raise TypeError("run() needs the `code` the frames were captured with (a recording: "
                        "fv.reconstruct_video(recording) or fv.open_capture(recording).run(method))")
    row, col = check_origin(origin)
    f = as_relative(frames, white=white)
    check_counts_within_white(frames, f, white, code)
    with progress_callback(progress, desc="reconstruct", unit="frame", total=f.shape[0] if f.ndim else None
                           ) as report:
        return _run(f, code, method, chunk_frames=chunk_frames, progress=report, extras=extras, missing=missing,
                    device=device, origin=(row, col))


def _refuse_recording(frames) -> None:
    """A Recording or a CaptureReader in ``frames``' place is refused with where it goes: read as an array it was
    "dtype object", which said nothing of the recording."""
    refuse_recording(frames, "fv.run", "fv.reconstruct_video(recording, method)",
                     "; or fv.open_capture(recording).run(method) gives the result object")


def check_counts_within_white(frames, relative: np.ndarray, white, code) -> None:
    """Refuse frames whose light no capture through ``code`` gives; the reconstruction had been white everywhere,
    clipped, without a word.

    - Integer counts given with ``white`` may reach at most twice the light of the code's most open pixel (one slot
      for an identity code, (K+1)/2 for an S-matrix one): beyond it ``white`` is not their white (a 12-bit camera's
      counts in the high bits of a uint16, white=4095 for counts up to 65520).
    - Floats without ``white`` (relative units) may reach at most 2·K: twice the light of every slot open on white
      for the whole exposure, ambient light included. Beyond it they are counts held as floats
      (``counts.astype(float)``: 8-bit ones reach 255), which need ``white``. A recording's frames, normalised by
      its own storage, stay far below it."""
    kind = np.asarray(frames).dtype.kind
    if not relative.size or kind not in "iuf" or (kind in "iu" and white is None):
        return
    c = validate_code(getattr(code, "code", code))  # a MultiplexedCode (the estimate and the choice take one)
    most_open, K = int(c.sum(axis=2).max()), c.shape[2]
    hi = float(relative.max())
    if white is None:  # floats taken as relative units
        if hi > 2 * K:  # NaN is not: refused later, naming its frame
            raise ValueError(f"`frames` are floats reaching {hi:g}, more than twice the light of all {K} slots open "
                             "on white (white = 1): counts held as floats? give `white=` (the count that stands for "
                             "white: 255 for 8-bit, 4095 for a 12-bit camera, 65535 for 16-bit counts), or divide "
                             "them by it")
        return
    if hi > 2 * most_open:
        raise ValueError(f"`frames` reach {hi * float(white):.0f} counts, {hi:.3g} times `white` = {float(white):g}, "
                         f"where the code lets in at most {most_open} slot(s) of white: `white` is not these counts' "
                         "white (counts in the high bits of their dtype? give the dtype's largest value, or shift "
                         "them down)")


def check_whole_tile(H: int, W: int, tile: tuple[int, int], K: int) -> None:
    """Frames of ``H`` × ``W`` pixels must hold at least one whole ``tile`` (m, n): in a smaller crop some of the K
    slots are sampled by no pixel, and every method would make their sub-frames up from the others (a video that
    looks right). ``ValueError`` naming the sizes."""
    m, n = (int(v) for v in tile)
    if H < m or W < n:
        raise ValueError(f"`frames` of {H}x{W} pixels hold less than one {m}x{n} tile: {K - min(H, m) * min(W, n)} of "
                         f"the code's K = {K} slots are sampled by no pixel, and their sub-frames would be made up "
                         f"from the others; a crop must hold at least one whole tile ({m}x{n} pixels)")


def _run(f: np.ndarray, code, method: Method, *, chunk_frames: int | None, progress: Progress | None, extras: bool,
         missing, device: str, origin: tuple[int, int]) -> MethodOutput:
    if f.ndim != 3:
        raise ValueError(f"`frames` must have shape (F, H, W); got {f.ndim} dimensions {f.shape}")
    if chunk_frames is not None and (isinstance(chunk_frames, bool) or not isinstance(chunk_frames, Integral)
                                     or chunk_frames < 1):
        raise ValueError(f"`chunk_frames` must be a whole number >= 1 or None; got {chunk_frames!r}")
    code = code_at_origin(code, origin)
    check_code_for(code, method)
    K = code.shape[2]
    F = f.shape[0]
    H, W = f.shape[1:]
    check_whole_tile(H, W, code.shape[:2], K)
    check_fits(reconstruction_bytes(F, K, H, W, chunk_frames, method.overlap(K)),
               f"reconstructing {F} frames of {H}x{W} at K = {K} in memory ({F * K} sub-frames)",
               "reconstruct it with reconstruct_batch (`flexvox batch` on the command line), which writes chunk by "
               "chunk (its memory follows the chunk's length, not the recording's)")
    missing = as_missing(missing, F)
    check_method_reach(missing, method, K)
    whole = sample_range(f, missing) if method.spec.needs_sample_range and F else None
    device, note = device_for(method, code, device)
    if device == "cuda":
        chunk_frames = gpu_chunk_frames(method, K, H, W, F, chunk_frames)
    chunks = chunk_plan(F, chunk_frames, context(method.overlap(K), missing))
    if len(chunks) == 1:
        out = run_chunk(f, code, method, sample_range=whole, extras=extras, missing=missing, device=device)
        out.device_note = note
        if progress:
            progress(F, F)
        return out
    video = np.empty((F * K, *f.shape[1:]), np.float32)
    arrays: dict[str, np.ndarray] = {}
    for c in chunks:
        part = run_chunk(f[c.lo:c.hi], code, method, left=c.start - c.lo, count=c.stop - c.start,
                         sample_range=whole, extras=extras,
                         missing=None if missing is None else missing[c.lo:c.hi], device=device)
        video[c.start * K: c.stop * K] = part.video
        for name, v in part.extras.items():
            if name not in arrays:
                arrays[name] = np.empty((F * K, *v.shape[1:]), v.dtype)
            arrays[name][c.start * K: c.stop * K] = v
        if progress:
            progress(c.stop, F)
    return MethodOutput(video, arrays, None if missing is None else interpolated_subframes(missing, K), device, note)


def reconstruct(frames, code, method: Method | str | None = None, *, chunk_frames: int | None = 16,
                progress: bool | Progress | None = None, missing=None, device: str = "cpu",
                origin: tuple[int, int] | None = None, white: float | None = None, **options: Any) -> np.ndarray:
    """Deprecated: the video of :func:`run` alone; call :func:`flexvox_core.reconstruct_video`, which does the same.

    It warns (``DeprecationWarning``) and will be removed in the next release: it is
    :func:`flexvox_core.reconstruct_video` (which also takes a recording) under a second name.

    Parameters
    ----------
    frames : ndarray (F, H, W)
        See :func:`run`.
    code : ndarray (m, n, K)
        See :func:`run`.
    method : Method or str, optional
        See :func:`run`.
    chunk_frames : int or None
        See :func:`run`.
    progress : bool or callable(done_frames, total_frames), optional
        See :func:`run`.
    missing : ndarray (F,) bool, optional
        See :func:`run`.
    device : {"cpu", "cuda", "auto"}
        See :func:`run`.
    origin : (int, int), optional
        See :func:`run`.
    white : float, optional
        See :func:`run`.
    **options
        See :func:`run`.
    """
    warnings.warn("flexvox_core.methods.reconstruct is deprecated and will be removed in the next release: call "
                  "flexvox_core.reconstruct_video (the same arguments, the same video)", DeprecationWarning,
                  stacklevel=2)
    return run(frames, code, method, chunk_frames=chunk_frames, progress=progress, missing=missing,
               device=device, origin=origin, white=white, **options).video
