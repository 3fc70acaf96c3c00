"""Constant-tensor diffusion as a method (:mod:`flexvox_core.reconstruct.diffusion`).

The paper's §3.1: Eq. 2 with one tensor for the whole video, whose one-pass solution is Eq. 3.
"""

from __future__ import annotations

import math

import numpy as np

from flexvox_core.codes import is_identity_code
from flexvox_core.gaps import bridge
from flexvox_core.methods.option_kinds import TRIPLE
from flexvox_core.methods.options import Option, choice, number
from flexvox_core.methods.spec import MethodOutput, MethodSpec, keywords
from flexvox_core.reconstruct.diffusion import DEFAULT_TENSOR, DEFAULT_TIME, SOLVERS, check_tensor, diffuse, sigmas
from flexvox_core.reconstruct.multiplexed import TIME_FRACTION, gap_gaussian


def _is_tensor(v) -> bool:
    try:
        check_tensor(v)  # the tensor alone: its blur with the time is `validate`'s
    except ValueError:
        return False
    return True


TENSOR = Option("tensor", DEFAULT_TENSOR, "three finite numbers >= 0 (cx, cy, ct), at least one of them > 0",
                _is_tensor, kind=TRIPLE, label="diffusion tensor",
                help="diffusion tensor (cx, cy, ct): large ct keeps spatial detail, large cx, cy temporal detail")
"""The diffusion tensor option (the Review workspace's continuum slider sets it)."""


def time_option(default: float, span) -> Option:
    """The diffusion time n (the accuracy knob), with a method's own default."""
    return number("time", default, strict=True, rule="a positive finite number", label="diffusion time n",
                  help="diffusion time n, the accuracy knob (not a convergence tolerance)", span=span)


class Diffusion(MethodSpec):
    """Diffusion with one constant tensor: normalized convolution, explicit or steady solver."""

    name = "diffusion"
    title = "constant-tensor diffusion (nc: the fast normalized convolution; explicit; steady)"
    trade = "one tensor (cx, cy, ct) for the whole video: large ct keeps spatial detail, large cx, cy temporal"
    option_specs = (
        TENSOR,
        time_option(DEFAULT_TIME, (0.05, 20.0, 0.25)),
        choice("solver", "nc", SOLVERS, label="solver",
               help="diffusion solver: nc (normalized convolution), explicit, steady (a global solve)"),
    )
    bench_axis = "time"

    def validate(self, values: dict) -> None:
        sigmas(values["tensor"], values["time"])  # the messages diffusion itself gives

    def resolve(self, given: dict) -> dict:
        values = super().resolve(given)
        values["tensor"] = tuple(values["tensor"])
        return values

    def overlap(self, options, K: int) -> int | None:
        if options.solver == "steady":
            return None  # a global linear solve
        sig_t = sigmas(options.tensor, options.time)[2]
        reach = 4 * sig_t + K  # the Gaussian's support, plus one frame for the nearest-sample fallback
        if options.solver == "explicit":
            reach *= 2  # the nc start, then diffusion of the same time
        return max(1, math.ceil(reach / K))

    takes_missing = True
    def takes_multiplexed(self, options) -> bool:
        return options.solver == "nc"  # GAP's denoiser is the Gaussian of Eq. 3, nc's one-pass form

    gpu_bytes_per_voxel = 28
    """The result and nc's four working volumes (flexvox_core.gpu.diffusion), and the frames."""

    def cpu_only(self, options, code) -> str | None:
        if not is_identity_code(code):
            return "a multiplexed capture's diffusion runs on the CPU"
        if options.solver != "nc":
            return f"diffusion's {options.solver} solver runs on the CPU"
        return None

    def run(self, frames, code, options, *, sample_range=None, extras=False, missing=None, device="cpu"
            ) -> MethodOutput:
        if not is_identity_code(code):  # a multiplexed capture: GAP with this tensor's Gaussian as denoiser
            return MethodOutput(gap_gaussian(frames, code, tensor=options.tensor,
                                             time=options.time * TIME_FRACTION))
        if device == "cuda":
            from flexvox_core.gpu.diffusion import diffuse_on_gpu

            video = diffuse_on_gpu(frames, code, tensor=options.tensor, time=options.time, missing=missing)
        else:
            video = diffuse(frames, code, **keywords(options), missing=missing)  # the options are diffuse's keywords
        if missing is not None:
            bridge(video, missing, code.shape[2])
        return MethodOutput(video, device=device)

    def label(self, values: dict) -> str:
        t = ",".join(f"{c:g}" for c in values["tensor"])
        return f"diffusion {values['solver']} ({t}) n={values['time']:g}"

    def bench_rank(self, row: dict, values: dict, code) -> tuple[tuple, bool]:
        other_solver = row["solver"] != values["solver"]
        tensor = tuple(row["tensor"])
        logs = np.log(np.asarray(tensor, float)) - np.log(np.asarray(values["tensor"], float))
        distance = float(np.linalg.norm(logs))
        return (other_solver, distance, tensor), not other_solver and distance <= 1e-6


DIFFUSION = Diffusion()
