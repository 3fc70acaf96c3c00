"""The projector's screen while the Calibrate workspace uses the rig (a projector fed by its video input).

On a real rig whose projector takes its patterns on a video input (the DLPC350), the operator picks
the screen that feeds it ("projector screen"); while a calibration, the live co-location numbers or
the synchronisation wizard use the rig, a :class:`~flexvox_app.gui.projector.display.ProjectorDisplay` on
that screen is the projector's display sink, so every pattern the session loads is shown
full-screen, pixel-exact, before its sequence starts. The window closes and the sink is removed
when the last of them is done.
"""

from __future__ import annotations

import html

from PySide6.QtCore import QObject, Qt
from PySide6.QtWidgets import QLabel, QWidget

from flexvox_app.gui.models.rig_service import RigService
from flexvox_app.gui.projector.display import ProjectorDisplay
from flexvox_app.gui.projector.window import ScreenPicker
from flexvox_app.gui.widgets.rich_text import RED
from flexvox_app.gui.widgets.settings import AppSettings


class ProjectorScreen(QObject):
    """The screen picker, the display sink it injects, and who is using it.

    Parameters
    ----------
    service : RigService
    settings : AppSettings
        Remembers the screen.
    """

    def __init__(self, service: RigService, settings: AppSettings, parent: QWidget):
        super().__init__(parent)
        self.service = service
        self.settings = settings
        self._parent = parent
        self.display: ProjectorDisplay | None = None
        """The display sink injected into the projector while the rig is in use (None otherwise)."""
        self._users: set[str] = set()
        self.screen_box = ScreenPicker(settings.get_str("calibrate/screen", ""))
        self.screen_box.setToolTip("the screen that feeds the projector's video input (HDMI): the calibration "
                                   "patterns go there full-screen, pixel for pixel")
        self.label = QLabel("")
        self.label.setWordWrap(True)
        self.label.setTextFormat(Qt.TextFormat.RichText)

    @property
    def needed(self) -> bool:
        """True on a real rig whose projector takes its patterns on a video input (it has a display sink)."""
        return not self.service.simulated and self.service.rig.projector.display_input is not None

    def chosen_screen(self):
        """The QScreen picked for the projector's video input (None: no screens)."""
        return self.screen_box.chosen()

    def attach(self, user: str) -> str | None:
        """Inject the display sink into the projector for ``user`` (a job); the reason when it cannot."""
        if not self.needed:
            return None
        screen = self.chosen_screen()
        if screen is None:
            return "no screen to show the patterns on: connect the projector's video input (HDMI) as a screen"
        if self.display is None or self.display.screen_name != screen.name():
            self._close_sink()
            self.display = ProjectorDisplay(screen, parent=self._parent)
            self.display.shown.connect(self._on_shown)
        self.settings.set("calibrate/screen", self.screen_box.currentData() or "")
        video_input = self.service.rig.projector.display_input
        assert video_input is not None  # `needed` checked it
        video_input.display = self.display
        self._users.add(user)
        self.label.setText(f"patterns go to {html.escape(screen.name() or 'the chosen screen')}")
        return None

    def release(self, user: str) -> None:
        """``user`` is done with the rig: when nobody else uses it, remove the sink and close its window."""
        self._users.discard(user)
        if not self._users:
            self._close_sink()

    def close(self) -> None:
        """Remove the sink from the projector and close its window, whoever uses it (the window is closing)."""
        self._users.clear()
        self._close_sink()

    def _close_sink(self) -> None:
        display, self.display = self.display, None
        if display is None:
            return
        video_input = self.service.rig.projector.display_input
        if video_input is not None and video_input.display is display:
            video_input.display = None
        display.close()
        display.deleteLater()
        self.label.setText("projector window closed")

    def _on_shown(self, n: int) -> None:
        d = self.display
        if d is not None and d.window is not None:
            H, W = d.window.frame_size
            warning = d.window.size_warning()
            text = f"showing pattern {d.frames_shown} ({W}×{H}, {n} frame{'s' if n > 1 else ''})"
            self.label.setText(text + (f"<br><span style='color:{RED}'>{html.escape(warning)}</span>"
                                       if warning else ""))
