"""What every process text asks first: does the model carry process laws, does it declare a
parameter, and a cubic's text (netgen.emit.process and netgen.emit.process_etch build on them)."""

from __future__ import annotations

from ..model import MacroModel
from .common import num


def enabled(model: MacroModel) -> bool:
    """The model carries process laws (its structure has [process]): without them every emitted
    text is the one of a model without process parameters."""
    return bool(model.process.get("coordinates"))


def declared(model: MacroModel, name: str) -> bool:
    """The structure's [process] declares parameter `name` (dg, tscale, escale, temp)."""
    return enabled(model) and name in model.process.get("parameters", [])


def poly(coeffs: list[float], x: str) -> str:
    """c0 + c1 x + c2 x^2 + c3 x^3 as products (no power operator: the dialects differ)."""
    terms = [f"{num(c)}" + "".join(f"*{x}" for _ in range(k)) for k, c in enumerate(coeffs) if c != 0.0]
    return "(" + (" + ".join(terms) if terms else "0") + ")"
