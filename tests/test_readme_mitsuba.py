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
    mi = pytest.importorskip("mitsuba", reason='Mitsuba 3 not installed: pip install "brdfcl[mitsuba]"')
    import drjit as dr
    try:
        mi.set_variant("llvm_ad_rgb")
    except Exception as e:
        pytest.skip(f"llvm_ad_rgb unavailable here: {str(e).splitlines()[0]}")
    import brdfcl.report.export.mitsuba as plugin
    if tuple(dr.detail.llvm_version()) < plugin.LLVM_MIN:
        pytest.skip("Dr.Jit's libLLVM is too old for its kernels (Debian 12: apt install libllvm19)")
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
    light = np.array([-0.5, 0.6, 0.62]) / np.linalg.norm([-0.5, 0.6, 0.62])

    def render(bsdf):
        return np.array(mi.render(mi.load_dict({
            "type": "scene", "integrator": {"type": "direct", "emitter_samples": 1, "bsdf_samples": 0},
            "sensor": {"type": "orthographic",
                       "to_world": mi.ScalarTransform4f.look_at(origin=[0, 0, 3], target=[0, 0, 0], up=[0, 1, 0]),
                       "film": {"type": "hdrfilm", "width": 256, "height": 256, "pixel_format": "rgb"},
                       "sampler": {"type": "stratified", "sample_count": 16, "seed": 2}},
            "sphere": {"type": "sphere", "bsdf": bsdf},
            "light": {"type": "directional", "direction": (-light).tolist()}})), dtype=np.float64)
    a, b = render(d["BSDF"]), render(d["BUILTIN"])
    lit = a > 1e-6 * a.max()
    rel = np.abs(b[lit] - a[lit]) / a[lit]
    print(f"\ndemo GGX metal, built-in vs brdfcl BSDF, 256 x 256, 16 spp: median relative difference "
          f"{np.median(rel):.2e}, largest {rel.max():.2e}, image sums {b[lit].sum() / a[lit].sum():.6f}")
    assert rel.max() < 0.01
