"""The structural checks of an opened recording (the values of its frames are checked as they are read)."""

from __future__ import annotations

from flexvox_core.codes import is_identity_code, validate_code
from flexvox_core.rates import rate_problems
from flexvox_core.recording.schema import PER_FRAME, REQUIRED_ATTRS


def validate_recording(rec) -> list[str]:
    """Structural problems of a recording (empty when it is sound).

    ``rec`` is a :class:`~flexvox_core.recording.reader.Recording`: its attributes, its arrays (looked
    up by name) and its frame count, from the journal for an interrupted capture.
    """
    problems = []
    missing = [k for k in REQUIRED_ATTRS if k not in rec.attrs]
    if missing:
        return [f"missing attribute(s): {', '.join(missing)}"]
    try:
        code = validate_code(rec.attrs["code"])
    except ValueError as exc:
        return [f"bad code attribute: {exc}"]
    m, n, K = code.shape
    if [m, n] != list(rec.attrs["tile"]) or K != rec.attrs["K"]:
        problems.append(f"code shape {code.shape} disagrees with tile {rec.attrs['tile']} and K {rec.attrs['K']}")
    problems += rate_problems(rec.attrs["rates"], K)
    if not rec.attrs.get("multiplexed") and not is_identity_code(code):
        problems.append("the code opens pixels in more than one slot (or slots for more than one pixel), but the "
                        "recording is not marked `multiplexed`: no reconstruction can tell what its frames hold")
    # Each array looked up by name, never by listing the folder: a capture writing beside this reader renames
    # zarr's temporary metadata files into place, and a listing that meets one as it vanishes fails.
    needed = ("frames", *PER_FRAME) + (("frame_crc",) if rec.attrs["schema_version"] >= 2 else ())
    for name in needed:
        if name not in rec.group:
            problems.append(f"array `{name}` is missing")
    has_gt, has_gt_crc = ("ground_truth" in rec.group), ("ground_truth_crc" in rec.group)  # each a read: once
    if has_gt and rec.attrs["schema_version"] >= 2 and not has_gt_crc:
        problems.append("array `ground_truth_crc` is missing")
    if problems:
        return problems
    F = rec.n_frames
    if rec.group["frames"].ndim != 3:
        problems.append(f"`frames` must be (F, H, W); got {rec.group['frames'].shape}")
    if rec.journal is None:
        for name in needed[1:]:
            if rec.group[name].shape != (F,):
                problems.append(f"`{name}` has {rec.group[name].shape[0]} entries for {F} frames")
    elif rec.attrs["schema_version"] >= 2 and rec.journal["frame_crc"] is None:
        problems.append("the capture journal has no frame checksums (schema 1) in a schema-2 recording")
    kind = rec.attrs["storage"].get("kind")
    if kind not in ("float", "counts"):
        problems.append(f"unknown storage kind {kind!r}")
    if has_gt:
        gt = rec.group["ground_truth"].shape
        if gt != (F * K, *rec.group["frames"].shape[1:]):
            problems.append(f"`ground_truth` {gt} does not match {F} frames of K = {K}")
        elif has_gt_crc and rec.group["ground_truth_crc"].shape != (gt[0],):
            problems.append(f"`ground_truth_crc` has {rec.group['ground_truth_crc'].shape[0]} entries for {gt[0]} "
                            "sub-frames")
    return problems


