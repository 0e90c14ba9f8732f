"""The inertial inputs of a MacroModel beyond a_in (netgen.mechanics.inertial derives them): frame
acceleration along x and y (ports a_x, a_y, 1 V = 1 m/s^2) and frame rotation rate about x, y, z
(ports w_x, w_y, w_z, 1 V = 1 rad/s), as data the emitters read:

    generalized force on q_v = - sum_i P_i[v] a_i - sum_k Omega_k sum_w G_k[v, w] q'_w
                               - sum_{kl} Omega_k Omega_l (sum_w S_kl[v, w] q_w + c_kl[v])

(SI: q in m or rad, forces in N or N*m). a_z stays the MacroModel's `acceleration` (port a_in)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

RATE_PORTS = ("w_x", "w_y", "w_z")
ACCEL_PORTS = ("a_x", "a_y")
PAIRS = ("xx", "yy", "zz", "xy", "xz", "yz")  # Omega_k Omega_l products, k <= l


@dataclass
class Inertial:
    """Participation per in-plane acceleration axis, Coriolis matrix per rate axis, centrifugal
    stiffness and constant force per product of rate axes (netgen.mechanics.inertial)."""

    participation: dict[str, list[float]] = field(default_factory=dict)  # "a_x"/"a_y" -> P[v], kg or kg*m
    gyroscopic: dict[str, list[list[float]]] = field(default_factory=dict)  # "x"/"y"/"z" -> G[v][w]
    centrifugal: dict[str, list[list[float]]] = field(default_factory=dict)  # "zz", "xz", ... -> S[v][w]
    centrifugal_force: dict[str, list[float]] = field(default_factory=dict)  # "zz", ... -> c[v]

    def __bool__(self) -> bool:
        return bool(self.participation or self.gyroscopic)

    def ports(self) -> list[dict]:
        """The input ports, in order: a_x, a_y (before a_in) and the rates (after it)."""
        return [{"name": k, "kind": "acceleration_in", "unit": "m/s^2"} for k in ACCEL_PORTS if k in self.participation]

    def rate_ports(self) -> list[dict]:
        return [{"name": f"w_{k}", "kind": "rate_in", "unit": "rad/s"} for k in "xyz" if k in self.gyroscopic]

    def force(self, q: np.ndarray, qdot: np.ndarray, inputs: dict[str, float]) -> np.ndarray:
        """Generalized inertial force (SI) at coordinates q and velocities qdot (SI), for the input
        values {port: value} (a_x, a_y in m/s^2; w_x, w_y, w_z in rad/s; others ignored)."""
        q, qdot = np.ravel(q), np.ravel(qdot)
        out = np.zeros_like(q, dtype=float)
        for port, p in self.participation.items():
            out -= np.asarray(p) * inputs.get(port, 0.0)
        rate = {k: inputs.get(f"w_{k}", 0.0) for k in self.gyroscopic}
        for k, g in self.gyroscopic.items():
            out -= rate[k] * (np.asarray(g) @ qdot)
        for pair, s in self.centrifugal.items():
            w2 = rate[pair[0]] * rate[pair[1]]
            out -= w2 * (np.asarray(s) @ q + np.asarray(self.centrifugal_force.get(pair, 0.0)))
        return out

    def to_dict(self) -> dict:
        """The model JSON's "inertial_inputs" entry."""
        return {
            "meaning": "frame acceleration a_x, a_y (m/s^2; a_z is a_in) and rotation rate w_x, w_y, w_z "
            "(rad/s): coordinate v feels - participation[a_i][v] a_i - sum_k w_k sum_u gyroscopic[k][v][u] "
            "dq_u/dt - sum_kl w_k w_l (sum_u centrifugal[kl][v][u] q_u + centrifugal_force[kl][v]), SI",
            "participation": self.participation,
            "gyroscopic": self.gyroscopic,
            "centrifugal": self.centrifugal,
            "centrifugal_force": self.centrifugal_force,
        }

    @classmethod
    def from_dict(cls, d: dict) -> Inertial:
        """From the JSON entry (or {} for a model without these inputs)."""
        return cls(
            {k: [float(x) for x in v] for k, v in d.get("participation", {}).items()},
            {k: [[float(x) for x in r] for r in v] for k, v in d.get("gyroscopic", {}).items()},
            {k: [[float(x) for x in r] for r in v] for k, v in d.get("centrifugal", {}).items()},
            {k: [float(x) for x in v] for k, v in d.get("centrifugal_force", {}).items()},
        )
