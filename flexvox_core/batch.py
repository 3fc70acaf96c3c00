"""Batch reconstruction of long recordings with dask: chunks in time, exact overlap, Zarr out.

The recording's raw frames are a dask array chunked in time (``chunk_frames`` camera frames per
chunk, read lazily from the Zarr store, each row checked against its checksum);
:func:`dask.array.map_overlap` gives each chunk the
method's overlap (:meth:`Method.overlap <flexvox_core.methods.method.Method.overlap>`) of
context on each side (none beyond the recording's ends). Each chunk is normalised (and, for a
method that does not take multiplexed captures, demultiplexed) by the reader's
:class:`~flexvox_core.capture_reader.Preparation` for the method and
reconstructed and trimmed to its own ``chunk_frames · K`` sub-frames by
:func:`~flexvox_core.methods.runner.run_chunk`, the per-chunk function of the in-memory runner;
the result is stored chunk by chunk into an OME-Zarr image (NGFF 0.5 on Zarr v3, :mod:`flexvox_core.ngff`:
array ``video``, one sub-frame per Zarr chunk, the sub-frame period as its t scale, optional pyramid
levels; the same layout ``flexvox reconstruct`` writes). Only the chunk planning is dask's
own (:func:`_chunks`: a last chunk shorter than the overlap joins its neighbour, as
``map_overlap`` needs). The result equals the in-memory :func:`~flexvox_core.methods.runner.run`
(the overlap is exact; methods that need the sample range get the whole recording's, read in one
pass first). Peak memory is a few chunks per worker thread, whatever the recording's length.

Scheduling: dask's local threaded scheduler by default; a ``dask.distributed`` scheduler
address (``tcp://host:8786``), a ``distributed.Client`` or a cluster (``LocalCluster``) runs the chunks there
(the workers must see the recording and the output path).
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from flexvox_core import ngff
from flexvox_core.capture_reader import CaptureReader, Preparation
from flexvox_core.gaps import context, interpolated_subframes
from flexvox_core.methods.method import Method
from flexvox_core.methods.runner import check_method_reach, device_for, gpu_chunk_frames, run_chunk
from flexvox_core.output_files import atomic_output, check_output, check_path
from flexvox_core.progress import progress_callback
from flexvox_core.recording import Recording, RecordingError, open_recording
from flexvox_core.recording.reader import check_recording_path
from flexvox_core.video_io import INTERPOLATED, VIDEO, provenance

_logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class BatchResult:
    """What a batch run wrote."""

    path: Path
    shape: tuple[int, int, int]
    chunk_frames: int
    overlap_frames: int
    seconds: float
    scheduler: str
    device: str = "cpu"
    device_note: str | None = None


def _chunks(F: int, chunk: int, ov: int) -> tuple[int, ...]:
    """Chunk lengths along time; a last chunk shorter than the overlap joins its neighbour."""
    sizes = [chunk] * (F // chunk) + ([F % chunk] if F % chunk else [])
    if len(sizes) > 1 and sizes[-1] < max(ov, 1):
        last = sizes.pop()
        sizes[-1] += last
    return tuple(sizes) or (0,)


_GPU_LOCK = threading.Lock()
"""One chunk at a time on the GPU: dask's threads would otherwise each hold a window's volumes on the card."""


def _run_chunk_on_gpu(*args, **kwargs):
    """:func:`run_chunk` with ``device="cuda"``, one at a time in this process (a module-level function: the dask
    kernel refers to it by name, where a lock of its own would not pickle for a distributed cluster)."""
    with _GPU_LOCK:
        return run_chunk(*args, **kwargs, device="cuda")


def _chunk_kernel(code, K: int, ov: int, F: int, method: Method, preparation: Preparation, sample_range=None,
                  missing=None, device: str = "cpu"):
    """The dask kernel: one chunk of raw rows (with its context) prepared, then :func:`run_chunk`
    (``missing``: the recording's dropped frames, or None; ``device``: ``cpu`` or ``cuda``)."""

    def kernel(block: np.ndarray, block_info=None) -> np.ndarray:
        s0, s1 = block_info[None]["array-location"][0]
        start, stop = s0 // K, s1 // K
        left, right = min(ov, start), min(ov, F - stop)
        if block.shape[0] != stop - start + left + right:
            raise RuntimeError(f"chunk [{start}, {stop}) arrived with {block.shape[0]} frames, expected "
                               f"{stop - start + left + right}")
        lost = None if missing is None else missing[start - left: stop + right]
        frames = preparation(block)
        run = _run_chunk_on_gpu if device == "cuda" else run_chunk
        return run(frames, code, method, left=left, count=stop - start, sample_range=sample_range, missing=lost).video

    return kernel


def batch_video(rec: Recording, method: Method | None = None, *, chunk_frames: int = 32, device: str = "cpu"):
    """The reconstruction of an opened recording as a lazy dask array ``(F·K, H, W)`` float32.

    Returns
    -------
    video : dask.array.Array (F·K, H, W) float32
    overlap : int
        Camera frames of context each chunk was given on each side (with dropped frames: the
        method's overlap, the longest gap and one more, :func:`flexvox_core.gaps.context`).

    Raises
    ------
    ValueError
        A recording the reader refuses (:class:`~flexvox_core.capture_reader.NotReconstructableError`), a bad
        ``chunk_frames``, a method that cannot run in chunks, or a run of dropped frames longer than
        the method bridges (:class:`~flexvox_core.gaps.GapTooLongError`).
    """
    import dask.array as da

    method = method or Method()
    reader = CaptureReader(rec)
    if isinstance(chunk_frames, bool) or not isinstance(chunk_frames, int) or chunk_frames < 1:
        raise ValueError(f"`chunk_frames` must be a whole number >= 1; got {chunk_frames!r}")
    K = reader.K
    F = reader.n_frames
    H, W = reader.shape
    ov = method.overlap(K)
    if ov is None:
        raise ValueError(f"{method.label} is a global solve and cannot run in chunks; choose another solver")
    check_method_reach(reader.missing, method, K)
    if device == "cuda":  # chunks that fit the card's free memory
        chunk_frames = gpu_chunk_frames(method, K, H, W, F, chunk_frames) or chunk_frames
    # A recording shorter than the context needs none beyond itself (dask refuses a depth above the array).
    ov = min(context(ov, reader.missing), max(0, F - 1))
    if chunk_frames < ov:
        _logger.info("batch: chunks of %d frames raised to the method's overlap of %d", chunk_frames, ov)
        chunk_frames = ov  # dask's map_overlap needs chunks at least as long as the overlap
    # Read through the reader's checked rows: a missing or damaged chunk fails the run, never reads as zeros.
    frames = da.from_array(reader.raw, chunks=(_chunks(F, chunk_frames, ov), H, W), asarray=True, lock=False,
                           fancy=False)
    # Methods that scale by the samples' range get the whole recording's in every chunk.
    sample_range = reader.sample_range(chunk_frames, method) if method.spec.needs_sample_range else None
    kernel = _chunk_kernel(reader.code_for(method), K, ov, F, method, reader.preparation_for(method), sample_range,
                           reader.missing, device)
    out_chunks = (tuple(c * K for c in frames.chunks[0]), (H,), (W,))
    return da.map_overlap(kernel, frames, depth={0: ov, 1: 0, 2: 0}, boundary="none", trim=False,
                          dtype=np.float32, chunks=out_chunks, meta=np.empty((0, 0, 0), np.float32)), ov


def reconstruct_batch(recording, output, method: Method | str | None = None, *, chunk_frames: int = 32,
                      scheduler: Any = None, overwrite: bool = False,
                      progress: bool | Callable[[int, int], None] | None = None,
                      connect_timeout_s: float = 10.0, pyramid: int = 0, device: str = "cpu",
                      **options: Any) -> BatchResult:
    """Reconstruct a recording chunk by chunk into an OME-Zarr image (array ``video``, as ``reconstruct`` writes).

    Parameters
    ----------
    recording : str, Path or Recording
    output : str or Path
        A ``.zarr`` store to create.
    method : Method or str, optional
        A :class:`~flexvox_core.methods.Method`, or a method's name with its options as keywords
        (``**options``). Default: motion-aware (:data:`~flexvox_core.methods.registry.DEFAULT`, as everywhere).
    chunk_frames : int
        Camera frames per chunk (memory per task grows with it, not with the recording);
        raised to the method's overlap when smaller.
    scheduler : str, distributed.Client or distributed cluster, optional
        Where the chunks run: a ``dask.distributed`` scheduler's address (``"tcp://host:8786"``), a
        ``distributed.Client`` (used as it is, left open), or a cluster (``distributed.LocalCluster()``: a
        client is opened on it and closed after); default: dask's local threaded scheduler.
    progress : bool or callable(done_chunks, total_chunks), optional
        True: a ``tqdm.auto`` bar; False or None: nothing; a callable is called as chunks finish
        (:mod:`flexvox_core.progress`). On a distributed scheduler the chunks are reported when the run ends.
    connect_timeout_s : float
        How long to wait for the distributed scheduler.
    pyramid : int
        Pyramid levels of 2×2 means below full resolution (:mod:`flexvox_core.ngff`; default none),
        computed from the same chunks as they are reconstructed.
    device : {"cpu", "cuda", "auto"}
        Where the chunks are reconstructed (:func:`~flexvox_core.methods.runner.device_for`; one chunk at a time
        on the GPU); recorded in the output's provenance. A distributed cluster's workers need the GPU too.

    Raises
    ------
    ValueError
        Bad arguments, an output that may not be written (onto the input, existing without
        ``overwrite``, a folder that refuses files), or a recording that cannot be reconstructed
        (a damaged chunk found while reading included: the output is then not written), or an unknown method.
    TypeError
        A ``method`` that is neither a Method nor a name, or a ``progress`` that is neither a bool nor a callable.
    """
    from flexvox_core.methods.runner import as_method
    from flexvox_core.progress import check_progress

    method = as_method(method, options)
    check_progress(progress)
    output = check_path(output, "output", call="fv.reconstruct_batch(recording, output, method)")
    if output.suffix.lower() != ".zarr":
        raise ValueError(f"the batch output must be a .zarr store; got {output}")
    if not isinstance(recording, Recording):
        check_recording_path(recording)
    source = recording.path if isinstance(recording, Recording) else recording
    check_output(output, overwrite=overwrite, inputs=[source])
    try:
        rec = recording if isinstance(recording, Recording) else open_recording(recording)
    except RecordingError as exc:
        raise ValueError(str(exc)) from None
    device, note = device_for(method, CaptureReader(rec).code_for(method), device)
    video, ov = batch_video(rec, method, chunk_frames=chunk_frames, device=device)
    pyramid = ngff.check_levels(pyramid, video.shape)
    chunk_frames = max(chunk_frames, ov)
    # Written beside the output and moved into place when every chunk is stored: a failed or
    # cancelled run leaves an old output as it was, and never a store with chunks of zeros.
    with atomic_output(output, overwrite=overwrite) as tmp, \
            progress_callback(progress, desc="batch", unit="chunk") as report:
        seconds, used = _store(rec, video, ov, chunk_frames, method, tmp, scheduler, report, connect_timeout_s,
                               pyramid, {"device": device, **({"device_note": note} if note else {})})
    _logger.info("batch: %s -> %s, %d sub-frames in %.2f s (%s)", rec.path, output, video.shape[0], seconds, used)
    return BatchResult(output, tuple(int(v) for v in video.shape), chunk_frames, ov, seconds, used, device, note)


def _store(rec, video, ov, chunk_frames, method, output, scheduler, progress, connect_timeout_s, pyramid=0,
           device=None):
    """Compute ``video`` into a new OME-Zarr image at ``output``; return (seconds, scheduler used)."""
    import dask
    import dask.array as da
    import zarr

    group = zarr.open_group(str(output), mode="w-", zarr_format=3)
    step = 1.0 / float(rec.attrs["rates"]["subframe_hz"])
    group.attrs["flexvox"] = provenance({"source": str(rec.path), "method": method.as_dict(),
                                         "chunk_frames": chunk_frames, "overlap_frames": ov, "batch": True,
                                         **(device or {"device": "cpu"})}, step)
    dropped = np.asarray(rec.per_frame("dropped"), bool)
    if dropped.any():  # which sub-frames were bridged across dropped frames, as `reconstruct` writes it
        flags = interpolated_subframes(dropped, video.shape[0] // len(dropped))
        group.create_array(INTERPOLATED, data=flags, chunks=(max(1, min(len(flags), 65536)),))
        group.attrs["flexvox"] = {**group.attrs["flexvox"], "interpolated_subframes": int(flags.sum())}
    targets = ngff.create_image(group, VIDEO, video.shape, time_step=step, levels=pyramid)
    sources = [video]
    for _ in targets[1:]:  # each level from the chunks of the one above, in the same pass
        sources.append(ngff.downsample(sources[-1]))
    # Each dask chunk covers whole Zarr chunks (one sub-frame each): parallel writes never share one.
    store = da.store(sources, targets, lock=False, compute=False)
    t0 = time.perf_counter()
    if scheduler is None:
        from dask.callbacks import Callback

        total = int(np.prod(video.numblocks))

        class _Progress(Callback):
            def __init__(self):
                super().__init__()
                self.chunks = set()

            @property
            def done(self) -> int:
                return len(self.chunks)

            def _posttask(self, key, result, dsk, state, id):  # noqa: A002 - dask's signature
                name = key[0] if isinstance(key, tuple) else key
                # Graph optimisation may fuse a chunk's tasks into one renamed key: count chunks.
                if isinstance(name, str) and "store-map" in name:
                    self.chunks.add(tuple(key[1:]) if isinstance(key, tuple) else name)
                    if progress:
                        progress(min(self.done, total), total)

        with _Progress() as counter:
            dask.compute(store, scheduler="threads")
        if progress and counter.done < total:
            progress(total, total)
        used = "local threads"
    else:
        from distributed import Client

        total = int(np.prod(video.numblocks))
        if progress:
            progress(0, total)
        if isinstance(scheduler, Client):  # the caller's client: used, left open
            scheduler.compute(store, sync=True)
            used = _address(scheduler)
        else:
            with Client(scheduler, timeout=connect_timeout_s) as client:
                client.compute(store, sync=True)
                used = scheduler if isinstance(scheduler, str) else _address(client)
        if progress:
            progress(total, total)
    return time.perf_counter() - t0, used


def _address(client) -> str:
    """A distributed client's scheduler, in words (its address when it has one)."""
    address = getattr(getattr(client, "scheduler", None), "address", None)
    return str(address) if address else repr(client)
