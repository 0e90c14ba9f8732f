"""The Xschem forms (netgen.emit.xschem) of the committed netlists: every symbol's pins are its
.subckt card's ports in order, and Xschem (Debian's 2.8.1, installed by .ci/setup) netlists the
generated testbench headless into a netlist whose ngspice transient equals an independently
written one: for the levitated disk the hand-written examples/levitated_disk_tb.cir, for the
three-axis accelerometer a netlist this test writes from the .subckt card alone."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from netgen.sim.ngspice import ngspice_path, run_file
from tests.fixtures import ROOT

NETLISTS = ROOT / "netlists"
LIBS = sorted(p for p in NETLISTS.rglob("*.lib") if not p.name.endswith(("_xspice.lib", "_osdi.lib")))
DEVICES = Path("/usr/share/xschem/xschem_library/devices")  # Debian's xschem: vsource, gnd, lab_pin, code
# Both netlists hold the same elements with the same values (the .include'd .lib, 0 V sources,
# the same drive), differing only in element names and order: ngspice's result differs by
# round-off of a reordered matrix (1e-15 relative per step over ~200 steps), far below 1e-9.
AGREEMENT = 1e-9


def card(lib: Path) -> tuple[str, list[str]]:
    """The .subckt card's name and ports, its continuation lines joined: the words before ngspice's
    `params:` keyword (the instance parameters' defaults follow it) that are not `name=value`."""
    lines = lib.read_text(encoding="utf-8").splitlines()
    start = next(i for i, line in enumerate(lines) if line.lower().startswith(".subckt"))
    words = lines[start].split()[1:]
    for line in lines[start + 1 :]:
        if not line.startswith("+"):
            break
        words += line[1:].split()
    words = words[: [w.lower() for w in words].index("params:")] if "params:" in map(str.lower, words) else words
    return words[0], [w for w in words[1:] if "=" not in w]


def symbol_pins(sym: Path) -> list[dict[str, str]]:
    """The pins of an Xschem symbol in file order (the order @pinlist writes): `B 5` boxes'
    attributes name=, dir=, pinnumber= (Xschem's file format: layer 5 is the pin layer)."""
    pins = []
    for line in sym.read_text(encoding="utf-8").splitlines():
        if line.startswith("B 5 "):
            attrs = line[line.index("{") + 1 : line.rindex("}")]
            pins.append(dict(a.split("=", 1) for a in attrs.split()))
    return pins


@pytest.mark.parametrize("lib", LIBS, ids=lambda p: p.stem)
def test_symbol_pins_are_the_subckt_ports_in_order(lib):
    """Pin k of <name>.sym is port k of the .subckt card; the labels carry the JSON's port units;
    the format instantiates the subcircuit and the template names an X instance."""
    name, ports = card(lib)
    sym = lib.with_suffix(".sym")
    pins = symbol_pins(sym)
    assert [p["name"] for p in pins] == ports
    assert [int(p["pinnumber"]) for p in pins] == list(range(1, len(ports) + 1))
    text = sym.read_text(encoding="utf-8")
    assert f'format="@name @pinlist {name}"' in text and 'template="name=X1"' in text
    units = {p["name"]: p["unit"] for p in json.loads(lib.with_suffix(".json").read_text())["ports"]}
    for port in ports:
        assert f"T {{{port} [{units[port]}]}}" in text


def netlist_with_xschem(folder: Path, name: str) -> Path:
    """Xschem 2.8.1 in batch mode (-n netlist, -s SPICE, -q quit, -x no X display, -r no
    readline), a private rc file naming the model folder as library and netlist folder."""
    if shutil.which("xschem") is None:
        pytest.fail("xschem is not installed: run `bash .ci/setup` (it installs Debian's xschem)")
    rc = folder / "xschemrc"
    rc.write_text(f"set XSCHEM_LIBRARY_PATH {folder}:{DEVICES}\nset netlist_dir {folder}\nset netlist_type spice\n")
    done = subprocess.run(
        ["xschem", "--rcfile", str(rc), "-n", "-s", "-q", "-x", "-r", str(folder / f"{name}_tb.sch")],
        cwd=folder,
        env={"HOME": str(folder), "PWD": str(folder), "PATH": "/usr/bin:/bin"},  # xschem.tcl reads PWD
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=120,
    )
    out = folder / f"{name}_tb.spice"
    assert done.returncode == 0 and out.exists(), done.stdout + done.stderr
    assert "MISSING" not in out.read_text() and "unable" not in (done.stdout + done.stderr).lower()
    return out


def model_folder(tmp_path: Path, lib: Path) -> Path:
    """The committed model's .lib, symbol and testbench copied into a folder of their own."""
    folder = tmp_path / "model"
    folder.mkdir()
    for suffix in (".lib", ".sym", "_tb.sch", ".json"):
        shutil.copy(lib.with_name(lib.stem + suffix), folder)
    return folder


def agree(netlisted: Path, reference: Path, tmp_path: Path, node: str = "x_z") -> float:
    """Run both netlists in ngspice; the largest difference of v(node) over the transient,
    relative to the reference's peak (the time grids must be the same points)."""
    (a,) = [p for p in run_file(netlisted, tmp_path / "xschem") if "tran" in p.name.lower()]
    (b,) = [p for p in run_file(reference, tmp_path / "reference") if "tran" in p.name.lower()]
    np.testing.assert_array_equal(a["time"], b["time"])
    peak = np.max(np.abs(b[node]))
    assert peak > 0
    return float(np.max(np.abs(a[node] - b[node])) / peak)


def test_disk_testbench_equals_the_hand_written_one(tmp_path):
    """The levitated disk's generated testbench, netlisted by Xschem, gives v(x_z) within 1e-9 of
    peak of examples/levitated_disk_tb.cir's (gravity on f_z, all electrodes at 0 V), and its
    .meas agrees with free fall z(20 us) = -g t^2 / 2 = -1.962e-3 um (g = 9.81) within 3.5e-6: f_z
    is written with 6 digits (0.5e-6 / 0.160656 = 3.1e-6) and .meas prints 7 (2.5e-7); the
    integration of a constant acceleration adds no error of its own."""
    folder = model_folder(tmp_path, NETLISTS / "levitated_disk.lib")
    netlisted = netlist_with_xschem(folder, "levitated_disk")
    assert agree(netlisted, ROOT / "examples" / "levitated_disk_tb.cir", tmp_path) <= AGREEMENT
    # the schematic's own .meas (ngspice prints it only without -r)
    done = subprocess.run(
        [ngspice_path(), "-b", str(netlisted)], cwd=folder, capture_output=True, text=True, timeout=300
    )
    z = float(done.stdout.split("x_z_20us")[1].split("=")[1].split()[0])
    assert z == pytest.approx(-9.81 * 20e-6**2 / 2 * 1e6, rel=3.5e-6)


def reference_netlist(lib: Path, folder: Path) -> Path:
    """A testbench written from the .subckt card alone (not from netgen): every electrode and the
    conductor at 0 V, a_in = 9.81 m/s^2 (gravity, per the JSON's acceleration_port), f_ at 0."""
    name, ports = card(lib)
    data = json.loads(lib.with_suffix(".json").read_text())
    kinds = {p["name"]: p["kind"] for p in data["ports"]}
    lines = [f"* {name}: reference testbench", f".include {lib.name}", f"X1 {' '.join(ports)} {name}"]
    driven = [p for p in ports if kinds[p] != "displacement_out"]
    lines += [f"V{k} {p} 0 {9.81 if p == 'a_in' else 0}" for k, p in enumerate(driven)]
    lines += [".options chgtol=1e-18", ".tran 0.1u 20u uic", ".end"]
    path = folder / "reference.cir"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_accelerometer_testbench_equals_one_written_from_the_card(tmp_path):
    """The three-axis accelerometer (23 ports, comb and plate electrodes): Xschem's netlist of the
    generated testbench against reference_netlist, v(x_z) within 1e-9 of peak."""
    folder = model_folder(tmp_path, NETLISTS / "accelerometer_xyz" / "accelerometer_xyz.lib")
    netlisted = netlist_with_xschem(folder, "accelerometer_xyz")
    reference = reference_netlist(folder / "accelerometer_xyz.lib", folder)
    assert agree(netlisted, reference, tmp_path) <= AGREEMENT
