"""docs/api.md runs as written: each of its ```python blocks on its own, in a fresh namespace (as
one script, ``__name__ == "__main__"``), in page order, on one material of the synthetic demo
database (what `brdfcl synth merl/` writes, as the page says).

The only changes to the page's code are those of ``substitutions()``; each must occur in the
page, so a change to the page's examples breaks this test rather than skipping its block.
Every block has a check below of what it returned; a new block needs a new check.
"""
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("distributed")

from brdfcl.data.merl import FILE_SIZE  # noqa: E402
from brdfcl.device.platforms import DeviceError, pick_device  # noqa: E402

PAGE = Path(__file__).resolve().parents[1] / "docs" / "api.md"
MATERIAL = "synth-smooth-metal"        # has a diffraction lobe: every block has something to find


def substitutions(db):
    """(as written in the page, what the test runs instead)."""
    subs = [(f'"merl/{MATERIAL}.binary"', repr(str(db / f"{MATERIAL}.binary"))),
            ('"merl/"', repr(f"{db}/")),
            ('Client("tcp://scheduler:8786")', "brdfcl.app.cluster.make_client(workers=1)")]
    try:
        pick_device("nvidia")
    except DeviceError:                 # no such GPU here: the default device
        subs.append(('FitOptions(device="nvidia")', "FitOptions(device=None)"))
    return subs


def python_blocks(text):
    """[(line number of the block's first line, code)] of the ```python blocks of a Markdown page."""
    return [(text.count("\n", 0, m.start(1)) + 1, m.group(1))
            for m in re.finditer(r"^```python\n(.*?)^```", text, re.S | re.M)]


def check_one_material(ns, work):
    res = ns["res"]
    assert res.name == MATERIAL and res.success and res.errors["rmse_log"] < 0.05
    assert res.history and 0 < ns["res"].params["ct.alpha"] < 1


def check_evaluate(ns, work):
    assert ns["rgb"].shape == (3, 1) and np.isfinite(ns["rgb"]).all() and (ns["rgb"] > 0).all()
    assert (work / f"{MATERIAL}-fit.binary").stat().st_size == FILE_SIZE


def check_database(ns, work):
    report = ns["report"]
    assert report.ok and [r.name for r in report.results] == [MATERIAL]
    for f in (f"{MATERIAL}.json", f"{MATERIAL}.binary", "summary.csv"):
        assert (work / "fits" / f).is_file(), f


def check_forms(ns, work):
    result, record = ns["result"], ns["record"]
    assert result.name == MATERIAL and record["form"] in ns["DEFAULT_FORMS"].split(",")
    assert set(record["form_errors"]) == set(ns["DEFAULT_FORMS"].split(","))


def check_analysis(ns, work):
    analyses = ns["analyses"]
    assert isinstance(analyses, list) and [a.name for a in analyses] == [MATERIAL]
    assert analyses[0].verdict == "diffraction" and analyses.skipped == {} and analyses.ok
    for f in ("analysis.csv", "index.html", f"{MATERIAL}.exr", f"figures/{MATERIAL}_gradient.png"):
        assert (work / "analysis" / f).is_file(), f


def check_cluster(ns, work):
    report = ns["report"]
    assert report.ok and [r.name for r in report.results] == [MATERIAL]      # fitted on the worker
    assert (work / "fits" / f"{MATERIAL}.json").is_file()
    assert ns["client"].status == "closed"


def check_device(ns, work):
    assert ns["describe"]() and all(isinstance(ln, str) for ln in ns["describe"]())
    assert ns["res"].success and ns["res"].name == MATERIAL


CHECKS = [check_one_material, check_evaluate, check_database, check_forms, check_analysis, check_cluster,
          check_device]


@pytest.mark.slow
def test_api_page_examples_run(demo_db, tmp_path, monkeypatch):
    db = tmp_path / "merl"
    db.mkdir()
    (db / f"{MATERIAL}.binary").symlink_to(demo_db / f"{MATERIAL}.binary")
    text = PAGE.read_text()
    # every fenced block of the page is a python block, so none escapes this test
    fences, python = len(re.findall(r"^```", text, re.M)), len(re.findall(r"^```python$", text, re.M))
    assert fences == 2 * python, "docs/api.md has a fenced block that is not ```python: this test would not run it"
    for old, new in substitutions(db):
        assert old in text, f"docs/api.md no longer has {old}: update this test's substitutions"
        text = text.replace(old, new)
    blocks = python_blocks(text)
    assert len(blocks) == len(CHECKS), f"docs/api.md has {len(blocks)} python blocks, this test checks {len(CHECKS)}"
    spaces = []
    try:
        for (line, code), check in zip(blocks, CHECKS):
            ns = {"__name__": "__main__"}           # each example runs on its own
            spaces.append(ns)
            # the cluster block writes fits/ as the database block did: a fresh folder, so that it fits
            work = tmp_path / ("cluster" if check is check_cluster else "work")
            work.mkdir(exist_ok=True)
            monkeypatch.chdir(work)
            # line numbers of tracebacks are the page's
            exec(compile("\n" * (line - 1) + code, str(PAGE), "exec"), ns)
            check(ns, work)
    finally:
        for ns in spaces:
            client = ns.get("client")
            if client is not None and client.status != "closed":
                client.close()


def test_submodules_are_attributes_of_a_bare_import():
    """`import brdfcl` then `brdfcl.app.cluster.make_client` (as the page writes it) works in a fresh
    process, and `import brdfcl` alone loads neither Dask nor OpenCL."""
    code = ("import sys, brdfcl\n"
            "heavy = [m for m in ('dask', 'distributed', 'pyopencl') if m in sys.modules]\n"
            "assert not heavy, heavy\n"
            "assert callable(brdfcl.app.cluster.make_client) and callable(brdfcl.app.analyze.analyze)\n"
            "try:\n    brdfcl.no_such_thing\nexcept AttributeError:\n    pass\n"
            "else:\n    raise SystemExit('no AttributeError')\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
