"""Shadowing-masking G.  A Smith form reads the alpha of its D (``uses``) and names the D terms it
is defined for (``ndfs``).  One file per form; importing it registers it."""
from brdfcl.model.terms.shadowing import none, smith_abc, smith_beckmann, smith_ggx, smith_gtr, vcavity  # noqa: F401
