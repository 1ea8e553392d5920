"""What a run writes.  Every output is a writer registered in brdfcl.report.writers (NAME.json,
summary.csv, exports for renderers, EXR maps, figures, analysis.csv and index.html, the HTML
report); the rest of this layer is what they write with: the result document and the resume
check (output), safe file writing (files), the figures (figures, style), the report's pictures
and pages (view) and the exporters (export)."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
