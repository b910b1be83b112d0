"""Self-contained HTML pages: one file that works offline, with its style, code and data
inline (the replay page, :mod:`crlbswarm.replay`, and the campaign report,
:mod:`crlbswarm.report`).

A page's script and style sheet ship in the package's ``web/`` folder
(:func:`package_text`); its data are JSON in a ``<script type="application/json">`` element
(:func:`json_script`); :func:`html_page` assembles the document under a content security
policy that lets it load nothing from the network or the disk.
"""

from __future__ import annotations

import html
import json
import os
from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Any

from .errors import FieldError

__all__ = ["PAGE_SUFFIXES", "check_page_path", "html_page", "json_script", "package_text"]

#: The file suffixes of a page (any case).
PAGE_SUFFIXES = (".html", ".htm")


def check_page_path(path: str | os.PathLike[str], field: str) -> Path:
    """A page's file name, checked to end in ``.html`` or ``.htm`` (so that a browser opens
    it as a page).

    Parameters
    ----------
    path : str or path-like
        The file to write.
    field : str
        The argument's name, for the error.

    Returns
    -------
    pathlib.Path
        The path.

    Raises
    ------
    FieldError
        If the suffix is another (naming ``field``).
    """
    dest = Path(path)
    if dest.suffix.lower() not in PAGE_SUFFIXES:
        raise FieldError(field, f"expected a file name ending in .html or .htm, got {str(dest)!r}")
    return dest


def package_text(name: str) -> str:
    """The text of a file shipped in the package's ``web/`` folder (script, style, markup).

    Parameters
    ----------
    name : str
        File name in ``crlbswarm/web/``, e.g. ``"replay.js"``.

    Returns
    -------
    str
        Its text (UTF-8).
    """
    return (
        resources.files(__package__ or "crlbswarm")
        .joinpath("web")
        .joinpath(name)
        .read_text(encoding="utf-8")
    )


def json_script(data: Any, element_id: str) -> str:
    """A ``<script type="application/json">`` element holding ``data``, safe to inline.

    ``<``, ``>`` and ``&`` are written as JSON escapes, so no text in the data can close
    the element or open a comment; the page reads it back with
    ``JSON.parse(document.getElementById(element_id).textContent)``.

    Parameters
    ----------
    data : object
        JSON-ready data (no NaN or infinity: they are not JSON).
    element_id : str
        The element's ``id``.

    Returns
    -------
    str
        The element.
    """
    text = json.dumps(data, separators=(",", ":"), allow_nan=False, ensure_ascii=False)
    for char, escape in (("<", "\\u003c"), (">", "\\u003e"), ("&", "\\u0026")):
        text = text.replace(char, escape)
    return f'<script type="application/json" id="{html.escape(element_id)}">{text}</script>'


def html_page(title: str, style: str, body: str, scripts: Sequence[str]) -> str:
    """One self-contained HTML document: inline style and scripts, a policy that forbids
    loading anything (no network, no file), and an empty icon (no request for one).

    Parameters
    ----------
    title : str
        Plain text of the title (escaped here).
    style : str
        CSS.
    body : str
        Markup of the body (inserted as is).
    scripts : sequence of str
        Elements placed at the end of the body, in order (e.g. a :func:`json_script`, then
        ``<script>`` with the code).

    Returns
    -------
    str
        The document.

    Raises
    ------
    ValueError
        If the style or a script holds the closing tag of its element (it would end the
        element early; a bug of the page, not an input of the user).
    """
    if "</style" in style.lower():
        raise ValueError("style: holds '</style', which would end its element early")
    for element in scripts:  # each ends once: a '</script' in its code would end it early
        if element.lower().count("</script") != 1:
            raise ValueError("scripts: each must be one <script> element without '</script'")
    # Nothing from the network or the disk; inline code only ('unsafe-eval' lets test and
    # automation tools evaluate expressions in the page, e.g. Playwright's wait_for_function).
    policy = (
        "default-src 'none'; script-src 'unsafe-inline' 'unsafe-eval'; "
        "style-src 'unsafe-inline'; img-src data: blob:; connect-src 'none'"
    )
    return "\n".join(
        [
            "<!DOCTYPE html>",
            '<html lang="en">',
            "<head>",
            '<meta charset="utf-8">',
            f'<meta http-equiv="Content-Security-Policy" content="{policy}">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            '<link rel="icon" href="data:,">',
            f"<title>{html.escape(title)}</title>",
            f"<style>\n{style}\n</style>",
            "</head>",
            "<body>",
            body,
            *scripts,
            "</body>",
            "</html>",
            "",
        ]
    )
