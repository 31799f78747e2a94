"""The page: one self-contained HTML file holding the vendored three.js, the viewer and the
scene data, which reads back as it was written whatever the titles hold."""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser
from importlib import resources

import pytest

from turbinefit.view.page import THREE_VERSION, is_view_page, page_html


class _Page(HTMLParser):
    """The elements of a page and the text of its scripts."""

    def __init__(self) -> None:
        super().__init__()
        self.tags: list[tuple[str, dict[str, str | None]]] = []
        self.scripts: list[tuple[dict[str, str | None], str]] = []
        self._in: dict[str, str | None] | None = None

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.tags.append((tag, dict(attrs)))
        if tag == "script":
            self._in = dict(attrs)
            self.scripts.append((self._in, ""))

    def handle_data(self, data: str) -> None:
        if self._in is not None:
            attrs, text = self.scripts[-1]
            self.scripts[-1] = (attrs, text + data)

    def handle_endtag(self, tag: str) -> None:
        if tag == "script":
            self._in = None


def _parse(text: str) -> _Page:
    p = _Page()
    p.feed(text)
    p.close()
    return p


def test_the_page_holds_its_library_script_and_data_and_reads_back() -> None:
    evil = "</script><script>alert(1)</script><!-- é"
    data = {"title": evil, "facts": [["fit", evil]], "numbers": [1.5, -2.0]}
    text = page_html(data)
    page = _parse(text)
    scripts = page.scripts
    assert len(scripts) == 3  # the data, three.js, the viewer
    assert scripts[0][0] == {"type": "application/json", "id": "turbinefit-data"}
    back = json.loads(scripts[0][1])
    assert back["title"] == evil and back["facts"] == [["fit", evil]]
    assert back["numbers"] == [1.5, -2.0] and back["three_version"] == THREE_VERSION
    assert "var THREE=" in scripts[1][1] and "OrbitControls" in scripts[1][1]
    assert "turbinefitView" in scripts[2][1]
    assert [t for t, _ in page.tags].count("script") == 3  # the title made none
    title = re.search(r"<title>(.*)</title>", text)
    assert title is not None and "<" not in title.group(1)
    assert is_view_page(text.encode()[:4096])
    assert not is_view_page(b"<!DOCTYPE html><html><head><title>x</title>")


def test_the_page_reaches_for_nothing_outside_itself() -> None:
    page = _parse(page_html({"title": "x"}))
    csp = [a["content"] for t, a in page.tags
           if t == "meta" and a.get("http-equiv") == "Content-Security-Policy"]
    assert len(csp) == 1 and csp[0] is not None and csp[0].startswith("default-src 'none'")
    for tag, attrs in page.tags:
        assert "src" not in attrs and "href" not in attrs, tag  # no file or URL is loaded


def test_the_vendored_three_js_is_the_recorded_version_with_its_licence() -> None:
    vendor = resources.files("turbinefit.view").joinpath("vendor")
    code = vendor.joinpath("three.min.js").read_text(encoding="utf-8")
    assert re.search(r'="' + THREE_VERSION.split(".")[1] + '"', code)  # REVISION
    assert "SPDX-License-Identifier: MIT" in code
    licence = vendor.joinpath("LICENSE.three").read_text(encoding="utf-8")
    assert licence.startswith("The MIT License") and "three.js authors" in licence
    readme = vendor.joinpath("README.md").read_text(encoding="utf-8")
    assert f"three@{THREE_VERSION}" in readme


def test_a_script_that_would_end_its_element_is_refused(monkeypatch: pytest.MonkeyPatch) -> None:
    import turbinefit.view.page as page

    real = page._resource.__wrapped__

    def bad(name: str) -> str:
        return "var x = '</script>';" if name == "viewer.js" else real(name)

    monkeypatch.setattr(page, "_resource", bad)
    with pytest.raises(ValueError, match="cannot be inlined"):
        page_html({"title": "x"})
