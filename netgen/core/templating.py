"""Jinja2 environment over the shipped templates (repo `templates/`, installed `netgen.templates`)."""

from __future__ import annotations

from functools import lru_cache
from importlib import resources

import jinja2

from .text import comment_lines, comment_text


@lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    """Strict environment: an undefined template variable is an error, never an empty string.
    Text from input files goes through the filters `comment(marker)` (comment lines) and
    `comment_text(marker)` (inside a comment line): netgen.core.text."""
    loader = jinja2.FunctionLoader(_load)
    env = jinja2.Environment(
        loader=loader, undefined=jinja2.StrictUndefined, keep_trailing_newline=True, autoescape=False
    )
    env.filters.update(comment=comment_lines, comment_text=comment_text)
    return env


def _load(name: str) -> str:
    return resources.files("netgen.templates").joinpath(name).read_text(encoding="utf-8")


def render(name: str, **context) -> str:
    """Render one template with the given context."""
    return environment().get_template(name).render(**context)
