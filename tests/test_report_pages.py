"""The run's report: a comparison page and a page per material, checked in a real browser."""
import re
import shutil
import subprocess
import sys

import pytest

from brdfcl.app.run import fit_all, write_pages

# -n with --dist loadgroup (the slow tier in .ci/run): one process runs this module's tests, not
# one after another, so its costly fixture is session-scoped: made once there
pytestmark = pytest.mark.xdist_group("test_report_pages")

NAMES = ["synth-smooth-metal", "synth-fabric"]
CHROMIUM = shutil.which("chromium") or shutil.which("chromium-browser")
PROBE = """<script>window.addEventListener('load', function () {
  var im = document.images, bad = [];
  for (var i = 0; i < im.length; i++)
    if (!(im[i].complete && im[i].naturalWidth > 0)) bad.push(im[i].getAttribute('src'));
  document.body.setAttribute('data-images', im.length + ' ' + bad.length + ' ' + bad.join(','));
});</script>"""


@pytest.fixture(scope="session")
def run(demo_db, tmp_path_factory):
    out = tmp_path_factory.mktemp("report") / "out"
    paths = [demo_db / f"{n}.binary" for n in NAMES]
    rep = fit_all(paths, out, model="diffuse+diffraction+ggx", pages=True)
    assert rep.ok and rep.pages == out / "report" / "index.html"
    return out


def test_pages_hold_what_a_user_reads(run):
    index = (run / "report" / "index.html").read_text()
    assert index.count("<tr class=") == len(NAMES)
    for n in NAMES:
        assert f"href='{n}.html'" in index and f"{n}/{n}-thumb.png" in index
        page = (run / "report" / f"{n}.html").read_text()
        for what in ("standard error", "Directional albedo", f"{n}-sphere-key.png", f"{n}-sphere-env.png",
                     f"{n}-slices.svg", f"{n}-lobes.svg", "median relative difference", "ct.alpha"):
            assert what in page, (n, what)
    assert "diffraction.rho" in index and "rmse_log" in index        # grouped parameters, metrics
    # the demo's known truth beside each fitted value: same names, 0 for a lobe the truth lacks
    fabric = (run / "report" / "synth-fabric.html").read_text()
    assert "<th>true value</th>" in fabric and "true model is <code>diffuse+beckmann:vcavity:none</code>" in fabric
    metal = (run / "report" / "synth-smooth-metal.html").read_text()
    row = re.search(r"<tr><td class='l'>ct\.alpha</td>(.*?)</tr>", metal).group(1)
    assert "data-v='0.02'" in row and "%" in row


def test_the_truth_of_a_synthetic_table_is_found_beside_it_or_its_target(demo_db, tmp_path):
    from brdfcl.model.synth import truth_of
    t = truth_of(demo_db / "synth-fabric.binary")
    assert t["model"] == "diffuse+beckmann:vcavity:none" and t["params"]["diffuse.rho_g"] == 0.25
    (tmp_path / "synth-fabric.binary").symlink_to(demo_db / "synth-fabric.binary")
    assert truth_of(tmp_path / "synth-fabric.binary")["params"] == t["params"]
    (tmp_path / "copy").mkdir()
    shutil.copy(demo_db / "synth-fabric.binary", tmp_path / "copy" / "synth-fabric.binary")
    assert truth_of(tmp_path / "copy" / "synth-fabric.binary") is None            # a table with no truth
    (tmp_path / "copy" / "truth.json").write_text("{not json")
    assert truth_of(tmp_path / "copy" / "synth-fabric.binary") is None


def test_images_are_redrawn_only_when_the_fit_changes(run, demo_db):
    thumb = run / "report" / "synth-fabric" / "synth-fabric-thumb.png"
    before = thumb.stat().st_mtime_ns
    write_pages(run, [demo_db / f"{n}.binary" for n in NAMES])
    assert thumb.stat().st_mtime_ns == before


@pytest.mark.skipif(CHROMIUM is None, reason="no Chromium (apt-get install chromium); .ci/run installs it")
@pytest.mark.parametrize("page", ["index"] + NAMES)
def test_page_loads_in_chromium_without_errors(run, page):
    src = run / "report" / f"{page}.html"
    probe = src.with_name(f".probe-{page}.html")            # beside it, so relative links resolve
    probe.write_text(src.read_text() + PROBE)
    r = subprocess.run([CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--enable-logging=stderr",
                        "--v=0", "--virtual-time-budget=5000", "--dump-dom", probe.as_uri()],
                       capture_output=True, text=True, timeout=120)
    probe.unlink()
    found = re.search(r'data-images="(\d+) (\d+) ([^"]*)"', r.stdout)
    assert found, r.stderr[-1500:]
    n, bad, which = int(found.group(1)), int(found.group(2)), found.group(3)
    assert n >= (len(NAMES) if page == "index" else 5) and bad == 0, which
    # Chromium's own notes on a WebGL context (software rendering, a synchronous readPixels) are
    # not the page's messages
    console = [ln for ln in r.stderr.splitlines() if "CONSOLE" in ln and not any(
        note in ln for note in ("Automatic fallback to software WebGL", "GPU stall due to ReadPixels"))]
    assert not console, console


@pytest.mark.slow
def test_cli_writes_the_report_and_can_skip_it(demo_db, tmp_path):
    d = tmp_path / "db"
    d.mkdir()
    (d / "synth-mirror.binary").symlink_to(demo_db / "synth-mirror.binary")
    cli = [sys.executable, "-m", "brdfcl.app.cli", "fit-all", str(d), "--model", "diffuse+ggx", "--quiet"]
    r = subprocess.run(cli + ["--out", str(tmp_path / "a")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "report" in r.stdout and (tmp_path / "a" / "report" / "synth-mirror.html").exists()
    r = subprocess.run(cli + ["--out", str(tmp_path / "b"), "--no-report"], capture_output=True, text=True)
    assert r.returncode == 0 and not (tmp_path / "b" / "report").exists()


@pytest.mark.slow
def test_cli_exports_a_finished_fit(run, tmp_path):
    from brdfcl.data.merl import read_merl
    fit = run / "synth-smooth-metal.json"
    r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "export", str(fit), "--brdf-explorer",
                        str(tmp_path / "m.brdf"), "--merl", str(tmp_path / "m.binary")], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert "::begin shader" in (tmp_path / "m.brdf").read_text()
    table = read_merl(tmp_path / "m.binary")
    assert table.valid.sum() > 0.4 * table.valid.size
    r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "export", str(fit), "--merl", str(fit)],
                       capture_output=True, text=True)
    assert r.returncode == 2 and "would overwrite" in r.stderr and fit.read_text().startswith("{")


def test_cli_compares_with_published_scores(run, demo_db, tmp_path):
    """``fit-all --published``: a rerun keeps the fits and its report names each scored material's
    best published fit with the ratio of brdfcl's rmse_log to it; a bad file stops the command in
    one line naming it."""
    import json
    out = tmp_path / "out"
    shutil.copytree(run, out)
    mine = json.loads((out / "synth-fabric.json").read_text())["errors"]["rmse_log"]
    scores = tmp_path / "scores.csv"
    scores.write_text("material,best_published,best_published_rmse_log\n"
                      f"synth-fabric,abc_low2012_smooth_e2,{2 * mine!r}\n")
    db = tmp_path / "db"
    db.mkdir()
    for n in NAMES:
        (db / f"{n}.binary").symlink_to(demo_db / f"{n}.binary")
    cli = [sys.executable, "-m", "brdfcl.app.cli", "fit-all", str(db),
           "--model", "diffuse+diffraction+ggx", "--quiet", "--out", str(out)]
    r = subprocess.run(cli + ["--published", str(scores)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr[-2000:]
    assert "fitted 0 materials" in r.stdout and "2 already done" in r.stdout
    index = (out / "report" / "index.html").read_text()
    assert "abc_low2012_smooth_e2" in index and ">0.500<" in index
    assert "1 material compared, median ratio 0.500" in index
    assert "this fit's is 0.500 times that (closer)" in (out / "report" / "synth-fabric.html").read_text()
    assert "Best published" not in (out / "report" / "synth-smooth-metal.html").read_text()
    scores.write_text("material,score\n")
    r = subprocess.run(cli + ["--published", str(scores)], capture_output=True, text=True)
    assert r.returncode != 0 and r.stderr.strip().count("\n") == 0
    assert str(scores) in r.stderr and "missing: best_published" in r.stderr
