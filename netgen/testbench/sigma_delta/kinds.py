"""The loop-filter kinds of the sigma-delta loop (FILTERS; re-exported as loop.FILTERS): a channel's
Design entry `filter` is {"kind": name, ...its coefficients}; each kind validates its [loop.filter]
table here and names the back ends that render it. A new kind: its module and one line in FILTERS.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ...core.options import OptionError
from ...core.reader import Reader, check_keys
from . import filters
from .options import OPTIONS


@dataclass(frozen=True)
class FilterKind:
    """A loop-filter kind: `read(rd, where, table)` validates its [loop.filter] table into the
    channel's `filter` dict (with "kind"); `order` of the whole loop (the mechanics' two
    integrations included); `backends`: the --simulator names that render it."""

    read: Callable[[Reader, str, dict], dict]
    order: int
    backends: tuple[str, ...]
    help: str
    # design(model, d, ch, spec) -> the channel's `filter` dict, run inside loop.design() with the
    # Design built (None: the table's dict is the filter, e.g. lead2)
    design: Callable[..., dict] | None = None


def read_lead2(rd: Reader, where: str, t: dict) -> dict:
    """lead2: y[n] = lead prev[n] - cur[n] (lead None: the design's `lead`, --lead, default 0.8)."""
    check_keys(rd, where, t, ["kind", "lead"])
    lead = t.get("lead")
    if lead is not None:
        try:
            lead = OPTIONS["lead"].read(lead, f"{where}.lead")
        except OptionError as exc:
            raise rd.fail(
                f"{where}.lead", exc.problem, f"{exc.fix} (the zero of the lead compensator, y = lead*prev - cur)"
            ) from None
    return {"kind": "lead2", "lead": None if lead is None else float(lead)}


# H_inf of the designed kinds' NTF per loop order when the table gives none (bench/sigma_delta_orders.py
# on the z accelerometer, 65536 periods at -6 dBFS: the numpy loop of order 5 is lost at 1.4 under
# gravity alone and at 1.5 with a -20 dBFS tone on top; the compiled ngspice loop at 1.3 within 500
# periods (the reference holds 1.3); at 1.2 both hold. Order 4 holds 1.2-1.5 in the reference)
H_INF = {3: 1.5, 4: 1.4, 5: 1.2}
OSR_RANGE = (4.0, 4096.0)
H_INF_RANGE = (1.05, 3.0)


def number(rd: Reader, where: str, t: dict, key: str, lo: float, hi: float, fix: str) -> float | None:
    """An optional finite number in [lo, hi] (bools refused), else a LoopError with the fix."""
    v = t.get(key)
    if v is not None and (
        isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or not lo <= v <= hi
    ):
        raise rd.fail(f"{where}.{key}", f"{key} = {v!r} must be a number in [{lo:g}, {hi:g}]", fix)
    return None if v is None else float(v)


def read_designed(kind: str) -> Callable[[Reader, str, dict], dict]:
    """The reader of a designed kind (cifb, crfb): order 3-5 (default 4), osr (default 64) and
    h_inf (default H_INF[order]); the coefficients come from its design step (design_designed)."""

    def read(rd: Reader, where: str, t: dict) -> dict:
        check_keys(rd, where, t, ["kind", "order", "osr", "h_inf"])
        order = t.get("order", 4)
        if isinstance(order, bool) or not isinstance(order, int) or order not in filters.ORDERS:
            raise rd.fail(
                f"{where}.order",
                f"order = {order!r}: a {kind} electromechanical loop has order "
                f"{', '.join(map(str, filters.ORDERS))} (the mechanics' two integrations plus 1-3 "
                "electronic integrators)",
                'write order = 4, or kind = "lead2" for a second-order loop',
            )
        osr = number(rd, where, t, "osr", *OSR_RANGE, "write osr = 64 (the oversampling ratio f_s / (2 f_band))")
        h_inf = number(
            rd,
            where,
            t,
            "h_inf",
            *H_INF_RANGE,
            "write h_inf = 1.4 (the NTF's peak gain; Lee's rule: below 2 for a 1-bit quantizer)",
        )
        return {
            "kind": kind,
            "order": order,
            "osr": 64.0 if osr is None else osr,
            "h_inf": H_INF[order] if h_inf is None else h_inf,
        }

    return read


def design_designed(model, d, ch: dict, spec: dict) -> dict:
    """A designed kind's coefficients for one channel of the Design: the channel's mechanics from
    the MacroModel (filters.mechanics_of) and filters.design's NTF fit; `x0` the readout at rest,
    trimmed from the filter's input (an untrimmed rest offset upsets a higher-order loop at start-up)."""
    mech = filters.mechanics_of(model, d, ch["name"])
    f = filters.design(mech, spec["order"], spec["osr"], spec["h_inf"], spec["kind"])
    return {**f.as_dict(), "x0": float(mech.offset)}


ALL_BACKENDS = ("ngspice", "ngspice-xspice", "vacask", "ngspice-osdi")
STATE_SPACE_BACKENDS = ALL_BACKENDS  # the behavioural and OSDI loops too (ngspice.analog_filters)
# loop-filter kinds by name (a channel's Design entry `filter`): a new kind is its module and one line here
FILTERS: dict[str, FilterKind] = {
    "lead2": FilterKind(
        read_lead2,
        2,
        ALL_BACKENDS,
        "second-order electromechanical loop, lead compensator y = lead*prev - cur (zero at z = lead)",
    ),
    "cifb": FilterKind(
        read_designed("cifb"),
        5,
        STATE_SPACE_BACKENDS,
        "electromechanical loop of order 3-5, electronic integrators in cascade (all NTF zeros at DC)",
        design_designed,
    ),
    "crfb": FilterKind(
        read_designed("crfb"),
        5,
        STATE_SPACE_BACKENDS,
        "electromechanical loop of order 3-5 with a resonator (an optimised in-band NTF zero pair)",
        design_designed,
    ),
}
