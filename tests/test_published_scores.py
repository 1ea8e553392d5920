"""brdfcl.report.published: the scores of published fits that a report compares with (no OpenCL)."""
import pytest

from brdfcl.report.published import Published, PublishedError, read_published
from brdfcl.report.view.pages import Entry, comparison_page, material_page

HEADER = "material,default,best_published,best_published_rmse_log\n"


def write(tmp_path, text, name="scores.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_scores_are_read_by_column_name(tmp_path):
    p = write(tmp_path, HEADER + "blue-fabric,0.003,abc_low2012_smooth_e2,0.004\n"
                                 "chrome,0.02,sgd_bagher2012,0.01\n")
    got = read_published(p)
    assert got == {"blue-fabric": Published("abc_low2012_smooth_e2", 0.004),
                   "chrome": Published("sgd_bagher2012", 0.01)}
    assert got["chrome"].ratio(0.03) == pytest.approx(3.0)
    assert got["chrome"].ratio(float("nan")) is None and got["chrome"].ratio(None) is None


@pytest.mark.parametrize("text, says", [
    ("material,best_published\nchrome,sgd\n", "missing: best_published_rmse_log"),
    (HEADER + "chrome,0.1,sgd,zero\n", "line 2: best_published_rmse_log 'zero' of chrome is not a positive number"),
    (HEADER + "chrome,0.1,sgd,-1\n", "is not a positive number"),
    (HEADER + "chrome,0.1,sgd,inf\n", "is not a positive number"),
    (HEADER + "chrome,0.1,sgd,0.1\nchrome,0.1,abc,0.2\n", "line 3: chrome appears twice"),
    (HEADER + ",0.1,sgd,0.1\n", "line 2: no material"),
    ("", "missing: material, best_published, best_published_rmse_log"),
])
def test_a_bad_scores_file_is_one_line_naming_it(tmp_path, text, says):
    p = write(tmp_path, text)
    with pytest.raises(PublishedError) as e:
        read_published(p)
    msg = str(e.value)
    assert msg.startswith(f"{p}: ") and says in msg and "\n" not in msg and len(msg) < 300


def test_a_missing_or_binary_scores_file_is_one_line(tmp_path):
    for p in (tmp_path / "absent.csv", tmp_path):
        with pytest.raises(PublishedError, match="cannot read the published scores"):
            read_published(p)
    b = tmp_path / "b.csv"
    b.write_bytes(b"\xff\xfe\x00binary" * 50)
    with pytest.raises(PublishedError) as e:
        read_published(b)
    assert "\n" not in str(e.value)


def entry(name, rmse_log, published=None):
    return Entry(name, "diffuse", {f"diffuse.rho_{c}": 0.1 for c in "rgb"}, {"rmse_log": rmse_log},
                 "converged", published=published)


def test_the_pages_name_the_best_published_fit_and_the_ratio(tmp_path):
    entries = [entry("a", 0.002, Published("abc_low2012_smooth_e2", 0.004)),
               entry("b", 0.03, Published("sgd_bagher2012", 0.02)),
               entry("c", 0.01)]                               # no published fit of it
    page = comparison_page(entries, "fits", tmp_path)
    assert "best published fit" in page and "rmse_log / published" in page
    assert "abc_low2012_smooth_e2" in page and ">0.500<" in page
    assert "<b>1.500</b>" in page                              # worse than published: in bold
    assert "2 materials compared, median ratio 1.000" in page and "worse on 1 (in bold): b" in page
    mine = material_page(entries[1], {}, tmp_path)
    assert "<b>sgd_bagher2012</b>, rmse_log 0.02; this fit's is 1.500 times that (not closer)" in mine
    assert "best published" not in comparison_page([entry("c", 0.01)], "fits", tmp_path)
    assert "Best published" not in material_page(entries[2], {}, tmp_path)


def test_fit_all_refuses_a_bad_scores_file_before_any_work(demo_db, tmp_path):
    from brdfcl.app.run import fit_all
    bad = write(tmp_path, "material,score\nx,1\n")
    with pytest.raises(PublishedError, match="missing: best_published"):
        fit_all([demo_db / "synth-fabric.binary"], tmp_path / "out", model="diffuse+ggx", published=bad)
    assert not (tmp_path / "out").exists() or not list((tmp_path / "out").glob("*.json"))
