"""Matplotlib (Agg) helpers shared by report sections: every figure of a page is made by
:func:`new_figure` and written by :func:`save`, which keep it readable where the pages show it.

A page shows a figure at most as wide as its main column: :data:`PAGE_COLUMN_PX` at a 1024 px
window (the report's layout, docs/report.md). A figure is at most :data:`MAX_WIDTH_IN` wide and
saved at :data:`DPI`, so it is shown at least at ``PAGE_COLUMN_PX / (MAX_WIDTH_IN · DPI)`` of its
size, and its smallest text, :data:`MIN_FONT_PT`, at least at :data:`MIN_TEXT_PX` (a font size in
CSS pixels, as a browser's ``font-size``). :func:`save` also keeps every legend off the data: a
legend that covers a line, a band, a marker or a bar of any axes of the figure is moved to the
right of its axes (a background band across the whole axes, such as a χ² band, is not data).
What it measured is written into the PNG (:data:`TEXT_KEY`, :func:`measured`), so that a page's
test reads each figure's smallest text and compares it, times the scale the browser shows the
figure at, with :data:`MIN_TEXT_PX`."""

from __future__ import annotations

import json
import math
from pathlib import Path

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.collections import Collection, LineCollection, PathCollection  # noqa: E402
from matplotlib.legend import Legend  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Patch  # noqa: E402
from matplotlib.text import Text  # noqa: E402
from matplotlib.transforms import Bbox  # noqa: E402

#: the main column of a page at a 1024 px window (px): 1024 less the contents column (11 rem), the
#: main column's padding (2 × 1 rem) and a scroll bar (15 px), the report's layout at that width
PAGE_COLUMN_PX = 1024 - 11 * 16 - 2 * 16 - 15
#: the smallest text a figure may show there (CSS px)
MIN_TEXT_PX = 9.0
#: pixels per inch of the PNGs
DPI = 110
#: the widest figure (in); a wider one is scaled down as a whole
MAX_WIDTH_IN = 9.0
#: the smallest font of a figure (pt): MIN_TEXT_PX at the narrowest scale a page shows a figure at,
#: rounded up to a whole point
MIN_FONT_PT = float(math.ceil(MIN_TEXT_PX * 72 * MAX_WIDTH_IN / PAGE_COLUMN_PX))
#: the PNG text chunk that records what :func:`save` measured
TEXT_KEY = "gpfverify-text"


def new_figure(ncols: int = 1, nrows: int = 1, width: float = 6.4, height: float = 4.0):
    """A figure of ``nrows × ncols`` panels of ``width × height`` inches each, scaled down as a whole
    to :data:`MAX_WIDTH_IN` when wider; ``axes`` always 2-D."""
    scale = min(1.0, MAX_WIDTH_IN / (width * ncols))
    fig, axes = plt.subplots(nrows, ncols, figsize=(width * ncols * scale, height * nrows * scale), squeeze=False)
    return fig, axes


def _texts(fig) -> list[Text]:
    """Every text the figure shows (titles, labels, tick labels, legends, annotations)."""
    return [t for t in fig.findobj(Text) if t.get_visible() and t.get_text().strip()]


def _data_hits(artist, box: Bbox) -> bool:
    """Whether a data artist draws inside ``box`` (display coordinates)."""
    if isinstance(artist, Line2D):
        xy = artist.get_transform().transform(np.column_stack(artist.get_data()).astype(float))
        xy = xy[np.isfinite(xy).all(axis=1)]
        if artist.get_marker() not in (None, "None", "", " ") and box.count_contains(xy):
            return True
        if artist.get_linestyle() in ("None", "", " ") or len(xy) < 2:
            return False
        from matplotlib.path import Path as MplPath

        return MplPath(xy).intersects_bbox(box, filled=False)
    if isinstance(artist, PathCollection):  # scatter markers: their centres
        centres = artist.get_offset_transform().transform(np.asarray(artist.get_offsets(), dtype=float))
        return bool(box.count_contains(centres[np.isfinite(centres).all(axis=1)]))
    if isinstance(artist, Collection):  # bands (filled) and segments
        filled = not isinstance(artist, LineCollection)
        transform = artist.get_transform()
        return any(transform.transform_path(p).intersects_bbox(box, filled=filled) for p in artist.get_paths())
    return artist.get_window_extent().overlaps(box)


def _span(artist, ax) -> bool:
    """A background band across the whole axes (``axhspan``, ``axvspan``, a shading drawn in the axes'
    x or y axis transform, such as a χ² band or the time of a manoeuvre): not data a legend must avoid."""
    placed = artist.get_data_transform() if isinstance(artist, Patch) else artist.get_transform()
    return any(placed is t for t in (ax.get_xaxis_transform(), ax.get_yaxis_transform(), ax.transAxes))


def legend_overlaps(fig) -> list[tuple[Legend, object]]:
    """(legend, data artist) for every legend of the figure that covers data of any of its axes:
    a line or its markers, a band, a scatter point, a bar or an image, inside the axes' box."""
    renderer = fig.canvas.get_renderer()
    legends = [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None] + list(fig.legends)
    found = []
    for legend in legends:
        box = legend.get_window_extent(renderer)
        for ax in fig.axes:
            inside = Bbox.intersection(box, ax.get_window_extent(renderer))
            if inside is None or inside.width <= 0 or inside.height <= 0:
                continue
            artists = [*ax.lines, *ax.collections, *[p for p in ax.patches if isinstance(p, Patch)], *ax.images]
            found += [(legend, a) for a in artists if a.get_visible() and not _span(a, ax) and _data_hits(a, inside)]
    return found


def _move_out(legend) -> None:
    """Put an axes' legend to the right of it, top-aligned."""
    legend.set_loc("upper left")
    legend.set_bbox_to_anchor((1.02, 1.0), transform=legend.axes.transAxes)


def save(fig, path: Path, dpi: int = DPI) -> Path:
    """Write ``fig`` as a PNG at ``dpi``: every text at least :data:`MIN_FONT_PT`, laid out
    tight, every legend off the data (:func:`legend_overlaps`; one that covers data is moved right
    of its axes), and what was measured recorded in the PNG (:data:`TEXT_KEY`: the smallest font in
    pixels of the PNG and the legends still over data)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    _floor_fonts(fig)
    fig.tight_layout()  # draws: the tick labels exist from here on
    if _floor_fonts(fig):
        fig.tight_layout()
    moved: set[int] = set()
    while True:  # a new layout moves the axes, and a legend placed "best" with them: look again
        over = {id(legend): legend for legend, _ in legend_overlaps(fig)
                if legend.axes is not None and id(legend) not in moved}
        if not over:
            break
        for legend in over.values():
            _move_out(legend)
        moved |= set(over)
        fig.tight_layout()
    record = {"min_font_px": round(min((_size(t) for t in _texts(fig)), default=MIN_FONT_PT) * dpi / 72, 2),
              "legends_over_data": len({id(legend) for legend, _ in legend_overlaps(fig)})}
    fig.savefig(path, dpi=dpi, metadata={TEXT_KEY: json.dumps(record, sort_keys=True)})
    plt.close(fig)
    return path


def _size(text: Text) -> float:
    """A text's font size in points."""
    return float(text.get_fontsize())


def _floor_fonts(fig) -> bool:
    """Raise every text smaller than :data:`MIN_FONT_PT` to it; whether any was."""
    small = [t for t in _texts(fig) if _size(t) < MIN_FONT_PT]
    for text in small:
        text.set_fontsize(MIN_FONT_PT)
    return bool(small)


def measured(png: bytes) -> dict:
    """What :func:`save` recorded in a PNG ({} for a PNG it did not write)."""
    import io

    from PIL import Image

    with Image.open(io.BytesIO(png)) as image:
        text = getattr(image, "text", {}).get(TEXT_KEY)
    return {} if text is None else json.loads(text)
