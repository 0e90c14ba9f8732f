"""Where the models' assumptions stop holding, checked once per structure file (parse_structure):
the parallel-plate and fringe forms need a gap much smaller than the conductor's lateral size; a
comb sits at the proof mass's edge with fingers shorter than the mass; the edge-fringe term
a + b ln(L/g) per unit edge length holds for the published, positive coefficients. Outside the
refusal limits the file is refused (StructureError, exit 2, with the number and the limit);
between the warning and the refusal limits the build warns (stderr and the model's report)."""

from __future__ import annotations

import math

from ..core.reader import Reader
from .electrodes import CombElectrode

GAP_WARN, GAP_REFUSE = 0.1, 0.5  # gap / lateral size of the conductor (parallel plate: gap << size)
COMB_LENGTH = 2.0  # finger length / lateral size of the mass, at most
COMB_REACH = 1.0  # distance of a comb's overlap centre from the mass centre, in (size + finger length)
FRINGE = {"fringe_a": (0.0, 5.0), "fringe_b": (0.0, 5.0)}  # the fringe form's coefficients (defaults 0.42, 1)


def lateral_size(conductor: object) -> float | None:
    """The conductor's smallest lateral dimension (a disk's diameter, a plate's shorter side)."""
    if hasattr(conductor, "radius"):
        return 2.0 * conductor.radius
    sides = [getattr(conductor, k) for k in ("length", "width") if isinstance(getattr(conductor, k, None), float)]
    return min(sides) if sides else None


def check(rd: Reader, conductor: object, sets: tuple, electrostatics: object) -> tuple[str, ...]:
    """Refuse what lies outside the refusal limits; the warnings for what lies near them."""
    warnings: list[str] = []
    for key, (lo, hi) in FRINGE.items():
        value = getattr(electrostatics, key)
        if not lo <= value <= hi:
            raise rd.fail(
                f"electrostatics.{key}",
                f"{key} = {value:g} lies outside {lo:g}..{hi:g}, where the edge-fringe form a + b ln(L/g) "
                "per unit edge length holds (a negative fringe removes capacitance)",
                f'give {key} in {lo:g}..{hi:g} (default {0.42 if key == "fringe_a" else 1.0}), or fringe = "none"',
            )
    dielectric(rd, sets, electrostatics)
    perforation(rd, conductor, electrostatics)
    size = lateral_size(conductor)
    if size is None:
        return ()
    for i, s in enumerate(sets):
        where = f"electrodes[{i}]"
        if hasattr(s, "fingers"):
            comb(rd, where, s, size)
            continue
        ratio = s.gap / size
        if ratio >= GAP_REFUSE:
            raise rd.fail(
                f"{where}.gap",
                f"gap {s.gap:g} m is {ratio:.3g} x the conductor's lateral size {size:g} m; the parallel-plate "
                f"and fringe forms hold for gap << size (refused from {GAP_REFUSE:g} x)",
                f"give a gap below {GAP_WARN * size:g} m, or check the unit",
            )
        if ratio > GAP_WARN:
            warnings.append(
                f"{where} ({s.name}): gap {s.gap:g} m is {ratio:.3g} x the lateral size {size:g} m (parallel plate "
                f"assumes gap << size; above {GAP_WARN:g} x the capacitance is only roughly right)"
            )
    return tuple(warnings)


def comb(rd: Reader, where: str, s: CombElectrode, size: float) -> None:
    """A comb's fingers no longer than COMB_LENGTH mass sizes, its overlap at the mass's edge."""
    if s.length > COMB_LENGTH * size:
        raise rd.fail(
            f"{where}.length",
            f"finger length {s.length:g} m is {s.length / size:.3g} x the mass's size {size:g} m "
            f"(at most {COMB_LENGTH:g} x: the fingers hang on the mass)",
            f"give a finger length up to {COMB_LENGTH * size:g} m, or check the unit",
        )
    reach = COMB_REACH * (size + s.length)
    distance = math.hypot(*s.center)
    if distance > reach:
        raise rd.fail(
            f"{where}.center",
            f"the comb's overlap centre lies {distance:g} m from the mass centre, beyond its reach of "
            f"{reach:g} m (mass size + finger length): its fingers cannot touch the mass",
            f"place the comb at the mass's edge (within {reach:g} m of its centre)",
        )


def dielectric(rd: Reader, sets: tuple, electrostatics: object) -> None:
    """A dielectric layer on an electrode is modelled by the parallel-plate extractor (its series
    gap, netgen.electrostatics.parallel_plate), the multipole extractor (a dielectric interface,
    netgen.electrostatics.fastcap_mesh.layered_panels) and a calibration on its points. The dense
    BEM does not model it: bempp's regular quadrature of the adjoint double layer between the
    layer's surface and the electrode t_d below it needs elements below t_d (a 0.2 um layer on a
    20 um electrode: over 10^5 unknowns, far beyond the dense matrix; docs/bem.md)."""
    extractor = getattr(electrostatics, "extractor", "parallel_plate")
    if extractor in ("parallel_plate", "fastcap"):
        return
    on_fastcap = getattr(electrostatics, "calibration_source", "bem") == "fastcap"
    if extractor == "calibrated" and on_fastcap and getattr(electrostatics, "calibration_points", 0):
        return
    for i, s in enumerate(sets):
        if getattr(s, "dielectric_thickness", 0.0) > 0.0:
            raise rd.fail(
                f"electrodes[{i}].dielectric_thickness",
                f"extractor = {extractor!r} does not model a dielectric layer on the electrodes (the dense BEM "
                "would need elements thinner than the layer, and a couplings file's solver is unknown)",
                'use extractor = "parallel_plate" (the layer as a series gap), "fastcap" (a dielectric '
                'interface) or "calibrated" with calibration_source = "fastcap", or drop the layer',
            )


def perforation(rd: Reader, conductor: object, electrostatics: object) -> None:
    """A proof mass's etch holes enter the parallel-plate extractor (a fill factor,
    netgen.electrostatics.perforation) and the multipole extractor (the holes meshed,
    fastcap_mesh.perforated_face); the dense BEM meshes a solid plate, so it and a calibration on
    its points would give a silently wrong model."""
    if not getattr(conductor, "hole", 0.0):
        return
    extractor = getattr(electrostatics, "extractor", "parallel_plate")
    points = getattr(electrostatics, "calibration_points", 0)
    on_bem = extractor == "calibrated" and points and getattr(electrostatics, "calibration_source", "bem") == "bem"
    if extractor == "bem" or on_bem:
        what = 'extractor = "bem"' if extractor == "bem" else 'calibration_source = "bem"'
        raise rd.fail(
            "conductor.hole",
            f"{what} meshes the proof mass as a solid plate: its etch holes would be left out of the capacitance",
            'use extractor = "fastcap" (the holes meshed), "calibrated" with calibration_source = "fastcap", '
            'or "parallel_plate" (a fill factor), or drop hole and hole_pitch',
        )
