"""brdfcl: fit diffuse + diffraction + Cook-Torrance to measured BRDF databases with OpenCL."""
from brdfcl._lazy import submodule_getattr
from brdfcl._version import __version__  # noqa: E402
from brdfcl.data.merl import MerlError, MerlTable, read_database, read_merl, write_merl  # noqa: E402
from brdfcl.model.compose import DEFAULT_MODEL, Model, ModelError  # noqa: E402

_submodule = submodule_getattr(__name__)


def __getattr__(name):
    # The OpenCL-backed API is imported on first use so that `import brdfcl` stays light.
    if name in ("fit_all", "RunReport"):
        from brdfcl.app import run
        return getattr(run, name)
    if name in ("FitOptions", "FitResult", "Fitter", "fit_tables"):
        from brdfcl.optim import fit
        return getattr(fit, name)
    if name == "Engine":
        from brdfcl.device.engine import Engine
        return Engine
    return _submodule(name)                                   # brdfcl.app.cluster.make_client


__all__ = ["DEFAULT_MODEL", "Engine", "FitOptions", "FitResult", "Fitter", "MerlError", "MerlTable",
           "Model", "ModelError", "RunReport", "__version__", "fit_all", "fit_tables", "read_database",
           "read_merl", "write_merl"]
