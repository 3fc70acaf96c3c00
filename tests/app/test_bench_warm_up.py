"""Both benchmarks run every method once on a small capture before timing any (no row pays a one-time compile)."""

import numpy as np

from flexvox_core.design import design_code
from flexvox_core.methods import Method


def test_the_recording_bench_warms_up_every_method_before_timing_any(recording, monkeypatch, tmp_path):
    import flexvox_core.warm_up as warm
    from flexvox_app.cli import bench_recording
    from flexvox_core.capture_reader import CaptureReader

    events = []
    monkeypatch.setattr(warm, "warm_up", lambda code, methods, **kw: events.append(("warm", list(methods), kw)))
    real_run = CaptureReader.run

    def reader_run(self, method, **kw):
        events.append(("run", method))
        return real_run(self, method, **kw)

    monkeypatch.setattr(CaptureReader, "run", reader_run)
    methods = [Method("rebin"), Method("diffusion")]
    monkeypatch.setattr(bench_recording, "methods_for", lambda code, quick: methods)
    (tmp_path / "b").mkdir()
    bench_recording.run_recording_bench(recording, tmp_path / "b", quick=True)
    assert events[0] == ("warm", methods, {"device": "cpu", "estimates": True})
    assert [e[0] for e in events[1:]] == ["run"] * 3  # the recording read once untimed, then each method timed


def test_the_scene_bench_warms_up_each_code_before_timing_any(monkeypatch, tmp_path):
    import flexvox_core.methods as methods_module
    import flexvox_core.warm_up as warm
    from flexvox_app import accuracy_bench
    from flexvox_core.forward import capture

    events = []
    monkeypatch.setattr(warm, "warm_up", lambda code, methods, **kw: events.append(("warm", code.shape)))
    real_run = methods_module.run
    monkeypatch.setattr(methods_module, "run", lambda *a, **k: (events.append(("run", None)), real_run(*a, **k))[1])
    cases = []
    for tile in ((2, 2), (2, 2), (1, 3)):
        code = design_code(tile).code
        truth = np.random.default_rng(0).random((2 * code.shape[2], 12, 12)).astype(np.float32)
        cases.append(accuracy_bench.Case(f"tiny {tile}", code.shape[2], truth, capture(truth, code), code))
    monkeypatch.setattr(accuracy_bench, "cases", lambda quick, sci: cases)
    monkeypatch.setattr(accuracy_bench, "methods_for", lambda case, quick: [("rebin", Method("rebin"))])
    accuracy_bench.run_bench(tmp_path / "b", quick=True, sci=False)
    # each code warmed up once, before its first timed run
    assert events == [("warm", (2, 2, 4)), ("run", None), ("run", None), ("warm", (1, 3, 3)), ("run", None)]
