"""Small helpers that studies use to write their results into the docs.

This module owns only text output; it computes nothing.
"""
from __future__ import annotations

import re
from pathlib import Path

from symcushion.run.output_files import atomic_write_text

__all__ = ["write_section"]


def write_section(path, heading: str, body: str, title: str = "# Results") -> None:
    """Replace the ``## heading`` section of a Markdown file, or append it.

    Parameters
    ----------
    path : path-like
        The Markdown file; created with ``title`` as its first line if missing.
    heading : str
        Section heading without the ``## ``.
    body : str
        The new section text.
    title : str
        First line of a new file.
    """
    path = Path(path)
    text = path.read_text() if path.exists() else title + "\n"
    block = f"## {heading}\n\n{body.strip()}\n"
    pattern = re.compile(rf"^## {re.escape(heading)}\n.*?(?=^## |\Z)", re.S | re.M)
    if pattern.search(text):
        text = pattern.sub(lambda _: block + "\n", text, count=1).rstrip() + "\n"
    else:
        text = text.rstrip() + "\n\n" + block
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(path, text)      # a killed study leaves the old page whole
