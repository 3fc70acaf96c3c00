"""Reading a small JSON file (a code, a calibration) with errors that say which file and what is wrong."""

from __future__ import annotations

import json
from pathlib import Path


def read_json(path, error: type[Exception] = ValueError):
    """The parsed content of the JSON file ``path``.

    Raises
    ------
    error
        ``"{path}: no such file"``, ``"{path}: cannot read: ..."`` or ``"{path}: not valid JSON (... at line N)"``
        (``error`` is the caller's exception class, e.g. a ``ValueError`` subclass).
    """
    path = Path(path)
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise error(f"{path}: cannot read: {exc}") from exc
    except json.JSONDecodeError as exc:
        raise error(f"{path}: not valid JSON ({exc.msg} at line {exc.lineno})") from None
