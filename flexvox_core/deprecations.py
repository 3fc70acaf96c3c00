"""Old names kept for one release: each warns with a ``DeprecationWarning`` that names the new one."""

from __future__ import annotations

import warnings
from typing import Any

__all__ = ["renamed_keyword", "warn_renamed"]


def warn_renamed(old: str, new: str, *, stacklevel: int = 3) -> None:
    """Warn that ``old`` is deprecated, to be removed in the next release, and that ``new`` replaces it."""
    warnings.warn(f"{old} is deprecated and will be removed in the next release: call {new}", DeprecationWarning,
                  stacklevel=stacklevel)


def renamed_keyword(given: dict[str, Any], old: str, new: str, value: Any, where: str) -> Any:
    """``value`` (keyword ``new``), or the value of the deprecated keyword ``old`` popped from ``given`` (warned).

    Raises
    ------
    TypeError
        Both ``old`` and ``new`` given.
    """
    if old not in given:
        return value
    old_value = given.pop(old)
    warn_renamed(f"`{old}` of {where}", f"it `{new}`", stacklevel=4)
    if value is not None:
        raise TypeError(f"{where} got `{new}` and its deprecated name `{old}`: give `{new}` alone")
    return old_value
