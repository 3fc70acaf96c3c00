"""Short reprs for flexvox's objects: an array as its shape and dtype (never its values), and a table for notebooks.

Every public object prints as one line ``<Name key facts>`` (:func:`short_repr`), and the ones with more to say
also as an HTML table in a notebook (:func:`html_table`, an object's ``_repr_html_``). Arrays appear as
``64×32×32 float32`` (:func:`describe_array`): printing a result never prints its samples.
"""

from __future__ import annotations

import html
from collections.abc import Iterable
from typing import Any

__all__ = ["describe_array", "html_table", "short_repr"]


def describe_array(array: Any) -> str:
    """An array's shape and dtype, ``"64×32×32 float32"``; ``"none"`` for None; else the object's type name.

    Anything with ``shape`` and ``dtype`` (numpy, zarr, dask, a GPU array) is described without reading its values.

    Examples
    --------
    >>> import numpy as np
    >>> describe_array(np.zeros((4, 3, 2), np.float32))
    '4×3×2 float32'
    >>> describe_array(None)
    'none'
    """
    if array is None:
        return "none"
    shape, dtype = getattr(array, "shape", None), getattr(array, "dtype", None)
    if shape is None or dtype is None:
        return type(array).__name__
    return f"{'×'.join(str(int(v)) for v in shape) or 'scalar'} {dtype}"


def short_repr(name: str, facts: Iterable[str]) -> str:
    """``<name fact, fact, ...>``: an object's one-line repr.

    Examples
    --------
    >>> short_repr("Thing", ["4 frames", "K = 4"])
    '<Thing 4 frames, K = 4>'
    """
    body = ", ".join(f for f in facts if f)
    return f"<{name} {body}>" if body else f"<{name}>"


def html_table(caption: str, rows: Iterable[tuple[str, object]]) -> str:
    """A two-column HTML table (``<th>`` field, ``<td>`` value), every text escaped: an object's ``_repr_html_``.

    Examples
    --------
    >>> html_table("Thing", [("frames", 4)])
    "<table><caption>Thing</caption><tr><th style='text-align:left'>frames</th><td>4</td></tr></table>"
    """
    body = "".join(f"<tr><th style='text-align:left'>{html.escape(str(k))}</th><td>{html.escape(str(v))}</td></tr>"
                   for k, v in rows)
    return f"<table><caption>{html.escape(caption)}</caption>{body}</table>"
