"""Submodules as attributes of their package on first use (``brdfcl.app.cluster`` after a bare
``import brdfcl``), so that importing the package stays light."""
from __future__ import annotations

import importlib
import importlib.util


def submodule_getattr(package: str):
    """A module-level ``__getattr__`` for ``package`` that imports ``package.name`` on request."""
    def __getattr__(name):
        if not name.startswith("_") and importlib.util.find_spec(f"{package}.{name}") is not None:
            return importlib.import_module(f"{package}.{name}")
        raise AttributeError(f"module '{package}' has no attribute '{name}'")
    return __getattr__
