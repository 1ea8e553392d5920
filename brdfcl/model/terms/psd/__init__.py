"""Power spectral densities S(f) of the surface height (f in 1/um), normalised to S(0) = 1.  One
file per PSD; importing it registers it."""
from brdfcl.model.terms.psd import abc, gauss, hp  # noqa: F401
