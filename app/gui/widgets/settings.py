"""Settings that persist between sessions, on an injectable :class:`QSettings`.

The application uses ``QSettings("flexvox", "flexvox")``; tests pass an INI file in a temporary
folder (:func:`settings_at`) so they never touch the user's settings.
"""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QByteArray, QSettings

ORGANISATION = "flexvox"
APPLICATION = "flexvox"
LAST_FOLDER = "files/last_folder"
"""The folder the last file dialog used (every dialog starts there when its own is not known)."""


def settings_at(path) -> AppSettings:
    """Settings stored in the INI file ``path`` (for tests and portable installs)."""
    return AppSettings(QSettings(str(Path(path)), QSettings.Format.IniFormat))


def default_settings() -> AppSettings:
    """The user's settings (the platform's usual place)."""
    return AppSettings(QSettings(ORGANISATION, APPLICATION))


class AppSettings:
    """Typed access to a :class:`QSettings`.

    Parameters
    ----------
    qsettings : QSettings
    """

    def __init__(self, qsettings: QSettings):
        self.qsettings = qsettings

    def get_str(self, key: str, default: str = "") -> str:
        """A string value."""
        value = self.qsettings.value(key, default)
        return default if value is None else str(value)

    def get_float(self, key: str, default: float) -> float:
        """A float value (the default when missing or unreadable)."""
        try:
            return float(self.qsettings.value(key, default))
        except (TypeError, ValueError):
            return default

    def get_int(self, key: str, default: int) -> int:
        """An int value (the default when missing or unreadable)."""
        try:
            return int(float(self.qsettings.value(key, default)))
        except (TypeError, ValueError):
            return default

    def get_bool(self, key: str, default: bool) -> bool:
        """A bool value (INI files store "true"/"false")."""
        value = self.qsettings.value(key, default)
        if isinstance(value, str):
            return value.lower() in ("1", "true", "yes")
        return bool(value)

    def get_bytes(self, key: str) -> QByteArray | None:
        """A byte array (window geometry), or None."""
        value = self.qsettings.value(key)
        return value if isinstance(value, QByteArray) else None

    def last_folder(self, key: str = "") -> str:
        """Where a file dialog starts: the folder last used for ``key`` (e.g. exports), else the folder last
        used by any dialog, else the working folder."""
        for k in (key, LAST_FOLDER):
            if k:
                folder = self.get_str(k, "")
                if folder and Path(folder).is_dir():
                    return folder
        return str(Path.cwd())

    def remember_folder(self, path, key: str = "") -> None:
        """Remember the folder of ``path`` (a file's or a store's parent) for ``key`` and for every dialog."""
        folder = str(Path(path).expanduser().parent)
        if key:
            self.set(key, folder)
        self.set(LAST_FOLDER, folder)

    def set(self, key: str, value) -> None:
        """Store ``value``."""
        self.qsettings.setValue(key, value)

    def sync(self) -> None:
        """Write pending changes to storage."""
        self.qsettings.sync()
