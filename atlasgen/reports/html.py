"""Shared machinery of the HTML reports: jinja2 templates, one stylesheet, legible plots.

Every page (library, validation, separable) extends ``templates/base.html.j2``, which
inlines ``templates/report.css``: a page is one file that needs nothing beside it but
its images. jinja2 and matplotlib are imported lazily, inside the functions.

Plots are drawn for the size the page shows them at: a figure of ``w`` x ``h`` inches
is shown at ``w * CSS_PX_PER_INCH`` CSS pixels wide, and saved at ``PLOT_DPI`` (twice
that, so that it stays sharp on high-density screens). Text of ``s`` points then
measures ``s * CSS_PX_PER_INCH / 72`` CSS pixels: the smallest font used (``MIN_FONT_PT``)
is at least 12 px.

Point labels are not drawn into the PNG: :func:`label_points` records them, and
:func:`figure_chart` places them, as HTML text over the image (``templates/chart.html.j2``),
where no two overlap (:func:`place_labels`): the browser test measures the boxes the page
really draws.
"""

from __future__ import annotations

import contextlib
import io
import re
from dataclasses import dataclass

__all__ = [
    "CSS_PX_PER_INCH",
    "PLOT_DPI",
    "MIN_FONT_PT",
    "render_page",
    "plot_style",
    "figure_png",
    "place_axes",
    "plot_width",
    "pareto_front",
    "label_points",
    "legend_beside",
    "series_style",
    "place_labels",
    "figure_chart",
    "Chart",
    "LABEL_FONT_PX",
]

#: CSS pixels per figure inch on every report page.
CSS_PX_PER_INCH = 100
#: Pixels per inch of the saved PNGs: two image pixels per CSS pixel.
PLOT_DPI = 2 * CSS_PX_PER_INCH
#: The smallest font size of any plot, in points (12.5 CSS px at CSS_PX_PER_INCH).
MIN_FONT_PT = 9

_RC = {
    "font.size": 11,
    "axes.titlesize": 12,
    "axes.labelsize": 11,
    "xtick.labelsize": 10,
    "ytick.labelsize": 10,
    "legend.fontsize": 9,
    # No layout engine: constrained layout measured each text's extent in a draw of its own,
    # 40% of a plot's CPU (0.70 s against 0.41 s for a log-log chart); place_axes sizes the
    # margins from the text instead.
    "figure.constrained_layout.use": False,
    "savefig.dpi": PLOT_DPI,
}
#: Room around the axes' text, in points: between the figure's edge and the outermost text, and
#: between one line of text and the next.
_EDGE_PT = 4.0
_LINE_SPACING = 1.25
#: Average advance of a character, in ems of its font (DejaVu Sans digits and letters: 0.55-0.64).
_CHAR_EM = 0.64


def render_page(template: str, **context) -> bytes:
    """UTF-8 bytes of ``templates/<template>`` rendered with ``context`` (autoescaped)."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.PackageLoader("atlasgen.reports", "templates"),
        autoescape=True,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    return env.get_template(template).render(**context).encode()


@contextlib.contextmanager
def plot_style():
    """Context in which plots get the report's font sizes; yields ``matplotlib.pyplot`` (Agg
    backend). :func:`figure_png` places the axes (:func:`place_axes`). Text reads its size when
    it is made, so draw the whole figure inside the context."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with matplotlib.rc_context(_RC):
        yield plt


def _text_lines(text) -> int:
    return text.get_text().count("\n") + 1 if text.get_visible() and text.get_text() else 0


def _tick_label_chars(axis) -> int:
    """Characters of the widest tick label in view, mathtext markup left out (``10^{-3}`` counts 5,
    ``4\\times10^{-2}`` 6): the formatters' strings, without drawing a tick. Minor ticks count too: a
    log axis spanning less than a decade labels them (``4x10^-2``) and may show no major label at all."""
    low, high = sorted(axis.get_view_interval())
    labels = []
    for locs, formatter in ((axis.get_majorticklocs(), axis.get_major_formatter()),
                            (axis.get_minorticklocs(), axis.get_minor_formatter())):  # fmt: skip
        shown = [x for x in locs if low <= x <= high]
        labels += formatter.format_ticks(shown) if shown else []
    plain = [re.sub(r"\\mathdefault|[{}$^\\]", "", label.replace("\\times", "x")) for label in labels]
    return max((len(t) for t in plain), default=0)


def place_axes(fig) -> None:
    """Set each axes of ``fig`` (one per report plot) inside margins that hold its text: the
    title above, the x tick labels and label below, the y tick labels and label (any number
    of lines) on the left. A margin is the sum of its text's line heights
    (``_LINE_SPACING`` x the font size), the ticks and their pads and ``_EDGE_PT``, and the tick
    labels' width, ``_CHAR_EM`` ems a character: what constrained layout would measure, without a
    draw to measure it (see ``_RC``). The right margin holds half of the last x tick label."""
    from matplotlib import rcParams
    from matplotlib.font_manager import FontProperties

    width, height = fig.get_size_inches()
    # The tick labels' size is the rc's (asking the ticks would make them, half a draw's work).
    x_ticks, y_ticks = (FontProperties(size=rcParams[f"{k}tick.labelsize"]).get_size_in_points() for k in "xy")
    tick_pt = {k: float(rcParams[f"{k}tick.major.size"]) + float(rcParams[f"{k}tick.major.pad"]) for k in "xy"}
    for ax in fig.axes:
        # Superscripts (10^{-3}) rise above a tick label's line: count the line as 1.4 high.
        below = (
            tick_pt["x"]
            + 1.4 * x_ticks * _LINE_SPACING
            + _text_lines(ax.xaxis.label) * ax.xaxis.label.get_fontsize() * _LINE_SPACING
        )
        left = (tick_pt["y"] + _tick_label_chars(ax.yaxis) * _CHAR_EM * y_ticks + float(rcParams["axes.labelpad"])
                + _text_lines(ax.yaxis.label) * ax.yaxis.label.get_fontsize() * _LINE_SPACING)  # fmt: skip
        above = float(rcParams["axes.titlepad"]) + _text_lines(ax.title) * ax.title.get_fontsize() * _LINE_SPACING
        right = max(0.5 * _tick_label_chars(ax.xaxis) * _CHAR_EM * x_ticks, ax.__dict__.get("_legend_beside_pt", 0.0))
        pt = 1.0 / 72.0
        ax.set_position([
            (left + _EDGE_PT) * pt / width,
            (below + _EDGE_PT) * pt / height,
            1.0 - (left + right + 2 * _EDGE_PT) * pt / width,
            1.0 - (below + above + 2 * _EDGE_PT) * pt / height,
        ])  # fmt: skip


#: Markers of a legend's series after the colour cycle's ten colours: with each colour, 40 series look different.
_SERIES_MARKERS = ("o", "s", "^", "D")


def series_style(i: int) -> dict:
    """Colour and marker of the ``i``-th series of a scatter plot: the colour cycle's ten colours
    with one marker, then again with the next, so that no two of 40 series look alike.

    >>> series_style(0), series_style(13)
    ({'color': 'C0', 'marker': 'o'}, {'color': 'C3', 'marker': 's'})
    """
    return {"color": f"C{i % 10}", "marker": _SERIES_MARKERS[(i // 10) % len(_SERIES_MARKERS)]}


def legend_beside(ax) -> tuple[float, float]:
    """Draw ``ax``'s legend in one column to the right of the axes and reserve its width for
    :func:`place_axes`; returns ``(width, height)`` in inches: the width to widen the figure by and the
    least figure height that holds the legend (a web page scrolls down, not sideways).

    Both are estimated as place_axes estimates text: the handle, its pad and the longest label
    (``_CHAR_EM`` ems a character) across; ``_LINE_SPACING + labelspacing`` ems a row down; the frame's pads around.
    """
    from matplotlib import rcParams
    from matplotlib.font_manager import FontProperties

    handles, labels = ax.get_legend_handles_labels()
    if not labels:
        return 0.0, 0.0
    em = FontProperties(size=rcParams["legend.fontsize"]).get_size_in_points()
    pad, spacing = float(rcParams["legend.borderpad"]), float(rcParams["legend.labelspacing"])
    # Half an em from the axes' top right corner (borderaxespad): the legend moves with the axes.
    ax.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.0, 1.0), borderaxespad=0.5)
    across = (0.5 + 2 * pad + float(rcParams["legend.handlelength"]) + float(rcParams["legend.handletextpad"])
              + max(len(t) for t in labels) * _CHAR_EM + 0.5) * em  # fmt: skip
    down = (0.5 + 2 * pad + len(labels) * (_LINE_SPACING + spacing) - spacing) * em
    ax.__dict__["_legend_beside_pt"] = across
    title = float(rcParams["axes.titlepad"]) + _text_lines(ax.title) * ax.title.get_fontsize() * _LINE_SPACING
    return across / 72.0, (down + title + 2 * _EDGE_PT) / 72.0


def figure_png(fig) -> bytes:
    """PNG bytes of ``fig`` at :data:`PLOT_DPI`, its axes placed by :func:`place_axes`, closed
    afterwards; no ``Software`` metadata, so the bytes depend only on what is drawn."""
    import matplotlib.pyplot as plt

    place_axes(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=PLOT_DPI, metadata={"Software": None})
    plt.close(fig)
    return buffer.getvalue()


def plot_width(fig_width_in: float) -> int:
    """Displayed width in CSS pixels of a plot ``fig_width_in`` inches wide."""
    return round(fig_width_in * CSS_PX_PER_INCH)


def pareto_front(points) -> list[int]:
    """Indices of the points ``(cost, error)`` no other point beats on both (lower is better
    on both), in order of increasing cost: the points a plot labels; a table lists the rest.
    Ties keep the first point."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1], i))
    front, best = [], float("inf")
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


#: Point labels' font size and line height in CSS px (report.css's ``.point-label``), and the width
#: :func:`place_labels` allows per character: wider than any system-ui glyph but "W" and "M".
LABEL_FONT_PX = 12
LABEL_LINE_PX = 16
_LABEL_CHAR_PX = 7.4
_LABEL_PAD_PX = 6
#: Offsets (dx, dy) in CSS px from a point to its label's top-left corner, tried in this order, then the
#: same twice and three times as far; dx < 0 means "to the left, by the label's width and dx".
_LABEL_OFFSETS = ((6, -20), (6, 4), (-6, -20), (-6, 4), (-0.5, -24), (-0.5, 8))


def label_points(ax, xy, labels) -> None:
    """Record labels for points ``xy`` (data coordinates) of ``ax``; :func:`figure_chart` places them
    as HTML text over the image, where none overlaps another."""
    ax.__dict__.setdefault("_point_labels", []).extend((float(x), float(y), str(t)) for (x, y), t in zip(xy, labels))


def _label_box(text: str, x: float, y: float, offset) -> tuple:
    w = len(text) * _LABEL_CHAR_PX + _LABEL_PAD_PX
    dx, dy = offset
    left = x - w + dx if dx < 0 and dx != -0.5 else (x - w / 2 if dx == -0.5 else x + dx)
    top = y + dy
    return left, top, left + w, top + LABEL_LINE_PX


def place_labels(points, width: float, height: float, margin: float = 3.0) -> list[dict]:
    """Greedy label placement: each ``(x, y, text)`` point (CSS px from the image's top-left), in the
    order given, gets the first of the candidate boxes around it (:data:`_LABEL_OFFSETS`, then farther)
    that stays inside ``width`` x ``height`` and keeps ``margin`` px from every label placed before it;
    where none does, the point goes unlabelled (labels written over one another read as neither, and
    every chart's table lists each point). Returns ``[{"text", "left", "top", "x", "y"}]`` in CSS px,
    for the points labelled.

    >>> [(l["left"], l["top"]) for l in place_labels([(100, 100, "a"), (102, 100, "b")], 400, 300)]
    [(106.0, 80.0), (108.0, 104.0)]
    """
    placed, out = [], []
    for x, y, text in points:
        best = None
        for scale in (1, 2, 3):
            for dx, dy in _LABEL_OFFSETS:
                offset = (dx * scale if dx != -0.5 else dx, dy * scale)
                box = _label_box(text, x, y, offset)
                inside = box[0] >= 0 and box[1] >= 0 and box[2] <= width and box[3] <= height
                overlap = sum(max(0.0, min(box[2], b[2]) + margin - max(box[0], b[0])) *
                              max(0.0, min(box[3], b[3]) + margin - max(box[1], b[1])) for b in placed)  # fmt: skip
                cost = overlap + (0.0 if inside else 1e9)
                if best is None or cost < best[0]:
                    best = (cost, box)
                if cost == 0.0:
                    break
            if best[0] == 0.0:
                break
        if best[0] > 0.0:
            continue
        box = best[1]
        placed.append(box)
        out.append({"text": text, "left": round(float(box[0]), 1), "top": round(float(box[1]), 1),
                    "x": round(float(x), 1), "y": round(float(y), 1)})  # fmt: skip
    return out


@dataclass(frozen=True)
class Chart:
    """A plot for a page: its PNG, its displayed size in CSS px, and its point labels placed over it
    (:func:`place_labels`; ``templates/chart.html.j2`` draws them)."""

    png: bytes
    width: int
    height: int
    labels: tuple = ()


def figure_chart(fig) -> Chart:
    """:func:`figure_png` of ``fig`` with the labels :func:`label_points` recorded on its axes placed over
    it: each point's position in the laid-out figure, in CSS px (``CSS_PX_PER_INCH`` per inch)."""
    fig.canvas.draw()  # autoscales, so that place_axes sizes the margins from the tick labels in view
    # The labels' points are taken where the PNG draws them: inside the margins figure_png sets, not the
    # default subplot's (whose right margin is 0.55 in wider: labels sat up to 50 px off their points).
    place_axes(fig)
    width_in, height_in = fig.get_size_inches()
    css = CSS_PX_PER_INCH / fig.dpi
    width, height = round(width_in * CSS_PX_PER_INCH), round(height_in * CSS_PX_PER_INCH)
    points = []
    for ax in fig.axes:
        for x, y, text in ax.__dict__.get("_point_labels", []):
            px, py = ax.transData.transform((x, y))
            points.append((px * css, height - py * css, text))
    labels = tuple(place_labels(points, width, height))
    return Chart(figure_png(fig), width, height, labels)
