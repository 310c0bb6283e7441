"""Matplotlib figures for the report: panels of line series, and a table heat map.

Figures are described as data (:class:`Series` in :class:`Panel` objects) and drawn by
:func:`plot_panels`; matplotlib is imported inside the drawing functions, with the
non-interactive Agg backend. PNG files are written atomically.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..io.atomic import atomic_path

__all__ = ["COLORS", "Panel", "Series", "heatmap", "plot_panels"]

#: Colour cycle (matplotlib's tab10), indexable by a series' position.
COLORS = (
    "#1f77b4",
    "#ff7f0e",
    "#2ca02c",
    "#d62728",
    "#9467bd",
    "#8c564b",
    "#e377c2",
    "#7f7f7f",
    "#bcbd22",
    "#17becf",
)


@dataclass(frozen=True, eq=False)
class Series:
    """One curve.

    Attributes
    ----------
    x, y : (n,) float arrays
        Non-finite points (and non-positive ones on a log axis) are not drawn.
    label : str
    lo, hi : (n,) float arrays, optional
        A shaded band (e.g. quartiles).
    style : str
        Matplotlib line style ("-", "--", ":", "" for markers only).
    marker : str
    color : str, optional
    width : float
    alpha : float
    """

    x: ArrayLike
    y: ArrayLike
    label: str = ""
    lo: ArrayLike | None = None
    hi: ArrayLike | None = None
    style: str = "-"
    marker: str = ""
    color: str | None = None
    width: float = 1.5
    alpha: float = 1.0


@dataclass(frozen=True, eq=False)
class Panel:
    """One set of axes.

    Attributes
    ----------
    series : sequence of Series
    title, xlabel, ylabel : str
    xscale, yscale : {"linear", "log", "symlog"}
    hlines : sequence of float
        Horizontal reference lines (dotted grey).
    vlines : sequence of float
        Vertical reference lines (dashed grey), e.g. a stability limit.
    diagonal : bool
        Draw ``y = x``.
    legend : bool
    """

    series: Sequence[Series]
    title: str = ""
    xlabel: str = ""
    ylabel: str = ""
    xscale: str = "linear"
    yscale: str = "linear"
    hlines: Sequence[float] = field(default_factory=tuple)
    vlines: Sequence[float] = field(default_factory=tuple)
    diagonal: bool = False
    legend: bool = True


def _pyplot():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    return plt


def _clean(x: NDArray, y: NDArray, xlog: bool, ylog: bool) -> NDArray[np.bool_]:
    ok = np.isfinite(x) & np.isfinite(y)
    if xlog:
        ok &= x > 0
    if ylog:
        ok &= y > 0
    return ok


def _draw(ax, panel: Panel) -> None:
    xlog, ylog = panel.xscale == "log", panel.yscale == "log"
    drawn = False
    line_y: list[NDArray] = []
    for i, s in enumerate(panel.series):
        x = np.asarray(s.x, dtype=float).ravel()
        y = np.asarray(s.y, dtype=float).ravel()
        ok = _clean(x, y, xlog, ylog)
        color = s.color or COLORS[i % len(COLORS)]
        if s.lo is not None and s.hi is not None:
            lo = np.asarray(s.lo, dtype=float).ravel()
            hi = np.asarray(s.hi, dtype=float).ravel()
            band = ok & np.isfinite(lo) & np.isfinite(hi)
            if ylog:
                band &= (lo > 0) & (hi > 0)
            if band.any():
                ax.fill_between(x[band], lo[band], hi[band], color=color, alpha=0.18, lw=0)
        if ok.any():
            line_y.append(y[ok])
            ax.plot(
                x[ok],
                y[ok],
                linestyle=s.style or "none",
                marker=s.marker or None,
                color=color,
                lw=s.width,
                alpha=s.alpha,
                ms=3.5,
                label=s.label or None,
            )
            drawn = True
    for h in panel.hlines:
        ax.axhline(h, color="0.5", lw=0.8, ls=":")
    for v in panel.vlines:
        ax.axvline(v, color="0.4", lw=0.8, ls="--")
    if panel.diagonal:
        lims = np.array([ax.get_xlim(), ax.get_ylim()])
        lo, hi = lims.min(), lims.max()
        ax.plot([lo, hi], [lo, hi], color="0.4", lw=0.8, ls="--", label="y = x")
    ax.set_xscale(panel.xscale)
    ax.set_yscale(panel.yscale)
    if ylog and line_y:
        _limit_bands(ax, np.concatenate(line_y), panel.hlines)
    for axis, scale, lim in (
        (ax.xaxis, panel.xscale, ax.get_xlim()),
        (ax.yaxis, panel.yscale, ax.get_ylim()),
    ):
        if scale == "log":
            _log_ticks(axis, lim)
        elif scale == "linear":
            axis.set_major_formatter(_ShortFormatter())
    ax.set_title(panel.title, fontsize=10)
    ax.set_xlabel(panel.xlabel, fontsize=9)
    ax.set_ylabel(panel.ylabel, fontsize=9)
    ax.tick_params(labelsize=8)
    ax.grid(True, which="major", alpha=0.3)
    if not drawn:
        ax.text(
            0.5,
            0.5,
            "no finite data",
            ha="center",
            va="center",
            transform=ax.transAxes,
            color="0.4",
        )
    if panel.legend and any(s.label for s in panel.series) and drawn:
        ax.legend(fontsize=7, frameon=False)


def _limit_bands(ax, y: NDArray, hlines: Sequence[float]) -> None:
    """On a log y axis, let bands (quartiles, +-std) reach at most one decade beyond the
    lines and reference lines, so a band down to 1e-24 does not flatten every curve."""
    y = y[np.isfinite(y) & (y > 0)]
    refs = [h for h in hlines if h > 0]
    if not y.size:
        return
    lo = min(float(y.min()), *refs) if refs else float(y.min())
    hi = max(float(y.max()), *refs) if refs else float(y.max())
    cur_lo, cur_hi = ax.get_ylim()
    ax.set_ylim(max(cur_lo, lo / 10), min(cur_hi, hi * 10))


def _tick_label(v: float, digits: int) -> str:
    """``v`` to ``digits`` significant digits: positional between 1e-3 and 1e5 (1250, not
    1.25e+03), scientific outside."""
    if v == 0 or not np.isfinite(v):
        return f"{v:g}"
    rounded = float(f"{v:.{digits}g}")
    if 1e-3 <= abs(rounded) < 1e5:
        return np.format_float_positional(rounded, trim="-")
    return f"{v:.{digits}g}"


def _short_formatter_labels(values: Sequence[float]) -> list[str]:
    """Tick labels with the fewest significant digits (3 or more) that keep them distinct."""
    values = list(values)
    for digits in range(3, 11):
        labels = [_tick_label(v, digits) for v in values]
        if len(set(labels)) == len(labels):
            return labels
    return labels


def _ShortFormatter():
    """A tick formatter without matplotlib's offset text (the "1e11" over a panel's title):
    every label is a plain number, with as many digits as distinct ticks need."""
    from matplotlib.ticker import Formatter

    class ShortFormatter(Formatter):
        def __call__(self, x, pos=None):
            return _tick_label(x, 3)

        def format_ticks(self, values):
            return _short_formatter_labels(values)

    return ShortFormatter()


def _log_ticks(axis, limits: tuple[float, float]) -> None:
    """Labelled ticks on a log axis: decades, or 1-2-5 steps when the range spans less
    than two decades (where decades alone would leave one label or none); minor tick
    labels off (they overlap)."""
    from matplotlib.ticker import LogFormatterSciNotation, LogLocator, NullFormatter

    lo, hi = sorted(limits)
    if lo > 0 and math.log10(hi / lo) < 2:
        axis.set_major_locator(LogLocator(base=10, subs=(1.0, 2.0, 5.0)))
        if 1e-3 <= lo and hi <= 1e4:  # plain numbers (0.2, 0.5, 1, 2) read better here
            axis.set_major_formatter(_ShortFormatter())
        else:
            axis.set_major_formatter(
                LogFormatterSciNotation(labelOnlyBase=False, minor_thresholds=(3, 3))
            )
    axis.set_minor_formatter(NullFormatter())


def plot_panels(
    panels: Sequence[Panel],
    path: str | os.PathLike[str],
    *,
    ncols: int = 2,
    title: str = "",
    dpi: int = 90,
    panel_size: tuple[float, float] = (4.2, 3.2),
) -> Path:
    """Draw ``panels`` in a grid of ``ncols`` columns; write a PNG atomically; return its path."""
    if not panels:
        raise ValueError("panels must not be empty")
    plt = _pyplot()
    ncols = max(1, min(int(ncols), len(panels)))
    nrows = math.ceil(len(panels) / ncols)
    fig, axes = plt.subplots(
        nrows,
        ncols,
        squeeze=False,
        figsize=(panel_size[0] * ncols, panel_size[1] * nrows),
        layout="constrained",  # room for every label: nothing clipped, nothing overlapping
    )
    try:
        for ax, panel in zip(axes.flat, panels):
            _draw(ax, panel)
        for ax in list(axes.flat)[len(panels) :]:
            ax.set_visible(False)
        if title:
            fig.suptitle(title, fontsize=11)
        return _save(fig, path, dpi)
    finally:
        plt.close(fig)


def heatmap(
    values: ArrayLike,
    rows: Sequence[str],
    cols: Sequence[str],
    path: str | os.PathLike[str],
    *,
    text: Sequence[Sequence[str]] | None = None,
    title: str = "",
    colorbar: str = "",
    xlabel: str = "",
    dpi: int = 90,
) -> Path:
    """A (rows x cols) colour table of ``values`` (NaN grey) with optional cell text and an
    x-axis label (the quantity across)."""
    plt = _pyplot()
    v = np.asarray(values, dtype=float)
    if v.shape != (len(rows), len(cols)):
        raise ValueError(f"values must have shape ({len(rows)}, {len(cols)}), got {v.shape}")
    fig, ax = plt.subplots(figsize=(1.3 * len(cols) + 2.8, 0.42 * len(rows) + 1.4))
    try:
        masked = np.ma.masked_invalid(v)
        cmap = plt.get_cmap("viridis").with_extremes(bad="0.85")
        im = ax.imshow(masked, cmap=cmap, aspect="auto")
        ax.set_xticks(range(len(cols)), cols, fontsize=8)
        ax.set_yticks(range(len(rows)), rows, fontsize=8)
        if text is not None:
            finite = v[np.isfinite(v)]
            mid = 0.5 * (finite.min() + finite.max()) if finite.size else 0.0
            for i in range(len(rows)):
                for j in range(len(cols)):
                    dark = np.isfinite(v[i, j]) and v[i, j] < mid
                    ax.text(
                        j,
                        i,
                        text[i][j],
                        ha="center",
                        va="center",
                        fontsize=7,
                        color="white" if dark else "black",
                    )
        cb = fig.colorbar(im, ax=ax)
        cb.set_label(colorbar, fontsize=8)
        cb.ax.tick_params(labelsize=7)
        ax.set_title(title, fontsize=10)
        if xlabel:
            ax.set_xlabel(xlabel, fontsize=9)
        fig.tight_layout()
        return _save(fig, path, dpi)
    finally:
        plt.close(fig)


def _save(fig, path: str | os.PathLike[str], dpi: int) -> Path:
    dest = Path(path)
    if dest.suffix.lower() != ".png":
        raise ValueError(f"path must end in .png, got {str(path)!r}")
    with atomic_path(dest) as tmp:
        fig.savefig(tmp, format="png", dpi=dpi, metadata={"Software": None})
    return dest
