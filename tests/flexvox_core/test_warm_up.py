"""Methods run once on a small capture before a benchmark times them (no row pays a one-time compile)."""

import numpy as np

from flexvox_core.design import design_code
from flexvox_core.methods import Method
from flexvox_core.methods import runner as runner_module
from flexvox_core.warm_up import WARM_UP_FRAMES, warm_up


def test_each_method_runs_once_on_a_small_capture_of_whole_tiles(monkeypatch):
    seen = []
    real = runner_module.run

    def run(frames, code, method, **kw):
        seen.append((frames.shape, frames.dtype, method))
        return real(frames, code, method, **kw)

    monkeypatch.setattr(runner_module, "run", run)
    code = design_code((3, 5)).code  # 32x48 is no whole number of 3x5 tiles: 30x45
    methods = [Method("rebin"), Method("diffusion", time=1.0)]
    assert warm_up(code, methods, dtype=np.float64) >= 0
    assert seen == [((WARM_UP_FRAMES, 30, 45), np.float64, m) for m in methods]


def test_a_method_that_refuses_the_small_capture_is_passed_over(monkeypatch):
    def run(frames, code, method, **kw):
        if method.name == "gap-tv":
            raise ValueError("too small")
        return None

    monkeypatch.setattr(runner_module, "run", run)
    warm_up(design_code((2, 2)).code, [Method("gap-tv"), Method("rebin")])  # no exception


def test_estimates_run_only_for_methods_not_refused_by_name(monkeypatch):
    import flexvox_core.accuracy as accuracy

    estimated = []
    monkeypatch.setattr(runner_module, "run", lambda *a, **k: None)
    monkeypatch.setattr(accuracy, "estimate_accuracy", lambda f, c, m, **k: estimated.append(m))
    methods = [Method("motion-aware"), Method("diffusion", time=1.5), Method("diffusion", solver="explicit")]
    warm_up(design_code((2, 2)).code, methods, estimates=True)
    assert estimated == [methods[1]]
