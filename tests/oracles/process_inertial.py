"""The crab-leg proof mass of tests/emit/test_process_inertial.py (z, tilt_x, tilt_y, rate ports) and its
references: the rebuilt model's Coriolis cross response and the .ac deck; shared with bench/process_terms.py."""

from __future__ import annotations

import numpy as np

from .crab_legs import crab_legs


def structure(t: float) -> str:
    """The proof mass 200 um square and `t` um thick on crab legs (150 um legs, 140 um thighs) over one
    plate, with its tilts and the rate inputs."""
    return (
        'name = "gyp"\ndescription = "proof mass on crab legs over one plate, rate inputs"\n'
        + crab_legs(200.0, t, 150.0, 140.0)
        + """[[electrodes]]
name = "bot"
side = "below"
gap = "2 um"
[coordinates]
rigid = ["z", "tilt_x", "tilt_y"]
inertial = ["a_z", "w_x", "w_y", "w_z"]
[sampling]
levels = 3
range = 0.3
[electrostatics]
fringe = "none"
[damping]
rayleigh = { alpha = 2000 }
"""
    )


PROCESS = '[process]\nparameters = ["tscale"]\n'
T_UM, OMEGA, FREQ, V0 = 5.0, 1e3, 2e3, 1.0  # um, rad/s (w_z), Hz (the .ac point), rad/s (tilt_y rate)
TSCALES = (0.9, 1.1)
SI = 1e-3 / 1e-9  # x_tilt_x in mrad per f_tilt_y in nN*m (the .lib's port units) -> rad / (N*m)


def reference_ac(ref, w: float) -> complex:
    """x_tilt_x / f_tilt_y (rad per N*m) of the rebuilt model at w_z = OMEGA, angular frequency w."""
    m, d, k = (np.diag([getattr(c, a) for c in ref.coordinates]) for a in ("mass", "damping", "stiffness"))
    g, s = np.array(ref.inertial.gyroscopic["z"]), np.array(ref.inertial.centrifugal["zz"])
    a = k - w * w * m + 1j * w * d + 1j * w * OMEGA * g + OMEGA**2 * s
    names = [c.name for c in ref.coordinates]
    f = np.zeros(len(names), dtype=complex)
    f[names.index("tilt_y")] = 1.0
    return complex(np.linalg.solve(a, f)[names.index("tilt_x")])


def netlist(include: str, tscale: float, control: str) -> str:
    return f"""* Coriolis coupling at tscale {tscale}
.include {include}
X1 0 0 fz xz ftx xtx fty xty 0 0 0 wz gyp tscale={tscale!r}
Vz fz 0 0
Vtx ftx 0 0
Vty fty 0 DC 0 AC 1
Vw wz 0 DC {OMEGA!r}
.ac lin 1 {FREQ!r} {FREQ!r}
{control}
.end
"""
