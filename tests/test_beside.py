"""Images drawn beside the fits (brdfcl.report.view.images.Beside): the measured side made in the
workers while the fits run gives the same files as a report drawn after them."""
import pytest

from brdfcl.app.run import fit_all
from brdfcl.report.view import images

NAMES = ["synth-smooth-metal", "synth-fabric", "synth-smooth-plastic"]


@pytest.fixture()
def two_workers(monkeypatch):
    """Workers for a report of a few materials, as a database's report would have."""
    monkeypatch.setattr(images, "PER_WORKER", 1)
    monkeypatch.setattr(images, "DRAW_PROCESSES", 2)


def _files(rep):
    return {p.relative_to(rep): p.read_bytes() for p in sorted(rep.rglob("*"))
            if p.is_file() and p.suffix in (".png", ".svg", ".json", ".exr")}


def test_images_drawn_beside_the_fits_are_those_drawn_after(demo_db, tmp_path, two_workers, monkeypatch):
    paths = [demo_db / f"{n}.binary" for n in NAMES]
    started = []
    real = images.Beside.__init__

    def spy(self, *a, **kw):
        real(self, *a, **kw)
        started.append(self.pool is not None and sorted(self.worker))
    monkeypatch.setattr(images.Beside, "__init__", spy)
    beside = fit_all(paths, tmp_path / "beside", model="diffuse+diffraction+ggx", pages=True)
    assert beside.ok and started == [sorted(NAMES)]

    monkeypatch.setattr(images.Beside, "__init__", lambda self, rep, tables, read: real(self, rep, {}, read))
    after = fit_all(paths, tmp_path / "after", model="diffuse+diffraction+ggx", pages=True)
    assert after.ok
    a, b = _files(tmp_path / "beside" / "report"), _files(tmp_path / "after" / "report")
    assert a.keys() == b.keys() and len(a) > 10 * len(NAMES)
    assert [k for k in a if a[k] != b[k]] == []
