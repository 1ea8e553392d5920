"""Keys of the code generated from terms' formulas, so that it can be kept on disk between runs.

Generated code (a term's OpenCL function, its float64 reference) depends only on the formula and
the code that derives and prints it; hashing those sources, not the generated text, keeps SymPy
out of a run that finds the text already made."""
from __future__ import annotations

import hashlib
import sys
from functools import cache
from pathlib import Path


@cache
def sympy_version() -> str:
    """The installed SymPy's version, read from its metadata: importing SymPy costs half a second,
    which a run that finds its generated code made does not pay."""
    from importlib.metadata import PackageNotFoundError, version
    try:
        return version("sympy")
    except PackageNotFoundError:
        import sympy
        return sympy.__version__


@cache
def _terms_files_hash() -> str:
    """A hash of every module of brdfcl.model.terms (this one, the cell symbols, the reference,
    the terms themselves): what every term's formula and its generated code are made from."""
    here = Path(__file__).resolve().parent
    h = hashlib.sha1(sympy_version().encode())
    for f in sorted(here.rglob("*.py")):
        h.update(f.relative_to(here).as_posix().encode() + b"\0" + f.read_bytes())
    return h.hexdigest()


def code_key(*files: Path) -> str:
    """A hash of the terms' modules and of ``files`` (the code that prints or compiles what
    they define): the key of text generated from the cell symbols rather than from one term."""
    h = hashlib.sha1(_terms_files_hash().encode())
    for f in files:
        h.update(b"\0" + Path(f).read_bytes())
    return h.hexdigest()[:24]


@cache
def formula_key(term) -> str:
    """A hash of what a term's formula and derivatives are made from (`_terms_files_hash`, the
    module that registered it, its identity): code generated from them and kept on disk
    (brdfcl._cache.generated) is stale once this changes.  A term registered from no file (a
    notebook) is keyed by its expressions, which costs SymPy's derivatives once."""
    h = hashlib.sha1(f"{_terms_files_hash()}\0{term.kind}\0{term.name}\0{term.origin}".encode())
    origin = getattr(sys.modules.get(term.origin), "__file__", None)
    if origin and Path(origin).is_file():
        h.update(Path(origin).read_bytes())
    else:
        import sympy as sp
        value, derivs = term.expressions()
        h.update(repr(term.params).encode() + sp.srepr((value, tuple(derivs.items()))).encode())
    return h.hexdigest()[:24]
