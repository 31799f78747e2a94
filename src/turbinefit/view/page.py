"""The interactive view as one self-contained HTML file: the page template, its style and
script, the vendored three.js and the scene's data (:func:`turbinefit.view.scene.scene_data`),
all inline, so that the file opens offline by double-click and can be sent as it is.

The page's Content-Security-Policy forbids every fetch (``default-src 'none'``): the
browser itself refuses any network access, and images are ``data:`` URIs.

three.js (MIT licence, ``vendor/LICENSE.three``) is vendored as ``vendor/three.min.js``:
the npm package three@:data:`THREE_VERSION` (its ES modules and ``OrbitControls``)
bundled into one minified script that defines the global ``THREE``; how it was made is in
``vendor/README.md``. A renderer, camera controls and picking are three.js's; the page's
own script (``viewer.js``) builds the scene, the legend and the photo panel.
"""

from __future__ import annotations

import html
import json
from functools import cache
from importlib import resources
from typing import Any

from turbinefit import __version__

#: The version of three.js in ``vendor/three.min.js`` (npm ``three``).
THREE_VERSION = "0.187.0"
#: What the page says made it (a ``<meta name="generator">``): ``--overwrite`` replaces
#: only a file that says so.
GENERATOR = "turbinefit view"

#: Markers of the template replaced by the page's parts (each exactly once).
_MARKERS = ("{{TITLE}}", "{{GENERATOR}}", "/*{{STYLE}}*/", "/*{{THREE}}*/", "/*{{VIEWER}}*/",
            "{{DATA}}")


@cache
def _resource(name: str) -> str:
    """A file of this package (the template, style, script, vendored library)."""
    return resources.files("turbinefit.view").joinpath(name).read_text(encoding="utf-8")


def _inline_script(text: str, what: str) -> str:
    """A script's text, refused if it could end its ``<script>`` element early."""
    low = text.lower()
    if "</script" in low or "<!--" in low:
        raise ValueError(f"{what} holds '</script' or '<!--': it cannot be inlined")
    return text


def _inline_json(text: str) -> str:
    """JSON text made safe inside ``<script>``: every ``<`` (only ever inside a string) as
    ``\\u003c``."""
    return text.replace("<", "\\u003c")


def page_html(data: dict[str, Any]) -> str:
    """The page of the scene ``data`` (the HTML text)."""
    template = _resource("page.html")
    for m in _MARKERS:
        if template.count(m) != 1:  # pragma: no cover - the template is part of the package
            raise ValueError(f"page.html must hold {m} once")
    payload = json.dumps({**data, "turbinefit_version": __version__,
                          "three_version": THREE_VERSION}, allow_nan=False, separators=(",", ":"))
    parts = {
        "{{TITLE}}": html.escape(str(data.get("title", "turbinefit view"))),
        "{{GENERATOR}}": html.escape(f"{GENERATOR} {__version__}"),
        "/*{{STYLE}}*/": _resource("viewer.css"),
        "/*{{THREE}}*/": _inline_script(_resource("vendor/three.min.js"), "three.js"),
        "/*{{VIEWER}}*/": _inline_script(_resource("viewer.js"), "viewer.js"),
        "{{DATA}}": _inline_json(payload),
    }
    # one pass, so that no part's text is searched for the markers of another
    out, rest = [], template
    while True:
        found = [(rest.find(m), m) for m in _MARKERS if rest.find(m) >= 0]
        if not found:
            out.append(rest)
            break
        i, m = min(found)
        out += [rest[:i], parts[m]]
        rest = rest[i + len(m):]
    return "".join(out)


def is_view_page(head: bytes) -> bool:
    """Whether the first bytes of a file say it is a page this module wrote."""
    return f'<meta name="generator" content="{GENERATOR}'.encode() in head
