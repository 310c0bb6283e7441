"""Plain text (scene names, descriptions, reasons) made safe for Markdown.

A scene file is data a user wrote: its description may hold ``|`` (which would split a
table cell), HTML tags (which a Markdown viewer would render or run) or line breaks. These
functions make such text display literally.
"""

from __future__ import annotations

__all__ = ["cell", "text"]


def text(value: object) -> str:
    """``value`` as literal Markdown text: HTML special characters become entities."""
    return (
        str(value)
        .replace("&", "&amp;")
        .replace("<", "&lt;")
        .replace(">", "&gt;")
        .replace("\r", " ")
        .replace("\n", " ")
    )


def cell(value: object) -> str:
    """``value`` as the literal content of one Markdown table cell (``|`` escaped too)."""
    return text(value).replace("\\", "\\\\").replace("|", "\\|")
