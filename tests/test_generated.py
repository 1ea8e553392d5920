"""Code generated from the terms' formulas is made once per machine: a later process reads it
back (no SymPy work), gets exactly what generation gives, and makes it again once a formula, the
printer or SymPy changes, or the kept file is damaged."""
import json

import numpy as np
import pytest

from brdfcl import _cache
from brdfcl.kernels import terms as kterms
from brdfcl.model.terms import REGISTRY, keys, reference
from tests.test_reference import random_cells


@pytest.fixture()
def fresh(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path))
    kterms.c_source.cache_clear()
    reference.compiled.cache_clear()
    yield tmp_path
    kterms.c_source.cache_clear()
    reference.compiled.cache_clear()


def test_text_is_made_once_and_a_damaged_file_is_made_again(fresh):
    calls = []
    make = lambda: calls.append(1) or "generated text"          # noqa: E731
    assert _cache.generated("c", "k1", make) == "generated text" and calls == [1]
    assert _cache.generated("c", "k1", make) == "generated text" and calls == [1]       # read back
    path = fresh / "generated" / "c" / "k1.json"
    doc = json.loads(path.read_text())
    path.write_text(json.dumps({"text": doc["text"][:-3], "sha1": doc["sha1"]}))        # damaged
    assert _cache.generated("c", "k1", make) == "generated text" and calls == [1, 1]
    path.write_text("{not json")
    assert _cache.generated("c", "k1", make) == "generated text" and calls == [1, 1, 1]


@pytest.mark.slow
@pytest.mark.parametrize("kind,name", [("ndf", "gtr"), ("shadowing", "smith_abc"), ("fresnel", "dielectric"),
                                       ("psd", "abc")])
def test_kept_code_is_what_generation_gives(fresh, monkeypatch, kind, name):
    term = REGISTRY[kind][name]
    made_c = kterms.c_source(term)
    args, made_ref = reference.compiled(term)
    kterms.c_source.cache_clear()
    reference.compiled.cache_clear()
    monkeypatch.setattr(kterms, "_print_c", lambda t: pytest.fail("printed again"))
    monkeypatch.setattr(reference, "_generate", lambda t: pytest.fail("lambdified again"))
    assert kterms.c_source(term) == made_c
    args2, kept_ref = reference.compiled(term)
    assert args2 == args
    rng = np.random.default_rng(1)
    if term.arg == "f":
        arg = [rng.uniform(0.1, 20.0, 50)] if args else []
    else:
        cells = random_cells(rng, 50)
        arg = [getattr(cells, a) for a in args]
    inputs = [p.default for p in term.params] + [0.5] * len(term.uses) + [1.0] * len(term.const_names)
    for a, b in zip(made_ref(*arg, *inputs), kept_ref(*arg, *inputs)):
        np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


def test_the_key_follows_the_terms_module(fresh, user_ndf):
    src, mine = user_ndf
    first = keys.formula_key(mine)
    keys.formula_key.cache_clear()
    src.write_text("# version 2\n")
    second = keys.formula_key(mine)
    keys.formula_key.cache_clear()
    assert first != second and keys.formula_key(REGISTRY["ndf"]["ggx"]) not in (first, second)


def test_generated_arrays_are_made_once_and_pruned(tmp_path, monkeypatch):
    import numpy as np

    from brdfcl import _cache
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path))
    calls = []

    def make(i):
        calls.append(i)
        return {"a": np.arange(i + 1)}
    for i in range(_cache.KEEP_ARRAYS + 2):
        assert _cache.generated_arrays("t", f"k{i}", lambda i=i: make(i))["a"].size == i + 1
    again = _cache.generated_arrays("t", f"k{_cache.KEEP_ARRAYS + 1}", lambda: make(-1))
    assert again["a"].size == _cache.KEEP_ARRAYS + 2 and -1 not in calls
    assert len(list((tmp_path / "generated" / "t").glob("*.npz"))) == _cache.KEEP_ARRAYS
    (tmp_path / "generated" / "t" / "k9.npz").write_bytes(b"not a zip")
    assert _cache.generated_arrays("t", "k9", lambda: {"a": np.zeros(2)})["a"].size == 2


def test_text_kept_of_one_kind_is_pruned(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDFCL_CACHE_DIR", str(tmp_path))
    for i in range(5):
        assert _cache.generated("kernel", f"k{i}", lambda i=i: f"text {i}", keep=3) == f"text {i}"
    assert len(list((tmp_path / "generated" / "kernel").glob("*.json"))) == 3
    assert _cache.generated("kernel", "k4", lambda: "made again", keep=3) == "text 4"


_STARTUP = """
import sys
import numpy as np
from brdfcl.data.geometry import table_geometry
from brdfcl.device.engine import Engine
from brdfcl.model.lobes.cells import Cells
from brdfcl.model.compose import DEFAULT_MODEL
from brdfcl.optim.forms import DEFAULT_FORMS, form_keys
import brdfcl.app.cli, brdfcl.app.runner, brdfcl.report.writers
for spec in form_keys(DEFAULT_MODEL, DEFAULT_FORMS).values():
    engine = Engine(spec)
    assert engine.self_test.ok, engine.self_test
    cells = Cells.from_geometry(table_geometry(), np.arange(0, 1_000_000, 997))
    engine.model.reference(cells, engine.model.defaults())
print(sorted({m.split('.')[0] for m in sys.modules} & {'sympy', 'mako', 'scipy', 'matplotlib'}))
"""


def test_a_second_process_imports_no_generators():
    # a fit's start (its engines, their self-tests, the float64 reference) once everything made
    # from the code is kept: no SymPy, no Mako (and no scipy, no matplotlib) imported
    import subprocess
    import sys
    run = lambda: subprocess.run([sys.executable, "-c", _STARTUP], capture_output=True, text=True,  # noqa: E731
                                 timeout=600)
    first = run()
    assert first.returncode == 0, first.stderr[-2000:]
    second = run()
    assert second.returncode == 0, second.stderr[-2000:]
    assert second.stdout.strip().splitlines()[-1] == "[]", second.stdout
