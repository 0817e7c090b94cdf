"""HTML views of gpfverify's records in a notebook, through a registry the display layer fills.

A record that shows itself in Jupyter (an audit, a fusion run, a claim record) inherits
:class:`HtmlView`: its ``_repr_html_`` asks :func:`html` for the renderer registered for its type.
The display layer (:mod:`gpfverify.notebook`) registers one renderer per record type
(:func:`register`) when it is imported, so the records never import their renderers and the data
sits below its display (docs/architecture.md). The first view asked for imports the display
layer by its module name, :data:`DISPLAY_MODULE` — the one default a record knows, as pandas knows
the name of its plotting backend.
"""

from __future__ import annotations

import importlib
import sys
from collections.abc import Callable
from typing import Any

#: the module that registers the renderers, imported on the first view asked for
DISPLAY_MODULE = "gpfverify.notebook"

_RENDERERS: dict[type, Callable[[Any], str]] = {}


def register(kind: type, render: Callable[[Any], str]) -> None:
    """Show records of type ``kind`` (and its subclasses) as ``render(record)`` (an HTML fragment)."""
    _RENDERERS[kind] = render


def html(record: object) -> str | None:
    """The HTML of ``record`` by the renderer registered for its type or nearest base; None when
    none is (a notebook then shows its ``repr``)."""
    if DISPLAY_MODULE not in sys.modules:
        importlib.import_module(DISPLAY_MODULE)
    for kind in type(record).__mro__:
        render = _RENDERERS.get(kind)
        if render is not None:
            return render(record)
    return None


class HtmlView:
    """Mixin of the records a notebook shows: ``_repr_html_`` through the registry (:func:`html`)."""

    __slots__ = ()

    def _repr_html_(self) -> str | None:
        return html(self)
