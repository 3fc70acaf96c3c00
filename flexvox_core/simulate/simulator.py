"""The simulator: a high-speed video, a code and the declared effects in; camera frames out.

The paper's §2 simulation of the per-pixel shutter (high-speed frames weighted by the code and summed), with
the rig's imperfections (§5: a projector as the shutter) as declared effects.

With no effect declared the frames are :func:`flexvox_core.forward.capture`, bit for bit.
Optical effects (pattern, timing, light stages) turn the code into per-slot weights
``W (K, H, W)`` and the frames become ``Σ_s W[s] · video[f·K + s]``; electron-domain
effects then act on ``frames · electrons_per_unit``. Only declared effects run.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from numbers import Integral, Real

import numpy as np

from flexvox_core.codes import code_from_order, is_identity_code, order_from_code, validate_code
from flexvox_core.forward import capture, check_video, tiled_code
from flexvox_core.memory_budget import FLOAT, check_fits, simulation_bytes
from flexvox_core.multiplex import MultiplexedCode, multiplexed_code
from flexvox_core.simulate.effects import Adc, Effect, SyncPhase
from flexvox_core.simulate.scene_file import SceneSpec
from flexvox_core.simulate.scenes import render_scene
from flexvox_core.simulate.sources import load_video, trim_to_frames, video_shape

_logger = logging.getLogger(__name__)


@dataclass
class SimulationResult:
    """Camera frames and everything a recording needs to describe them.

    Attributes
    ----------
    frames : ndarray (F, H, W)
        float32 in relative units (1 = a white scene seen for one slot), or uint16 counts
        when the ``adc`` effect is declared.
    dropped : ndarray (F,) bool
    ground_truth : ndarray (S, H, W) float32
    code : ndarray (m, n, K) bool
    storage : dict
        How to turn ``frames`` back into relative units (see :meth:`normalised`).
    effects : dict
        ``{name: params}`` of exactly the effects applied, in pipeline order.
    """

    frames: np.ndarray
    dropped: np.ndarray
    ground_truth: np.ndarray
    code: np.ndarray
    storage: dict
    effects: dict
    seed: int
    rate_hz: float
    multiplexed: bool = False
    placement: np.ndarray | None = None
    source: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def K(self) -> int:  # noqa: N802
        """Slots per frame."""
        return self.code.shape[2]

    def normalised(self) -> np.ndarray:
        """Frames as float32 relative units, whatever the storage."""
        return normalise_frames(self.frames, self.storage)

    def __repr__(self) -> str:
        F, H, W = self.frames.shape
        m, n, K = self.code.shape
        effects = ", ".join(self.effects) or "none"
        return (f"<SimulationResult: {F} frames of {H}x{W} ({self.frames.dtype}), tile {m}x{n} (K = {K}), "
                f"{int(np.count_nonzero(self.dropped))} dropped, effects: {effects}>")


def normalise_frames(frames: np.ndarray, storage: dict) -> np.ndarray:
    """Counts → relative units: ``(DN − black_level) / (gain · electrons_per_unit)``."""
    if storage.get("kind") == "counts":
        scale = storage["gain"] * storage["electrons_per_unit"]
        return ((frames.astype(np.float32) - np.float32(storage["black_level"])) / np.float32(scale))
    return frames.astype(np.float32, copy=False)


def _pattern_stage(light: np.ndarray, effects: list[Effect]) -> np.ndarray:
    """Projected light per slot after misregistration, pattern blur and leakage (as declared)."""
    for e in effects:
        if e.stage == "pattern":
            light = e.apply(light)
    return light


def _weights(code: np.ndarray, H: int, W: int, effects: list[Effect]) -> np.ndarray | None:
    """Per-slot weights after the pattern stage (None: no optical effect, the ideal code)."""
    if not any(e.stage in ("pattern", "light") for e in effects):
        return None
    return _pattern_stage(tiled_code(code, H, W).astype(np.float32), effects)


def _light(weights: np.ndarray, effects: list[Effect]) -> np.ndarray:
    for e in effects:
        if e.stage == "light":
            weights = e.apply(weights)
    return weights


def _weighted_capture(video: np.ndarray, weights: np.ndarray) -> np.ndarray:
    K = weights.shape[-3]
    F = video.shape[0] // K
    out = np.zeros((F,) + video.shape[1:], dtype=video.dtype)
    per_frame = weights.ndim == 4
    tmp = np.empty(video.shape[1:], dtype=video.dtype)
    for f in range(F):
        w = weights[f] if per_frame else weights
        for s in range(K):
            np.multiply(w[s], video[f * K + s], out=tmp)
            out[f] += tmp
    return out


def render_exposures(
    video,
    light,
    *,
    effects: list[Effect] = (),
    seed: int = 0,
    stream: int = 0,
    rate_hz: float = 15.0,
    electrons_per_unit: float = 1000.0,
):
    """Camera frames of ``video`` lit by arbitrary per-slot projector light, with ``effects``.

    This is the simulator's core, for callers whose patterns are not a tiled code (the
    simulated rig shows Gray codes, single slots, ...).

    Parameters
    ----------
    video : ndarray, shape (F·K, H, W)
        Scene radiance per sub-frame, in [0, 1].
    light : ndarray, shape (K, H, W) or (F, K, H, W)
        Projected light reaching each camera pixel in each slot, in [0, 1] (1 = open),
        already in camera coordinates; one set for all frames, or one per frame.
    effects, seed, rate_hz, electrons_per_unit
        As in :func:`simulate_video`.
    stream : int
        Mixed into every effect's random generator: give each call a different stream
        (a frame counter) so successive calls draw different noise.

    Returns
    -------
    frames : ndarray (F, H, W)
        float32 relative units, or uint16 counts with ``adc``.
    dropped : ndarray (F,) bool
    storage : dict
    """
    light = np.asarray(light, dtype=np.float32)
    if light.ndim not in (3, 4):
        raise ValueError(f"`light` must have shape (K, H, W) or (F, K, H, W); got {light.shape}")
    K = light.shape[-3]
    video = check_video(video, K)
    S, H, W = video.shape
    F = S // K
    if light.shape[-2:] != (H, W) or (light.ndim == 4 and light.shape[0] != F):
        raise ValueError(f"`light` {light.shape} does not match {F} frames of K = {K} slots of {H}x{W}")
    if not np.isfinite(light).all() or light.min() < 0:
        raise ValueError("`light` must hold finite values >= 0")
    _check_effects(effects, rate_hz, electrons_per_unit, seed)
    if light.ndim == 4:
        weights = np.stack([_pattern_stage(light[f], effects) for f in range(F)])
    else:
        weights = _pattern_stage(light, effects)
    timing = next((e for e in effects if e.stage == "timing"), None)
    weights = _timed(weights, timing, effects, seed, stream, F)
    frames = _weighted_capture(video, weights)
    return _sensor_and_drops(frames, effects, seed, stream, rate_hz, electrons_per_unit)


def _check_effects(effects, rate_hz, electrons_per_unit, seed) -> None:
    if isinstance(seed, bool) or not isinstance(seed, Integral) or seed < 0:
        raise ValueError(f"`seed` must be a whole number >= 0; got {seed!r}")
    if not all(isinstance(v, Real) and not isinstance(v, bool) and v > 0 for v in (rate_hz, electrons_per_unit)):
        raise ValueError(f"`rate_hz` and `electrons_per_unit` must be numbers > 0; got {rate_hz!r}, "
                         f"{electrons_per_unit!r}")
    names = [e.name for e in effects]
    if len(set(names)) != len(names):
        raise ValueError(f"each effect may be declared once; got {names}")


def _timed(weights, timing, effects, seed, stream, F):
    """Apply the timing stage (if declared) and then the light stage."""
    if timing is None:
        return _light(weights, effects)
    if timing.jitter > 0:
        phases = timing.offset + timing.jitter * timing.rng(seed, stream).standard_normal(F)
        per = [weights[f] if weights.ndim == 4 else weights for f in range(F)]
        return np.stack([_light(SyncPhase.shifted(w, p), effects) for w, p in zip(per, phases, strict=True)])
    if weights.ndim == 4:
        return np.stack([_light(SyncPhase.shifted(w, timing.offset), effects) for w in weights])
    return _light(SyncPhase.shifted(weights, timing.offset), effects)


def _sensor_and_drops(frames, effects, seed, stream, rate_hz, electrons_per_unit):
    sensor = [e for e in effects if e.stage == "sensor"]
    storage = {"kind": "float", "units": "relative (1 = white scene, one open slot)"}
    if sensor:
        electrons = frames.astype(np.float64) * electrons_per_unit
        exposure_s = 1.0 / rate_hz
        for e in sensor:
            electrons = e.apply(electrons, exposure_s=exposure_s, rng=e.rng(seed, stream) if e.random else None)
        adc = next((e for e in sensor if isinstance(e, Adc)), None)
        if adc is None:
            frames = (electrons / electrons_per_unit).astype(np.float32)
            storage = {**storage, "electrons_per_unit": electrons_per_unit}  # the noise's scale, stated
        else:
            frames = electrons  # uint16 counts from Adc.apply
            storage = {
                "kind": "counts", "units": "DN", "bits": adc.bits, "gain": adc.gain,
                "black_level": adc.black_level, "electrons_per_unit": electrons_per_unit,
            }
    dropped = np.zeros(frames.shape[0], dtype=bool)
    for e in effects:
        if e.stage == "frames":
            dropped = e.drops(frames.shape[0], e.rng(seed, stream))
            frames[dropped] = 0
    return frames, dropped, storage


def simulate_video(
    video,
    code,
    *,
    effects: list[Effect | str] | dict | str | None = (),
    seed: int = 0,
    rate_hz: float = 15.0,
    electrons_per_unit: float = 1000.0,
) -> SimulationResult:
    """Simulate the camera frames of ``video`` seen through ``code`` with ``effects``.

    Parameters
    ----------
    video : ndarray, shape (S, H, W)
        Ground truth in [0, 1] (integers, an 8-bit clip, divided by their dtype's largest value; floats outside
        [0, 1] are refused); S a multiple of K.
    code : ndarray, shape (m, n, K), or MultiplexedCode
        An identity code, or a multiplexed one (:func:`~flexvox_core.multiplexed_code`, given itself: the result
        is then marked ``multiplexed`` with its placement, and :func:`~flexvox_core.recording.write_simulation`
        writes a recording every reconstruction reads). A code array that is neither (its ``.code`` among them)
        simulates all the same, but no recording is written of it.
    effects : list of str or Effect, or mapping
        Only these are simulated, in the pipeline's order (see :mod:`flexvox_core.simulate.effects`): effect
        names at their defaults (``["photon_noise", "read_noise"]``, ``fv.EFFECTS`` lists them), Effect
        objects, or a mapping ``{name: {param: value}}`` (a scene file's ``[effects]``, read by
        :func:`~flexvox_core.simulate.parse_effects`).
    seed : int
        Seeds every effect's own generator.
    rate_hz : float
        Camera frame rate (the exposure of dark current is one frame period).
    electrons_per_unit : float
        Electrons from a white scene in one open slot.

    Returns
    -------
    SimulationResult
        ``frames`` (F, H, W), ``dropped``, ``ground_truth`` (the video), ``code`` and what a recording needs.

    Examples
    --------
    >>> from flexvox_core import render_scene, sequential_order, code_from_order
    >>> code = code_from_order(sequential_order((2, 2)))
    >>> sim = simulate_video(render_scene("balls", 8, 16, 16), code, effects={"read_noise": {"sigma": 2}})
    >>> sim.frames.shape, list(sim.effects)
    ((2, 16, 16), ['read_noise'])
    """
    from flexvox_core.simulate.effects import as_effects

    effects = as_effects(effects)
    mc = code if isinstance(code, MultiplexedCode) else None
    code = validate_code(code if mc is None else mc.code)
    K = code.shape[2]
    video = check_video(video, K)
    _check_unit_range(video)
    _check_effects(effects, rate_hz, electrons_per_unit, seed)
    S, H, W = video.shape
    F = S // K
    weights = _weights(code, H, W, effects)
    timing = next((e for e in effects if e.stage == "timing"), None)
    if timing is not None:
        base = tiled_code(code, H, W).astype(np.float32) if weights is None else weights
        weights = _timed(base, timing, effects, seed, 0, F)
    elif weights is not None:
        weights = _light(weights, effects)
    # No optical effect: the exact forward model, bit for bit.
    frames = capture(video, code) if weights is None else _weighted_capture(video, weights)
    frames, dropped, storage = _sensor_and_drops(frames, effects, seed, 0, rate_hz, electrons_per_unit)
    applied = {e.name: e.as_dict() for e in effects}
    _logger.info("simulated %d frames of %dx%d, K=%d, effects: %s", F, H, W, K, ", ".join(applied) or "none")
    return SimulationResult(frames, dropped, video, code, storage, applied, int(seed), float(rate_hz),
                            multiplexed=mc is not None, placement=None if mc is None else mc.placement,
                            extra={"electrons_per_unit": electrons_per_unit})


def _check_unit_range(video: np.ndarray) -> None:
    """The ground truth lies in [0, 1] (white = 1), as a video file's floats must (``sources``): a float clip in
    0..255 had been simulated 255 times too bright, its recording's ground truth in counts."""
    lo, hi = float(video.min()), float(video.max())
    if lo < 0 or hi > 1:
        hint = " (8-bit values in a float array? divide by 255)" if hi > 2 else ""
        raise ValueError(f"`video` values must lie in [0, 1] (white = 1); got {lo:g} to {hi:g}{hint}")


def code_for(spec: SceneSpec):
    """The code a scene asks for: (code, multiplexed, placement order or None)."""
    if spec.order is not None:
        return code_from_order(spec.order), False, None
    if spec.multiplexed:
        mc = multiplexed_code(spec.tile, placement=spec.placement)
        return mc.code, True, mc.placement
    from flexvox_core.design import design_code  # its solver's scipy.optimize: only when a code is designed

    return design_code(spec.tile).require(), False, None


_FILE_ADVICE = "cut the video to fewer or smaller frames, or simulate fewer frames"


def _check_file_fits(spec: SceneSpec, K: int) -> None:
    """Refuse a video file whose simulation would not fit in memory, from its header (before it is read)."""
    shape = video_shape(spec.file)
    if shape is None:
        return
    S, H, W = shape
    frames = S // K if spec.camera_frames() is None else min(S // K, spec.camera_frames())
    if frames < 1:
        return  # trim_to_frames says it holds less than one camera frame
    untrimmed = (S - frames * K) * H * W * FLOAT  # the loaded video is kept whole, the simulation uses its start
    check_fits(simulation_bytes(frames, K, H, W) + untrimmed,
               f"simulating {spec.source_label()} ({frames} frames of {H}x{W} at K = {K})", _FILE_ADVICE)


def simulate(spec: SceneSpec, *, video: np.ndarray | None = None) -> SimulationResult:
    """Simulate a scene file's scene (render or load its source, trim, design its code).

    What would not fit in memory is refused first (:mod:`flexvox_core.memory_budget`): a built-in
    scene before it is rendered, a video file from its header before it is read, a ``video``
    already read before the simulation's working copies are made.
    """
    code, multiplexed, placement = code_for(spec)
    K = code.shape[2]
    given = video is not None
    if video is None:
        if spec.file is not None:
            _check_file_fits(spec, K)
            video = load_video(spec.file, white=spec.white)
        else:
            frames = spec.camera_frames() or 8
            check_fits(simulation_bytes(frames, K, spec.height, spec.width),
                       f"simulating {spec.height}x{spec.width} with {frames} frames of K = {K}",
                       "use a smaller size or fewer frames")
            video = render_scene(spec.builtin, frames * K, spec.height, spec.width, seed=spec.seed)
    video = trim_to_frames(video, K, frames=spec.camera_frames() if spec.file is not None else None,
                           source=spec.source_label())
    if given:  # already in memory (read by the caller): refuse the simulation's working copies that would not fit
        F, H, W = video.shape[0] // K, video.shape[1], video.shape[2]
        check_fits(simulation_bytes(F, K, H, W) - F * K * H * W * FLOAT,
                   f"simulating {spec.source_label()} ({F} frames of {H}x{W} at K = {K})", _FILE_ADVICE)
    result = simulate_video(video, code, effects=spec.effects, seed=spec.seed, rate_hz=spec.rate_hz,
                            electrons_per_unit=spec.electrons_per_unit)
    result.multiplexed = multiplexed
    if placement is None and is_identity_code(code):
        placement = order_from_code(code)
    result.placement = placement
    result.source = spec.source_label()
    return result
