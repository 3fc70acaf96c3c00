"""Which slot each camera pixel really sampled, read from a recording and its ground truth.

A capture through a wrong homography or a wrong phase still looks like a video: every pixel
holds *some* sample, only from the wrong instant. With the scene's ground truth (simulated
recordings) the instant can be read back. Camera pixel ``(y, x)`` of frame ``f`` holds
``Σ_s w_s(y, x) · truth[f·K + s, y, x]``: the light of each slot ``s`` it was open in, weighted
by how much of the pixel that slot's projector mirrors lit. An ideal shutter has one weight 1;
a real one leaks a little of the neighbours' slots (projector pixels straddle camera pixels).

- With at least K frames, the weights are fitted per pixel (least squares over the frames) and
  the pixel's **dominant slot** is the largest weight;
- with fewer, the single slot whose truth best explains the pixel's values is taken. That fit assumes the
  pixel saw one slot alone: the light a projector spills from neighbouring slots (its pixels straddle the
  camera's; about a quarter of it on the simulated rig) then reads as wrong slots, and a right calibration
  scores 58–81 % on the simulated rig from 3–8 frames. Its line says so (:meth:`SlotCheck.describe`).

A pixel is *decidable* when its truth differs between slots (a still pixel looks the same in
every slot) and the fit separates the best slot from the runner-up. The **slot accuracy** is the
fraction of decidable pixels whose slot is the code's. The ``strobe`` scene (one flash every
17 sub-frames over a wall) makes every lit pixel decidable: record 17 frames of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flexvox_core.forward import check_video, tiled_order

MIN_DECIDED = 0.1
"""Below this fraction of decided pixels the accuracy says little about the recording."""
STROBE_FRAMES = 17
"""Frames of the ``strobe`` scene that visit every slot of a 4×4 code (its flash every 17 sub-frames)."""


@dataclass(frozen=True)
class SlotCheck:
    """What :func:`slot_accuracy` found.

    Attributes
    ----------
    accuracy : float
        Fraction of decidable pixels that sampled their code slot (NaN when none is decidable).
    decidable_fraction : float
        Fraction of the frame's pixels that could be decided.
    seen : ndarray (H, W) int
        The slot each pixel sampled (−1 where undecidable).
    expected : ndarray (H, W) int
        The code's slot of each pixel.
    frames, slots : int
        The frames read and the code's K: fewer frames than K took the single-slot fit (the module's caveat).
    """

    accuracy: float
    decidable_fraction: float
    seen: np.ndarray
    expected: np.ndarray
    frames: int = 0
    slots: int = 0

    @property
    def single_slot_fit(self) -> bool:
        """True when fewer frames than K were read: each pixel was taken to see one slot alone."""
        return self.frames < self.slots

    @property
    def decided(self) -> int:
        """How many pixels could be decided."""
        return int((self.seen >= 0).sum())

    def describe(self, warnings: list[str] | tuple[str, ...] = ()) -> str:
        """One line, with a warning when too few pixels decide it (a scene that barely changes between slots) or
        fewer frames than K were read (the single-slot fit reads a projector's spilled light as wrong slots).
        ``warnings``: what the capture stated of its timing (a recording's ``calibration["warnings"]``), named
        before the advice to record the strobe scene, since a timing guess is a cause the strobe cannot cure."""
        total = self.seen.size
        stated = "".join(f"; the capture states: {w}" for w in warnings)
        if not np.isfinite(self.accuracy):
            return ("slot accuracy: no pixel changes enough between slots to tell its slot" + stated
                    + ": record the strobe scene")
        line = (f"slot accuracy {self.accuracy:.1%} of the {self.decided} of {total} pixels "
                f"({self.decidable_fraction:.1%}) whose slot can be told from the ground truth")
        few_pixels = self.decidable_fraction < MIN_DECIDED
        if self.single_slot_fit:
            line += (f"; read from {self.frames} frame(s), fewer than K = {self.slots}, each pixel taken to see one "
                     "slot alone: the light a projector spills from neighbouring slots reads as wrong slots, so a "
                     "right calibration can score low (58-81 % on the simulated rig)")
        if few_pixels:
            line += f"; too few pixels to judge the recording (under {MIN_DECIDED:.0%})"
        if few_pixels or self.single_slot_fit:
            line += stated + f": record {STROBE_FRAMES} frames of the strobe scene"
        return line


def slot_accuracy(frames, truth, code, *, min_spread: float = 0.02, margin: float = 2.0) -> SlotCheck:
    """Read back which slot every pixel sampled, and compare with the code.

    Parameters
    ----------
    frames : ndarray (F, H, W)
        The captured frames, normalised (an identity code: one sample each).
    truth : ndarray (F·K, H, W)
        The scene's ground truth of those frames.
    code : ndarray (m, n, K)
        The identity code of the capture.
    min_spread : float
        A pixel is decidable only where its truth's RMS difference between slots reaches this
        (in the video's units, [0, 1]).
    margin : float
        ... and where the runner-up slot's squared error is at least ``margin`` times the best's.

    Examples
    --------
    >>> from flexvox_core.design import design_code
    >>> from flexvox_core.forward import capture
    >>> code = design_code((2, 2)).code
    >>> rng = np.random.default_rng(0)
    >>> video = rng.random((8, 6, 6)).astype(np.float32)
    >>> slot_accuracy(capture(video, code), video, code).accuracy
    1.0
    >>> slot_accuracy(capture(np.roll(video, 1, axis=0), code), video, code).accuracy < 0.5
    True
    """
    c = np.asarray(frames, dtype=np.float64)
    if c.ndim != 3:
        raise ValueError(f"`frames` must have shape (F, H, W); got {c.shape}")
    code = np.asarray(code, dtype=bool)
    if code.ndim != 3 or not (code.sum(axis=2) == 1).all():
        raise ValueError("`code` must be an identity code (m, n, K) with one open slot per pixel")
    K = code.shape[2]
    F, H, W = c.shape
    t = check_video(truth, K, name="truth").astype(np.float64)
    if t.shape != (F * K, H, W):
        raise ValueError(f"`truth` must have shape ({F * K}, {H}, {W}) for {F} frames of K = {K}; got {t.shape}")
    t = t.reshape(F, K, H, W)
    spread = np.sqrt(((t - t.mean(axis=1, keepdims=True)) ** 2).mean(axis=(0, 1)))
    if F >= K:
        score, decidable = _dominant_slot(c, t)
    else:
        err = ((c[:, None] - t) ** 2).sum(axis=0)  # (K, H, W)
        order = np.sort(err, axis=0)
        score = -err
        decidable = order[1] >= margin * order[0] + 1e-12
    best = np.argmax(score, axis=0)
    decidable &= spread >= min_spread
    expected = tiled_order(code, H, W)
    n = int(decidable.sum())
    acc = float((best[decidable] == expected[decidable]).mean()) if n else float("nan")
    return SlotCheck(acc, n / (H * W), np.where(decidable, best, -1), expected, frames=F, slots=K)


def _dominant_slot(c: np.ndarray, t: np.ndarray, *, ridge: float = 1e-6, ratio: float = 1.25):
    """Per-pixel least-squares slot weights ``(K, H, W)`` and where the largest clearly leads.

    Solves ``min_w Σ_f (c_f − Σ_s w_s t_{f,s})²`` (a tiny ridge keeps ill-posed pixels finite);
    a pixel is decidable when its system is well conditioned and the largest weight exceeds
    ``ratio`` times the runner-up.
    """
    F, K, H, W = t.shape
    a = t.reshape(F, K, H * W).transpose(2, 0, 1)  # (P, F, K)
    b = c.reshape(F, H * W).T  # (P, F)
    ata = a.transpose(0, 2, 1) @ a
    scale = np.trace(ata, axis1=1, axis2=2) / K + 1e-12
    ata += (ridge * scale)[:, None, None] * np.eye(K)
    atb = np.einsum("pfk,pf->pk", a, b)
    w = np.linalg.solve(ata, atb[..., None])[..., 0]  # (P, K)
    cond_ok = np.linalg.eigvalsh(ata)[:, 0] > 1e-3 * scale
    top = np.sort(w, axis=1)
    lead = (top[:, -1] > 0) & (top[:, -1] >= ratio * np.maximum(top[:, -2], 0))
    return w.T.reshape(K, H, W), (cond_ok & lead).reshape(H, W)


__all__ = ["SlotCheck", "slot_accuracy"]
