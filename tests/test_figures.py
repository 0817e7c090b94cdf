"""The figure helpers keep every figure readable where the pages show it (gpfverify.report.figures):
no figure wider than MAX_WIDTH_IN, no text below MIN_FONT_PT, no legend over data — a legend
placed over a curve, a band or markers is found and moved right of its axes — and what was
measured is recorded in the PNG. The pages' browser test (tests/test_page_layout.py) reads that
record for every figure a page shows."""

from __future__ import annotations

import numpy as np
import pytest

from gpfverify.report import figures
from gpfverify.report.figures import (DPI, MAX_WIDTH_IN, MIN_FONT_PT, MIN_TEXT_PX, PAGE_COLUMN_PX,
                                      legend_overlaps, measured, new_figure, save)


def test_the_smallest_font_at_the_widest_figure_is_shown_at_least_min_text_px():
    narrowest_scale = PAGE_COLUMN_PX / (MAX_WIDTH_IN * DPI)
    assert narrowest_scale < 1  # the widest figure is scaled down on the page
    assert MIN_FONT_PT * DPI / 72 * narrowest_scale >= MIN_TEXT_PX
    assert (MIN_FONT_PT - 1) * DPI / 72 * narrowest_scale < MIN_TEXT_PX  # and no larger than needed


def test_a_wide_grid_of_panels_is_scaled_down_to_the_widest_figure():
    fig, axes = new_figure(3, 2, width=4.4, height=3.0)
    width, height = fig.get_size_inches()
    assert axes.shape == (2, 3) and width == pytest.approx(MAX_WIDTH_IN)
    assert height / width == pytest.approx((2 * 3.0) / (3 * 4.4))  # the same shape
    fig, _ = new_figure(1, 1, width=6.4, height=4.0)
    assert tuple(fig.get_size_inches()) == (6.4, 4.0)
    figures.plt.close("all")


def _curve_under_the_legend(tmp_path, kind: str):
    fig, axes = new_figure()
    ax = axes[0, 0]
    x = np.linspace(0, 1, 50)
    if kind == "line":
        ax.plot(x, np.ones_like(x), label="flat at the top")
        ax.plot(x, x - 5, label="far below")
    elif kind == "band":
        ax.fill_between(x, 0.9, 1.1, label="band at the top")
        ax.plot(x, x - 5, label="far below")
    else:
        ax.scatter([0.05, 0.5], [1.0, -5.0], label="a point in the corner")
    ax.legend(loc="upper left")
    return fig, ax


@pytest.mark.parametrize("kind", ["line", "band", "markers"])
def test_a_legend_over_data_is_found_and_moved_off_it(tmp_path, kind):
    fig, ax = _curve_under_the_legend(tmp_path, kind)
    renderer = fig.canvas.get_renderer()
    fig.canvas.draw()
    assert legend_overlaps(fig), "a legend over the data is not found"
    path = save(fig, tmp_path / "f.png")
    record = measured(path.read_bytes())
    assert record["legends_over_data"] == 0
    assert ax.get_legend().get_window_extent(renderer).x0 >= ax.get_window_extent(renderer).x1  # right of the axes


def test_a_legend_clear_of_the_data_stays_where_it_is(tmp_path):
    fig, axes = new_figure()
    ax = axes[0, 0]
    x = np.linspace(0, 1, 50)
    ax.plot(x, -np.ones_like(x), label="low")
    ax.set_ylim(-2, 2)
    ax.legend(loc="upper right")
    renderer = fig.canvas.get_renderer()
    fig.canvas.draw()
    assert legend_overlaps(fig) == []
    save(fig, tmp_path / "f.png")
    box, inside = ax.get_legend().get_window_extent(renderer), ax.get_window_extent(renderer)
    assert inside.x0 < box.x0 and box.x1 <= inside.x1 + 1  # still inside its axes


def test_small_text_is_raised_to_the_floor_and_the_record_says_so(tmp_path):
    fig, axes = new_figure()
    ax = axes[0, 0]
    ax.plot([0, 1], [0, 1], label="a")
    ax.set_title("tiny", fontsize=4)
    ax.set_yticks([0, 1], ["zero", "one"], fontsize=5)
    ax.legend(fontsize=3, loc="lower right")
    record = measured(save(fig, tmp_path / "f.png").read_bytes())
    assert record["min_font_px"] == pytest.approx(MIN_FONT_PT * DPI / 72, abs=0.01)


def test_a_png_not_written_by_save_has_no_record(tmp_path):
    fig, _ = new_figure()
    fig.savefig(tmp_path / "plain.png")
    figures.plt.close(fig)
    assert measured((tmp_path / "plain.png").read_bytes()) == {}


def test_the_same_figure_gives_the_same_bytes(tmp_path):
    paths = []
    for name in ("a.png", "b.png"):
        fig, _ = _curve_under_the_legend(tmp_path, "band")
        paths.append(save(fig, tmp_path / name))
    assert paths[0].read_bytes() == paths[1].read_bytes()


def test_a_background_band_across_the_axes_is_not_data(tmp_path):
    """A χ² band (axhspan) or a shaded time span under the legend does not move it; the curve does."""
    fig, axes = new_figure()
    ax = axes[0, 0]
    ax.axhspan(-1, 1, alpha=0.2)
    ax.fill_between([0.0, 0.3], 0, 1, transform=ax.get_xaxis_transform(), color="0.9")
    ax.plot([0, 1], [-0.5, -0.5], label="inside the band, low")
    ax.set_ylim(-1, 1)
    ax.legend(loc="upper left")
    fig.canvas.draw()
    assert legend_overlaps(fig) == []
    ax.plot([0, 1], [0.9, 0.9], label="along the top")
    ax.legend(loc="upper left")
    fig.canvas.draw()
    assert legend_overlaps(fig)
    figures.plt.close(fig)
