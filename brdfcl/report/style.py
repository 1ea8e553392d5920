"""One style for the analysis figures (brdfcl.report.figures): sized for a page about 1400 px wide.

Every figure is FIG_WIDTH inches wide and saved at DPI, so it is 1400 px wide and its text reads
at about the size of the page's text when shown at its own size.  Colour maps: BRDF values on a
log scale in VALUE_CMAP, angles in ANGLE_CMAP, log ratios in RESIDUAL_CMAP (diverging, centred
on 0), the per-cell vote of the gradient test in VOTE_COLORS (categorical); channels in
CHANNEL_COLORS.
"""
from __future__ import annotations

from contextlib import contextmanager

DPI = 100
FIG_WIDTH = 14.0                     # inches: 1400 px at DPI
CHANNELS = "RGB"
CHANNEL_COLORS = ("#d62728", "#2ca02c", "#1f77b4")
VALUE_CMAP = "viridis"
ANGLE_CMAP = "cividis"
RESIDUAL_CMAP = "RdBu_r"
NO_DATA = "0.88"                     # face colour behind masked cells

# the gradient test's per-cell vote: value -> (label, colour)
VOTE_OUTSIDE, VOTE_UNDECIDED, VOTE_CT, VOTE_DIFFRACTION = 0, 1, 2, 3
VOTE_COLORS = {VOTE_OUTSIDE: ("outside the\ntested region", "#ffffff"),
               VOTE_UNDECIDED: ("undecided: below noise,\nno lobe signal, or the\npredictions < 10 deg apart",
                                "#c8c8c8"),
               VOTE_CT: ("Cook-Torrance", "#5e3c99"),
               VOTE_DIFFRACTION: ("diffraction", "#e66101")}

RC = {
    "figure.dpi": DPI,
    "savefig.dpi": DPI,
    "font.size": 11,
    "axes.titlesize": 12,
    "axes.labelsize": 11,
    "xtick.labelsize": 10,
    "ytick.labelsize": 10,
    "legend.fontsize": 10,
    "figure.titlesize": 14,
    "axes.titlelocation": "center",
}

TH_LABEL = r"$\theta_h$ (degrees)"
TD_LABEL = r"$\theta_d$ (degrees)"


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


@contextmanager
def style():
    """The figures' rc settings, for the duration of building and saving one figure."""
    import matplotlib
    with matplotlib.rc_context(RC):
        yield


def angle_axes(ax, xlabel=True, ylabel=True):
    """Label a (theta_d, theta_h) map at phi_d ~ 90 deg."""
    ax.set_xlim(0, 90)
    ax.set_ylim(0, 90)
    ax.set_xticks(range(0, 91, 15))
    ax.set_yticks(range(0, 91, 15))
    if xlabel:
        ax.set_xlabel(TD_LABEL)
    if ylabel:
        ax.set_ylabel(TH_LABEL)
