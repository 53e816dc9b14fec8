"""The report's page (index.html) opened in a real headless Chromium: it loads with no console
error and no network request, and every figure renders. CI installs Chromium (.ci/run); a
machine without it skips these tests, except under CI, where a missing browser fails them."""

import os
import re

import browser
import pytest
from report_fakes import crossover_study

from zrp_ga import report

CHROMIUM = browser.find_browser()
if CHROMIUM is None and os.environ.get("CI"):
    raise RuntimeError("CI: no Chromium on the PATH; .ci/run installs Debian's chromium")
needs_chromium = pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on the PATH (Debian: apt-get install chromium)")


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    root = tmp_path_factory.mktemp("page")
    crossover_study(root / "runs")
    report.write_report([root / "runs"], root / "out", formats=("svg",))
    return root / "out" / "index.html"


def test_the_page_is_one_file_that_asks_for_nothing(page):
    text = page.read_text()
    assert not re.search(r"""(src|href)\s*=\s*["'](?!#)""", text)  # nothing to fetch, only in-page links
    assert "<script" not in text and "@import" not in text and "url(http" not in text
    for heading in ("Conclusions", "Design", "Figures", "Tables", "Methods: how it was made"):
        assert f">{heading}</h2>" in text
    assert "On inst-A (3 configurations paired by seed, 4 seeds shared by all;" in text
    assert "Lowest median: blend crossover" in text  # blend ends lowest on every seed of every instance


@needs_chromium
def test_the_page_loads_in_chromium_with_every_figure_drawn(page, tmp_path):
    shot = tmp_path / "page.png"
    found = browser.inspect(page, screenshot=shot, width=1000)
    assert found["errors"] == []
    assert found["requests"] == []
    names = [f["id"] for f in found["figures"]]
    assert names == ["convergence_by_configuration", "ecdf_evals_to_target", "ecdf_by_instance", "critical_difference",
                     "validation_error_boxplot", "fig2_convergence"]  # fmt: skip
    for f in found["figures"]:
        assert f["kind"] == "svg" and f["width"] > 200 and f["height"] > 100, f
    assert found["tables"] >= 5
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and shot.stat().st_size > 20_000


@needs_chromium
def test_the_check_sees_errors_and_requests(tmp_path):
    """The browser check itself: a page that logs an error, throws and asks for an image fails it."""
    bad = tmp_path / "bad.html"
    bad.write_text('<!doctype html><title>bad</title><figure id="f"><img src="http://127.0.0.1:9/x.png"></figure>'
                   '<script>console.error("boom"); undefined_call();</script>')  # fmt: skip
    found = browser.inspect(bad)
    assert any("boom" in e for e in found["errors"]) and any("undefined_call" in e for e in found["errors"])
    assert found["requests"] == ["http://127.0.0.1:9/x.png"]
    assert found["figures"][0]["complete"] is False
