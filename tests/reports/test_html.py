"""The shared report machinery: the Pareto front the plots label, legible text, escaped pages."""

from __future__ import annotations

import pytest

from atlasgen.reports.html import CSS_PX_PER_INCH, MIN_FONT_PT, pareto_front, plot_style, render_page


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
