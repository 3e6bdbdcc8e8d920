"""The shared report machinery: the Pareto front the plots label, legible text, escaped pages."""

from __future__ import annotations

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from atlasgen.reports.html import CSS_PX_PER_INCH, LABEL_LINE_PX, MIN_FONT_PT, pareto_front, place_labels, plot_style, render_page


def test_pareto_front_keeps_exactly_the_undominated_points():
    points = [(3.0, 0.5), (1.0, 0.9), (2.0, 0.95), (2.0, 0.4), (4.0, 0.4), (5.0, 0.1)]
    # (2, 0.95) is beaten by (1, 0.9); (3, 0.5) by (2, 0.4); (4, 0.4) ties (2, 0.4) on error at a higher cost.
    assert pareto_front(points) == [1, 3, 5]
    for i in range(len(points)):
        dominated = any(q[0] <= points[i][0] and q[1] <= points[i][1] and q != points[i] for q in points)
        assert (i in pareto_front(points)) == (not dominated)


@pytest.mark.slow
def test_every_plot_text_is_at_least_nine_css_pixels():
    with plot_style() as plt:
        fig, ax = plt.subplots(figsize=(6, 4))
        ax.plot([1, 2], [3, 4], label="line")
        ax.set_title("title")
        ax.set_xlabel("x")
        ax.legend()
        fig.canvas.draw()
        sizes = [t.get_fontsize() for t in fig.findobj(lambda a: hasattr(a, "get_fontsize")) if t.get_text()]
        plt.close(fig)
    assert sizes and min(sizes) >= MIN_FONT_PT
    assert MIN_FONT_PT * CSS_PX_PER_INCH / 72 >= 9


def test_pages_escape_what_they_show():
    page = render_page("library.html.j2", atlas="<b>a</b>", encoding="srgb", layout="array", links=[], plot=None, rows=[])
    assert b"&lt;b&gt;a&lt;/b&gt;" in page and b"<b>a</b>" not in page


@given(st.lists(st.tuples(st.floats(60, 540), st.floats(60, 340), st.text("abcK0123/", min_size=1, max_size=12)),
                min_size=1, max_size=6))  # fmt: skip
@example(points=[(60.0, 60.0, "0"), (60.0, 75.0, "0"), (60.0, 81.25, "0000000")])  # the farthest candidate, rounded
# A crowded corner: the fifth point finds no clear box and goes unlabelled, so labels and points no longer pair up.
@example(points=[(60.0, 60.0, "0"), (60.0, 70.0, "0"), (60.0, 84.0, "0000000"), (60.0, 94.0, "0000000"), (60.0, 60.0, "0")])
@settings(max_examples=60, deadline=None)
@pytest.mark.slow
def test_placed_labels_stay_inside_and_do_not_overlap_where_there_is_room(points):
    """A handful of labels on a 600 x 400 chart: each box inside it, none within the margin of another
    (boxes as place_labels sizes them), each within a few label heights of its point. A point with no
    clear box goes unlabelled, so the labels are the points' subsequence, in order; three always fit."""
    labels = place_labels(points, 600, 400)
    boxes, remaining = [], iter(points)
    for label in labels:
        # The first point not yet matched that this label names: place_labels keeps the points' order.
        x, y, text = next(
            p for p in remaining if (round(p[0], 1), round(p[1], 1), p[2]) == (label["x"], label["y"], label["text"])
        )
        w = len(text) * 7.4 + 6
        box = (label["left"], label["top"], label["left"] + w, label["top"] + LABEL_LINE_PX)
        # "left" and "top" are rounded to 0.1 px.
        assert box[0] >= -0.05 and box[1] >= -0.05 and box[2] <= 600 + 0.05 and box[3] <= 400 + 0.05
        # The farthest candidate is 3 x 24 px above its point (4 label lines + 8 px).
        assert abs(label["top"] - y) <= 4 * LABEL_LINE_PX + 8 + 0.05 + 1e-9
        assert abs(label["left"] - x) <= w + 18 + 0.05 + 1e-9
        boxes.append(box)
    for i, a in enumerate(boxes):  # clear of each other by the 3 px margin, less the rounding
        for b in boxes[i + 1 :]:
            assert not (a[0] < b[2] + 2.9 and b[0] < a[2] + 2.9 and a[1] < b[3] + 2.9 and b[1] < a[3] + 2.9), (a, b)
    if len(points) <= 3:  # always room for three: every one labelled
        assert len(labels) == len(points)


@pytest.mark.slow
@pytest.mark.parametrize(
    ("size", "errors"),
    [((4.2, 3.0), (1e-6, 1e2)), ((7.5, 5.0), (1e-6, 1e2)), ((3.8, 2.8), (0.036, 0.0475))],
)
def test_placed_axes_keep_every_text_inside_the_figure_and_off_the_axes(size, errors):
    # The report plots' worst cases: log axes over many decades (10^-6 ... 10^2), two-line title
    # and y label, a two-line x label (the Pareto charts'); and errors within one decade, where the
    # minor ticks carry the only labels (4 x 10^-2: a library cell's chart once cut them and its y label off).
    from atlasgen.reports.html import place_axes

    with plot_style() as plt:
        fig, ax = plt.subplots(figsize=size)
        ax.loglog([1e-1, 1e3], errors, "o")
        ax.set_title("first line of a title\nsecond line", fontsize="medium")
        ax.set_xlabel("lighting pass cost (ns)\non a device")
        ax.set_ylabel("rel. RMS\n(exact: drawn at 1e-06)")
        place_axes(fig)
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        figure_box, axes_box = fig.bbox, ax.get_window_extent(renderer)
        texts = [ax.title, ax.xaxis.label, ax.yaxis.label]
        for axis, coordinate in ((ax.xaxis, 0), (ax.yaxis, 1)):  # the tick labels drawn: those in view
            low, high = sorted(axis.get_view_interval())
            for minor in (False, True):
                texts += [t for t in axis.get_ticklabels(minor=minor)
                          if t.get_text() and low <= t.get_position()[coordinate] <= high]  # fmt: skip
        boxes = [(t.get_text(), t.get_window_extent(renderer)) for t in texts]
        boxes.append(("everything drawn", ax.get_tightbbox(renderer)))
        plt.close(fig)
    for text, box in boxes:
        inside = box.x0 >= figure_box.x0 and box.y0 >= figure_box.y0 and box.x1 <= figure_box.x1 and box.y1 <= figure_box.y1
        assert inside, f"{text!r} at {box.extents} leaves the figure {figure_box.extents}"
        assert text == "everything drawn" or not box.overlaps(axes_box), (
            f"{text!r} at {box.extents} overlaps the axes {axes_box.extents}"
        )


@pytest.mark.slow
@pytest.mark.parametrize("size", [(3.8, 2.8), (7.0, 4.5)])  # the library page's two chart sizes
def test_a_point_label_is_anchored_where_the_png_draws_its_point(size):
    """figure_chart's label anchors against the markers found in its own PNG: a red marker in each
    corner of a log-log chart, each label's (x, y) at its marker's centre, in CSS px."""
    import io

    import numpy as np
    from PIL import Image

    from atlasgen.reports.html import PLOT_DPI, figure_chart, label_points

    points = [(1.0, 1e-4), (100.0, 1e-1)]
    with plot_style() as plt:
        fig, ax = plt.subplots(figsize=size)
        ax.scatter(*zip(*points), color="red", s=30)
        ax.set(xscale="log", yscale="log", xlabel="lighting cost", ylabel="error", title="title")
        label_points(ax, points, ["low", "high"])
        chart = figure_chart(fig)
    image = np.asarray(Image.open(io.BytesIO(chart.png)).convert("RGB")).astype(int)
    red = (image[..., 0] > 200) & (image[..., 1] < 80) & (image[..., 2] < 80)
    ys, xs = np.nonzero(red)
    per_css_px = PLOT_DPI / CSS_PX_PER_INCH
    for label, left in zip(chart.labels, (True, False)):
        side = xs < image.shape[1] / 2 if left else xs >= image.shape[1] / 2
        centre = xs[side].mean() / per_css_px, ys[side].mean() / per_css_px
        assert label["x"] == pytest.approx(centre[0], abs=1.5) and label["y"] == pytest.approx(centre[1], abs=1.5), (
            label,
            centre,
        )


@pytest.mark.slow
@pytest.mark.parametrize("count", [3, 16, 40])
def test_a_legend_beside_the_axes_names_every_series_inside_the_figure_and_off_the_axes(count):
    """The library chart's legend (legend_beside): one entry per series, each series its own colour and marker,
    the legend wholly inside the widened figure and clear of the axes, whatever the count (it once had none
    beyond 12 series, and the colour cycle repeats after 10)."""
    from atlasgen.reports.html import legend_beside, place_axes, series_style

    names = [f"separable-rough-metal-{i}" if i % 3 == 0 else f"m{i}" for i in range(count)]
    with plot_style() as plt:
        fig, ax = plt.subplots(figsize=(7.0, 4.5))
        for i, name in enumerate(names):
            ax.scatter([1.0 + i], [10.0 ** -(i % 6)], label=name, **series_style(i))
        ax.set(xscale="log", yscale="log", xlabel="lighting cost", ylabel="error", title="title\non a device")
        across, down = legend_beside(ax)
        fig.set_size_inches(7.0 + across, max(4.5, down))
        place_axes(fig)
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        legend = ax.get_legend()
        box, axes_box, figure_box = legend.get_window_extent(renderer), ax.get_window_extent(renderer), fig.bbox
        shown = [t.get_text() for t in legend.get_texts()]
        plt.close(fig)
    assert shown == names
    assert len({tuple(series_style(i).values()) for i in range(count)}) == count
    assert box.x0 >= figure_box.x0 and box.y0 >= figure_box.y0 and box.x1 <= figure_box.x1 and box.y1 <= figure_box.y1, (
        box.extents, figure_box.extents)  # fmt: skip
    assert not box.overlaps(axes_box), (box.extents, axes_box.extents)


def test_labels_with_no_room_are_left_out_in_order_never_written_over_another():
    """Eight long labels on points a few px apart in a 280 x 180 chart (a crowded Pareto front): the first is
    always placed, those that would overlap a placed one are left out, and no two placed ones intersect."""
    points = [(120.0 + 4 * i, 90.0 + 3 * i, f"separable:{i + 1} (nmf)") for i in range(8)]
    labels = place_labels(points, 280, 180)
    assert labels[0]["text"] == points[0][2] and 1 < len(labels) < len(points)
    assert [label["text"] for label in labels] == [t for _, _, t in points if t in {label["text"] for label in labels}]
    boxes = [(label["left"], label["top"], label["left"] + len(label["text"]) * 7.4 + 6, label["top"] + LABEL_LINE_PX)
             for label in labels]  # fmt: skip
    for i, a in enumerate(boxes):
        assert a[0] >= 0 and a[1] >= 0 and a[2] <= 280 and a[3] <= 180
        for b in boxes[i + 1 :]:
            assert not (a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]), (a, b)


def test_the_module_s_doctests_pass():
    import doctest

    from atlasgen.reports import html

    result = doctest.testmod(html)
    assert result.attempted >= 2 and result.failed == 0
