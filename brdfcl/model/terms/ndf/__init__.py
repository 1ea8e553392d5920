"""Microfacet normal distributions D, normalised: D cos th integrates to 1 over the hemisphere.
One file per distribution; importing it registers it."""
from brdfcl.model.terms.ndf import abc, beckmann, epd, ggx, gtr, sgd  # noqa: F401
