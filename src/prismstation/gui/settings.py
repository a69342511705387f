"""Settings kept between sessions (QSettings), with keys as an enum carrying typed defaults.

Tests and screenshots point QSettings at a temporary directory with :func:`use_settings_dir`
(or the ``PRISMSTATION_SETTINGS_DIR`` environment variable) so that the user's own settings are
never read or written; under pytest, a temporary directory is chosen when none was.
"""
from __future__ import annotations

import os
import tempfile
from enum import Enum

from PySide6.QtCore import QByteArray, QCoreApplication, QSettings

ORGANIZATION = "prismstation"
APPLICATION = "prismstation"
MAX_RECENT = 8


class Key(Enum):
    """``(QSettings key, default)``; the default's type is the value's type."""

    GEOMETRY = ("window/geometry", QByteArray())
    STATE = ("window/state", QByteArray())
    SPLITTER = ("window/splitter", QByteArray())
    RECENT_FILES = ("files/recent", [])
    LAST_PROJECT_DIR = ("files/last_project_dir", "")
    LAST_IMPORT_DIR = ("files/last_import_dir", "")
    LAST_EXPORT_DIR = ("files/last_export_dir", "")
    REPORT_OPERATOR = ("report/operator", "")
    AUTOSAVE_SECONDS = ("files/autosave_seconds", 60)
    RESIDUAL_SCALE = ("view/residual_screen_px_per_px", 40.0)
    SHOW_LABELS = ("view/show_labels", True)

    @property
    def name_(self) -> str:
        return self.value[0]

    @property
    def default(self):
        return self.value[1]


_applied_dir: str | None = None


def use_settings_dir(path) -> None:
    """Keep settings as an INI file under ``path`` (tests, screenshots)."""
    global _applied_dir
    _applied_dir = str(path)
    QSettings.setDefaultFormat(QSettings.Format.IniFormat)
    for fmt in (QSettings.Format.IniFormat, QSettings.Format.NativeFormat):
        QSettings.setPath(fmt, QSettings.Scope.UserScope, str(path))


def configure() -> None:
    """Organisation and application names; honours ``PRISMSTATION_SETTINGS_DIR``."""
    QCoreApplication.setOrganizationName(ORGANIZATION)
    QCoreApplication.setApplicationName(APPLICATION)
    d = os.environ.get("PRISMSTATION_SETTINGS_DIR")
    if d:
        use_settings_dir(d)



def _settings() -> QSettings:
    """The settings store; honours ``PRISMSTATION_SETTINGS_DIR`` whenever it changes, and under
    pytest without it uses a temporary directory (never the user's own settings)."""
    d = os.environ.get("PRISMSTATION_SETTINGS_DIR")
    if not d and "PYTEST_CURRENT_TEST" in os.environ:
        d = os.environ["PRISMSTATION_SETTINGS_DIR"] = tempfile.mkdtemp(prefix="prismstation-test-settings-")
    if d and d != _applied_dir:
        use_settings_dir(d)
    return QSettings(QSettings.Format.IniFormat, QSettings.Scope.UserScope, ORGANIZATION, APPLICATION)


def value(key: Key):
    """The stored value of ``key`` converted to its default's type (the default if absent)."""
    d = key.default
    v = _settings().value(key.name_, None)
    if v is None:
        return list(d) if isinstance(d, list) else d
    try:
        if isinstance(d, bool):
            return v if isinstance(v, bool) else str(v).lower() in ("true", "1", "yes")
        if isinstance(d, list):
            return [str(x) for x in v] if isinstance(v, (list, tuple)) else ([str(v)] if v else [])
        if isinstance(d, QByteArray):
            return v if isinstance(v, QByteArray) else QByteArray(v)
        return type(d)(v)
    except (TypeError, ValueError):
        return d


def set_value(key: Key, v) -> None:
    s = _settings()
    s.setValue(key.name_, v)
    s.sync()


def add_recent(path: str) -> list[str]:
    """Put ``path`` first in the recent files (unique, at most MAX_RECENT); returns the list."""
    path = os.path.abspath(path)
    files = [p for p in value(Key.RECENT_FILES) if p != path]
    files = [path] + files[:MAX_RECENT - 1]
    set_value(Key.RECENT_FILES, files)
    return files
