"""One path from any measurement to a fit: readers return Measurements, the fitter takes any.

The fitter sees only a measurement's layout (its cells) and values: MERL tables share one layout
and one uploaded geometry; scattered samples bring their own; a dense layout gets a coarse subset
for the global search, a sparse one is used whole."""
from __future__ import annotations

import numpy as np
import pytest

from brdfcl.data.geometry import N_CELLS, TABLE, table_geometry, table_values
from brdfcl.data.measurement import Layout, Measurement
from brdfcl.data.merl import MerlError, MerlFile, open_merl, read_merl
from brdfcl.data.readers import READERS, read_measurement
from brdfcl.data.samples import make_samples, rgb_channels
from brdfcl.optim.fit import FitOptions, Fitter


def _samples(n=300, seed=0):
    rng = np.random.default_rng(seed)
    ti, to = rng.uniform(0, 1.3, n), rng.uniform(0, 1.3, n)
    pi, po = rng.uniform(-np.pi, np.pi, n), rng.uniform(-np.pi, np.pi, n)
    return make_samples(None, ti, pi, to, po, np.full((n, 3), 0.1), rgb_channels(), name=f"s{seed}")


def test_every_reader_returns_a_measurement(demo_db, tmp_path):
    m = read_measurement(demo_db / "synth-fabric.binary")
    assert isinstance(m, MerlFile) and isinstance(m, Measurement) and m.layout is TABLE
    assert m.name == "synth-fabric" and m.n_channels == 3
    np.testing.assert_allclose(m.wavelengths, [0.645, 0.526, 0.444])
    assert read_merl(m.path).layout is TABLE                      # a table in memory too
    assert isinstance(_samples(), Measurement) and not _samples().layout.dense
    assert set(READERS) >= {".binary", ".brdf", ".csv"}
    bad = tmp_path / "short.binary"
    bad.write_bytes(b"\x00" * 5)
    with pytest.raises(MerlError, match="short.binary: not a MERL file"):
        open_merl(bad)                                            # the header is checked when opened


def test_values_are_read_at_the_cells_asked_for(demo_db):
    path = demo_db / "synth-fabric.binary"
    index = TABLE.select(80.0)[::5000]
    out = np.empty((3, index.size), np.float32)
    MerlFile(path).values_at([index], [out])
    np.testing.assert_allclose(out, read_merl(path).brdf()[:, index], rtol=1e-6)
    np.testing.assert_array_equal(table_values(MerlFile(path), index), read_merl(path).brdf()[:, index])


def test_tables_share_one_geometry_samples_bring_their_own(demo_db):
    f = Fitter(FitOptions(model="diffuse+ggx"))
    tables = [MerlFile(p) for p in sorted(demo_db.glob("*.binary"))[:2]]
    b = f.load(tables)
    assert b.targets.full.cells.shared and b.targets.full.cells.geo_stride == 0
    assert b.targets.coarse.cells.index.size < b.targets.full.cells.index.size      # dense: a coarse subset
    assert b.targets.preview is not None
    s = f.load([_samples(300, 0), _samples(200, 1)])
    assert not s.targets.full.cells.shared and s.targets.coarse is s.targets.full and s.targets.preview is None
    assert s.data.shape[0] == 2 and np.isnan(s.data[1, :, 200:]).all()


def test_a_file_that_cannot_be_read_now_is_told_and_left_out(demo_db, tmp_path):
    good = MerlFile(demo_db / "synth-fabric.binary")
    gone = MerlFile(tmp_path / "gone.binary")
    told = []
    b = Fitter(FitOptions(model="diffuse")).load([gone, good], on_error=lambda m, e: told.append((m, str(e))))
    assert b.names == ["synth-fabric"] and b.read == [1]
    assert told[0][0] is gone and "disappeared" in told[0][1]


class _Coarser(Layout):
    """Another table: every other theta_h bin of the MERL table's cells, as a layout of its own
    (cells numbered 0 .. n-1) with a lookup from direction pairs."""

    dense = True

    def __init__(self):
        g = table_geometry()
        self.cells = np.flatnonzero(g.above_horizon & ((np.arange(N_CELLS) // (90 * 180)) % 2 == 0))

    def select(self, cutoff_deg):
        return np.flatnonzero(np.isin(self.cells, TABLE.select(cutoff_deg)))

    def weights(self, index, cutoff_deg):
        return 2.0 * table_geometry().weight[self.cells[index]]

    def rows(self, index):
        return TABLE.rows(self.cells[index])

    def lookup(self, wi, wo):
        cell = TABLE.lookup(wi, wo)
        even = cell - (cell // (90 * 180) % 2) * 90 * 180        # the even theta_h bin below
        return np.where(cell >= 0, np.searchsorted(self.cells, even), -1)


class _OnCoarser(Measurement):
    channels = rgb_channels()

    def __init__(self, table, layout):
        self.name, self.path, self._layout = table.name, None, layout
        self.values = table.brdf()[:, layout.cells]

    @property
    def layout(self):
        return self._layout

    def values_at(self, indices, outs):
        for o, idx in zip(outs, indices):
            o[...] = self.values[:, idx]


def test_a_table_of_another_layout_fits_and_looks_up(demo_db):
    """A layout the fitter has never seen: fitted on its own cells, read at the MERL table's cells
    through its lookup (what the analysis and the report read)."""
    table = read_merl(demo_db / "synth-smooth-plastic.binary")
    layout = _Coarser()
    m = _OnCoarser(table, layout)
    (r,) = Fitter(FitOptions(model="diffuse+ggx:smith:dielectric")).fit([m])
    (ref,) = Fitter(FitOptions(model="diffuse+ggx:smith:dielectric")).fit([table])
    assert r.success and r.errors["rmse_log"] < 2 * ref.errors["rmse_log"] + 1e-3
    assert r.params["ct.alpha"] == pytest.approx(ref.params["ct.alpha"], rel=0.05)
    even = TABLE.select(80.0)[(TABLE.select(80.0) // (90 * 180)) % 2 == 0][::997]
    np.testing.assert_array_equal(table_values(m, even), table.brdf()[:, even])
    with pytest.raises(ValueError, match="not a table"):
        table_values(_samples(), even)
