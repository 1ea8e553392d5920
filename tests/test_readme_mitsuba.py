"""The README's Mitsuba 3 example, run as a user runs it: its two commands, then its Python block,
in a fresh folder; then the demo's GGX metal rendered with the built-in BSDFs against the brdfcl
BSDF.  Slow (a demo fit and four renders); skips without the extra or a usable LLVM."""
import re
import runpy
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.mitsuba_scenes import relative_difference, render, sphere_scene, use_variant

ROOT = Path(__file__).resolve().parents[1]
BLOCK = re.compile(r"<!-- mitsuba example[^>]*-->\n```python\n(.*?)```\n<!-- end of mitsuba example -->", re.S)
GRADIENT = re.compile(r"<!-- mitsuba gradient[^>]*-->\n```python\n(.*?)```\n<!-- end of mitsuba gradient -->", re.S)


def _example(path):
    text = path.read_text()
    code = BLOCK.search(text)
    assert code, f"{path.name}: the Mitsuba example block is missing"
    start = text.index(code.group(0))
    commands = [ln.strip() for ln in text[:start].splitlines()[-6:] if ln.startswith("    brdfcl ")]
    return commands, code.group(1)


def test_docs_and_readme_give_the_same_example():
    assert _example(ROOT / "README.md") == _example(ROOT / "docs" / "mitsuba.md")


@pytest.mark.slow
def test_readme_mitsuba_example_runs_as_is(tmp_path):
    mi = use_variant("llvm_ad_rgb")
    commands, code = _example(ROOT / "README.md")
    assert len(commands) == 2
    exe = Path(sys.executable).with_name("brdfcl")
    for cmd in commands:
        argv = cmd.split()
        run = subprocess.run([str(exe) if exe.exists() else "brdfcl", *argv[1:]], cwd=tmp_path,
                             capture_output=True, text=True, timeout=900)
        assert run.returncode == 0, f"{cmd}: {run.stderr[-2000:]}"
    run = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True, text=True, timeout=900)
    assert run.returncode == 0, run.stderr[-2000:]
    for png in ("synth-smooth-metal.png", "synth-smooth-metal-builtin.png"):
        assert (tmp_path / "out" / png).stat().st_size > 1000

    # docs/mitsuba.md's gradient, after the example, as it is
    gradient = GRADIENT.search((ROOT / "docs" / "mitsuba.md").read_text())
    assert gradient, "docs/mitsuba.md: the gradient block is missing"
    run = subprocess.run([sys.executable, "-c", gradient.group(1)], cwd=tmp_path, capture_output=True, text=True,
                         timeout=900)
    assert run.returncode == 0, run.stderr[-2000:]
    value = float(run.stdout.strip().splitlines()[-1].strip("[]"))
    assert np.isfinite(value) and value != 0

    # the demo's GGX metal: Mitsuba's own BSDFs against the brdfcl BSDF, same sample positions
    d = runpy.run_path(str(tmp_path / "out" / "mitsuba" / "synth-smooth-metal.py"))
    assert d["BUILTIN_NOTE"].startswith("exact")
    a, b = (render(mi, sphere_scene(mi, d[k], 256, 16)) for k in ("BSDF", "BUILTIN"))
    rel, lit = relative_difference(a, b)
    print(f"\ndemo GGX metal, built-in vs brdfcl BSDF, 256 x 256, 16 spp: median relative difference "
          f"{np.median(rel):.2e}, largest {rel.max():.2e}, image sums {b[lit].sum() / a[lit].sum():.6f}")
    assert rel.max() < 0.01
