"""brdfcl: fit diffuse + diffraction + Cook-Torrance to measured BRDF databases with OpenCL."""
__version__ = "0.1.0"

from .merl import MerlError, MerlTable, read_database, read_merl, write_merl  # noqa: E402
from .model import DEFAULT_MODEL, Model, ModelError  # noqa: E402

__all__ = ["DEFAULT_MODEL", "MerlError", "MerlTable", "Model", "ModelError", "__version__",
           "read_database", "read_merl", "write_merl"]
