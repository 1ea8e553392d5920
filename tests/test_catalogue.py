"""docs/terms.md is the term registry's own table, so the documentation cannot drift."""
import subprocess
import sys
from pathlib import Path

from brdfcl.model.catalogue import lobes_markdown, source_file, terms_markdown
from brdfcl.model.terms import REGISTRY

DOC = Path(__file__).resolve().parents[1] / "docs" / "terms.md"


def test_docs_terms_page_is_current():
    assert DOC.read_text() == terms_markdown() + "\n", "docs/terms.md is stale: brdfcl terms > docs/terms.md"


def test_every_registered_term_is_listed_with_its_parameters():
    text = terms_markdown()
    for kind in REGISTRY.values():
        for t in kind.values():
            assert f"| `{t.name}` |" in text and source_file(t) in text
            for p in t.params:
                assert f"`{p.name}`" in text


def test_cli_prints_it():
    r = subprocess.run([sys.executable, "-m", "brdfcl.app.cli", "terms"], capture_output=True, text=True)
    assert r.returncode == 0 and r.stdout == terms_markdown() + "\n"


def test_readme_model_table_is_current():
    """The README's table of lobes is made from the lobe classes and the term registry."""
    readme = (DOC.parents[1] / "README.md").read_text()
    assert lobes_markdown() in readme, "README.md's lobe table is stale: paste lobes_markdown() over it"
