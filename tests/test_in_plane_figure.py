"""The in-plane figure of scattered samples on sets no gonioreflectometer's usual layout fits: the
light held fixed as the second direction (ALTA's retro data), and a 1-D slice in which every
sample is its own incidence (ALTA's COS_TH, wi = wo)."""
from __future__ import annotations

import numpy as np

from brdfcl.data.samples import make_samples, rgb_channels
from brdfcl.model.compose import Model
from brdfcl.report.sample_figures import figure_in_plane, in_plane, incidence_first, incidence_panels

MODEL = Model("diffuse+ggx")
PARAMS = {s.name: s.param.default for s in MODEL.slots}


def samples(ti, pi_, to, po):
    n = len(ti)
    return make_samples(None, np.radians(ti), np.radians(pi_), np.radians(to), np.radians(po),
                        np.full((n, 3), 0.3), rgb_channels())


def test_the_fixed_direction_is_the_incidence():
    view = np.linspace(0, 80, 9)
    s = samples(view, np.full(9, 180.0), np.full(9, 30.0), np.zeros(9))     # the light second, at 30 deg
    ti, to = incidence_first(s)
    np.testing.assert_allclose(np.degrees(ti), 30.0)
    np.testing.assert_allclose(np.degrees(to), view)
    mask, signed = in_plane(s)
    assert mask.all() and np.allclose(signed, view)                          # the view on the specular side
    np.testing.assert_allclose(np.degrees(incidence_panels(s, mask)), [30.0], atol=0.01)     # to 1e-4 rad


def test_a_backscatter_slice_is_drawn_against_theta_h(tmp_path):
    th = np.linspace(0, 80, 12)
    s = samples(th, np.zeros(12), th, np.zeros(12))                          # wi = wo: each its own incidence
    assert incidence_panels(s, in_plane(s)[0]) == []
    fig = figure_in_plane(s, MODEL, PARAMS, tmp_path / "slice.png")
    assert "no incidence angle with 3 samples" in fig.axes[0].get_title()
    assert fig.axes[0].get_xlabel() == r"$\theta_h$ (degrees)"
    assert len(fig.axes[0].lines) == 6                                       # measured and fitted per band
    assert (tmp_path / "slice.png").stat().st_size > 10000
