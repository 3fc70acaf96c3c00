"""Every command's bad input and faults, through the real command line.

Each case runs ``python -m flexvox_app.cli.main ...`` in a subprocess, as a user would, and checks four
things: the exit status, exactly one line on stderr that names the problem, no traceback, and the
bytes of every input file unchanged. The cases are a table (``CASES``) so that a new fault is one
row; the faults that need a second process or a resource limit are the tests after it.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import pytest

from tests.app.command_line import ENV, ROOT, assert_refused, flexvox, stderr_lines
from tests.app.no_display import unserved_display


def digest(path: Path) -> dict:
    """Every file under ``path`` (or ``path`` itself) with the hash of its bytes."""
    path = Path(path)
    files = [path] if path.is_file() else sorted(p for p in path.rglob("*") if p.is_file())
    return {str(p.relative_to(path.parent)): hashlib.sha256(p.read_bytes()).hexdigest() for p in files}


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A small simulated recording (drummer, 2x2 tile, 6 frames of 24x32) and a code file."""
    from flexvox_app.cli.main import main

    folder = tmp_path_factory.mktemp("faults")
    rec = folder / "base.zarr"
    assert main(["simulate", "drummer", "--size", "24x32", "--frames", "6", "--tile", "2x2", "-o", str(rec)]) == 0
    assert main(["design", "--tile", "2x2", "-o", str(folder / "code.json")]) == 0
    return folder


def _delete_chunk(rec: Path) -> None:
    (rec / "frames" / "c" / "2" / "0" / "0").unlink()


def _garble_chunk(rec: Path) -> None:
    chunk = rec / "frames" / "c" / "3" / "0" / "0"
    data = bytearray(chunk.read_bytes())
    data[len(data) // 2] ^= 0xFF
    chunk.write_bytes(bytes(data))


def _truncate_chunk(rec: Path) -> None:
    chunk = rec / "frames" / "c" / "1" / "0" / "0"
    chunk.write_bytes(chunk.read_bytes()[:20])


def _ids_backwards(rec: Path) -> None:
    import zarr

    zarr.open_group(str(rec), mode="r+")["frame_id"][4] = 1


def _video_file(rec: Path) -> None:
    import numpy as np

    np.save(rec.parent / "clip.npy", np.random.default_rng(0).random((16, 24, 32), dtype=np.float32))


def _truncated_tiff(rec: Path) -> None:
    import numpy as np
    import tifffile

    clip = rec.parent / "clip.tif"
    tifffile.imwrite(clip, np.zeros((16, 24, 32), np.float32), imagej=True)
    clip.write_bytes(clip.read_bytes()[: clip.stat().st_size // 3])


def _random_bytes(name: str):
    """3000 random bytes named ``name`` beside the recording (a download that went wrong)."""
    import numpy as np

    return lambda rec: (rec.parent / name).write_bytes(np.random.default_rng(18).bytes(3000))


def _truncated_npy(rec: Path) -> None:
    _video_file(rec)
    clip = rec.parent / "clip.npy"
    clip.write_bytes(clip.read_bytes()[:3000])


def _huge_npy(rec: Path) -> None:
    """A .npy declaring 4096x4096x4096 uint8 (64 GiB; 384 GiB to read as float32) whose data is a hole in the file:
    no disk used, and nothing may read it (its bytes are not hashed: that would read 64 GiB of zeros)."""
    from numpy.lib import format as npy_format

    with open(rec.parent / "huge.npy", "wb") as fh:
        npy_format.write_array_header_1_0(fh, {"descr": "|u1", "fortran_order": False, "shape": (4096, 4096, 4096)})
        fh.truncate(fh.tell() + 4096 ** 3)


def _video_store(rec: Path) -> None:
    import numpy as np

    import flexvox_core as fv

    fv.write_video(rec.parent / "video.zarr", np.zeros((4, 8, 8), np.float32))


def _png_folder(rec: Path) -> None:
    folder = rec.parent / "pngs"
    folder.mkdir()
    (folder / "frame_00000.png").write_bytes(b"an earlier export")
    (folder / "notes.txt").write_text("the operator's notes")


NO_DISPLAY = {"DISPLAY": None, "WAYLAND_DISPLAY": None, "QT_QPA_PLATFORM": None}


def _existing_outputs(folder: Path) -> None:
    (folder / "cal.json").write_text('{"a real rig\'s calibration": true}\n')
    (folder / "out.npy").write_bytes(b"an earlier result")


@dataclass
class Case:
    """One command line: its arguments (``{rec}``, ``{dir}`` and ``{code}`` filled in), the expected exit
    status and stderr line, and what to do to the recording copy first."""

    args: str
    status: int
    stderr: str
    prepare: object = None
    inputs: tuple = ("rec",)
    env: dict = field(default_factory=dict)
    """Environment changes: a value of None removes the variable."""
    needs_gib: float = 0.0
    """A request refused for memory that some machine might have: skipped on one with this many GiB available."""


CASES = {
    # integrity: a missing, truncated or garbled chunk is never read as zeros
    "reconstruct-deleted-chunk": Case("reconstruct {rec} -o {dir}/v.npy", 2,
                                      r"frames row 2 is damaged: its chunk file is missing", _delete_chunk),
    "export-deleted-chunk": Case("export {rec} -o {dir}/f.tif", 2,
                                 r"frames row 2 is damaged: its chunk file is missing; .*f.tif was not written",
                                 _delete_chunk),
    "export-reconstruction-deleted-chunk": Case("export {rec} --what reconstruction -o {dir}/r.npy", 2,
                                                r"frames row 2 is damaged", _delete_chunk),
    "batch-deleted-chunk": Case("batch {rec} -o {dir}/b.zarr", 2, r"frames row 2 is damaged", _delete_chunk),
    "reconstruct-garbled-chunk": Case("reconstruct {rec} -o {dir}/v.npy", 2, r"frames row 3 is damaged: its ",
                                      _garble_chunk),
    "reconstruct-truncated-chunk": Case("reconstruct {rec} -o {dir}/v.npy", 2,
                                        r"frames row 1 is damaged: its chunk cannot be decoded", _truncate_chunk),
    # a reconstruction's flags beside --what frames (the default) would export the coded frames without a word
    "export-method-with-frames": Case("export {rec} --method diffusion -o {dir}/f.tif", 2,
                                      r"--method goes with --what reconstruction; --what frames \(the default\) "
                                      r"exports the camera frames as they are: add --what reconstruction"),
    "export-option-with-ground-truth": Case("export {rec} --what ground-truth --time 3 -o {dir}/f.tif", 2,
                                            r"--time goes with --what reconstruction; --what ground-truth exports "
                                            r"the ground truth as it is"),
    # a recording under another suffix would be taken for a file of that kind (np.load of a folder)
    "simulate-output-not-zarr": Case("simulate balls --tile 2x2 --frames 2 --size 24x32 -o {dir}/s.npy", 2,
                                     r"a recording \(a Zarr store\) is a folder whose name ends in .zarr: .*s.npy "
                                     r"ends in .npy; write .*s.zarr", inputs=()),
    "capture-output-not-zarr": Case("capture --frames 2 --clock virtual -o {dir}/run", 2,
                                    r"a recording \(a Zarr store\) is a folder whose name ends in .zarr: .*run has "
                                    r"no suffix; write .*run.zarr", inputs=()),
    # a path that is no recording is named for what it is, never called a damaged recording (exit 1)
    "info-array-inside-recording": Case("info {rec}/frames", 2,
                                        r"rec.zarr/frames is the `frames` array of the recording .*rec.zarr, not a "
                                        r"recording: give the recording's folder, .*rec.zarr$"),
    "info-video-store": Case("info {dir}/video.zarr", 2,
                             r"video.zarr is a reconstructed video \(an OME-Zarr image\), not a recording of camera "
                             r"frames: flexvox export writes it to TIFF, MP4, PNG or .npy; napari and Fiji open it",
                             _video_store),
    "slots-deleted-chunk": Case("info {rec} --slots --quick", 2, r"--slots: .*row 2 is damaged", _delete_chunk),
    "reconstruct-ids-backwards": Case("reconstruct {rec} -o {dir}/v.npy", 2,
                                      r"frame ids do not increase at row 4 \(3 then 1\)", _ids_backwards),
    # outputs never destroy inputs, whatever the flags
    "reconstruct-onto-input": Case("reconstruct {rec} -o {rec} --overwrite", 2,
                                   r"the output .*rec.zarr is the input .*: an output never replaces its input"),
    "export-onto-input": Case("export {rec} -o {rec} --overwrite", 2, r"is the input"),
    "batch-onto-input": Case("batch {rec} -o {rec} --overwrite", 2, r"is the input"),
    "export-folder-holding-input": Case("export {rec} -o {dir} --overwrite", 2, r"holds the input"),
    "export-png-folder-with-other-files": Case("export {rec} -o {dir}/pngs --overwrite", 2,
                                               r"pngs holds other files than an earlier export's PNGs \(notes.txt\)",
                                               _png_folder, inputs=("pngs",)),
    "reconstruct-inside-input": Case("reconstruct {rec} -o {rec}/v.npy", 2, r"lies inside the input"),
    "bench-into-input": Case("bench {rec} --quick -o {rec}", 2,
                             r"the output .*rec.zarr/results.csv lies inside the input .*rec.zarr: an output never "
                             r"replaces its input"),
    "bench-inside-input": Case("bench {rec} --quick -o {rec}/results", 2, r"results/results.csv lies inside the input"),
    "capture-onto-code-file": Case("capture --code {code} -o {code} --overwrite --frames 2 --clock virtual", 2,
                                   r"is the input .*code.json", inputs=("code",)),
    "simulate-onto-its-video": Case("simulate {dir}/clip.npy -o {dir}/clip.npy --overwrite --tile 2x2", 2,
                                    r"the output .*clip.npy is the input", _video_file, inputs=("clip",)),
    "design-onto-a-recording": Case("design --tile 2x2 -o {rec} --overwrite", 2,
                                    r"rec.zarr is a recording \(camera frames\); overwriting replaces a recording only "
                                    r"with a recording"),
    "design-onto-verified-file": Case("design --verify {code} -o {code} --overwrite", 2, r"is the input",
                                      inputs=("code",)),
    # -o onto an existing file needs --overwrite, design and calibrate included
    "design-existing-output": Case("design --tile 2x2 -o {dir}/cal.json", 2,
                                   r"cal.json already exists; use --overwrite to replace it",
                                   _existing_outputs, inputs=("cal",)),
    "calibrate-existing-output": Case("calibrate --rig mock -o {dir}/cal.json", 2,
                                      r"cal.json already exists; use --overwrite .*checked before calibrating",
                                      _existing_outputs, inputs=("cal",)),
    # batch had said "pass overwrite=True", the Python keyword
    "batch-existing-output": Case("batch {rec} -o {dir}/video.zarr --method diffusion", 2,
                                  r"video.zarr already exists; use --overwrite to replace it$", _video_store),
    "reconstruct-existing-output": Case("reconstruct {rec} -o {dir}/out.npy", 2, r"out.npy already exists",
                                        _existing_outputs, inputs=("rec", "out")),
    # bad values are named with their rule
    "reconstruct-fps-0": Case("reconstruct {rec} -o {dir}/v.mp4 --fps 0", 2,
                              r"--fps must be above 0 and at most 1000 frames per second; got '0'"),
    "export-fps-negative": Case("export {rec} -o {dir}/v.mp4 --fps -5", 2, r"--fps must be above 0"),
    # a folder that is no recording is named for what it is, not as the folder the output would lie in
    "reconstruct-folder-not-recording": Case("reconstruct {dir} -o {dir}/w.npy", 2,
                                             r"not a readable Zarr store \(its zarr.json is missing\)"),
    "export-folder-not-recording": Case("export {dir} -o {dir}/w.npy", 2,
                                        r"not a readable Zarr store \(its zarr.json is missing\)"),
    # --fps is an .mp4's rate: with another output it was ignored without a word
    "reconstruct-fps-not-mp4": Case("reconstruct {rec} --fps 30 -o {dir}/v.npy", 2,
                                    r"--fps sets an .mp4's playback rate; -o .*v.npy is not an .mp4 \(its time step "
                                    r"comes from the recording's rates\): leave --fps out, or write an .mp4"),
    "export-fps-not-mp4": Case("export {rec} -o {dir}/fr.npy --fps 3", 2,
                               r"--fps sets an .mp4's playback rate; -o .*fr.npy is not an .mp4"),
    "reconstruct-folder-missing": Case("reconstruct {rec} -o {dir}/no/such/v.npy", 2,
                                       r"the folder .*no/such does not exist"),
    # tracebacks and aborts become messages
    "simulate-tile-without-a-code": Case("simulate drummer --tile 6x6 --frames 2 -o {dir}/s.zarr", 2,
                                         r"no code for a 6x6 tile: no 6x6 code supports .*infeasible", inputs=()),
    "simulate-truncated-tiff": Case("simulate {dir}/clip.tif --tile 2x2 -o {dir}/s.zarr", 2,
                                    r"clip.tif: a damaged TIFF \(.*\); it may be truncated", _truncated_tiff,
                                    inputs=("tif",)),
    "simulate-huge-size": Case("simulate drummer --size 100000x100000 -o {dir}/s.zarr", 2,
                               r"simulating 100000x100000 with 8 frames of K = 16 needs about \d+\.\d GiB of memory; "
                               r"this machine has \d+\.\d GiB available", inputs=()),
    "simulate-huge-frame-count": Case("simulate drummer --size 24x32 --frames 100000000 -o {dir}/s.zarr", 2,
                                      r"simulating 24x32 with 100000000 frames of K = 16 needs about \d+\.\d GiB",
                                      inputs=()),
    "simulate-huge-video-file": Case("simulate {dir}/huge.npy --tile 2x2 -o {dir}/s.zarr", 2,
                                     r"huge.npy: reading its 4096x4096x4096 uint8 samples as a float32 video needs "
                                     r"about 384.0 GiB of memory; this machine has \d+\.\d GiB available",
                                     _huge_npy, inputs=(), needs_gib=384),
    "capture-huge-camera-size": Case("capture --size 8192x8192 --frames 2 -o {dir}/c.zarr --clock virtual", 2,
                                     r"the drummer scene at 8192x8192 with 256 sub-frames needs about 128.0 GiB .*: "
                                     r"use a smaller camera size", inputs=(), needs_gib=128),
    "simulate-random-bytes-tiff": Case("simulate {dir}/clip.tif --tile 2x2 -o {dir}/s.zarr", 2,
                                       r"clip.tif: not a readable TIFF \(not a TIFF file.*\); it is damaged or another "
                                       r"format", _random_bytes("clip.tif"), inputs=("tif",)),
    "simulate-truncated-npy": Case("simulate {dir}/clip.npy --tile 2x2 -o {dir}/s.zarr", 2,
                                   r"clip.npy: a damaged .npy: its header declares 16x24x32 float32 \(49152 bytes\) "
                                   r"but the file holds \d+ bytes after it; it may be truncated", _truncated_npy,
                                   inputs=("clip",)),
    "simulate-random-bytes-npy": Case("simulate {dir}/clip.npy --tile 2x2 -o {dir}/s.zarr", 2,
                                      r"clip.npy: not a NumPy .npy file \(no .npy header\)", _random_bytes("clip.npy"),
                                      inputs=("clip",)),
    "simulate-unreadable-video": Case("simulate {dir}/clip.mp4 --tile 2x2 -o {dir}/s.zarr", 2,
                                      r"clip.mp4: OpenCV cannot open this video \(damaged, or a codec it lacks\)",
                                      _random_bytes("clip.mp4"), inputs=("mp4",)),
    "capture-mock-projector-size": Case("capture --projector-size 8192x8192 --frames 2 --clock virtual "
                                        "-o {dir}/c.zarr", 2,
                                        r"--projector-size 8192x8192: the simulated rig's projector is 240x320",
                                        inputs=()),
    "app-without-a-display": Case("app", 2, r"no display to open the window on \(DISPLAY is not set\); .*"
                                  r"QT_QPA_PLATFORM=offscreen", inputs=(), env=NO_DISPLAY),
    "app-with-a-display-qt-cannot-use": Case("app", 2, r"Qt( cannot start its platform plugin here \(.+\); |'s X11 "
                                                      r"platform plugin \(xcb\) cannot load: this system lacks \S)",
                                             inputs=(), env={"DISPLAY": unserved_display(), "QT_QPA_PLATFORM": "xcb"}),
    "figures-into-a-file": Case("reconstruct {rec} -o {dir}/v.npy --method motion-aware --figures {dir}/out.npy", 2,
                                r"--figures .*out.npy is a file; the figures go into a folder", _existing_outputs,
                                inputs=("rec", "out")),
    "batch-chunk-0": Case("batch {rec} -o {dir}/b.zarr --chunk 0", 2,
                          r"--chunk must be a whole number of camera frames >= 1; got '0'"),
    "slots-deleted-ground-truth-chunk": Case("info {rec} --slots --quick", 2,
                                             r"--slots: .*ground truth row 3 is damaged",
                                             lambda rec: (rec / "ground_truth" / "c" / "3" / "0" / "0").unlink()),
    "repair-a-sound-recording-is-harmless": Case("info {rec} --repair --quick", 0, r"", inputs=()),
}


@pytest.mark.parametrize("name", list(CASES))
def test_fault(name, base, tmp_path):
    case = CASES[name]
    if case.needs_gib:
        from flexvox_core.memory_budget import GIB, available_bytes

        if (available_bytes() or 0) >= case.needs_gib * GIB:
            pytest.skip(f"this machine has {case.needs_gib} GiB available: the request would be carried out")
    rec = tmp_path / "rec.zarr"
    shutil.copytree(base / "base.zarr", rec)
    shutil.copy(base / "code.json", tmp_path / "code.json")
    if case.prepare is _existing_outputs:
        _existing_outputs(tmp_path)
    elif case.prepare is not None:
        case.prepare(rec)
    files = {"rec": rec, "code": tmp_path / "code.json", "cal": tmp_path / "cal.json", "out": tmp_path / "out.npy",
             "clip": tmp_path / "clip.npy", "tif": tmp_path / "clip.tif", "pngs": tmp_path / "pngs",
             "mp4": tmp_path / "clip.mp4"}
    before = {k: digest(files[k]) for k in case.inputs}
    args = case.args.format(rec=rec, dir=tmp_path, code=tmp_path / "code.json").split()
    env = {k: v for k, v in {**ENV, **case.env}.items() if v is not None}
    proc = flexvox(*args, env=env)
    if case.status == 0:
        assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    else:
        assert_refused(proc, case.status, case.stderr)
    assert {k: digest(files[k]) for k in case.inputs} == before
    assert not [p.name for p in tmp_path.iterdir() if ".partial-" in p.name or ".replaced-" in p.name]


def test_info_lists_the_damage_and_exits_1(base, tmp_path):
    rec = tmp_path / "rec.zarr"
    shutil.copytree(base / "base.zarr", rec)
    _delete_chunk(rec)
    _garble_chunk(rec)
    before = digest(rec)
    proc = flexvox("info", rec)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr and stderr_lines(proc) == []
    assert "problem: frames row 2: its chunk file is missing" in proc.stdout
    assert re.search(r"problem: frames row 3: its ", proc.stdout) and proc.stdout.strip().endswith("DAMAGED")
    assert flexvox("info", rec, "--quick").returncode == 0  # the metadata alone is sound
    assert digest(rec) == before


def test_a_read_only_folder_is_refused_before_the_computation(base, tmp_path):
    if os.geteuid() == 0:
        folder = Path("/proc/sys")  # root ignores permissions; /proc/sys takes no new files
    else:
        folder = tmp_path / "ro"
        folder.mkdir()
        folder.chmod(0o555)
    for command in (("reconstruct", base / "base.zarr", "-o", folder / "v.npy", "--method", "motion-aware"),
                    ("batch", base / "base.zarr", "-o", folder / "v.zarr"),
                    ("export", base / "base.zarr", "-o", folder / "f.tif")):
        t0 = time.perf_counter()
        proc = flexvox(*command)
        assert_refused(proc, 2, r"cannot write .*: the folder .* does not accept new files \(")
        assert time.perf_counter() - t0 < 60  # refused, not after a long computation (a bound, not a timing)


def _wait_for_frames(path: Path, n: int, proc, stderr: Path, seconds: float = 180.0) -> None:
    """Until the recording at ``path`` holds ``n`` frames; ``stderr`` is the file ``proc`` writes its stderr to.

    A process starting on a loaded machine takes tens of seconds: ``seconds`` is a bound against a hang, not a
    timing."""
    from flexvox_core.recording import RecordingError, open_recording

    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and proc.poll() is None:
        try:
            if open_recording(path).n_frames >= n:
                return
        except RecordingError:
            pass
        time.sleep(0.05)
    raise AssertionError(f"the first capture did not write {n} frames: {stderr.read_text()}")


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="POSIX process control")
def test_a_second_capture_to_a_recording_being_written_is_refused(tmp_path):
    path = tmp_path / "run.zarr"
    # Its stderr goes to a file, not a pipe: a loaded machine makes it warn for every frame the queue discards, and
    # a pipe nobody reads until the end would fill and stop it in the middle of a write.
    stderr = tmp_path / "first-capture.stderr"
    with open(stderr, "w") as err:
        first = subprocess.Popen([sys.executable, "-m", "flexvox_app.cli.main", "capture", "--frames", "100000", "-o",
                                  str(path), "--size", "24x32", "--tile", "2x2", "--rate", "100", "--scene", "balls"],
                                 cwd=ROOT, env={**ENV, "PYTHONFAULTHANDLER": "1"}, stdout=subprocess.DEVNULL,
                                 stderr=err)
    try:
        _wait_for_frames(path, 10, first, stderr)
        for extra in ((), ("--overwrite",)):
            second = flexvox("capture", "--frames", "5", "-o", path, "--size", "24x32", "--tile", "2x2",
                             "--clock", "virtual", *extra)
            pattern = (rf"run.zarr is being written by process {first.pid} \(.*capture" if extra
                       else r"run.zarr already exists")
            assert_refused(second, 2, pattern)
        proc = flexvox("simulate", "balls", "--size", "24x32", "--frames", "2", "-o", path, "--overwrite")
        assert_refused(proc, 2, rf"being written by process {first.pid}")
        proc = flexvox("info", path, "--repair")
        assert_refused(proc, 2, rf"--repair: .*being written by process {first.pid}")
        first.send_signal(signal.SIGINT)  # Ctrl-C: the first capture stops and keeps what it captured
        # It writes the frames still queued (up to 64 when the disk fell behind the camera), finalises and exits:
        # seconds here, tens of seconds on a loaded machine. The capture's own bound on stopping is 30 s
        # (`stop_timeout`, exit status 1 past it); this wait is longer, so that it is the bound that counts.
        try:
            code = first.wait(timeout=180)
        except subprocess.TimeoutExpired:
            first.send_signal(signal.SIGABRT)  # faulthandler writes every thread's stack to its stderr
            first.wait(timeout=30)
            raise AssertionError("the first capture did not stop within 180 s of Ctrl-C; its threads then:\n"
                                 + stderr.read_text()[-20000:]) from None
        assert code == 0, stderr.read_text()
    finally:
        if first.poll() is None:
            first.kill()
            first.wait(timeout=10)
    from flexvox_core.recording import open_recording

    rec = open_recording(path)
    assert not rec.interrupted and rec.n_frames >= 10 and rec.verify() == []
    ids = rec.per_frame("frame_id")
    assert (ids == ids[0] + range(len(ids))).all()  # one writer's frames, in order: no zero rows from another


def test_a_failed_overwrite_leaves_the_old_recording(base, tmp_path):
    """``simulate --overwrite`` under a file-size limit: the write fails, the old recording is as it was."""
    import resource

    rec = tmp_path / "rec.zarr"
    shutil.copytree(base / "base.zarr", rec)
    before = digest(rec)

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails (EFBIG) instead of killing
        resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, 20_000))

    proc = flexvox("simulate", "drummer", "--size", "96x128", "--frames", "8", "-o", rec, "--overwrite",
                   preexec_fn=limit)
    assert_refused(proc, 2, r"cannot write .*rec.zarr: File too large; the old recording is unchanged")
    assert digest(rec) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.zarr"]


def test_a_capture_that_cannot_create_its_recording_says_why_and_leaves_nothing(tmp_path):
    """Under a file-size limit of 7 KiB the recording's first metadata file (it holds the code) is refused: the
    capture names the limit and that nothing was recorded, and leaves no folder for `flexvox info` to call
    damaged."""
    import resource

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (7 * 1024, 7 * 1024))

    rec = tmp_path / "x.zarr"
    proc = flexvox("capture", "--rig", "mock", "--frames", "400", "--size", "16x16", "--clock", "virtual", "-o", rec,
                   preexec_fn=limit)
    assert "Traceback" not in proc.stderr, proc.stderr
    assert proc.returncode == 1, (proc.stdout, proc.stderr)
    last = stderr_lines(proc)[-1]
    assert re.fullmatch(r"flexvox capture: error: capture stopped: cannot create \S*x\.zarr: a file would pass the "
                        r"file-size limit \(`ulimit -f`\) .*File too large\); nothing was recorded \(\S*x\.zarr was "
                        r"not created\); 0 dropped \(0 by the queue\)", last), last
    assert "already exists" not in proc.stderr and "finalising" not in proc.stderr
    assert list(tmp_path.iterdir()) == []
