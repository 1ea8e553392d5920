"""Export a fitted model to renderers and viewers.

* ``brdfcl.report.export.mitsuba``: a Mitsuba 3 BSDF plugin named ``"brdfcl"`` that evaluates and
  importance-samples the fitted lobes (needs ``pip install "brdfcl[mitsuba]"``; importing
  this package does not import Mitsuba).
* ``brdfcl.report.export.brdf_explorer``: a Disney BRDF Explorer ``.brdf`` file (analytic GLSL) whose
  shader is generated from the same kernel sources as the OpenCL fit.

Both read what ``brdfcl fit-all --out DIR`` writes per material (``DIR/NAME.json``), or the same
document as a dict (``brdfcl.report.export.fitfile.load_fit``).
"""
