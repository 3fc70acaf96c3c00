"""OME-Zarr (NGFF 0.5, on Zarr v3) descriptions of the images flexvox writes.

A reconstruction written as ``.zarr`` (``flexvox reconstruct``, ``export``, ``batch``) and a
recording's raw ``frames`` are OME-Zarr images, so napari, Fiji (through its OME-Zarr readers) and any
NGFF reader know their axes and their time step without flexvox:

* axes ``t`` (type ``time``, unit ``second``), ``y``, ``x`` (type ``space``, no physical unit: pixels);
  every image array carries the same ``dimension_names``, as NGFF 0.5 requires;
* one multiscale whose first dataset is the full-resolution array (``video`` for a reconstruction,
  ``frames`` for a recording: the names flexvox always wrote, so readers of earlier outputs keep
  working); its scale transformation gives the time step in seconds (one sub-frame, 1/(fps·K), for a
  reconstruction; one camera frame, 1/fps, for a recording's frames) and 1 pixel in y and x;
* an optional pyramid (``levels`` ≥ 1, off by default): level i is array ``NAME_i``, each sub-frame's
  2×2 mean of level i−1 (a trailing odd row or column is dropped), scale 2^i and translation
  (2^i − 1)/2 pixels in y and x (the centre of the block it averages), the same time step;
* flexvox's own attributes stay under the group's ``flexvox`` key; NGFF's are under ``ome``.

The ``ome`` block is built as a plain dict (:func:`image_attrs`); the tests build the same block through
the models of ``ome-zarr-models`` and compare, and :func:`validate_image` checks a written store against
those models (the tests validate every image flexvox writes). ome-zarr-models (and pydantic) is imported
only by :func:`validate_image`: writing an image does not need it.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from flexvox_core.numbers import positive_number

NGFF_VERSION = "0.5"
AXES = ("t", "y", "x")
"""The axes of every image flexvox writes, in array order (its Zarr ``dimension_names``)."""


def check_time_step(time_step) -> float | None:
    """A time step in seconds: a finite number above 0, or None (unknown: the t axis then has no unit)."""
    if time_step is None:
        return None
    return positive_number("the time step", time_step, unit="seconds")


def max_levels(shape) -> int:
    """The most pyramid levels an image of ``shape`` (…, H, W) can have (the last one at least 1×1)."""
    H, W = int(shape[-2]), int(shape[-1])
    return max(0, int(math.floor(math.log2(min(H, W))))) if min(H, W) >= 1 else 0


def check_levels(levels, shape) -> int:
    """Pyramid levels below full resolution: a whole number from 0 to :func:`max_levels` of ``shape``."""
    top = max_levels(shape)
    if isinstance(levels, bool) or not isinstance(levels, int | np.integer) or not 0 <= levels <= top:
        raise ValueError(f"the pyramid levels must be a whole number from 0 to {top} (each level halves the "
                         f"{shape[-2]}x{shape[-1]} image in y and x); got {levels!r}")
    return int(levels)


def level_path(dataset: str, level: int) -> str:
    """The array of pyramid ``level`` (0: ``dataset`` itself, the full resolution)."""
    return dataset if level == 0 else f"{dataset}_{level}"


def level_shape(shape, level: int) -> tuple[int, int, int]:
    """The shape of pyramid ``level`` of an image of ``shape`` (T, H, W)."""
    T, H, W = (int(v) for v in shape)
    return T, H >> level, W >> level


def image_attrs(dataset: str, *, time_step: float | None, levels: int = 0, name: str | None = None) -> dict:
    """The group's ``ome`` attribute (NGFF 0.5) for the image ``dataset`` and its pyramid levels.

    A plain dict, in the form ome-zarr-models' pydantic models (``Axis``, ``Dataset``, ``Multiscale``,
    ``ImageAttrs``) dump: the tests build the same block through those models for every form this
    function writes and check the two are equal, and validate every image flexvox writes. Building it
    through the models at run time cost every writer 0.15 s of importing pydantic.
    """
    step = check_time_step(time_step)
    if isinstance(levels, bool) or not isinstance(levels, int | np.integer) or levels < 0:
        raise ValueError(f"the pyramid levels must be a whole number >= 0; got {levels!r}")
    levels = int(levels)
    t_axis = {"name": "t", "type": "time"}
    if step is not None:
        t_axis["unit"] = "second"
    axes = [t_axis, {"name": "y", "type": "space"}, {"name": "x", "type": "space"}]
    datasets = []
    for level in range(levels + 1):
        factor = float(2 ** level)
        shift = (factor - 1) / 2
        transforms = [{"type": "scale", "scale": [float(step or 1.0), factor, factor]}]
        if level:
            transforms.append({"type": "translation", "translation": [0.0, shift, shift]})
        datasets.append({"path": level_path(dataset, level), "coordinateTransformations": transforms})
    multiscale = {"axes": axes, "datasets": datasets, "name": name or dataset}
    if levels:
        multiscale["type"] = "local_mean"
    return {"version": NGFF_VERSION, "multiscales": [multiscale]}


def create_image(group, dataset: str, shape, *, time_step: float | None, levels: int = 0, dtype="float32",
                 name: str | None = None, fill_value=0) -> list:
    """Create ``dataset`` (and its pyramid levels) in the Zarr v3 ``group`` with the ``ome`` attribute.

    Each array has one t-step per chunk and ``dimension_names`` ("t", "y", "x"). Returns the arrays,
    full resolution first; the caller writes their values (:func:`downsample` makes each level).
    """
    levels = check_levels(levels, shape)
    group.attrs["ome"] = image_attrs(dataset, time_step=time_step, levels=levels, name=name)
    arrays = []
    for level in range(levels + 1):
        T, H, W = level_shape(shape, level)
        arrays.append(group.create_array(level_path(dataset, level), shape=(T, H, W), chunks=(1, H, W),
                                         dtype=dtype, fill_value=fill_value, dimension_names=AXES,
                                         compressors=image_compressor()))
    return arrays


def image_compressor():
    """Blosc LZ4 with byte shuffle, for reconstructions and the ground truth of simulated recordings (a
    recording's ``frames`` keep zarr's default Zstd): on a 1-s 640×480 K = 16 reconstruction (295 MB of
    float32) it wrote in 0.69 s and read in 0.29 s, against 1.17 and 0.90 s for zarr's default Zstd, at
    the same size (234 against 238 MB). Every reader of Zarr v3 (zarr-python, napari, Fiji's N5/Zarr
    readers via Blosc) decodes it."""
    from zarr.codecs import BloscCodec

    return BloscCodec(cname="lz4", clevel=5, shuffle="shuffle")


def downsample(video):
    """One pyramid step: each (T, H, W) sub-frame's 2×2 means, float32, (T, H//2, W//2); numpy or dask."""
    T, H, W = video.shape
    h, w = H // 2, W // 2
    if not isinstance(video, np.ndarray) and hasattr(video, "map_blocks"):  # a dask array
        import dask.array as da

        return da.coarsen(np.mean, video, {1: 2, 2: 2}, trim_excess=True).astype(np.float32)
    v = np.asarray(video, dtype=np.float32)[:, : 2 * h, : 2 * w]
    return v.reshape(T, h, 2, w, 2).mean(axis=(2, 4), dtype=np.float32)


def write_pyramid(arrays, video) -> None:
    """Write ``video`` (T, H, W) into ``arrays`` (from :func:`create_image`), each level from the one above."""
    level = video
    for i, arr in enumerate(arrays):
        if i:
            level = downsample(level)
        arr[:] = level


def validate_image(store):
    """Check the OME-Zarr image at ``store`` (a path or a zarr group) against NGFF 0.5; return its model.

    Uses ome-zarr-models' ``Image.from_zarr`` (axes, coordinate transformations, datasets that exist
    with matching dimensions and ``dimension_names``): a checking tool, installed with the ``test`` extra
    (writing an image does not need it).

    Raises
    ------
    ValueError
        Naming the store and what NGFF refuses in it.
    ImportError
        ome-zarr-models is not installed (with what to install).
    """
    import zarr

    import flexvox_core.zarr_exit  # noqa: F401 - a quiet exit (see there)

    try:
        import pydantic
        from ome_zarr_models.v05.image import Image
    except ImportError as exc:
        raise ImportError(f"checking an OME-Zarr image needs ome-zarr-models ({exc}); install it with "
                          "`pip install ome-zarr-models` or the test extra, `pip install 'flexvox[test]'`") from None

    group = zarr.open_group(str(store), mode="r") if isinstance(store, str | Path) else store
    try:
        return Image.from_zarr(group)
    except (ValueError, pydantic.ValidationError) as exc:
        raise ValueError(f"{store} is not a valid OME-Zarr {NGFF_VERSION} image: {exc}") from None


def time_step(attrs: dict, dataset: str) -> float | None:
    """The time step in seconds that a group's ``ome`` attribute gives ``dataset``, or None."""
    for multiscale in (attrs.get("ome") or {}).get("multiscales", []):
        axes = multiscale.get("axes", [])
        if not axes or axes[0].get("type") != "time" or axes[0].get("unit") != "second":
            continue
        for ds in multiscale.get("datasets", []):
            if ds.get("path") == dataset:
                for tf in ds.get("coordinateTransformations", []):
                    if tf.get("type") == "scale":
                        return float(tf["scale"][0])
    return None
