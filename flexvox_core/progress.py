"""The one progress rule of flexvox's long calls (``reconstruct_video``, ``run``, ``reconstruct_batch``,
``calibrate_rig``).

``progress`` is one of:

- ``True``: a ``tqdm.auto`` bar with its total (a widget in Jupyter, which needs the ``ipywidgets`` package;
  without it tqdm warns and draws text; text in a terminal);
- ``False`` or ``None``: nothing;
- a callable ``progress(done, total)``, called as the work advances (an exception it raises stops the call).

Anything else is a ``TypeError``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

__all__ = ["Progress", "check_progress", "progress_callback"]

Progress = Callable[[int, int], None]
"""A progress callback: ``progress(done, total)``."""


def check_progress(progress: object) -> None:
    """``TypeError`` unless ``progress`` is True, False, None or a callable."""
    if not (progress is None or isinstance(progress, bool) or callable(progress)):
        raise TypeError(f"`progress` must be True (a bar), False or None (nothing), or a callable "
                        f"progress(done, total); got {type(progress).__name__} {progress!r}")


@contextmanager
def progress_callback(progress: bool | Progress | None, *, desc: str, unit: str,
                      total: int | None = None) -> Iterator[Progress | None]:
    """The callback ``progress(done, total)`` that ``progress`` stands for (see the module), or None for nothing.

    Parameters
    ----------
    progress : bool, None or callable(done, total)
    desc : str
        The bar's description.
    unit : str
        What ``done`` counts ("frame", "chunk", "step").
    total : int, optional
        The bar's total when known at the start (each call's ``total`` sets it too).
    """
    check_progress(progress)
    if progress is None or progress is False:
        yield None
        return
    if progress is not True:
        yield progress
        return
    from tqdm.auto import tqdm  # type: ignore[import-untyped]

    with tqdm(total=total, desc=desc, unit=unit, leave=False) as bar:
        def update(done: int, total: int) -> None:
            if bar.total != total:
                bar.total = total
            bar.update(done - bar.n)

        yield update
