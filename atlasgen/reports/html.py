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

__all__ = [
    "CSS_PX_PER_INCH",
    "PLOT_DPI",
    "MIN_FONT_PT",
    "render_page",
    "plot_style",
    "figure_png",
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
    "figure.constrained_layout.use": True,
    "savefig.dpi": PLOT_DPI,
}


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
    """Context in which plots get the report's font sizes and constrained layout (labels
    never overlap each other or the axes); yields ``matplotlib.pyplot`` (Agg backend).
    Text reads its size when it is made, so draw the whole figure inside the context."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    with matplotlib.rc_context(_RC):
        yield plt


def figure_png(fig) -> bytes:
    """PNG bytes of ``fig`` at :data:`PLOT_DPI`, closed afterwards; no ``Software`` metadata, so
    the bytes depend only on what is drawn."""
    import matplotlib.pyplot as plt

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
