"""Recordings: a Zarr v3 store (a directory) readable by anyone with zarr, dask or napari.

Layout (schema version 2)::

    REC.zarr/
      zarr.json            group attributes under "flexvox": schema_version, software_version,
                           created_utc, kind (simulated | captured), tile, K, code (m×n×K 0/1),
                           order (identity codes), multiplexed, placement_order, rates
                           {camera_hz, subframe_hz}, effects {name: params}, seed, source,
                           storage {kind: float | counts, ...}, calibration, rig;
                           and under "ome" an OME-Zarr (NGFF 0.5) image description of `frames`
                           (axes t, y, x; t scale = one camera frame in seconds), so generic
                           OME-Zarr readers open the raw frames (flexvox reads only "flexvox")
      frames/              (F, H, W) float32 (relative units) or uint16 counts; one frame per chunk;
                           dimension_names ("t", "y", "x")
      frame_id/            (F,) int64
      timestamp/           (F,) float64, seconds
      dropped/             (F,) bool; a dropped frame is a zero row with its flag set
      frame_crc/           (F,) uint32: CRC-32 of each frame's values (schema 2)
      ground_truth/        (S, H, W) float32, S = F·K — simulated recordings only
      ground_truth_crc/    (S,) uint32: CRC-32 of each ground-truth sub-frame (schema 2)
      frames/capture.journal   only while a capture writes (or after it was killed)

Frames are written as they arrive; every completed frame is a chunk of its own, so a capture
that stops early still leaves the frames it wrote.

The package's modules, one per part:

* :mod:`~flexvox_core.recording.schema` — the schema version, the arrays, the ``flexvox``
  attribute block (:func:`recording_attrs`) and the per-frame checksum (:func:`values_crc`);
* :mod:`~flexvox_core.recording.errors` — :class:`RecordingError`, :class:`DamagedRecordingError`;
* :mod:`~flexvox_core.recording.journal` — the capture journal's binary format (:func:`read_journal`);
* :mod:`~flexvox_core.recording.writer` — :class:`RecordingWriter` (crash-safe appends, one writer
  per recording) and :func:`write_simulation`;
* :mod:`~flexvox_core.recording.verified_rows` — :class:`VerifiedRows`, rows checked as they are read;
* :mod:`~flexvox_core.recording.reader` — :func:`open_recording` and :class:`Recording`;
* :mod:`~flexvox_core.recording.validation` — :func:`validate_recording`, the structural checks;
* :mod:`~flexvox_core.recording.repair` — :func:`repair_recording` (and :func:`recover_recording`), an
  interrupted capture finalised in place, or the recording it was replacing put back when it holds no frame.

Every name below is importable from the package itself (``from flexvox_core.recording import X``).
"""

import flexvox_core.zarr_exit  # noqa: F401 - zarr's I/O thread stopped before its exit hook (see there)
from flexvox_core.recording.errors import DamagedRecordingError, RecordingError
from flexvox_core.recording.journal import JOURNAL, read_journal
from flexvox_core.recording.reader import SNAPSHOT_TRIES, GroundTruthRows, Recording, open_recording
from flexvox_core.recording.repair import Repair, moved_aside_by, recover_recording, repair_recording
from flexvox_core.recording.schema import (
    FRAME_AXES,
    PER_FRAME,
    SCHEMA_VERSION,
    frames_ngff,
    recording_attrs,
    values_crc,
)
from flexvox_core.recording.validation import validate_recording
from flexvox_core.recording.verified_rows import RowsView, VerifiedRows
from flexvox_core.recording.writer import DEFAULT_BLOCK_FRAMES, RecordingWriter, write_simulation

__all__ = [
    "DEFAULT_BLOCK_FRAMES",
    "FRAME_AXES",
    "JOURNAL",
    "PER_FRAME",
    "SCHEMA_VERSION",
    "SNAPSHOT_TRIES",
    "DamagedRecordingError",
    "GroundTruthRows",
    "Recording",
    "RecordingError",
    "RecordingWriter",
    "Repair",
    "RowsView",
    "VerifiedRows",
    "frames_ngff",
    "moved_aside_by",
    "open_recording",
    "read_journal",
    "recording_attrs",
    "recover_recording",
    "repair_recording",
    "validate_recording",
    "values_crc",
    "write_simulation",
]
