"""Fresnel factors F(theta_d).  A per-channel term is evaluated once per channel.  One file per
form; importing it registers it."""
from brdfcl.model.terms.fresnel import conductor, dielectric, none, schlick  # noqa: F401
