"""Jinja2 environment over the shipped templates (repo `templates/`, installed `netgen.templates`)."""

from __future__ import annotations

from functools import lru_cache
from importlib import resources

import jinja2


@lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    """Strict environment: an undefined template variable is an error, never an empty string."""
    loader = jinja2.FunctionLoader(_load)
    return jinja2.Environment(loader=loader, undefined=jinja2.StrictUndefined, keep_trailing_newline=True,
                              autoescape=False)


def _load(name: str) -> str:
    return resources.files("netgen.templates").joinpath(name).read_text(encoding="utf-8")


def render(name: str, **context) -> str:
    """Render one template with the given context."""
    return environment().get_template(name).render(**context)
