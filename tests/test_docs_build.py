"""The documentation site builds with warnings as errors, and the README's links into it resolve.

mkdocs.yml turns broken links, missing anchors and pages left out of the nav into warnings, and
``strict: true`` makes any warning fail the build (``./r360 docs`` runs the same build)."""
from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    out = tmp_path_factory.mktemp("site")
    proc = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)],
                          cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    return out


def test_the_site_builds_strictly(site):
    assert (site / "index.html").is_file()
    api = (site / "api" / "index.html").read_text(encoding="utf-8")
    # The API reference is generated from the docstrings, not written by hand.
    assert "Load a Gaussian-splat scene" in api and "measure_view_methods" in api


def test_api_page_shows_no_sphinx_roles(site):
    """The docstrings are Markdown (mkdocs.yml: docstring_style null renders them as written): a Sphinx
    role such as :func:`x` would reach the page as the raw text ":func:" before the code span."""
    api = (site / "api" / "index.html").read_text(encoding="utf-8")
    assert "r360gpu.protocol" in api and "MIN_SCENES_TO_RANK" in api
    roles = re.findall(r":(?:py:)?[a-z]+:(?:<code>|`)", re.sub(r"<span[^>]*>|</span>", "", api))
    assert roles == [], f"{len(roles)} Sphinx roles on the API page, e.g. {roles[:5]}"


def test_every_page_is_in_the_nav():
    import yaml

    def pages(node):
        if isinstance(node, str):
            yield node
        elif isinstance(node, list):
            for x in node:
                yield from pages(x)
        elif isinstance(node, dict):
            for x in node.values():
                yield from pages(x)

    cfg = yaml.load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"), Loader=yaml.SafeLoader)
    listed = set(pages(cfg["nav"]))
    on_disk = {p.relative_to(ROOT / "docs").as_posix() for p in (ROOT / "docs").rglob("*.md")}
    assert on_disk - listed == set(), "add these pages to the nav of mkdocs.yml"
    assert listed - on_disk == set()


def test_readme_links_resolve(site):
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    links = re.findall(r"\]\((docs/[^)#\s]+)(?:#([^)\s]+))?\)", readme)
    assert len(links) >= 10
    for page, anchor in links:
        assert (ROOT / page).is_file(), page
        if anchor:
            html = (site / Path(page).relative_to("docs").with_suffix("") / "index.html").read_text(encoding="utf-8")
            assert f'id="{anchor}"' in html, f"README links to {page}#{anchor}: no such anchor"


def test_readme_is_short():
    assert len((ROOT / "README.md").read_text(encoding="utf-8").splitlines()) <= 150


def test_viewer_page_lists_the_viewer_key_bindings():
    """The key table of docs/viewer.md is the viewer's own KEY_BINDINGS (its help panel), row for row."""
    from r360gpu.viewer.state import KEY_BINDINGS

    page = (ROOT / "docs" / "viewer.md").read_text(encoding="utf-8")
    table = page[page.index("| Keys | Action |"):].split("\n\n")[0].splitlines()[2:]
    rows = [tuple(c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line)[1:-1]) for line in table]
    assert rows == [tuple(kb) for kb in KEY_BINDINGS]
