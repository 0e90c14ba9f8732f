"""A TOML document as text: the writer of the structure files a sweep's runs build from (netgen.sweep.plan)
and of the documents rebuilt at a process point (netgen.sweep.point); below both, so neither imports the other
for it."""

from __future__ import annotations

import json
import math
from typing import Any


def to_toml(doc: dict) -> str:
    """A TOML document (tables, arrays of tables, scalars and arrays) as text."""

    def scalar(v: Any) -> str:
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, int):
            return str(v)
        if isinstance(v, float):
            return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
        if isinstance(v, str):
            return json.dumps(v, ensure_ascii=False)
        if isinstance(v, list):
            return "[" + ", ".join(scalar(x) for x in v) + "]"
        if isinstance(v, dict):
            return "{" + ", ".join(f"{json.dumps(k)} = {scalar(x)}" for k, x in v.items()) + "}"
        raise TypeError(f"cannot write {type(v).__name__} as TOML")

    def table(d: dict, name: str) -> list[str]:
        lines = [f"{json.dumps(k)} = {scalar(v)}" for k, v in d.items() if not _is_table(v)]
        out = [f"[{name}]", *lines, ""] if name else [*lines, ""]
        for k, v in d.items():
            sub = f"{name}.{json.dumps(k)}" if name else json.dumps(k)
            if isinstance(v, dict):
                out += table(v, sub)
            elif _is_table(v):
                for item in v:
                    out += [f"[[{sub}]]"] + table(item, sub)[1:]
        return out

    return "\n".join(table(doc, "")) + "\n"


def _is_table(v: Any) -> bool:
    return isinstance(v, dict) or (isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v))
