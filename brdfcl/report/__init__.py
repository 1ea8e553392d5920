"""What a run writes: results (CSV, JSON, EXR), figures, the HTML report and exports for
renderers."""
from brdfcl._lazy import submodule_getattr

__getattr__ = submodule_getattr(__name__)
