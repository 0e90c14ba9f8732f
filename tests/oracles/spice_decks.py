"""Decks several tests run the same way: the unbiased piston's noise in VACASK (tests/emit/
test_noise_ngspice.py, tests/emit/test_process_va.py) and the small free disk held by a soft spring
(tests/emit/test_process_film.py)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from netgen.sim.vacask import run_vacask

DISK_PORTS = "0 0 0 0 0 0 0 0 0 fz xz"  # the disk's eight ring sectors and the plate grounded, then f_z, x_z


def vacask_piston_noise(osdi: Path, name: str, tmp_path: Path, card: str = "") -> tuple[np.ndarray, np.ndarray]:
    """(frequency Hz, PSD V^2/Hz at x_z) of a piston module (ports drive, plate, f_z, x_z) in VACASK's
    noise analysis, unbiased, the force input f_z the input, 5..25 kHz at 41 points; `card`: the
    model card's parameters (VACASK's onoise is the PSD itself)."""
    net = f"""{name} noise
ground 0
load "{osdi}"
model mems {name}{" " + card if card else ""}
model vsource vsource
x1 (drive plate fz xz) mems
v_drive (drive 0) vsource dc=0
v_plate (plate 0) vsource dc=0
v_fz (fz 0) vsource dc=0 mag=1
control
  analysis n1 noise out="xz" in="v_fz" from=5k to=25k mode="lin" points=40
endc
"""
    plot = run_vacask(net, tmp_path, analysis="n1")
    return np.real(plot["frequency"]), np.real(plot["onoise"])


def disk_library(folder: Path, form: str) -> tuple[Path, list[str]]:
    """The disk's .lib (form "lib") or _osdi.lib with its module loaded ("osdi") in `folder` (d.lib,
    d_osdi.lib, d.osdi) and the .control lines that load it."""
    if form == "osdi":
        return folder / "d_osdi.lib", [f"pre_osdi {folder / 'd.osdi'}", "set num_threads=1"]
    return folder / "d.lib", []


def disk_deck(lib: Path, control: list[str], params: str, k: float, analysis: str) -> str:
    """An ngspice deck of the damped_disk subcircuit in `lib` with instance `params`, z held by a
    noiseless spring k (N/m, a B source from x_z into f_z) behind the AC source Vac, running
    `analysis` (an .ac or a .noise line) after the `control` lines."""
    run = "\n".join([".control", *control, "run", "write out.raw all", ".endc"]) if control else ""
    return f"""* damped disk: {analysis}
.include {lib}
X1 {DISK_PORTS} damped_disk {params}
Vac fz fsp DC 0 AC 1
Bsp fsp 0 V={-k!r}*v(xz)
{analysis}
{run}
.end
"""
