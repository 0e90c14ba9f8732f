"""`netgen gyro` (netgen.testbench.gyro) on examples/gyroscope_z.toml: the drive loop, the sense
mode in the sigma-delta force-feedback loop, the demodulation into rate and quadrature, against
the design's closed forms (independent of the run: the structure's mass, the drive amplitude asked
for, the resonance of the model's x, and the loop design's feedback force F_fb):
- the drive loop holds x at the set amplitude X_d at the x resonance;
- the quadrature force read from the bits equals k_xy X (k_xy from the structure file);
- the rate read equals the applied rate: the scale factor 2 m X_d w_d / F_fb of the design within 2 %.

Tolerances (derived): the drive loop's amplitude control settles as e^(-G w t / (2 Q)) (G = 100,
Q = 2000: 6 drive periods; the run starts at X_d); its steady amplitude is exact up to the
amplitude estimator's second-order ripple, so 1e-3 on X and on the frequency (the drive loop runs at
the x resonance; the Coriolis and electrostatic side forces shift it by less than 1e-4). The rate and
quadrature reads: their noise is the bitstream's shaped quantisation noise at the drive frequency,
whose standard deviation over the run the analysis reports (rate_read_sigma_rad_s, the density over
sqrt(2 T)); the test takes 4 of them plus the systematic part: the sense loop's finite gain at the
drive frequency leaves a residual sense motion (k_y - m w^2 + i w b_y) Y that the bits do not carry
and that leaks quadrature into rate; measured (bench/gyroscope.py, 16384-period runs) the scale
factor is 0.35 % low and the zero-rate output 1e-5 of the quadrature; so 2 % on the scale factor and
1 % on the quadrature force (0.5 % measured) hold several sigma of margin. 2048 periods of T_s = 1 us (26 drive periods)
in ngspice with the compiled loop (ngspice-xspice): about 40 s."""

from __future__ import annotations

import math

import pytest

from netgen.build import build_model
from netgen.cli import commands as cli
from netgen.emit.ngspice import subcircuit
from netgen.structure import load_structure
from netgen.testbench.gyro.run import GyroRequest, run, sense_design
from netgen.testbench.sigma_delta.loopfile import read_structure_loop
from tests.fixtures import ROOT

EXAMPLE = ROOT / "examples" / "gyroscope_z.toml"
MASS = 2330.0 * 10e-6 * (500e-6**2 - 50 * 50 * (4e-6) ** 2)  # rho t (L W - holes), the file's numbers
K_XY = 5e-3  # N/m, the file's k_xy
X_D = 4e-6


def test_gyro_reads_rate_and_quadrature(tmp_path):
    """One run at 0.4 of the full-scale rate (module docstring)."""
    model = build_model(load_structure(EXAMPLE))
    lib = tmp_path / "g.lib"
    lib.write_text(subcircuit(model))
    cx = next(c for c in model.coordinates if c.name == "x")
    w = math.sqrt(cx.stiffness / cx.mass)
    spec = read_structure_loop(EXAMPLE)
    fs_force = sense_design(model, spec, GyroRequest()).channels[0]["full_scale_force_si"]
    full_scale = fs_force / (2 * MASS * X_D * w)  # rad/s
    rate = 0.4 * full_scale
    s = run(model, lib, tmp_path / "run", spec, GyroRequest(cycles=2048, rate_deg_s=math.degrees(rate), progress=False))
    r = s["runs"][0]
    assert r["drive_amplitude_m"] == pytest.approx(X_D, rel=1e-3)
    assert r["drive_hz"] == pytest.approx(w / (2 * math.pi), rel=1e-3)
    assert r["quadrature_force_n"] == pytest.approx(K_XY * X_D, rel=0.01)
    sigma = r["rate_read_sigma_rad_s"]
    assert abs(r["rate_rad_s"] - rate) <= 0.02 * rate + 4 * sigma
    assert (tmp_path / "run" / "spectrum.png").exists() and (tmp_path / "run" / "summary.json").exists()


@pytest.mark.parametrize(
    "old, new, key",
    [
        ('inertial = ["a_x", "a_y", "w_z"]', 'inertial = ["a_x", "a_y"]', "coordinates.inertial"),
        ("[loop.channels.y]", "[loop.channels.x]", "loop.channels"),
    ],
)
def test_bad_gyro_descriptions_exit_2_naming_file_and_key(tmp_path, capsys, old, new, key):
    """No rate port, or the sense loop on another coordinate: exit 2 naming the file, the key and
    the fix, and no result set in the output folder."""
    text = EXAMPLE.read_text()
    assert old in text
    path = tmp_path / "g.toml"
    path.write_text(text.replace(old, new))
    out = tmp_path / "out"
    assert cli.main(["gyro", str(path), "-o", str(out), "--cycles", "64", "-q"]) == 2
    err = capsys.readouterr().err
    assert str(path) in err and key in err and "fix:" in err
    assert not (out / "summary.json").exists()
