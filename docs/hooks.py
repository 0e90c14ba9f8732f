"""MkDocs hook: the repository's README.md is the site's home page and CHANGELOG.md its
changelog page, their links into docs/ made relative to the site."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PAGES = {"index.md": ROOT / "README.md", "changelog.md": ROOT / "CHANGELOG.md"}


def on_page_markdown(markdown: str, page, config, files) -> str:
    """The text of the repository file behind a placeholder page, with docs/x.md links as x.md."""
    source = PAGES.get(page.file.src_uri)
    if source is None:
        return markdown
    text = source.read_text(encoding="utf-8")
    text = re.sub(r"\]\(docs/([^)]+)\)", r"](\1)", text)
    return text.replace("](CHANGELOG.md)", "](changelog.md)")
