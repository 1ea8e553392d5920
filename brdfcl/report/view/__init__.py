"""Seeing a fit: lit spheres (brdfcl.report.view.sphere) and slice plots (brdfcl.report.view.slices) of a
fitted model beside the measured table, computed with brdfcl's own float64 reference (no
external renderer), so that a fit can be judged by eye and compared with renderers' output."""
