"""``flexvox info``: what a recording holds, and whether it is sound."""

from __future__ import annotations

import json
from pathlib import Path

from flexvox_app.cli.errors import EXIT_FAILED, EXIT_OK, CliError
from flexvox_core.writer_lock import lock_holder


def register(sub) -> None:
    """Add the ``info`` subcommand."""
    p = sub.add_parser(
        "info",
        help="summarise a recording and check it (schema, counts, gaps, every chunk's checksum)",
        description=(
            "Print what a recording holds (kind, code, rates, frames, dropped frames, ground truth, "
            "calibration, rig) and check it: schema and attributes, array lengths, frame ids (they must "
            "increase, and every gap must be a row flagged dropped), timestamps, and every frame's chunk: "
            "it must exist, decode and match the checksum written with it (a progress bar on long "
            "recordings; --quick checks the metadata only). Exit 0 when it is sound, 1 when it is "
            "damaged, 2 when it cannot be found. A capture that was killed or lost power is "
            "'interrupted': sound, its journal gives the true count; --repair finalises it."
        ),
    )
    p.add_argument("recording", type=Path, metavar="REC", help="a flexvox recording (.zarr)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--quick", action="store_true",
                   help="check the metadata only (schema, counts, frame ids), not every chunk's data")
    p.add_argument("--repair", action="store_true",
                   help="finalise an interrupted capture in place (exact array lengths, journal removed); one that "
                        "--overwrite began and that was killed before its first frame is deleted and the recording "
                        "it had moved aside put back")
    p.add_argument("--slots", action="store_true",
                   help="simulated recordings: read back which slot every pixel sampled (against the ground "
                        "truth) and print the slot accuracy; record 17 frames of the strobe scene for a full answer")
    p.set_defaults(func=run)


def leftovers(path) -> list[str]:
    """Hidden siblings an unfinished write left beside ``path`` (``.NAME.partial-*``, ``.NAME.replaced-*``)."""
    path = Path(path)
    patterns = (f".{path.stem}.partial-*{path.suffix}", f".{path.stem}.replaced-*{path.suffix}")
    return sorted(p.name for pattern in patterns for p in path.parent.glob(pattern))


def _beside(path) -> list:
    """The leftovers of unfinished writes of ``path`` beside it (:func:`flexvox_core.leftovers.find_leftovers`;
    lock files left out)."""
    from flexvox_core.leftovers import find_leftovers

    path = Path(path)
    if not path.parent.is_dir():
        return []
    return [i for i in find_leftovers(path.parent) if i.output.name == path.name and i.kind != "lock"]


def _only_copy(item) -> bool:
    """Whether a leftover is an earlier output that is now its only copy (never to be removed)."""
    return item.kind == "replaced" and item.writer is None and not item.removable


def _left_by_a_killed_write(path) -> str:
    """"; a killed write left …" when unfinished outputs of ``path`` lie beside it, else ""."""
    items = _beside(path)
    parts = [f"{i.path.name} beside it is {i.why}" for i in items if _only_copy(i)]
    rest = [i.path.name for i in items if not _only_copy(i)]
    if rest:
        parts.append(f"an unfinished write left {', '.join(rest)} beside it (`flexvox clean {Path(path).parent}` "
                     "lists such leftovers and removes them)")
    return "".join(f"; {p}" for p in parts)


def _leftover_notes(path) -> list[str]:
    """One "note:" line for each leftover of an unfinished write beside the recording ``path``."""
    lines = []
    for item in _beside(path):
        if _only_copy(item):
            lines.append(f"note: {item.path.name} beside it is {item.why}")
            continue
        kind = "the recording an overwriting capture moved aside" if item.kind == "replaced" else "a partial write"
        lines.append(f"note: {item.path.name} beside it is {kind}, left by a write that did not finish; "
                     "`flexvox clean` lists such leftovers and removes them")
    return lines


def not_a_recording(path) -> str | None:
    """Why ``path`` (which exists) is not a recording at all, in words, or None when it looks like one.

    A recording is a Zarr folder (``NAME.zarr/zarr.json``); a file or a folder without ``zarr.json`` is something
    else (exit 2), not a damaged recording (exit 1).
    """
    path = Path(path)
    if not path.is_dir():
        return (f"{path} is a file, not a flexvox recording (a recording is a .zarr folder, as flexvox simulate "
                "and flexvox capture write it)")
    if not (path / "zarr.json").is_file():
        return (f"{path} is a folder but not a flexvox recording: it holds no zarr.json (a recording is a .zarr "
                "folder, as flexvox simulate and flexvox capture write it)")
    if _node_type(path) == "array" and _node_type(path.parent) == "group":
        return (f"{path} is the `{path.name}` array of the recording {path.parent}, not a recording: give the "
                f"recording's folder, {path.parent}")
    if (path / "video" / "zarr.json").is_file() and not (path / "frames").exists():
        return (f"{path} is a reconstructed video (an OME-Zarr image), not a recording of camera frames: "
                "flexvox export writes it to TIFF, MP4, PNG or .npy; napari and Fiji open it")
    return None


def _node_type(path: Path) -> str | None:
    """The ``node_type`` a Zarr folder's zarr.json states ("group", "array"), or None."""
    import json

    try:
        doc = json.loads((path / "zarr.json").read_bytes())
    except (OSError, ValueError):
        return None
    return doc.get("node_type") if isinstance(doc, dict) else None


def check(rec, *, quick: bool = False, progress=None) -> tuple[dict, list[str]]:
    """Summary of an opened recording and the problems found beyond its structure.

    Unless ``quick``, every frame and ground-truth chunk is read and checked against its checksum
    (:meth:`~flexvox_core.recording.Recording.verify`; ``progress(done, total)`` follows it).
    """
    import numpy as np

    from flexvox_core.recording import moved_aside_by

    problems = []
    ids = rec.per_frame("frame_id")
    dropped = rec.per_frame("dropped")
    stamps = rec.per_frame("timestamp")
    steps = np.diff(ids)
    if np.any(steps <= 0):
        k = int(np.flatnonzero(steps <= 0)[0])
        problems.append(f"frame ids do not increase at row {k + 1} ({ids[k]} then {ids[k + 1]})")
    gaps = int(np.sum(np.maximum(steps - 1, 0)))
    if gaps:
        k = int(np.flatnonzero(steps > 1)[0])
        problems.append(f"{gaps} frame id(s) missing without a dropped row (first after id {ids[k]})")
    good = stamps[~dropped]
    if good.size > 1 and np.any(np.diff(good) < 0):
        problems.append("timestamps of recorded frames go backwards")
    if not np.all(np.isfinite(stamps)):
        problems.append("timestamps hold NaN or infinity")
    F, H, W = rec.frames.shape
    notes = []
    if not quick:
        for line in rec.verify(progress):
            (notes if line.startswith("no checksums") else problems).append(line)
    aside = moved_aside_by(rec.path) if rec.interrupted and F == 0 else None
    a = rec.attrs
    for key in ("calibration", "rig", "capture"):  # objects as written; an edited one is named, not a traceback
        if a.get(key) is not None and not isinstance(a[key], dict):
            problems.append(f"the `{key}` attribute must be an object; got {a[key]!r} (the attributes were edited "
                            "or damaged)")
    rates = a.get("rates", {})
    summary = {
        "path": str(rec.path), "kind": a.get("kind"), "schema_version": a.get("schema_version"),
        "software_version": a.get("software_version"), "created_utc": a.get("created_utc"),
        "tile": a.get("tile"), "K": rec.K, "multiplexed": bool(a.get("multiplexed")),
        "camera_hz": rates.get("camera_hz"), "subframe_hz": rates.get("subframe_hz"),
        "frames": F, "height": H, "width": W, "dtype": str(rec.frames.dtype),
        "storage": a.get("storage", {}).get("kind"), "dropped": int(dropped.sum()),
        "first_dropped_rows": np.flatnonzero(dropped)[:5].tolist(),
        "frame_ids": [int(ids[0]), int(ids[-1])] if F else None,
        "duration_s": float(F / rates["camera_hz"]) if rates.get("camera_hz") else None,
        "ground_truth": rec.has_ground_truth, "interrupted": rec.interrupted,
        "calibration": a.get("calibration"), "rig": a.get("rig"), "capture": a.get("capture"),
        "effects": a.get("effects"), "writer": lock_holder(rec.path), "leftovers": leftovers(rec.path),
        "checked": "metadata" if quick else "metadata and every chunk",
        "checksums": rec.has_checksums, "notes": notes, "problems": problems,
        "moved_aside": aside.name if aside is not None else None,
    }
    return summary, problems


def _text(s: dict) -> list[str]:
    lines = [
        f"{s['path']}: {s['kind']} recording, schema {s['schema_version']}, flexvox {s['software_version']}, "
        f"created {s['created_utc']}",
        f"code: tile {s['tile'][0]}x{s['tile'][1]}, K = {s['K']}{', multiplexed' if s['multiplexed'] else ''}; "
        f"camera {s['camera_hz']:g} Hz, sub-frames {s['subframe_hz']:g} Hz",
        f"frames: {s['frames']} of {s['height']}x{s['width']} {s['dtype']} ({s['storage']})"
        + (f", ids {s['frame_ids'][0]}..{s['frame_ids'][1]}" if s["frame_ids"] else "")
        + (f", {s['duration_s']:.2f} s" if s["duration_s"] is not None else ""),
        f"dropped: {s['dropped']}" + (f" (first rows {s['first_dropped_rows']})" if s["dropped"] else ""),
        f"ground truth: {'yes' if s['ground_truth'] else 'no'}",
    ]
    cal = s["calibration"]
    if cal and isinstance(cal, dict):
        delay = cal.get("trigger_delay_us")
        lines.append(f"calibration: {cal.get('source', '?')}, phase {cal.get('phase_slots', '?')} slot(s)"
                     + (f", camera trigger delay {delay:.0f} µs" if delay else ""))
    if s["rig"] and isinstance(s["rig"], dict):
        lines.append("rig: " + ", ".join(f"{k} {v:g}" if isinstance(v, float) else f"{k} {v}"
                                         for k, v in s["rig"].items() if not isinstance(v, dict | list)))
    if s["capture"] and isinstance(s["capture"], dict):
        c = s["capture"]
        lines.append(f"capture: ended {c.get('reason')}" + (f" ({c['error']})" if c.get("error") else "")
                     + f", {c.get('queue_drops', 0)} frame(s) discarded by the queue")
    lines.append(f"checked: {s['checked']}" + ("" if s["checksums"] else " (no checksums: schema 1)"))
    lines += [f"note: {n}" for n in s["notes"]]
    if s["interrupted"] and s["writer"]:
        lines.append(f"being written now by {s['writer']}: the frames committed so far are readable")
    elif s["interrupted"] and s["moved_aside"]:
        lines.append(f"interrupted: the capture was killed before its first frame; `flexvox info --repair` deletes "
                     f"it and puts back {s['moved_aside']}, the earlier recording it had moved aside to replace it")
    elif s["interrupted"]:
        lines.append("interrupted: the capture did not finish (killed or power lost); every committed frame "
                     "is readable. `flexvox info --repair` finalises it.")
    lines += _leftover_notes(s["path"])
    return lines


def _slots(rec) -> dict:
    """The slot check of a recording with ground truth (:mod:`flexvox_core.slot_check`)."""
    from flexvox_core.capture_reader import read_capture
    from flexvox_core.recording import RecordingError
    from flexvox_core.slot_check import slot_accuracy

    if not rec.has_ground_truth:
        raise CliError(f"{rec.path} holds no ground truth: --slots needs a simulated recording "
                       "(flexvox capture --rig mock --ground-truth, or flexvox simulate)")
    try:
        frames, code = read_capture(rec)
        truth = rec.ground_truth[:]
    except RecordingError as exc:
        raise CliError(f"--slots: {exc}") from None
    check = slot_accuracy(frames, truth, code)
    cal = rec.attrs.get("calibration")
    stated = cal.get("warnings") if isinstance(cal, dict) else None  # the capture's timing guesses, if any
    warnings = [str(w) for w in stated] if isinstance(stated, list) else []
    return {"accuracy": check.accuracy, "decidable_fraction": check.decidable_fraction,
            "single_slot_fit": check.single_slot_fit, "message": check.describe(warnings)}


def run(args) -> int:
    """Carry out ``flexvox info``."""
    from flexvox_core.output_files import OutputError
    from flexvox_core.recording import RecordingError, open_recording, repair_recording

    if not args.recording.exists():
        raise CliError(f"{args.recording}: no such recording{_left_by_a_killed_write(args.recording)}")
    not_one = not_a_recording(args.recording)
    if not_one:
        raise CliError(not_one)
    try:
        if args.repair:
            try:
                repair = repair_recording(args.recording)
            except OutputError as exc:  # a capture still writes it
                raise CliError(f"--repair: {exc}") from None
            except OSError as exc:  # a read-only recording
                raise CliError(f"--repair: cannot finalise {args.recording}: {exc.strerror or exc}; nothing was "
                               "changed") from None
            print(f"{args.recording}: {repair.describe()}")
        rec = open_recording(args.recording)
    except RecordingError as exc:
        payload = {"path": str(args.recording), "problems": [str(exc)]}
        if args.json:
            print(json.dumps(payload))
        else:
            print(f"{args.recording}: DAMAGED: {exc}")
            for line in _leftover_notes(args.recording):
                print(line)
        return EXIT_FAILED
    from tqdm import tqdm

    with tqdm(unit="frame", desc="checking", leave=False, disable=args.quick or rec.n_frames < 64 or None) as bar:
        def progress(done, total):
            bar.total = total
            bar.update(done - bar.n)

        summary, problems = check(rec, quick=args.quick, progress=progress)
    if args.slots:
        summary["slots"] = _slots(rec)
    if args.json:
        print(json.dumps(summary))
    else:
        print("\n".join(_text(summary)))
        if args.slots:
            print(summary["slots"]["message"])
        for p in problems:
            print(f"problem: {p}")
        print("DAMAGED" if problems else "OK")
    return EXIT_FAILED if problems else EXIT_OK
