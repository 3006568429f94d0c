"""The one place where text reaches the report's reStructuredText: escaping for rst and Jinja2.

Every string the report did not type itself — material names (from file
names), path and scene names, candidate labels and every other config
string, configuration file names, the database label, CSV cells read back
into claims — goes through :func:`text` (running text, list and table
cells) or :func:`literal` (file names shown in monospace).  Either renders
exactly the characters given, whatever they are:

* Whitespace (newlines, U+2028/2029, tabs, …) becomes single spaces, so a
  string cannot start a new line: no directive (``.. raw:: html``,
  ``.. include::``, ``.. image::``), no section, list, table, block quote or
  substitution definition.
* Every character that is neither a letter, a digit nor a space is
  backslash-escaped.  In rst a backslash makes any character stand for
  itself, so no inline markup (emphasis, literals, ``name_`` and
  ```text <javascript:…>`_`` references, ``:role:`…```, footnotes,
  substitutions) and no standalone hyperlink (``javascript:…``,
  ``http://…``, ``a@b.c``) can form, and no line can begin a block
  construct (``..``, ``-``, ``#.``, ``|``, ``+--``, ``::``).
* Control characters (C0, C1, DEL) are shown as ``\\xNN``; a NUL would
  otherwise reach docutils, which uses NUL internally for escapes.
* Snakemake renders captions with Jinja2 before docutils: an escaped text
  holds no ``{{``, ``{%`` or ``{#`` (the ``{`` is always followed by a
  backslash), so it cannot end the caption's ``{% raw %}`` block nor run
  template code.  :func:`jinja_raw` wraps a whole caption.

Docutils' HTML writer escapes ``<``, ``>`` and ``&`` itself, so the escaped
text reaches the page as text.  The tests render hostile names through
Jinja2 and docutils as Snakemake does and check that no raw HTML, script,
``javascript:`` link or included file survives.
"""

from __future__ import annotations

import unicodedata

__all__ = ["text", "literal", "jinja_raw"]


def _visible(ch: str) -> str:
    if unicodedata.category(ch) in ("Cc", "Cf"):  # controls; format characters (bidi overrides, zero width)
        return f"\\x{ord(ch):02x}" if ord(ch) < 0x100 else f"\\u{ord(ch):04x}"
    return ch


def text(value: object, *, empty: str = "–") -> str:
    """``value`` as rst text that renders literally (see the module docstring); ``empty`` if blank."""
    raw = " ".join(str(value).split())  # every Unicode whitespace, line and paragraph separators included
    raw = "".join(_visible(ch) for ch in raw)
    out = []
    for ch in raw:
        out.append(ch if ch == " " or ch.isalnum() else "\\" + ch)
    return "".join(out) or empty


def literal(value: object) -> str:
    """``value`` in monospace (rst ``:literal:`` role) rendering exactly its characters.

    Inside interpreted text a backslash escapes the next character as in
    running text, so the role's content is :func:`text`'s escaping; an
    empty value gives an en dash.
    """
    inner = text(value, empty="")
    return f":literal:`{inner}`" if inner else "–"


def jinja_raw(rst: str) -> str:
    """Protect a whole caption from Snakemake's Jinja2 pass (``{% raw %}`` … ``{% endraw %}``).

    Any ``{%`` in ``rst`` becomes ``{\\%`` first: Jinja2 then finds no tag
    inside (no early ``endraw``, with or without ``-`` or spaces), and rst
    shows ``{\\%`` as ``{%`` in running text.
    """
    return "{% raw %}" + rst.replace("{%", "{\\%") + "{% endraw %}"
