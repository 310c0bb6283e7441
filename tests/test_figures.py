"""Figure helpers: readable tick labels, bands that do not flatten the curves."""

from __future__ import annotations

import numpy as np

from continuum_vs_network.report.figures import (
    Panel,
    Series,
    _limit_bands,
    _short_formatter_labels,
    plot_panels,
)


def test_tick_labels_are_distinct_plain_and_short():
    assert _short_formatter_labels([0, 250, 1000, 1250]) == ["0", "250", "1000", "1250"]
    assert _short_formatter_labels([1.00001, 1.00002]) == ["1.00001", "1.00002"]  # distinct
    assert _short_formatter_labels([1e11, 2e11]) == ["1e+11", "2e+11"]  # no offset needed


def test_a_band_reaches_at_most_a_decade_beyond_the_lines():
    import matplotlib

    matplotlib.use("Agg", force=True)
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    y = np.array([1.0, 0.1, 0.01])
    ax.fill_between([0, 1, 2], y * 1e-22, y * 2)
    ax.plot([0, 1, 2], y)
    ax.set_yscale("log")
    _limit_bands(ax, y, (1.0,))
    lo, hi = ax.get_ylim()
    plt.close(fig)
    assert lo >= 1e-3 * 0.999 and hi <= 20.0


def test_figure_with_huge_values_is_written(tmp_path):
    x = np.arange(10.0)
    path = plot_panels(
        [Panel([Series(x, 1e11 * (1 + x))], "big", "step", "E^C")], tmp_path / "f.png"
    )
    assert path.stat().st_size > 1000
