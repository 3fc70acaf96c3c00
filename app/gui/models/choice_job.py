"""A knob chosen by the estimate, as a Review job (Qt-free): what Reconstruct runs when the method form's "choose …
by the estimated PSNR" is checked (:meth:`flexvox_app.gui.review.method_form.MethodForm.auto_knob`).

:func:`run_choice` runs on a worker thread like :func:`~flexvox_app.gui.models.jobs.run_reconstruction`: it
tries each candidate (:func:`flexvox_core.choice.choose`), checks the cancel token between the chunks and runs
of each, and returns the chosen reconstruction as a
:class:`~flexvox_app.gui.models.jobs.ReconstructionResult` whose ``extra["choice"]`` holds the
:class:`~flexvox_core.choice.Choice` (every candidate's estimate and what choosing cost; :func:`choice_lines`
words it for the result line).
"""

from __future__ import annotations

import time

import numpy as np

from flexvox_app.gui.models.jobs import CancelToken, ReconstructionResult
from flexvox_core.methods import Method


def run_choice(frames, code, method: Method, knob: str, *, cancel: CancelToken | None = None, progress=None,
               chunk_frames: int = 4, truth: np.ndarray | None = None, missing=None, noise=None,
               device: str = "auto") -> ReconstructionResult:
    """Choose ``knob`` of ``method`` by the estimated PSNR on ``frames`` and return the chosen reconstruction.

    Parameters
    ----------
    frames : ndarray (F, H, W), identity-code capture (demultiplexed)
    code : ndarray (m, n, K)
    method : Method
        Its other options are kept; ``knob`` takes each candidate (:func:`flexvox_core.choice.candidates_for`).
    knob : str
    cancel : CancelToken, optional
        Checked between the chunks and runs of each candidate (its reconstruction and its estimate).
    progress : callable(done_candidates, total_candidates), optional
    chunk_frames : int
    truth : ndarray (F·K, H, W), optional
        Ground truth: read only after the choice, for the result's PSNR.
    missing : ndarray (F,) bool, optional
        Dropped frames.
    noise : NoiseModel, optional
        The recording's noise (:func:`flexvox_core.accuracy.noise_of`).
    device : {"auto", "cpu", "cuda"}

    Returns
    -------
    ReconstructionResult
        ``seconds`` is the chosen candidate's reconstruction alone; ``extra["choice"]`` the Choice.

    Raises
    ------
    NotEstimable
        The estimate refuses the method, or no candidate could be scored (the reasons quoted).
    Cancelled
        When ``cancel`` was set; no partial result is returned.

    Examples
    --------
    >>> from flexvox_core import capture, render_scene
    >>> from flexvox_core.design import design_code
    >>> code = design_code((2, 2)).code
    >>> r = run_choice(capture(render_scene("balls", 16, 24, 32), code), code, Method("diffusion"), "time",
    ...                device="cpu")
    >>> r.method.time in (1.5, 2.0, 3.0, 4.0, 6.0), len(r.extra["choice"].candidates)
    (True, 5)
    """
    from flexvox_core.choice import choose

    cancel = cancel or CancelToken()
    cancel.check()

    def checked(done: int, total: int) -> None:
        if progress:
            progress(done, total)
        cancel.check()

    choice = choose(np.asarray(frames, np.float32), np.asarray(code, bool), method, knob, noise=noise,
                    missing=missing, chunk_frames=chunk_frames, device=device, progress=checked)
    out = choice.output
    if out is None:  # not kept (a capture the estimate demultiplexes): made once more
        t0 = time.perf_counter()
        from flexvox_core.methods import run

        out = run(frames, code, choice.method, chunk_frames=chunk_frames, missing=missing, device=device)
        seconds = time.perf_counter() - t0
    else:
        seconds = next(c.run_seconds for c in choice.candidates if c.value == choice.value)
    cancel.check()
    score = None
    if truth is not None:  # only now, after the choice
        from flexvox_core.metrics import psnr

        score = float(psnr(truth, out.video))
    result = ReconstructionResult(out.video, choice.method, seconds, psnr=score, device=out.device,
                                  device_note=out.device_note, extra={"choice": choice})
    if out.interpolated is not None:
        result.extra["interpolated"] = out.interpolated
    return result


def choice_lines(result: ReconstructionResult) -> list[str]:
    """What the result line adds for a reconstruction chosen by the estimate: the choice, each candidate's estimate
    and the cost (:meth:`flexvox_core.choice.Choice.lines`); none for any other result."""
    choice = result.extra.get("choice")
    return [] if choice is None else [line.strip() for line in choice.lines()]
