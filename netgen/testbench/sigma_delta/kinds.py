"""The loop-filter kinds of the sigma-delta loop (FILTERS; re-exported as loop.FILTERS): a channel's
Design entry `filter` is {"kind": name, ...its coefficients}; each kind validates its [loop.filter]
table here and names the back ends that render it. A new kind: its module and one line in FILTERS.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...structure.reader import Reader, check_keys


@dataclass(frozen=True)
class FilterKind:
    """A loop-filter kind: `read(rd, where, table)` validates its [loop.filter] table into the
    channel's `filter` dict (with "kind"); `order` of the whole loop (the mechanics' two
    integrations included); `backends`: the --simulator names that render it."""
    read: Callable[[Reader, str, dict], dict]
    order: int
    backends: tuple[str, ...]
    help: str


def read_lead2(rd: Reader, where: str, t: dict) -> dict:
    """lead2: y[n] = lead prev[n] - cur[n] (lead None: the design's `lead`, --lead, default 0.8)."""
    check_keys(rd, where, t, ["kind", "lead"])
    lead = t.get("lead")
    if lead is not None and (isinstance(lead, bool) or not isinstance(lead, (int, float))
                             or not np.isfinite(lead) or abs(lead) > 10):
        raise rd.fail(f"{where}.lead", f"lead = {lead!r} must be a number in [-10, 10]",
                      "write lead = 0.8 (the zero of the lead compensator, y = lead*prev - cur)")
    return {"kind": "lead2", "lead": None if lead is None else float(lead)}


ALL_BACKENDS = ("ngspice", "ngspice-xspice", "vacask", "ngspice-osdi")
# loop-filter kinds by name (a channel's Design entry `filter`): a new kind is its module and one line here
FILTERS: dict[str, FilterKind] = {
    "lead2": FilterKind(read_lead2, 2, ALL_BACKENDS, "second-order electromechanical loop, lead compensator "
                        "y = lead*prev - cur (zero at z = lead)"),
}
