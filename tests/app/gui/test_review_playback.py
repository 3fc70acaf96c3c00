"""Review's playback model alone, without Qt or a recording: the frame, playing, the speed, what is shown."""

from types import SimpleNamespace

import numpy as np
import pytest

from flexvox_app.gui.models.jobs import ReconstructionResult
from flexvox_app.gui.models.review_playback import PlaybackModel
from flexvox_core.methods import Method

from .model_helpers import Settings

K, F = 4, 5


def session(subframe_hz=60.0):
    """What playback reads of a session: K, the sub-frames, the recording's rates."""
    rates = {"subframe_hz": subframe_hz} if subframe_hz else {}
    return SimpleNamespace(K=K, n_subframes=F * K, recording=SimpleNamespace(attrs={"rates": rates}))


def result(first_frame, frames):
    return ReconstructionResult(np.zeros((frames * K, 2, 2), np.float32), Method("rebin"), 0.1,
                                first_frame=first_frame)


@pytest.fixture
def playback():
    p = PlaybackModel(Settings({"review/fps": 8}))
    p.set_session(session())
    p.events = []
    for name in ("frame_changed", "playing_changed", "speed_changed", "shown_changed", "comparison_changed",
                 "preview_due"):
        getattr(p, name).connect(lambda *args, name=name: p.events.append((name, *args)))
    return p


def test_each_part_has_its_own_signal_with_the_new_value(playback):
    p = playback
    p.set_subframe(6)
    assert p.events == [("frame_changed", 6), ("preview_due",)]  # paused, nothing shown covers it
    shown = result(1, 2)
    p.events.clear()
    p.set_shown(shown)
    p.set_subframe(7)  # sub-frames 4..11 are shown: no preview due
    assert p.events == [("shown_changed", shown), ("frame_changed", 7)]
    p.events.clear()
    p.set_comparison(result(3, 1))  # beside it, but not covering sub-frame 7: a preview is due there
    p.set_subframe(8)
    assert p.events == [("comparison_changed", p.comparison), ("frame_changed", 8), ("preview_due",)]
    p.events.clear()
    p.set_comparison(None)
    p.set_fps(20)
    assert p.events == [("comparison_changed", None), ("speed_changed",)] and p.settings["review/fps"] == 20


def test_a_tick_advances_whole_frames_until_a_result_is_shown_and_stopping_makes_a_preview_due(playback):
    p = playback
    assert p.fps == 8 and p.step() == K and p.interval_ms() == 500
    p.set_playing(True)
    p.events.clear()
    p.tick(p.last_tick + 1.0)  # 8 sub-frames a second: two frames of 4
    assert p.subframe == 8 and p.events == [("frame_changed", 8)]  # never a preview while playing
    p.set_real_time(True)
    assert p.speed() == 60.0 and p.interval_ms() == 67  # one frame at 60/s: 15 pictures a second
    p.set_shown(result(0, F))
    assert p.step() == 1 and p.interval_ms() == 33  # every sub-frame, but at most 30 pictures a second
    p.tick(p.last_tick + 0.25)
    assert p.subframe == (8 + 15) % (F * K)
    p.events.clear()
    p.set_playing(False)
    assert p.events == [("playing_changed", False), ("preview_due",)]


def test_without_a_session_nothing_plays_and_real_time_falls_back_to_the_speed_box():
    p = PlaybackModel(Settings({"review/real_time": True}))
    p.set_playing(True)
    assert not p.playing and p.subframe_hz() is None and p.speed() == 12.0  # the default speed box
    p.tick(5.0)
    assert p.subframe == 0
    p.set_session(session(subframe_hz=None))
    assert p.speed() == 12.0 and not p.covers(None, 0)
