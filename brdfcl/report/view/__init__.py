"""Seeing a fit: lit spheres (brdfcl.report.view.sphere) and slice plots (brdfcl.report.view.slices) of a
fitted model beside the measured table, with brdfcl's own code (no external renderer), so that a
fit can be judged by eye and compared with renderers' output.  The report plans every view once
(brdfcl.report.view.views), evaluates the fits of a model together (brdfcl.report.view.evaluate)
and draws each material's images (brdfcl.report.view.material) in worker processes
(brdfcl.report.view.drawer)."""
