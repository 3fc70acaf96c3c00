"""Messages from the layers below the window, in the window's words (Qt-free).

The drivers, the calibration and the capture service speak to programmers and to the command
line: a parameter in backticks (```plan`: …``), a driver call to make first ("call
start_acquisition() first"), a command-line flag ("flexvox capture --sync-profile"). The same
failure shown in the window names what happened and what to do there: the Devices panel, a
button's name, a workspace. :func:`in_gui_words` rewrites a message so; a message it does not know
passes through with only its backticks removed.
"""

from __future__ import annotations

import re

_RULES: tuple[tuple[re.Pattern, str], ...] = tuple((re.compile(p), r) for p, r in (
    # driver states: what the operator does about them
    (r"cannot read a frame: call start_acquisition\(\) first",
     "the camera is not delivering frames (it was disconnected, switched off or closed): connect it in the Devices "
     "panel and start again"),
    (r"cannot trigger: call start_acquisition\(\) first",
     "the camera is not acquiring: connect it in the Devices panel and start again"),
    (r"\s*\(call (?:open|enable)\(\) first\)", " (connect it in the Devices panel)"),
    (r":?\s*call stop(?:_acquisition)?\(\) first", " (stop the live view or the recording that uses it first)"),
    (r"\s*\(call \w+\(\) first\)", ""),
    # command-line flags, where the window has its own control
    (r"\s*\(flexvox capture --sync-profile; Capture: \"Load sync profile…\"\)", " (“Load sync profile…”)"),
    (r"\s*\(flexvox capture --calibration; Capture: \"Load calibration…\"\)", " (“Load calibration…”)"),
    (r"\(flexvox capture --delay-set-by-hand; in the Capture workspace, tick ", "(tick "),
    (r"calibrate the rig \(flexvox calibrate -o CAL\.json\) and load the file",
     "run the calibration in Calibrate and “Use for capture”, or load its file"),
    (r"calibrate this rig \(flexvox calibrate\) instead of reusing it",
     "calibrate this rig in the Calibrate workspace instead of reusing it"),
    (r" \(or open the simulated rig with the seed it was made on: --seed\)",
     " (or start flexvox on the simulated rig with the seed that file was made with)"),
    (r"run the synchronisation step", "run the calibration or the synchronisation wizard in Calibrate"),
    (r"run the synchronisation at this timing",
     "run the calibration or the synchronisation wizard in Calibrate at this timing"),
    (r"check the projector size \(capture --projector-size, or the rig profile's\)",
     "check the projector size in the rig profile"),
    (r"\s*\(check it with flexvox design --verify\)", " (the code file may be damaged: write it again)"),
    (r"\(write it again with flexvox design --multiplexed\)", "(write it again as a multiplexed code)"),
    # what a file is not, and what to open instead (no exception names, no parser positions)
    (r"not a readable Zarr store \([^()]*(?:\([^()]*\)[^()]*)*\)",
     "is not a recording (a recording is the .zarr folder a recording in the Capture workspace wrote; open that "
     "folder)"),
    (r"not a flexvox recording \(no `flexvox` attributes\)",
     "is not a recording flexvox wrote (another program's data; open the .zarr folder a recording in the Capture "
     "workspace wrote)"),
    (r"not valid JSON \([^()]*\)",
     "not a file flexvox wrote: its text is not JSON (open the .json file Calibrate saved, or a code file flexvox "
     "designed)"),
    # a parameter's name before the reason
    (r"^`\w+`:\s*", ""),
))
_TICKED = re.compile(r"`([^`]+)`")


def in_gui_words(message: str) -> str:
    """``message`` as the window says it (see the module docstring).

    Examples
    --------
    >>> in_gui_words("cannot read a frame: call start_acquisition() first")[:40]
    'the camera is not delivering frames (it '
    >>> in_gui_words("`plan`: no S-matrix exists for K = 16")
    'no S-matrix exists for K = 16'
    """
    text = str(message)
    for pattern, replacement in _RULES:
        text = pattern.sub(replacement, text)
    return _TICKED.sub(lambda m: f"“{m.group(1)}”" if " " in m.group(1) else m.group(1), text)
