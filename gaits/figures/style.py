"""Distinct styles for many series in one axes: no two series share colour *and* marker *and*
line style, so a figure with 18 series (a work-precision chart) reads without guessing.

:func:`series_styles` cycles ten colours (tab10), and for every further ten a new marker and
line style; the first ten series are the plain tab10 colours. Keyword dicts for ``ax.plot``;
nothing global (no ``rcParams``) is changed.
"""
from __future__ import annotations

__all__ = ["series_styles", "COLORS", "MARKERS", "LINESTYLES"]

COLORS = tuple(f"C{i}" for i in range(10))              # the tab10 cycle
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "*", "<", ">")
LINESTYLES = ("-", "--", ":", "-.")


def series_styles(count: int, *, markers: bool = False) -> list:
    """``count`` keyword dicts (``color``, ``marker``, ``linestyle``), pairwise distinct.

    ``markers``: give every series a marker (for point data such as work-precision curves);
    otherwise the first ten are plain lines and markers start with the eleventh.
    """
    styles = []
    for i in range(count):
        block = i // len(COLORS)
        style = {"color": COLORS[i % len(COLORS)], "linestyle": LINESTYLES[block % len(LINESTYLES)]}
        if markers:                       # a marker per series; a colour's repeats shift it by 3
            style["marker"] = MARKERS[(i % len(COLORS) + block * 3) % len(MARKERS)]
        elif block:                       # lines: markers from the eleventh series on
            style["marker"] = MARKERS[block % len(MARKERS)]
        styles.append(style)
    return styles
