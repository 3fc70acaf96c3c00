"""Reading a recording: :func:`open_recording` validates a store and returns a :class:`Recording`.

A store that still has a capture journal is an *interrupted* capture: :func:`open_recording` takes
the count and the per-frame values from the journal (``Recording.interrupted`` is True,
``n_frames`` is the true count and ``frames`` shows exactly those rows). A reader beside a running
capture looks at the frames' rows before and after looking for the journal, so a capture starting
or finishing meanwhile is never seen as a finished recording whose capacity rows are frames; each
array is looked up by name, never by listing the folders, where zarr's temporary files come and go.
"""

from __future__ import annotations

import html
import json
import logging
import warnings
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
import zarr

from flexvox_core.recording.errors import RecordingError
from flexvox_core.recording.journal import JOURNAL, read_journal
from flexvox_core.recording.schema import SCHEMA_VERSION, WRITTEN_PER_FRAME
from flexvox_core.recording.validation import validate_recording
from flexvox_core.recording.verified_rows import VerifiedRows, chunk_files_missing

_logger = logging.getLogger(__name__)


def _deprecated(old: str, new: str) -> None:
    warnings.warn(f"`Recording.{old}` is deprecated and goes in flexvox 0.3: use {new}", DeprecationWarning,
                  stacklevel=3)


class GroundTruthRows(VerifiedRows):
    """The simulated high-speed video ``(S, H, W)`` float32 as an array-like (:class:`VerifiedRows`).

    Calling it, ``rec.ground_truth(start, stop)``, is the old method's spelling: it still returns
    sub-frames ``[start, stop)``, with a DeprecationWarning, until flexvox 0.3 (write
    ``rec.ground_truth[start:stop]``).
    """

    def __call__(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        warnings.warn("`Recording.ground_truth` is an array-like now; calling it is deprecated and goes in flexvox "
                      "0.3: write `rec.ground_truth[start:stop]` (or `np.asarray(rec.ground_truth)`)",
                      DeprecationWarning, stacklevel=2)
        return self.read(start, self.n if stop is None else stop)


@dataclass(repr=False)
class Recording:
    """An opened, validated recording (:func:`open_recording`).

    Array-likes (read lazily, every row checked against its checksum): :attr:`frames` ``(F, H, W)`` as
    stored and :attr:`ground_truth` ``(S, H, W)`` (simulated recordings). Metadata: :attr:`code`,
    :attr:`tile`, :attr:`K`, :attr:`n_frames`, :attr:`camera_hz`, :attr:`dropped`, :attr:`calibration`,
    and every attribute in :attr:`attrs`.

    ``journal`` holds the committed per-frame values of an *interrupted* capture (a store
    whose writer never closed, see the module docstring); it is None for a finished one.

    Examples
    --------
    >>> rec = open_recording("rec.zarr")  # doctest: +SKIP
    >>> rec.n_frames, rec.K, rec.dropped.sum(), rec.ground_truth[:2].shape  # doctest: +SKIP
    (12, 16, 0, (2, 120, 160))
    """

    path: Path
    group: zarr.Group
    attrs: dict
    journal: dict | None = field(default=None, repr=False)
    rows_seen: int | None = field(default=None, repr=False)
    """The frames' rows when it was opened (a finished recording's count); None: read them now."""

    @property
    def rows(self) -> int | None:
        """Deprecated (until flexvox 0.3): the frames' rows seen when opened; use :attr:`n_frames`."""
        _deprecated("rows", "`n_frames` (the number of camera frames)")
        return self.rows_seen

    @property
    def interrupted(self) -> bool:
        """True when the capture writing this recording did not finish (journal present)."""
        return self.journal is not None

    @property
    def has_checksums(self) -> bool:
        """True when every frame carries a CRC (schema 2 and later)."""
        if self.journal is not None:
            return self.journal.get("frame_crc") is not None
        return "frame_crc" in self.group

    @cached_property
    def frames(self) -> VerifiedRows:
        """The raw frames ``(F, H, W)`` as stored (float32 or uint16 counts), checked as they are read.

        Exactly the committed rows (an interrupted capture may have rows allocated past them), as
        they were when the recording was opened.
        """
        crcs = None
        if self.has_checksums:
            crcs = self.journal["frame_crc"] if self.journal is not None else np.asarray(self.group["frame_crc"][:])
        return VerifiedRows(self.group["frames"], self.n_frames, crcs=crcs, what="frames",
                            store=self.path, required=None if crcs is not None else ~self.per_frame("dropped"))

    @property
    def code(self) -> np.ndarray:
        """The code ``(m, n, K)`` bool."""
        return np.asarray(self.attrs["code"], dtype=bool)

    @property
    def K(self) -> int:  # noqa: N802
        """Slots per frame."""
        return int(self.attrs["K"])

    @property
    def n_frames(self) -> int:
        """Camera frames stored (committed frames of an interrupted capture)."""
        if self.journal is not None:
            return min(len(self.journal["frame_id"]), int(self.group["frames"].shape[0]))
        if self.rows_seen is not None:  # as seen when opened: a capture starting since cannot add rows to it
            return self.rows_seen
        return int(self.group["frames"].shape[0])

    @property
    def has_ground_truth(self) -> bool:
        """True for simulated recordings that hold the high-speed video."""
        return "ground_truth" in self.group

    def per_frame(self, name: str) -> np.ndarray:
        """``frame_id``, ``timestamp``, ``dropped`` (or ``frame_crc``, schema 2) as a numpy array."""
        if name not in WRITTEN_PER_FRAME:
            raise RecordingError(f"`name` must be one of {', '.join(WRITTEN_PER_FRAME)}; got {name!r}")
        if self.journal is not None:
            values = self.journal.get(name)
            if values is None:
                raise RecordingError(f"{self.path} has no `{name}` (schema 1)")
            return values[: self.n_frames].copy()
        if name not in self.group:
            raise RecordingError(f"{self.path} has no `{name}` (schema {self.attrs.get('schema_version')})")
        return np.asarray(self.group[name][:])

    @property
    def ground_truth(self) -> GroundTruthRows:
        """The simulated high-speed video ``(S, H, W)`` float32, S = F·K, an array-like checked as it is read:
        ``rec.ground_truth[:8]``, ``np.asarray(rec.ground_truth)``. :class:`RecordingError` for a captured
        recording (:attr:`has_ground_truth` says beforehand)."""
        if not self.has_ground_truth:
            raise RecordingError(f"{self.path} holds no ground truth (a captured recording)")
        gt = self.group["ground_truth"]
        crcs = np.asarray(self.group["ground_truth_crc"][:]) if "ground_truth_crc" in self.group else None
        return GroundTruthRows(gt, gt.shape[0], crcs=crcs, what="ground truth", store=self.path)

    @property
    def ground_truth_rows(self) -> VerifiedRows:
        """Deprecated (until flexvox 0.3): :attr:`ground_truth`."""
        _deprecated("ground_truth_rows", "`ground_truth` (the same array-like)")
        return self.ground_truth

    @property
    def tile(self) -> tuple[int, int]:
        """The code's tile ``(m, n)``."""
        m, n = self.attrs["tile"]
        return int(m), int(n)

    @property
    def shape(self) -> tuple[int, int, int]:
        """The frames' shape ``(F, H, W)``."""
        return self.frames.shape

    @property
    def camera_hz(self) -> float:
        """Camera frames per second (sub-frames per second: ``camera_hz * K``)."""
        return float(self.attrs["rates"]["camera_hz"])

    @property
    def dropped(self) -> np.ndarray:
        """``(F,)`` bool: the frames the camera dropped (stored as zero rows)."""
        return self.per_frame("dropped").astype(bool)

    @property
    def calibration(self) -> dict | None:
        """The calibration a capture used: its source (the file's name and checksum), ``calibrated`` (False for a
        capture made without a calibration file, on the identity map), homography, phase, trigger delay and
        warnings. None for a simulated recording, which has no rig."""
        return self.attrs.get("calibration")

    def __repr__(self) -> str:
        F, H, W = self.shape
        m, n = self.tile
        drops = int(self.dropped.sum()) if F else 0
        state = ", interrupted" if self.interrupted else ""
        truth = ", ground truth" if self.has_ground_truth else ""
        cal = self.calibration
        calib = ""
        if isinstance(cal, dict):  # a capture's: say which, by its flag (an uncalibrated capture has one too)
            calib = ", calibrated" if cal.get("calibrated") is True else ", uncalibrated"
        return (f"<Recording {self.path.name}: {F} frames of {H}x{W}, tile {m}x{n} (K = {self.K}), "
                f"{self.camera_hz:g} Hz, {drops} dropped{truth}{calib}{state}>")

    def _repr_html_(self) -> str:
        F, H, W = self.shape
        m, n = self.tile
        rows = [("path", str(self.path)), ("kind", self.attrs.get("kind", "")),
                ("frames", f"{F} of {H}×{W} ({self.frames.dtype})"), ("tile", f"{m}×{n} (K = {self.K})"),
                ("camera", f"{self.camera_hz:g} Hz ({self.camera_hz * self.K:g} sub-frames/s)"),
                ("dropped", str(int(self.dropped.sum()) if F else 0)),
                ("ground truth", "yes" if self.has_ground_truth else "no"),
                ("calibration", str(self.calibration.get("source", ""))
                 if isinstance(self.calibration, dict) else "none"),
                ("interrupted", "yes" if self.interrupted else "no")]
        body = "".join(f"<tr><th style='text-align:left'>{html.escape(k)}</th><td>{html.escape(v)}</td></tr>"
                       for k, v in rows)
        return f"<table><caption>Recording</caption>{body}</table>"

    def normalised_frames(self, start: int = 0, stop: int | None = None) -> np.ndarray:
        """Frames ``[start, stop)`` as float32 relative units (counts converted)."""
        from flexvox_core.simulate.simulator import normalise_frames

        return normalise_frames(np.asarray(self.frames[start:stop]), self.attrs["storage"])

    def _per_frame_gaps(self) -> list[str]:
        """Checksum chunks whose file is missing (zarr reads them as zeros). Only ``frame_crc`` is checked:
        zarr writes no chunk whose values all equal the fill value, which ``dropped`` (all False) and a
        one-frame ``frame_id`` legitimately are, while a chunk of CRCs that are all 0 does not occur."""
        if self.journal is not None:
            return []  # an interrupted capture's per-frame values come from its journal
        lines = []
        for name in ("frame_crc",):
            if name in self.group:
                arr = self.group[name]
                for j in chunk_files_missing(arr, self.path):
                    a, b = j * arr.chunks[0], min(arr.shape[0], (j + 1) * arr.chunks[0]) - 1
                    lines.append(f"per-frame array `{name}` rows {a}..{b}: its chunk file is missing (it reads as "
                                 "zeros)")
        return lines

    def verify(self, progress=None, *, chunk_rows: int = 16) -> list[str]:
        """Check every committed frame (and ground-truth sub-frame): each chunk exists, decodes, matches its
        CRC and holds no NaN or inf. Returns one line per damaged row (empty when all are sound).

        ``progress(done, total)`` is called as rows are checked (rows of frames and ground truth).
        """
        parts = [self.frames] + ([self.ground_truth] if self.has_ground_truth else [])
        total = sum(p.n for p in parts)
        done = 0
        found = self._per_frame_gaps()
        for part in parts:
            for start in range(0, part.n, chunk_rows):
                stop = min(part.n, start + chunk_rows)
                found += [f"{part.what} row {row}: {why}" for row, why in part.problems(start, stop)]
                done += stop - start
                if progress is not None:
                    progress(done, total)
        if not self.has_checksums:
            found.append("no checksums (schema 1): missing chunks were checked, changed values cannot be")
        return found


def _unreadable(path: Path) -> str:
    """Why a store zarr cannot open is unreadable, in words (never an exception's class name)."""
    meta = path / "zarr.json"
    if not path.is_dir():
        if path.suffix.lower() in (".npy", ".tif", ".tiff", ".mp4"):
            return "it is a video file; a recording is a .zarr folder: fv.read_video(path) reads a video"
        return "it is a file; a recording is a .zarr folder"
    if not meta.is_file():
        return "its zarr.json is missing"
    try:
        doc = json.loads(meta.read_bytes())
    except (OSError, ValueError):
        return "its zarr.json is not readable JSON: the file is damaged or truncated"
    if isinstance(doc, dict) and doc.get("node_type") == "array" and (path.parent / "zarr.json").is_file():
        return f"it is the `{path.name}` array inside the store {path.parent}: open {path.parent}"
    if not isinstance(doc, dict) or doc.get("node_type") != "group":
        return "its zarr.json does not describe a Zarr group"
    return "its zarr.json does not describe a Zarr version 3 group"


def check_recording_path(path, name: str = "recording") -> None:
    """A recording's path must be a ``str`` or a path: frames in memory (an array, ``rec.frames``) had raised
    pathlib's "expected str, bytes or os.PathLike object, not ndarray"."""
    import os

    if isinstance(path, str | os.PathLike):
        return
    if isinstance(path, VerifiedRows):
        what = "a recording's frames (rec.frames): give the recording itself"
    elif hasattr(path, "shape"):
        what = f"{type(path).__name__}: frames in memory go to fv.reconstruct_video(frames, code, method)"
    else:
        what = f"{type(path).__name__} {path!r}"
    raise TypeError(f"`{name}` must be a recording's path or a Recording; got {what}")


def open_recording(path) -> Recording:
    """Open and validate a recording's structure; :class:`RecordingError` says what is wrong.

    Frames are checked as they are read (:attr:`Recording.frames`); :meth:`Recording.verify`
    checks them all. A ``path`` that is no path (an array, a recording's ``frames``) is a ``TypeError`` in words.
    """
    check_recording_path(path)
    path = Path(path)
    if not path.exists():
        raise RecordingError(f"{path}: no such recording")
    try:
        group = zarr.open_group(str(path), mode="r")
    except Exception as exc:  # zarr raises several types for a damaged store: say what is wrong in words
        raise RecordingError(f"{path}: not a readable Zarr store ({_unreadable(path)})") from exc
    attrs = dict(group.attrs).get("flexvox")
    if "video" in group and "frames" not in group:
        raise RecordingError(f"{path}: a reconstructed video (an OME-Zarr image that fv.write_video, `flexvox "
                             "reconstruct` or `flexvox batch` writes), not a recording of camera frames: read it with "
                             "fv.read_video(path), or lazily with fv.open_video_store(path)")
    if not isinstance(attrs, dict):
        raise RecordingError(f"{path}: not a flexvox recording (no `flexvox` attributes)")
    version = attrs.get("schema_version")
    if version is None:
        raise RecordingError(f"{path}: the recording has no schema_version; it was not written by flexvox")
    if isinstance(version, bool) or not isinstance(version, int) or version < 1:
        raise RecordingError(f"{path}: schema version {version!r} is not a whole number >= 1; the recording's "
                             "metadata is damaged")
    if version > SCHEMA_VERSION:
        raise RecordingError(
            f"{path}: schema version {version!r} is newer than this software reads ({SCHEMA_VERSION}); "
            "update flexvox"
        )
    for _ in range(SNAPSHOT_TRIES):
        journal, rows = _journal_snapshot(path, group)
        rec = Recording(path, group, attrs, journal, rows)
        problems = validate_recording(rec)
        # Seen without a journal, and one there now: a capture started while this looked (its per-frame arrays may
        # already have grown past the rows seen). Look again rather than call it damaged.
        if not (problems and journal is None and (path / JOURNAL).exists()):
            break
    if problems:
        raise RecordingError(f"{path}: " + "; ".join(problems))
    if journal is not None:
        _logger.info("%s: an interrupted capture; %d committed frames", path, len(journal["frame_id"]))
    return rec


SNAPSHOT_TRIES = 5
"""Times :func:`open_recording` looks again at a recording whose frames changed while it looked."""


def _journal_snapshot(path: Path, group):
    """(journal, rows): the capture journal's committed records and None, or None and the frames' rows of a
    finished recording, seen consistently with each other.

    A writer creates the journal before it first grows the frames and removes it after trimming them to the
    count. So the frames' rows are read before and after looking for the journal: with a journal, the rows were
    read while it existed; without one, equal rows mean a finished recording (a capture starting between the
    two reads would show its first block of empty rows as frames, one finishing its capacity).
    """
    def rows():
        try:
            return group["frames"].shape[0]
        except KeyError:  # no frames array (yet): validate_recording says so
            return None

    for _ in range(SNAPSHOT_TRIES):
        before = rows()
        if (path / JOURNAL).exists():
            try:
                return read_journal(path / JOURNAL), None
            except FileNotFoundError:  # the capture finished meanwhile: look again
                continue
            except OSError as exc:
                raise RecordingError(f"{path}: cannot read the capture journal ({exc})") from exc
        if rows() == before:
            return None, before
    raise RecordingError(f"{path}: the recording changed while it was opened {SNAPSHOT_TRIES} times (a capture "
                         "starting or finishing in it); open it again")

