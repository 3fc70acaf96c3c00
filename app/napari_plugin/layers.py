"""What the napari plugin shows, as plain Python: npe2 layer-data tuples, and reconstruction steps.

Nothing here imports napari or Qt: napari's reader contract is a function returning a list of
``(data, kwargs, layer_type)`` tuples, and the dock widgets turn a finished reconstruction into
the same tuples (:func:`result_layers`), so all of it is tested without a viewer.

Time in napari is in seconds: every layer's scale in t is its time step — one camera frame
(1/fps) for a recording's coded frames, one sub-frame (1/(fps·K)) for ground truth and
reconstructions — so a recording and its reconstruction play together on one slider. A coded
frame is shifted by (K − 1)/2 sub-frames (its exposure's centre), so that at any sub-frame the
slider shows the camera frame whose exposure holds it (napari shows a layer's nearest index).
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from pathlib import Path

import numpy as np

FRAMES, TRUTH, RECONSTRUCTION, FLOW, TR = "coded frames", "ground truth", "reconstruction", "flow", "TR map"
"""The kinds of layer the plugin makes (``metadata["flexvox"]["kind"]``)."""


class Cancelled(Exception):
    """The reconstruction was cancelled between two chunks."""


# --------------------------------------------------------------------------- reader


def get_reader(path):
    """npe2 reader hook: :func:`read` for a flexvox recording or reconstruction (a ``.zarr`` folder), else None."""
    if isinstance(path, list | tuple):
        if len(path) != 1:
            return None
        path = path[0]
    return read if what_is(path) is not None else None


def what_is(path) -> str | None:
    """"recording", "reconstruction" or None (not a Zarr store flexvox wrote). Reads only ``zarr.json``."""
    import json

    p = Path(path)
    try:
        meta = json.loads((p / "zarr.json").read_text())
    except (OSError, ValueError):
        return None
    attrs = (meta.get("attributes") or {}).get("flexvox")
    if not isinstance(attrs, dict):
        return None
    if "schema_version" in attrs and (p / "frames").is_dir():
        return "recording"
    if (p / "video").is_dir():
        return "reconstruction"
    return None


def read(path) -> list[tuple]:
    """The layers of a flexvox recording (coded frames; ground truth where stored) or reconstruction.

    Raises
    ------
    ValueError
        Not a flexvox store, or a recording flexvox refuses (its message says why).
    """
    if isinstance(path, list | tuple):
        path = path[0]
    kind = what_is(path)
    if kind == "recording":
        return recording_layers(path)
    if kind == "reconstruction":
        return reconstruction_layers(path)
    raise ValueError(f"{path}: not a flexvox recording or reconstruction (a .zarr store with a `flexvox` "
                     "attribute and a `frames` or `video` array)")


def _lazy(rows):
    """A dask array over checked rows (:class:`~flexvox_core.recording.VerifiedRows`): napari reads the
    frames it shows, each checked against its CRC as every flexvox reader does."""
    import dask.array as da

    return da.from_array(rows, chunks=(1, *rows.shape[1:]), asarray=True, lock=False, fancy=False)


def recording_layers(path) -> list[tuple]:
    """A recording's coded frames (raw, as stored) and, when stored, its ground truth."""
    from flexvox_core.recording import open_recording

    rec = open_recording(path)
    attrs = rec.attrs
    camera_hz, sub_hz, K = float(attrs["rates"]["camera_hz"]), float(attrs["rates"]["subframe_hz"]), rec.K
    stem = Path(path).name.removesuffix(".zarr")
    common = {"recording": str(Path(rec.path).resolve()), "K": K, "camera_hz": camera_hz, "subframe_hz": sub_hz,
              "tile": list(attrs["tile"]), "kind_of_recording": attrs.get("kind")}
    layers = [(_lazy(rec.frames), {
        "name": f"{stem}: {FRAMES}",
        "scale": (1.0 / camera_hz, 1.0, 1.0),
        "translate": ((K - 1) / 2 / sub_hz, 0.0, 0.0),
        "colormap": "gray",
        "metadata": {"flexvox": {"kind": FRAMES, **common}},
    }, "image")]
    if rec.has_ground_truth:
        layers.append((_lazy(rec.ground_truth), {
            "name": f"{stem}: {TRUTH}",
            "scale": (1.0 / sub_hz, 1.0, 1.0),
            "contrast_limits": (0.0, 1.0),
            "colormap": "gray",
            "visible": False,
            "metadata": {"flexvox": {"kind": TRUTH, **common}},
        }, "image"))
    return layers


def method_label(method: dict | None) -> str:
    """A stored method (``Method.as_dict()``) as :meth:`Method.label` words, or its name when it no longer parses."""
    if not isinstance(method, dict) or "name" not in method:
        return "reconstruction"
    from flexvox_core.methods import Method

    try:
        values = {k: tuple(v) if isinstance(v, list) else v for k, v in method.items() if k != "name"}
        return Method(method["name"], **values).label()
    except (ValueError, TypeError):
        return str(method["name"])


def reconstruction_layers(path) -> list[tuple]:
    """A reconstruction store (OME-Zarr or the earlier plain group), its pyramid as napari multiscale."""
    from flexvox_core.video_io import open_video_store

    store = open_video_store(path)
    stem = Path(path).name.removesuffix(".zarr")
    step = store.time_step
    levels = list(store.levels)
    name = f"{stem}: {method_label(store.attrs.get('method'))}"
    return [(levels if len(levels) > 1 else levels[0], {
        "name": name,
        "scale": (step or 1.0, 1.0, 1.0),
        "contrast_limits": (0.0, 1.0),
        "colormap": "gray",
        "multiscale": len(levels) > 1,
        "metadata": {"flexvox": {"kind": RECONSTRUCTION, "source": store.attrs.get("source"),
                                 "method": store.attrs.get("method"), "time_step_s": step}},
    }, "image")]


# --------------------------------------------------------------------------- reconstruction


def recording_of(metadata) -> str | None:
    """The recording a layer came from (a layer of :func:`recording_layers`), else None."""
    meta = (metadata or {}).get("flexvox") if isinstance(metadata, dict) else None
    if isinstance(meta, dict) and meta.get("kind") in (FRAMES, TRUTH):
        return meta.get("recording")
    return None


def reconstruction_steps(path, method, *, chunk_frames: int = 16, extras: bool = False,
                         cancel: threading.Event | None = None, device: str = "auto") -> Iterator[int]:
    """Reconstruct a recording with flexvox's one runner, yielding after every chunk.

    A generator for napari's ``thread_worker``: each ``yield`` gives the camera frames done since the
    last one (napari's progress bar counts them); its return value (``StopIteration.value``) is the
    :class:`~flexvox_core.methods.spec.MethodOutput` (its ``device`` says where it ran: the GPU by default when
    one is usable and the method has a GPU path). The runner works in lock-step with the consumer:
    it waits after each chunk until the generator is resumed, so closing the generator, or setting
    ``cancel``, stops it at the next chunk boundary (raising :class:`Cancelled` in the generator when
    ``cancel`` was set).

    Raises
    ------
    ValueError
        A recording that cannot be opened or reconstructed, or a method the recording refuses.
    Cancelled
        ``cancel`` was set.
    """
    from flexvox_core.capture_reader import open_capture

    cancel = cancel or threading.Event()
    reader = open_capture(path)
    steps: queue.Queue = queue.Queue()
    resume = threading.Semaphore(0)
    box: dict = {}

    def progress(done: int, total: int) -> None:
        steps.put(done)
        while not resume.acquire(timeout=0.05):
            if cancel.is_set():
                break
        if cancel.is_set():
            raise Cancelled("the reconstruction was cancelled")

    def work() -> None:
        try:
            box["out"] = reader.run(method, chunk_frames=chunk_frames, progress=progress, extras=extras, device=device)
        except BaseException as exc:  # noqa: BLE001 - handed to the generator, which raises it
            box["error"] = exc
        finally:
            steps.put(None)

    runner = threading.Thread(target=work, name="flexvox-napari-reconstruction", daemon=True)
    runner.start()
    last = 0
    try:
        while (done := steps.get()) is not None:
            yield done - last
            last = done
            resume.release()
    finally:
        if runner.is_alive():  # closed early (napari's quit, a viewer closing): stop at the next chunk
            cancel.set()
            runner.join()
    if "error" in box:
        raise box["error"]
    return box["out"]


def result_layers(output, *, method, recording: str, subframe_hz: float, K: int) -> list[tuple]:
    """A finished reconstruction as layers: the video and, when the method returned them, the flow as a
    colour wheel (RGB) and the TR map (temporal-resolution gain per voxel; SR = 1/TR)."""
    from flexvox_core.flow.visualize import flow_to_color

    stem = Path(recording).name.removesuffix(".zarr")
    step = (1.0 / float(subframe_hz), 1.0, 1.0)
    meta = {"recording": str(recording), "method": method.as_dict(), "time_step_s": step[0]}
    if getattr(output, "interpolated", None) is not None:  # sub-frames bridged across dropped frames
        meta["interpolated_subframes"] = np.flatnonzero(output.interpolated).tolist()
    layers = [(output.video, {"name": f"{stem}: {method.label()}", "scale": step, "contrast_limits": (0.0, 1.0),
                              "colormap": "gray", "metadata": {"flexvox": {"kind": RECONSTRUCTION, **meta}}},
               "image")]
    flow, tr = output.extras.get("flow"), output.extras.get("tr")
    if flow is not None:
        speed = np.hypot(flow[..., 0], flow[..., 1])
        top = float(np.nanmax(speed)) if np.isfinite(speed).any() else 1.0
        wheel = np.stack([flow_to_color(f, max_magnitude=max(top, 1e-6)) for f in flow])
        layers.append((wheel, {"name": f"{stem}: flow (colour wheel, full = {top:.2g} px/sub-frame)",
                               "scale": step, "rgb": True, "visible": False,
                               "metadata": {"flexvox": {"kind": FLOW, "max_px_per_subframe": top, **meta}}},
                       "image"))
    if tr is not None:
        layers.append((np.asarray(tr, np.float32), {
            "name": f"{stem}: TR map (1 = high SR, {K} = high TR; SR = 1/TR)", "scale": step,
            "contrast_limits": (1.0, float(K)), "colormap": "viridis", "visible": False,
            "metadata": {"flexvox": {"kind": TR, **meta}}}, "image"))
    return layers
