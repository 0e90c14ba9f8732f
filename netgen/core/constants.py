"""Physical constants and material tables shared by the stages (SI units)."""

from __future__ import annotations

from dataclasses import dataclass

EPS0 = 8.8541878188e-12
"""Vacuum permittivity in F/m (CODATA 2022: scipy.constants.epsilon_0 from scipy 1.15 on, what a
user's scipy gives them; CODATA 2018's 8.8541878128e-12 is 6.8e-10 smaller)."""

K_B = 1.380649e-23
"""Boltzmann constant in J/K (exact, SI 2019)."""

G = 9.81
"""Standard gravity in m/s^2, as the sigma-delta testbench and the acceleration port use it."""

ATMOSPHERE = 101325.0
"""Pa: the reference pressure of the tabulated mean free paths."""


@dataclass(frozen=True)
class Gas:
    """Dynamic viscosity (Pa s) and mean free path at 1 atm (m), both near 300 K."""

    name: str
    viscosity: float
    mean_free_path: float


GASES = {  # viscosities: CRC handbook near 300 K; mean free paths at 1 atm (Veijola/Bao tables)
    "air": Gas("air", 1.85e-5, 68e-9),
    "nitrogen": Gas("nitrogen", 1.78e-5, 66e-9),
    "argon": Gas("argon", 2.27e-5, 70e-9),
    "helium": Gas("helium", 1.99e-5, 190e-9),
}
