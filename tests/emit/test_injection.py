"""Text from input files is data, never code: generated hostile strings through every field that
carries text into every format netgen writes.

Fields: the structure file's description and file name, [import] mode labels, the model JSON's
names and strings, a sweep file's structure values and the structure path its runs' files name.
Formats: every registered emitter (.lib, _xspice.lib, .va, ...), the sigma-delta ngspice and VACASK
netlists, a sweep run's structure file. Each hostile string is either refused when it is read
(an InputError naming the field, exit 2 from the command line), or the emitted files' code (their
lines without comments, stripped here by an independent reading of each dialect's comment rules)
equals the benign baseline's, every emitted character is printable, and the real tools execute
nothing: ngspice 39 and 46 load every emitted .lib (`shell touch FLAG` never creates FLAG, the
testbench's `.param vdd=1` stays 1, the operating point equals the baseline's) and openvaf-r
compiles the .va with no second module. The emitters' own guard is tested without the readers:
the hostile text put straight into a MacroModel.
"""

from __future__ import annotations

import json
import re
import subprocess
import tomllib
import unicodedata
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from netgen import export as importers
from netgen.build import build
from netgen.cli import commands as cli
from netgen.core.errors import InputError, ModelError, StructureError, SweepError
from netgen.emit import EMITTERS
from netgen.mechanics.imported import read_modes
from netgen.model import MacroModel
from netgen.model.plots import mode_shapes
from netgen.sim.vacask import compile_va
from netgen.structure import load_structure, parse_structure
from netgen.sweep.plan import plan
from netgen.sweep.spec import parse_sweep
from netgen.testbench.sigma_delta import ngspice as sd_ngspice
from netgen.testbench.sigma_delta import vacask as sd_vacask
from netgen.testbench.sigma_delta.loop import design
from tests.fixtures import NETLISTS, NGSPICE, ROOT

PISTON = ROOT / "examples" / "piston.toml"
BREAKS = ["\n", "\r", "\r\n", "\u2028", "\u2029", "\x85", "\x0b", "\x0c", "\x1c"]
BAD_CATEGORIES = {"Cc", "Cf", "Zl", "Zp", "Co", "Cs", "Cn"}  # control, format, separators, private, unassigned


def hostile(flag: Path) -> list[str]:
    """The hostile strings: SPICE cards, a .control block that touches `flag`, Verilog-A modules,
    directives and comment ends, quotes and shell characters, each alone (printable: accepted as
    free text) and wrapped in every kind of line break (refused), NUL, and very long strings."""
    touch = f"shell touch {flag}"
    payloads = [
        f".control\n{touch}\n.endc",
        ".param vdd=99",
        ".options reltol=0.5",
        "Rinj drive 0 1",
        f"*#{touch}",
        f"#{touch}",
        "+ drive 0 1",
        EVIL_VA,
        '`include "/etc/hostname"',
        "`define piston evil_module",
        "module evil_module; endmodule",
        "\"quoted\" 'single' $HOME ; $(touch x) `x` trailing \\",
    ]
    out = [p for p in payloads if "\n" not in p]
    out += [b + p.replace("\n", b) + b for p in payloads for b in BREAKS]
    out += [
        f"\x00{touch}",
        f"a\x00\n{touch}",
        "\t.param vdd=99",
        "\x1b[2J\x1b[31mred",
        "\u202e.param vdd=99",
        "µ 日本 ü ∂ –",
        "A b " * 25_000,
        (f".control {touch} .endc ") * 2_000,
        (f"\n.control\n{touch}\n.endc") * 500,
    ]
    return out


def control_block(flag: Path) -> str:
    """The injection of the report: a TOML "\\n" ends the header comment and runs a shell command."""
    return f"\n.control\nshell touch {flag}\n.endc\n.param vdd=99\n"


EVIL_VA = "*/ module evil_module(); endmodule /*"


SPICE_CARD = '"\\;$'  # what a double-quoted ngspice .include path cannot hold (tests/test_trust_paths.py)


def refusable(text: str) -> bool:
    """Independent expectation: text with a control, format or separator character is refused."""
    return any(unicodedata.category(ch) in BAD_CATEGORIES for ch in text)


def toml_string(text: str) -> str:
    """`text` as a TOML basic string (the escapes TOML requires for quotes, backslash, controls)."""
    body = re.sub(
        r'["\\]|[\x00-\x1f\x7f-\x9f]',
        lambda m: "\\" + m.group() if m.group() in '"\\' else f"\\u{ord(m.group()):04x}",
        text,
    )
    return f'"{body}"'


# ----------------------------------------------------------------------------- each dialect's code lines


def spice_code(text: str) -> list[str]:
    """The lines ngspice reads as cards: split at newlines only (what ngspice does), without the
    lines whose first character is '*' (comments) and blank lines."""
    return [ln for ln in text.split("\n") if ln.strip() and not ln.startswith("*")]


def c_code(text: str) -> list[str]:
    """Verilog-A / VACASK / C text without // and /* */ comments (outside "strings"), by line."""
    out, i, n, string = [], 0, len(text), False
    while i < n:
        ch = text[i]
        if string:
            out.append(ch)
            string = ch != '"' or text[i - 1] == "\\"
        elif text.startswith("//", i):
            i = text.find("\n", i)
            i = n if i < 0 else i
            continue
        elif text.startswith("/*", i):
            end = text.find("*/", i + 2)
            i = n if end < 0 else end + 2
            continue
        else:
            out.append(ch)
            string = ch == '"'
        i += 1
    return [ln.rstrip() for ln in "".join(out).split("\n") if ln.strip()]


def code(name: str, text: str) -> list[str]:
    """The code lines of an emitted file, by its dialect (.va, VACASK and the FMU's C: C-like comments)."""
    return c_code(text) if name.endswith((".va", ".sim", ".c")) else spice_code(text)


def printable(text: str) -> bool:
    """Every character a newline or printable (no CR, NUL, U+2028, bidi override ...)."""
    return all(unicodedata.category(ch) not in BAD_CATEGORIES for ch in re.findall(r"[^\n -~]", text))


def emitted(model: MacroModel) -> dict[str, str]:
    """Every registered emitter's text of `model`, by file name (the dialects the model has)."""
    return {f"{model.name}{e.suffix}": e.render(model) for f, e in EMITTERS.items() if not e.refusal(model)}


def assert_inert(variants: list[MacroModel], baseline: dict[str, str]) -> list[dict[str, str]]:
    """Each variant's files: all printable, code lines equal to the baseline's; returns the texts."""
    out = []
    for k, model in enumerate(variants):
        texts = emitted(model)
        assert texts.keys() == baseline.keys()
        for name, text in texts.items():
            assert printable(text), f"variant {k}: {name} holds a control character"
            assert code(name, text) == code(name, baseline[name]), f"variant {k}: {name} code changed"
        out.append(texts)
    return out


# ----------------------------------------------------------------------------- the real tools

OP_BENCH = """* injection check {k}
.param vdd=1
.include {lib}
X1 drive plate f_z x_z piston
Vd drive 0 {{vdd}}
Vp plate 0 0
Vf f_z 0 0
.end
"""


def run_ngspice(libs: list[str], folder: Path, flag: Path) -> None:
    """Every .lib text in ngspice 39 and 46, one process per release sourcing one bench per .lib
    (the baseline first): nothing executed, vdd and the operating point as in the baseline."""
    folder.mkdir(parents=True, exist_ok=True)
    lines = ["* injection driver", ".control"]
    for k, text in enumerate(libs):
        (folder / f"v{k}.lib").write_text(text, encoding="utf-8")
        (folder / f"v{k}.cir").write_text(OP_BENCH.format(k=k, lib=folder / f"v{k}.lib"), encoding="utf-8")
        lines += [f"source {folder / f'v{k}.cir'}", "op", f"echo netgen-variant {k}", "print v(drive) v(x_z)"]
    # `quit 0`: ngspice 39 exits 1 after a .control-only deck even when every command worked
    (folder / "driver.cir").write_text("\n".join(lines + ["quit 0", ".endc", ".end", ""]), encoding="utf-8")
    for release, exe in NGSPICE.items():
        if release != "39" and not Path(exe).exists():
            pytest.fail(f"ngspice {release} is missing at {exe}: run .ci/setup")
        done = subprocess.run(
            [exe, "-b", str(folder / "driver.cir")], cwd=folder, capture_output=True, text=True, timeout=120
        )
        assert done.returncode == 0, done.stdout[-2000:] + done.stderr[-2000:]
        blocks = done.stdout.split("netgen-variant ")[1:]
        assert len(blocks) == len(libs), f"ngspice {release}: {len(blocks)} of {len(libs)} benches ran"
        values = [re.findall(r"v\((drive|x_z)\) = (\S+)", b) for b in blocks]
        assert values[0][0] == ("drive", "1.000000e+00")
        assert all(v == values[0] for v in values), f"ngspice {release}: a bench changed"
        assert not flag.exists(), f"ngspice {release} executed a shell command from a .lib"


def compile_vas(vas: list[str], folder: Path) -> None:
    """openvaf-r (warnings denied) compiles each .va into an OSDI holding only the model's module."""
    folder.mkdir(parents=True, exist_ok=True)
    for k, text in enumerate(vas):
        va = folder / f"v{k}.va"
        va.write_text(text, encoding="utf-8")
        osdi, _ = compile_va(va, folder / f"v{k}.osdi")
        assert b"evil_module" not in osdi.read_bytes(), f"variant {k}: a second module was compiled"


# ----------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def piston_build():
    """The piston's build (0.1 s): the tiny model every variant starts from."""
    return build(parse_structure(PISTON.read_text(encoding="utf-8"), "examples/piston.toml"))


@pytest.fixture(scope="module")
def piston(piston_build) -> MacroModel:
    return piston_build.model


@pytest.fixture
def flag(tmp_path) -> Path:
    return tmp_path / "PWNED"


def with_text(model: MacroModel, text: str) -> MacroModel:
    """The model with `text` in every free-text field at once (description, source, generator,
    every coordinate's label): the emitters' guard with no reader in front of it."""
    return replace(
        model,
        description=text,
        source=text,
        generator=text,
        coordinates=[replace(c, label=text) for c in model.coordinates],
    )


# ----------------------------------------------------------------------------- the emitters' own guard


def test_emitters_write_any_text_inert_without_the_readers(piston, flag, tmp_path):
    """Every hostile string in every free-text field of a MacroModel: every format's code lines
    unchanged, nothing non-printable written; ngspice 39 and 46 run every .lib, openvaf-r compiles
    the .va of every payload and every kind of line break; nothing executes. A hostile name is
    refused by every emitter."""
    strings = hostile(flag)
    base = emitted(piston)
    texts = assert_inert([with_text(piston, h) for h in strings], base)
    assert any("shell touch" in t[f"{piston.name}.lib"] for t in texts)  # the payloads are there
    run_ngspice([base[f"{piston.name}.lib"]] + [t[f"{piston.name}.lib"] for t in texts], tmp_path / "ng", flag)
    # openvaf-r (0.1-0.3 s each) on the Verilog-A payloads as they are, and one per kind of line break
    va_payloads = [EVIL_VA, '`include "/etc/hostname"', "`define piston evil_module", "module evil_module; endmodule"]
    picks = [strings.index(p) for p in va_payloads] + [strings.index(b + va_payloads[3] + b) for b in BREAKS[:4]]
    compile_vas([base[f"{piston.name}.va"]] + [texts[k][f"{piston.name}.va"] for k in picks], tmp_path / "va")
    for h in strings[:8] + ["x\n", "piston\n.control"]:
        for e in EMITTERS.values():
            with pytest.raises(ValueError, match="not usable"):
                e.render(replace(piston, name=h))


# ----------------------------------------------------------------------------- read time: structure files


def test_structure_description_and_file_name_are_refused_or_inert(piston, flag, tmp_path):
    """The description (a TOML string) and the structure file's own name: refused with the field
    named exactly when the string holds a control or separator character; otherwise copied as
    is, and every format's code lines equal the baseline's; ngspice runs the accepted .libs."""
    text = PISTON.read_text(encoding="utf-8")
    accepted, refused = [], 0
    for h in hostile(flag):
        doc = re.sub(r"(?m)^description = .*$", lambda _: "description = " + toml_string(h), text)
        try:
            s = parse_structure(doc, "piston.toml")
        except StructureError as err:
            assert err.where == "description" and "description" in str(err) and err.fix, str(err)
            refused += 1
            continue
        assert not refusable(h) and s.description == h
        accepted.append(replace(piston, description=s.description))
    names = [h for h in hostile(flag) if "/" not in h and "\x00" not in h and len(h.encode()) < 200]
    for k, h in enumerate(names):
        path = tmp_path / f"p{k}{h}.toml"
        path.write_text(text, encoding="utf-8")
        try:
            s = load_structure(path)
        except StructureError as err:
            assert err.where == "file name" and refusable(h) and err.fix, str(err)
            refused += 1
            continue
        assert not refusable(h) and s.source == str(path)
        accepted.append(replace(piston, source=s.source))
    assert refused == sum(map(refusable, hostile(flag))) + sum(map(refusable, names))
    texts = assert_inert(accepted, emitted(piston))
    run_ngspice(
        [emitted(piston)[f"{piston.name}.lib"]] + [t[f"{piston.name}.lib"] for t in texts], tmp_path / "ng", flag
    )


def test_build_command_refuses_a_hostile_description_and_writes_nothing(flag, tmp_path, capsys):
    """`netgen build` of a structure whose description carries a .control block: exit 2, the
    message names the file, the line and the field, and no output folder appears."""
    evil = tmp_path / "evil.toml"
    evil.write_text(
        re.sub(
            r"(?m)^description = .*$",
            lambda _: "description = " + toml_string(control_block(flag)),
            PISTON.read_text(encoding="utf-8"),
        ),
        encoding="utf-8",
    )
    assert cli.main(["build", str(evil), "-o", str(tmp_path / "out"), "-q", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert f"{evil}:4: description:" in err and "fix:" in err
    assert not (tmp_path / "out").exists() and not flag.exists()


def test_imported_mode_labels_are_refused_or_inert(piston_build, piston, flag, tmp_path):
    """Mode labels of an imported modes.npz: refused with import.modes.labels[0] named when they
    hold a control character, else carried into the header's coordinate table only as comment
    text (one full [import] build checks the path through the pipeline), and the mode-shape figure
    draws a label as text, not mathtext."""
    importers.export(piston_build, tmp_path)
    with np.load(tmp_path / "modes.npz") as z:
        arrays = {k: z[k] for k in z.files}
    accepted = []
    for h in hostile(flag):
        np.savez(tmp_path / "modes.npz", **(arrays | {"labels": np.array([h])}))
        label = str(np.array([h])[0])  # numpy drops trailing NULs
        try:
            data = read_modes(tmp_path / "modes.npz")
        except StructureError as err:
            assert err.where == "import.modes.labels[0]" and refusable(label) and err.fix, str(err)
            continue
        assert not refusable(label) and list(data["labels"]) == [label]
        accepted.append(replace(piston, coordinates=[replace(c, label=label) for c in piston.coordinates]))
    assert 0 < len(accepted) < len(hostile(flag))
    np.savez(tmp_path / "modes.npz", **(arrays | {"labels": np.array([EVIL_VA])}))
    imp = '\n[import]\nmass_matrix = "M.mtx"\nstiffness_matrix = "K.mtx"\nmodes = "modes.npz"\n'
    model = build(parse_structure(PISTON.read_text(encoding="utf-8") + imp, str(tmp_path / "piston.toml"))).model
    assert model.coordinates[0].label == EVIL_VA
    lib = emitted(model)[f"{piston.name}.lib"]
    assert "translation */ module evil_module" in lib
    assert_inert(accepted, emitted(piston))
    mode = replace(model.coordinates[0], kind="mode", label="$\\undefinedcmd$ $x^$")  # mathtext would fail
    png = mode_shapes(
        tmp_path / "modes.png", replace(model, coordinates=[mode]), piston_build.mechanics.basis, 100e-6, []
    )
    assert png.stat().st_size > 0


# ----------------------------------------------------------------------------- read time: model JSON

NAME_FIELDS = [
    "name",
    "plate",
    "coordinates.0.name",
    "coordinates.0.kind",
    "coordinates.0.unit",
    "electrodes.0.name",
    "capacitances.0.electrode",
    "capacitances.0.target",
    "sampling.samples",
]
TEXT_FIELDS = [
    "description",
    "source",
    "generator",
    "coordinates.0.label",
    "electrodes.0.group",
    "report.electrostatics.extractor",
    "contact.points.0.electrode",
]


def set_field(doc: dict, field: str, value: str) -> dict:
    """A copy of the JSON document with the dotted `field` (list indices as numbers) set."""
    doc = json.loads(json.dumps(doc))
    *path, last = field.split(".")
    target = doc
    for part in path:
        target = target[int(part)] if isinstance(target, list) else target[part]
    target[int(last) if isinstance(target, list) else last] = value
    return doc


def test_model_json_names_and_text_are_refused_or_inert(piston, flag, tmp_path):
    """Every hostile string in every name and text field of a model JSON: names (written outside
    comments) are always refused, text is refused exactly when it holds a control character, each
    ModelError naming the entry; the accepted models emit the baseline's code lines."""
    doc = json.loads(piston.json_text())
    accepted = []
    for field in NAME_FIELDS + TEXT_FIELDS:
        where = re.sub(r"\.(\d+)", r"[\1]", field)
        for h in hostile(flag):
            try:
                model = MacroModel.from_dict(set_field(doc, field, h), "piston.json")  # load_json's check
            except ModelError as err:
                assert err.where == where and err.fix and (field in NAME_FIELDS or refusable(h)), str(err)
                continue
            assert field in TEXT_FIELDS and not refusable(h)
            accepted.append(model)
    assert len(accepted) == len(TEXT_FIELDS) * sum(not refusable(h) for h in hostile(flag))
    texts = assert_inert(accepted, emitted(piston))
    run_ngspice(
        [emitted(piston)[f"{piston.name}.lib"]] + [t[f"{piston.name}.lib"] for t in texts], tmp_path / "ng", flag
    )


def test_sigma_delta_refuses_a_hostile_model_json(flag, tmp_path, capsys):
    """`netgen sigma-delta --model` with a JSON whose description carries a .control block: exit 2,
    the message names the JSON and the entry, before anything is simulated or written."""
    doc = set_field(json.loads((NETLISTS / "levitated_disk.json").read_text()), "description", control_block(flag))
    evil = tmp_path / "evil.json"
    evil.write_text(json.dumps(doc), encoding="utf-8")
    out = tmp_path / "run"
    assert cli.main(["sigma-delta", str(PISTON), "--model", str(evil), "-o", str(out), "-q", "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert f"model file {evil}: description:" in err and "fix:" in err
    assert not out.exists() and not flag.exists()


# ----------------------------------------------------------------------------- testbench netlists and sweeps


def test_sigma_delta_netlists_write_text_and_paths_inert(flag, tmp_path):
    """The sigma-delta ngspice and VACASK netlists around the reference model: hostile text in the
    model changes no code line; a hostile .lib or OSDI path is refused (InputError naming the
    path) when it holds a control character, a quote or (ngspice: ; and $, which ngspice 39 reads
    as inline comments, tests/test_trust_paths.py) else appears only in its own card."""
    model = MacroModel.load_json(NETLISTS / "levitated_disk.json")
    d = design(model, 1e-6)
    lib, osdi, blocks = tmp_path / "m" / "levitated_disk.lib", tmp_path / "m.osdi", tmp_path / "b.osdi"

    def benches(m: MacroModel, lib: Path, osdi: Path) -> dict[str, str]:
        return {
            "tb.cir": sd_ngspice.testbench(m, d, lib, 64, "sd.raw"),
            "tb.sim": sd_vacask.testbench(m, d, osdi, blocks, 64),
        }

    base = benches(model, lib, osdi)
    for h in hostile(flag):
        for name, text in benches(with_text(model, h), lib, osdi).items():
            assert printable(text) and code(name, text) == code(name, base[name]), name
    for k, h in enumerate(h for h in hostile(flag) if "\x00" not in h):
        other = tmp_path / f"d{k}{h}" / "levitated_disk.lib"
        try:
            cir = sd_ngspice.testbench(model, d, other, 64, "sd.raw")
        except InputError as err:
            assert err.where == "path" and (refusable(h) or any(ch in h for ch in SPICE_CARD)), str(err)
        else:
            assert not refusable(h) and not any(ch in h for ch in SPICE_CARD) and printable(cir)
            assert code("tb.cir", cir) == [ln.replace(str(lib), str(other)) for ln in code("tb.cir", base["tb.cir"])]
        try:
            sim = sd_vacask.testbench(model, d, tmp_path / f"o{k}{h}.osdi", blocks, 64)
        except InputError as err:
            assert err.where == "path" and (refusable(h) or '"' in h or "\\" in h), str(err)
        else:
            assert not refusable(h) and '"' not in h and "\\" not in h and printable(sim)
            assert code("tb.sim", sim) == [
                ln.replace(str(osdi), str(tmp_path / f"o{k}{h}.osdi")) for ln in code("tb.sim", base["tb.sim"])
            ]


SWEEP = """[fixed]
cycles = 64
"structure.description" = {value}

[[parameters]]
name = "ts"
values = ["1 us"]
"""


def test_sweep_values_and_structure_path_are_refused_or_inert(piston, flag, tmp_path):
    """A sweep file's structure value (the description) is refused with its field named when it
    holds a control character; else each run's structure file has exactly the base document with
    that value, and the first comment line that names the structure path (itself hostile) stays
    one TOML comment: the run reads back the same structure, whose .lib code is the baseline's."""
    base_doc = tomllib.loads(PISTON.read_text(encoding="utf-8"))
    accepted = []
    for h in hostile(flag):
        try:
            sweep = parse_sweep(SWEEP.format(value=toml_string(h)), "sweep.toml")
        except SweepError as err:
            assert err.where == "fixed.structure.description" and refusable(h) and err.fix, str(err)
            continue
        assert not refusable(h)
        (run,) = plan(sweep, PISTON, tmp_path / "sweep")
        assert tomllib.loads(run.structure_text) == base_doc | {"description": h}
        s = parse_structure(run.structure_text, str(Path(run.dir) / "structure.toml"))
        accepted.append(replace(piston, description=s.description))
    assert len(accepted) == sum(not refusable(h) for h in hostile(flag))
    assert_inert(accepted, emitted(piston))
    sweep = parse_sweep(SWEEP.format(value='"benign"'), "sweep.toml")
    names = [h for h in hostile(flag) if "/" not in h and "\x00" not in h and len(h.encode()) < 200]
    for k, h in enumerate(names):
        structure = tmp_path / f"s{k}{h}.toml"
        structure.write_text(PISTON.read_text(encoding="utf-8"), encoding="utf-8")
        (run,) = plan(sweep, structure, tmp_path / "sweep")
        comments = [ln for ln in run.structure_text.split("\n") if ln.startswith("#")]
        assert comments == [run.structure_text.split("\n")[0]] and printable(run.structure_text)
        assert tomllib.loads(run.structure_text) == base_doc | {"description": "benign"}


def test_comment_writer_by_hand():
    """netgen.core.text on hand-written cases: one marker and a space per line (so never `*#`), every
    line break a new comment line, other controls escaped, // comments without backticks, /*, */
    or a trailing backslash, long text wrapped; an identifier is the whole string."""
    from netgen.core.text import comment_lines, comment_text, is_identifier

    assert comment_lines("a\n.control\r\nb\u2028c\x85", "*") == "* a\n* .control\n* b\n* c"
    assert comment_lines("#shell ls", "*") == "* #shell ls" and comment_lines("", "*") == "*"
    assert comment_text("x\x00y\tz\u202e", "*") == "x\\x00y\\tz\\u202e"
    assert comment_text("*/ m `define /*/ q \\", "//") == "* / m 'define / * / q \\x5c"
    assert comment_text("*/ `x`", "*") == "*/ `x`"  # nothing to neutralise in SPICE
    assert comment_lines("w " * 120, "//").split("\n") == ["//" + " w" * 49] * 2 + ["//" + " w" * 22]  # 100 wide
    assert is_identifier("piston") and not is_identifier("piston\n") and not is_identifier("p\u00e9")


def test_pyspice_title_stays_one_card(piston, flag, tmp_path):
    """netgen.sim.pyspice.ModelCircuit with a hostile title: the deck's title is one card and
    every other card is the baseline's."""
    from netgen.sim.pyspice import ModelCircuit

    lib = tmp_path / "piston.lib"
    lib.write_text(emitted(piston)["piston.lib"], encoding="utf-8")
    base = str(ModelCircuit.build(piston, lib, title="benign").circuit).split("\n")
    for h in hostile(flag):
        deck = str(ModelCircuit.build(piston, lib, title=h).circuit).split("\n")
        assert printable("\n".join(deck)) and deck[0].startswith(".title ") and deck[1:] == base[1:]
