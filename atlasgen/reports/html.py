"""Shared machinery of the HTML reports: jinja2 templates, one stylesheet, legible plots.

Every page (library, validation, separable) extends ``templates/base.html.j2``, which
inlines ``templates/report.css``: a page is one file that needs nothing beside it but
its images. jinja2 and matplotlib are imported lazily, inside the functions.

Plots are drawn for the size the page shows them at: a figure of ``w`` x ``h`` inches
is shown at ``w * CSS_PX_PER_INCH`` CSS pixels wide, and saved at ``PLOT_DPI`` (twice
that, so that it stays sharp on high-density screens). Text of ``s`` points then
measures ``s * CSS_PX_PER_INCH / 72`` CSS pixels: the smallest font used (``MIN_FONT_PT``)
is at least 12 px.
"""

from __future__ import annotations

import contextlib
import io
import re

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
    """Characters of the widest major tick label in view, mathtext markup left out (``10^{-3}``
    counts 5): the formatter's strings, without drawing a tick."""
    low, high = sorted(axis.get_view_interval())
    locs = [x for x in axis.get_majorticklocs() if low <= x <= high]
    labels = axis.get_major_formatter().format_ticks(locs) if locs else []
    plain = [re.sub(r"\\mathdefault|[{}$^\\]", "", label) for label in labels]
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
        right = 0.5 * _tick_label_chars(ax.xaxis) * _CHAR_EM * x_ticks
        pt = 1.0 / 72.0
        ax.set_position([
            (left + _EDGE_PT) * pt / width,
            (below + _EDGE_PT) * pt / height,
            1.0 - (left + right + 2 * _EDGE_PT) * pt / width,
            1.0 - (below + above + 2 * _EDGE_PT) * pt / height,
        ])  # fmt: skip


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


def label_points(ax, xy, labels) -> None:
    """Label points (in order of increasing x) with text of the plot's smallest size,
    alternately above and below, so that neighbours along a front do not overlap; the
    last one's label reads leftwards, so that it stays inside the axes."""
    for n, ((x, y), label) in enumerate(zip(xy, labels)):
        last = n == len(labels) - 1 and n > 0
        ax.annotate(
            label,
            (x, y),
            fontsize=MIN_FONT_PT,
            xytext=(-5 if last else 5, 6 if n % 2 == 0 else -14),
            textcoords="offset points",
            ha="right" if last else "left",
        )
