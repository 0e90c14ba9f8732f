"""The gyroscope testbench's options, declared once (netgen.core.options): the drive loop's
amplitude and gain, the rate and the rate sweep; the sampling period and the number of periods are
the sigma-delta testbench's declarations (netgen.testbench.sigma_delta.options), shared."""

from __future__ import annotations

from ...core.options import Option, by_name
from ..sigma_delta.options import OPTIONS as SIGMA_DELTA

# every sigma-delta back end (netgen.testbench.sigma_delta.options.SIMULATORS), each with the drive loop:
# a B-source in ngspice and ngspice-xspice, the Verilog-A block drive.va in vacask and ngspice-osdi
SIMULATORS = ("ngspice", "ngspice-xspice", "vacask", "ngspice-osdi")

_options = [
    Option(
        "rate",
        "the rotation rate Omega_z on the model's w_z port, deg/s",
        low=-1e5,
        high=1e5,
        default=0.0,
        example="200",
        flag="--rate",
    ),
    Option(
        "rate_points",
        "the rates of a linearity sweep, evenly over +-rate_span of the full-scale rate",
        type="int",
        low=3,
        high=41,
        zero="no sweep: one run at --rate",
        default=0,
        example="5",
        flag="--rate-points",
    ),
    Option(
        "rate_span",
        "the sweep's extent, a fraction of the full-scale rate F_fb / (2 m X_d w_d)",
        low=0.0,
        high=1.0,
        open_low=True,
        default=0.5,
        example="0.5",
        flag="--rate-span",
    ),
    Option(
        "drive_amplitude",
        "the drive amplitude X_d the drive loop holds",
        quantity="length",
        low=1e-9,
        high=1e-4,
        default=4e-6,
        default_text="4 um",
        example="4 um",
        flag="--drive-amplitude",
    ),
    Option(
        "agc_gain",
        "the drive loop's amplitude-control gain G (drive force b_x x' (1 + G (1 - A / X_d)))",
        low=0.0,
        high=1e4,
        open_low=True,
        default=100.0,
        example="100",
        flag="--agc-gain",
    ),
    Option(
        "simulator",
        "ngspice with the behavioural-source loop around the .lib, or with the compiled loop and the "
        "model's plate terms in code models (about 4x faster), the drive loop a B-source; or VACASK, or "
        "ngspice 45+ through OSDI, with the compiled Verilog-A module, the drive loop a Verilog-A block",
        type="choice",
        choices=SIMULATORS,
        default="ngspice-xspice",
        example="ngspice",
        flag="--simulator",
    ),
]

OPTIONS = by_name(_options) | {k: SIGMA_DELTA[k] for k in ("ts", "cycles")}
