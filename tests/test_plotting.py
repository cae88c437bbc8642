"""What every plot shares (driver.plotting): titles wrapped between words only, legends under
the axes so that the axes keep the figure's width, and no marker clipped at an axis' edge."""

from __future__ import annotations

import re

from driver.bench_plots import plot_rays_held
from driver.plotting import wrap
from driver.core.words import wrap as core_wrap

TITLE = ("rays held per RT unit over the frame: bunny_floor 128x128 ao (spp 2, 4 AO rays); "
         "baseline-unified, latency 11; box32 BVH; rtx2060-vulkan-sim preset, one-kernel frame, "
         "30 RT units, warps of 32, R=128, 1 pipeline, 64 KiB 512-way node cache, 3072 KiB L2, "
         "100-cycle 246.2 B/cycle memory")


def test_a_title_wraps_between_words_never_inside_a_word_or_a_quantity():
    """Titles were broken at "baseline-|unified" and "246.2 | B/cycle"; every plot (the RT-unit
    layer's too) wraps with the one function."""
    assert wrap is core_wrap
    for width in range(40, 120, 7):
        lines = wrap(TITLE, width).split("\n")
        assert len(lines) > 1
        assert " ".join(lines).replace("\u00a0", " ") == TITLE     # only spaces became breaks
        for a, b in zip(lines, lines[1:]):
            assert not a.endswith("-"), (width, a)
            assert not (re.search(r"\d$", a) and re.match(r"[A-Za-z]", b)), (width, a, b)


def test_the_rays_held_plot_keeps_the_figure_width(tmp_path, monkeypatch):
    """Its legend beside the axes squeezed them to 60 % of the figure's width."""
    import matplotlib.figure
    seen = {}
    save = matplotlib.figure.Figure.savefig

    def record(fig, *a, **k):
        seen["axes"] = fig.axes[0].get_position()
        return save(fig, *a, **k)
    series = {"bin_cycles": 100, "per_unit": [120, 90, 60, 30, 10, 0]}
    frame = {"rtunit_memory": {"rays_in_flight": 128, "cycles": 600, "utilization": 0.5,
                               "simt": {"rays_held_series": series}}}
    monkeypatch.setattr(matplotlib.figure.Figure, "savefig", record)
    plot_rays_held(frame, tmp_path / "h.png", TITLE)
    assert seen["axes"].width > 0.85
    assert (tmp_path / "h.png").stat().st_size > 1000
