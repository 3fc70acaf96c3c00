"""Simulated twins of the projector and the sync box that need no scene.

They implement the interfaces faithfully (the same contract tests run against them and the
real drivers) and keep their state where a test or the demo app can look at it. Time comes
from an injectable clock, so nothing here sleeps and tests are deterministic.

The simulated *camera*, coupled to these through a scene, lives elsewhere.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

import numpy as np

from rig_drivers.errors import IncompatibleStateError
from rig_drivers.interfaces import (
    PatternSequence,
    Projector,
    RunState,
    SyncController,
    SyncSettings,
)

_logger = logging.getLogger(__name__)

SIMULATED_SYNC_VERSION = "flexvox-simulated-syncbox 1.0"


def _monotonic_us() -> int:
    return time.monotonic_ns() // 1000


class SimulatedProjector(Projector):
    """A projector that keeps the pattern sequence, its timing and its run state.

    Parameters
    ----------
    clock_us : callable, optional
        Returns the current time in µs (default: the monotonic clock). Tests pass a
        counter they advance by hand.
    name : str, optional
        Name used in messages.
    """

    def __init__(self, *, clock_us: Callable[[], int] | None = None, name: str | None = None):
        super().__init__(name=name or "simulated projector")
        self._clock_us = clock_us or _monotonic_us
        self._start_us: int | None = None
        self._elapsed_before_pause_us = 0

    def _do_open(self) -> None:
        self._elapsed_before_pause_us = 0

    def _do_close(self) -> None:
        self._start_us = None

    def _do_load_sequence(self, sequence: PatternSequence) -> None:
        _logger.debug("simulated projector: %d patterns, %d µs period", sequence.K, sequence.period_us)
        self._elapsed_before_pause_us = 0

    def _do_start(self) -> None:
        self._start_us = int(self._clock_us())

    def _do_pause(self) -> None:
        self._elapsed_before_pause_us = self.elapsed_us()
        self._start_us = None

    def _do_stop(self) -> None:
        self._start_us = None
        self._elapsed_before_pause_us = 0

    def elapsed_us(self, at_us: int | None = None) -> int:
        """Display time since start (pauses excluded; 0 when stopped), now or at clock time ``at_us``.

        Callers that already read the clock pass that reading, so a real clock that moved on
        in between cannot shift the answer.
        """
        if self._run_state is RunState.STOPPED:
            return 0
        if self._start_us is None:
            return self._elapsed_before_pause_us
        now = int(self._clock_us()) if at_us is None else int(at_us)
        return self._elapsed_before_pause_us + now - self._start_us

    def current_slot(self) -> int | None:
        """Index of the pattern on display now, or None when nothing is shown."""
        seq = self._sequence
        if seq is None or self._run_state is RunState.STOPPED:
            return None
        shown = self.elapsed_us() // seq.period_us
        if not seq.repeat and shown >= seq.K:
            return None
        return int(shown % seq.K)

    def current_patterns(self) -> np.ndarray:
        """The loaded patterns, ``(K, H, W)`` bool (read-only).

        Raises
        ------
        IncompatibleStateError
            When no sequence is loaded.
        """
        if self._sequence is None:
            raise IncompatibleStateError("no sequence loaded: call load_sequence() first")
        return self._sequence.patterns


class SimulatedSyncController(SyncController):
    """A sync box whose counters follow an injectable clock.

    ``pulse_count`` is the number of pattern pulses whose start time has passed since
    :meth:`start` (the first pulse fires at start), ``elapsed_us`` the time since start.
    """

    def __init__(self, *, clock_us: Callable[[], int] | None = None, name: str | None = None):
        super().__init__(name=name or "simulated sync box")
        self._clock_us = clock_us or _monotonic_us
        self._start_us: int | None = None
        self._stopped_elapsed_us = 0
        self._has_run = False

    def _do_open(self) -> None:
        self._start_us = None
        self._stopped_elapsed_us = 0
        self._has_run = False

    def _do_close(self) -> None:
        self._start_us = None

    def _do_configure(self, settings: SyncSettings) -> None:
        _logger.debug("simulated sync box: period %d µs, %d pulses per frame",
                      settings.period_us, settings.pulses_per_frame)

    def _do_start(self) -> None:
        self._start_us = int(self._clock_us())
        self._stopped_elapsed_us = 0
        self._has_run = True

    def _do_stop(self) -> None:
        self._stopped_elapsed_us = self._do_elapsed_us()
        self._start_us = None

    def _do_elapsed_us(self) -> int:
        if self._start_us is None:
            return self._stopped_elapsed_us
        return int(self._clock_us()) - self._start_us

    def _do_pulse_count(self) -> int:
        if self._settings is None or not self._has_run:
            return 0
        return self._do_elapsed_us() // self._settings.period_us + 1

    def _do_firmware_version(self) -> str:
        return SIMULATED_SYNC_VERSION
