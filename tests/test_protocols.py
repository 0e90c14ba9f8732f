"""Every registered plug-in satisfies its kind's declared interface (a typing.Protocol): the
registry's entries have each member the protocol declares, callable with the protocol's
parameters. The checker is shown to fail on planted misfits first, so these tests can fail."""

from __future__ import annotations

import inspect
from typing import Any, Protocol

import pytest

from netgen import electrostatics, emit, mechanics, sim, testbench
from netgen.structure import conductors


def members(proto: type) -> dict[str, Any]:
    """The methods a protocol declares (its own and its bases', `__call__` included)."""
    out: dict[str, Any] = {}
    for klass in reversed(proto.__mro__):
        if klass in (object, Protocol, Any) or not getattr(klass, "_is_protocol", False):
            continue
        for name, value in vars(klass).items():
            if name.startswith("_") and name != "__call__":
                continue
            if isinstance(value, classmethod | staticmethod):
                value = value.__func__
            if callable(value):
                out[name] = value
    return out


def parameters(fn: Any, drop_first: bool) -> list[inspect.Parameter]:
    """The parameters a caller passes (without self/cls)."""
    params = list(inspect.signature(fn).parameters.values())
    return params[1:] if drop_first and params else params


def misfits(obj: Any, proto: type) -> list[str]:
    """Why `obj` (a class, module, function or instance) does not satisfy `proto`: missing members
    and members that cannot be called with the protocol's positional parameters by name."""
    out = []
    for name, declared in members(proto).items():
        target = obj if name == "__call__" and not isinstance(obj, type) else getattr(obj, name, None)
        if target is None or not callable(target):
            out.append(f"no {name}")
            continue
        wanted = parameters(declared, drop_first=True)
        try:
            sig = inspect.signature(target)
        except (TypeError, ValueError):
            continue  # a builtin without a signature: presence is all we can check
        # a plain method read off a class still takes the instance first
        unbound = isinstance(obj, type) and inspect.isfunction(inspect.getattr_static(obj, name, None))
        try:
            sig.bind(*(["self"] if unbound else []), *[p.name for p in wanted if p.kind is not p.KEYWORD_ONLY])
        except TypeError as exc:
            out.append(f"{name}: takes {sig}, the protocol passes ({', '.join(p.name for p in wanted)}): {exc}")
    return out


REGISTRIES = [
    ("conductor kind", conductors.CONDUCTORS, conductors.ConductorKind),
    ("mechanics", mechanics.KINDS, mechanics.MechanicsKind),
    ("extractor", electrostatics.EXTRACTORS, electrostatics.ExtractorBuilder),
    ("emitter render", {k: e.render for k, e in emit.EMITTERS.items()}, emit.Render),
    ("emitter refusal", {k: e.refusal for k, e in emit.EMITTERS.items()}, emit.Refusal),
    ("emitter outputs", {k: e.extra for k, e in emit.EMITTERS.items() if e.extra}, emit.Outputs),
    ("simulator run", {k: s.run for k, s in sim.SIMULATORS.items()}, sim.RunNetlist),
    ("simulator run_file", {k: s.run_file for k, s in sim.SIMULATORS.items() if s.run_file}, sim.RunFile),
    ("testbench", testbench.TESTBENCHES, testbench.TestbenchCommand),
]


@pytest.mark.parametrize("kind, registry, proto", REGISTRIES, ids=[r[0] for r in REGISTRIES])
def test_every_registered_entry_satisfies_its_protocol(kind, registry, proto):
    assert registry, f"the {kind} registry is empty"
    bad = {name: why for name, entry in registry.items() if (why := misfits(entry, proto))}
    assert bad == {}, f"{kind} entries that do not satisfy {proto.__name__}: {bad}"


# ----------------------------------------------------------------------------- the checker can fail


class Shape(Protocol):
    def area(self, scale: float) -> float: ...

    @classmethod
    def read(cls, text: str) -> Shape: ...


class Builder(Protocol):
    def __call__(self, s: Any, plate: Any) -> Any: ...


def test_checker_finds_a_missing_member_and_a_wrong_arity():
    class NoRead:
        def area(self, scale):
            return scale

    class Narrow:
        def area(self):
            return 1.0

        @classmethod
        def read(cls, text):
            return cls()

    assert misfits(NoRead, Shape) == ["no read"]
    assert misfits(Narrow, Shape)[0].startswith("area: takes (self)")


def test_checker_reads_functions_and_modules():
    def one(s):
        return s

    def two(s, plate):
        return s

    assert misfits(two, Builder) == []
    assert misfits(one, Builder)[0].startswith("__call__: takes (s)")
    assert misfits(mechanics.piston, mechanics.MechanicsKind) == []
    assert misfits(emit, mechanics.MechanicsKind) == ["no mechanics"]
