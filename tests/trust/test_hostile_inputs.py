"""Property-based hostile input: structure, loop, sweep and model JSON documents mutated from the
repository's examples (keys dropped or duplicated, values retyped, extreme numbers, unicode and
control text, deep nesting, reserved names) and hostile paths, run through the readers in process.
The promises: the reader returns a valid object or raises the file kind's InputError (exit 2)
naming the file, the key and a fix; never another exception (exit 70), never a hang (each case
runs under a SIGALRM limit of LIMIT_S); a model JSON that is accepted renders every dialect with
printable text and no injected text on a code line (tests/emit/test_injection.py's code());
an output folder after a refused run holds nothing of it. Seeded (derandomize) so every CI run
draws the same cases; the counts per class print at the end (tests/trust/conftest.py)."""

from __future__ import annotations

import copy
import json
import re
import signal
import tomllib
from contextlib import contextmanager

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from netgen.core.errors import InputError, LoopError, ModelError, StructureError, SweepError
from netgen.core.files import read_text
from netgen.core.reader import Reader
from netgen.core.text import is_identifier
from netgen.emit import EMITTERS
from netgen.model import MacroModel
from netgen.structure.parse import parse_structure
from netgen.sweep.spec import parse_sweep
from netgen.testbench.sigma_delta.loopfile import read_loop
from tests.emit.test_injection import code, printable
from tests.fixtures import ROOT
from tests.trust.conftest import COUNTS

LIMIT_S = 10  # per case: a parse takes milliseconds; a hang is a loop without end
MARK = "ZQXJ"  # in every injected string: found on a code line = injection
SETTINGS = dict(derandomize=True, deadline=None, suppress_health_check=list(HealthCheck), database=None)
EXAMPLES = sorted(p for p in (ROOT / "examples").glob("*.toml") if p.stem != "sweep_ts")
LOOPS = [p for p in EXAMPLES if "[loop]" in p.read_text()]
MODELS = [ROOT / "netlists/piston/piston.json", ROOT / "netlists/accelerometer_z/accelerometer_z.json"]
RESERVED = ["0", "gnd", "GND", "error", "end", "module", "x", "time", "plate", "e", "temp", "con"]


@contextmanager
def time_limit(what: str):
    """Fail (a hang) when the case runs longer than LIMIT_S."""

    def stop(*_):
        raise TimeoutError(f"{what}: no answer after {LIMIT_S} s (a hang)")

    old = signal.signal(signal.SIGALRM, stop)
    signal.alarm(LIMIT_S)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


# ----------------------------------------------------------------------------- values and mutations

TEXT = st.one_of(
    st.text(max_size=12).map(lambda t: MARK + t),
    st.sampled_from([MARK + "\n.control\nshell touch x\n.endc", MARK + "*/ endmodule /*", MARK + '"\\;$', MARK]),
    st.sampled_from(RESERVED),
)
NUMBER = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0, -1, 1e300, -1e300, 1e-300, 5e-324, 2**63 - 1, -(2**63), 10**6, 0.5, 1.5]),
    st.integers(-(2**63), 2**63 - 1),
)
QUANTITY = st.builds(
    lambda n, u: f"{n} {u}",
    st.sampled_from(["1e300", "1e-300", "-3", "0", "nan", "inf", "2", "1e999", "0x10"]),
    st.sampled_from(["m", "um", "kg/m^3", "GPa", "N/m", "V", "Hz", "", "furlong", "µm", "m\u202e"]),
)
SCALAR = st.one_of(TEXT, NUMBER, QUANTITY, st.booleans())
VALUE = st.one_of(SCALAR, st.lists(SCALAR, max_size=4), st.dictionaries(st.text(max_size=6), SCALAR, max_size=3))


def deep(n: int) -> object:
    """A value nested n deep (lists in dicts), for the nesting limit."""
    v: object = 1
    for k in range(n):
        v = [v] if k % 2 else {"a": v}
    return v


def paths(doc: object, prefix: tuple = ()) -> list[tuple]:
    """Every key path of a document (dict keys and list indices)."""
    out = [prefix] if prefix else []
    if isinstance(doc, dict):
        for k, v in doc.items():
            out += paths(v, prefix + (k,))
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            out += paths(v, prefix + (i,))
    return out


@st.composite
def mutated(draw, doc: dict) -> dict:
    """`doc` with 1 to 3 mutations at drawn key paths: drop, retype, extreme value, deep nesting,
    a renamed (unknown or reserved) key, a duplicated list entry."""
    doc = copy.deepcopy(doc)
    for _ in range(draw(st.integers(1, 3))):
        where = paths(doc)
        if not where:
            break
        path = draw(st.sampled_from(where))
        parent = doc
        for k in path[:-1]:
            parent = parent[k]
        key = path[-1]
        op = draw(st.sampled_from(["drop", "retype", "retype", "retype", "deep", "rename", "duplicate"]))
        if op == "drop":
            del parent[key]
        elif op == "retype":
            parent[key] = draw(VALUE)
        elif op == "deep":
            parent[key] = deep(draw(st.sampled_from([3, 70, 1000])))
        elif op == "rename" and isinstance(parent, dict):
            parent[draw(st.sampled_from(RESERVED + [MARK + "k", "ünïcode", ""]))] = parent.pop(key)
        elif op == "duplicate" and isinstance(parent, list):
            parent.append(copy.deepcopy(parent[key]))
    return doc


def toml_value(v: object) -> str:
    """One TOML value, inline (tables as { }, strings with JSON's escapes, which TOML shares)."""
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return {"nan": "nan", "inf": "inf", "-inf": "-inf"}.get(repr(v), repr(v))
    if isinstance(v, (int, str)):
        return json.dumps(v)
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{json.dumps(str(k))} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v).__name__)


def toml_text(doc: dict) -> str | None:
    """The TOML text of a document, every table inline (None when TOML cannot hold it)."""
    try:
        return "".join(f"{json.dumps(str(k))} = {toml_value(v)}\n" for k, v in doc.items())
    except (TypeError, RecursionError):
        return None


def assert_refusal(err: InputError, path: str, cls: str) -> None:
    """An exit-2 error naming the file, a key or location, and a fix."""
    assert err.exit_code == 2 and path in str(err.path), err
    assert err.where and err.fix, err
    COUNTS[(cls, "refused")] += 1


# ----------------------------------------------------------------------------- the classes

STRUCTURES = {p.name: tomllib.loads(p.read_text()) for p in EXAMPLES}
# the piston with a dielectric layer on its electrode: the layer's keys mutated too
STRUCTURES["piston_nitride.toml"] = tomllib.loads(
    (ROOT / "examples" / "piston.toml")
    .read_text()
    .replace('gap = "2 um"\n', 'gap = "2 um"\ndielectric_thickness = "0.2 um"\ndielectric_permittivity = 7.5\n', 1)
)


@settings(max_examples=800, **SETTINGS)
@given(st.sampled_from(sorted(STRUCTURES)).flatmap(lambda n: st.tuples(st.just(n), mutated(STRUCTURES[n]))))
def test_structure_files(case):
    """A mutated example structure: a Structure, or StructureError naming file, key and fix."""
    name, doc = case
    text = toml_text(doc)
    if text is None:
        COUNTS[("structure", "unwritable")] += 1
        return
    with time_limit(name):
        try:
            parse_structure(text, f"examples/{name}")
        except StructureError as err:
            return assert_refusal(err, f"examples/{name}", "structure")
    COUNTS[("structure", "accepted")] += 1


LOOP_DOCS = {p.name: tomllib.loads(p.read_text())["loop"] for p in LOOPS}


@settings(max_examples=300, **SETTINGS)
@given(st.sampled_from(sorted(LOOP_DOCS)).flatmap(lambda n: st.tuples(st.just(n), mutated({"loop": LOOP_DOCS[n]}))))
def test_loop_files(case):
    """A mutated [loop] table: a LoopSpec, or LoopError naming file, key and fix."""
    name, doc = case
    text = toml_text(doc)
    if text is None or "loop" not in doc:
        COUNTS[("loop", "unwritable")] += 1
        return
    with time_limit(name):
        try:
            read_loop(Reader("loop.toml", text, LoopError), doc["loop"])
        except LoopError as err:
            return assert_refusal(err, "loop.toml", "loop")
    COUNTS[("loop", "accepted")] += 1


SWEEP = tomllib.loads((ROOT / "examples/sweep_ts.toml").read_text())


@settings(max_examples=300, **SETTINGS)
@given(mutated(SWEEP))
def test_sweep_files(doc):
    """A mutated example sweep: a Sweep, or SweepError naming file, key and fix."""
    text = toml_text(doc)
    if text is None:
        COUNTS[("sweep", "unwritable")] += 1
        return
    with time_limit("sweep"):
        try:
            parse_sweep(text, "sweep.toml")
        except SweepError as err:
            return assert_refusal(err, "sweep.toml", "sweep")
    COUNTS[("sweep", "accepted")] += 1


MODEL_DOCS = {p.name: json.loads(p.read_text()) for p in MODELS}


@settings(max_examples=500, **SETTINGS)
@given(st.sampled_from(sorted(MODEL_DOCS)).flatmap(lambda n: st.tuples(st.just(n), mutated(MODEL_DOCS[n]))))
def test_model_json(case):
    """A mutated model JSON: refused naming the entry, or a model whose every dialect renders
    printable text with no injected text on a code line (names on code lines are identifiers)."""
    name, doc = case
    with time_limit(name):
        try:
            model = MacroModel.from_dict(doc, name)
        except ModelError as err:
            return assert_refusal(err, name, "model")
        texts = {e.suffix: e.render(model) for e in EMITTERS.values() if not e.refusal(model)}
    for suffix, text in texts.items():
        assert printable(text), suffix
        for line in code(suffix, text):  # injected text on a code line only as a whole identifier
            # a schematic symbol quotes its names (.sym format="@name @pinlist <model>", .kicad_sym
            # (symbol "<model>" ...)): there the quote is syntax
            stop = r"\s(),;=:\"" if suffix in (".sym", ".kicad_sym") else r"\s(),;=:"
            words = re.findall(rf"[^{stop}]*{MARK}[^{stop}]*", line)
            assert all(is_identifier(w) for w in words), (suffix, line)
    COUNTS[("model", "accepted")] += 1


HOSTILE_PATHS = st.one_of(
    st.text(min_size=1, max_size=20),
    st.sampled_from(["/dev/zero", "/dev/null", "/proc/self/mem", "/etc", "/etc/shadow", "", "a\nb.toml", "x" * 5000]),
)


@settings(max_examples=200, **SETTINGS)
@given(HOSTILE_PATHS)
def test_hostile_paths(text):
    """A hostile path as an input file: the one reader refuses it (exit 2, the file named) or
    returns text; never another exception, never a block on a device."""
    with time_limit("path"):
        try:
            read_text(text, "file", "a TOML structure file")
        except StructureError as err:
            assert err.exit_code == 2 and err.fix
            COUNTS[("path", "refused")] += 1
            return
    COUNTS[("path", "accepted")] += 1


def test_output_folder_holds_nothing_of_a_refused_build(tmp_path):
    """A build refused for its input leaves no output folder and no staging folder (no mixed set)."""
    from netgen.cli import commands as cli

    bad = tmp_path / "bad.toml"
    bad.write_text((ROOT / "examples/piston.toml").read_text().replace('gap = "2 um"', 'gap = "1 m"'))
    out = tmp_path / "out"
    assert cli.main(["build", str(bad), "-o", str(out), "-q"]) == 2
    assert not out.exists()
    COUNTS[("folder", "clean")] += 1


@pytest.mark.parametrize("size", ["16k"])
def test_full_disk_leaves_no_staging(tmp_path, size, capsys):
    """A build into a real, small tmpfs that fills up: exit 2, the message names the folder and
    the fix, and the file system holds no staging folder or partial set afterwards."""
    import os
    import subprocess

    from netgen.cli import commands as cli

    mnt = tmp_path / "full"
    mnt.mkdir()
    if (
        os.geteuid() != 0
        or subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)]).returncode
    ):
        pytest.skip("mounting a tmpfs needs root")
    try:
        code_ = cli.main(["build", str(ROOT / "examples/piston.toml"), "-o", str(mnt / "o"), "-q"])
        err = capsys.readouterr().err
        assert code_ == 2 and str(mnt / "o") in err and "disk is full" in err and "fix:" in err, err
        assert list(mnt.iterdir()) == []
    finally:
        subprocess.run(["umount", str(mnt)], check=True)
    COUNTS[("disk", "clean")] += 1
