"""Small free disks the extractor tests and their benches share (tests/fixtures.py re-exports
SMALL_BEM_DISK; bench scripts load this module through bench/support.py)."""

from __future__ import annotations


def conductor(radius: str, thickness: str) -> str:
    """The [conductor] table of a polysilicon free disk."""
    return f"""[conductor]
kind = "free_disk"
radius = "{radius}"
thickness = "{thickness}"
youngs_modulus = "160 GPa"
poisson_ratio = 0.22
density = "2330 kg/m^3"
"""


def electrode(name: str, side: str, gap: str, radius: str, sectors: int, more: str = "") -> str:
    """One [[electrodes]] entry: a full ring out to `radius` in `sectors` sectors (plus `more` lines)."""
    return f"""[[electrodes]]
name = "{name}"
side = "{side}"
gap = "{gap}"
rings = [["0 um", "{radius}"]]
sectors = {sectors}
{more}"""


# the 100 um, 2 um polysilicon free disk both structures move
CONDUCTOR = conductor("100 um", "2 um")

# a 100 um disk between two full-disk electrodes at 20 um, a few hundred BEM elements per level
# (format with extractor= and extra=)
SMALL_BEM_DISK = (
    'name = "small_bem"\n'
    + CONDUCTOR
    + electrode("top", "above", "20 um", "100 um", 1)
    + electrode("bot", "below", "20 um", "100 um", 1)
    + """[coordinates]
rigid = ["z"]
[electrostatics]
extractor = "{extractor}"
{extra}
"""
)

# a 100 um disk 10 um under four quadrant electrodes, with its (2,0) cosine mode: a field solve at a
# non-zero mode-shape amplitude (tests/electrostatics/test_fastcap_modes.py, bench/fastcap_mode.py)
MODE_GAP = 10e-6
MODE_DISK = (
    'name = "disk_mode"\n'
    + CONDUCTOR
    + electrode("top", "above", "10 um", "100 um", 4, 'sector_start = "-45 deg"\n')
    + """[coordinates]
modes = ["2,0c"]
[electrostatics]
extractor = "fastcap"
"""
)

# the 200 um free disk over two mirror-image sectors of tests/pipeline/test_import_validation.py and
# bench/import_ulp_sensitivity.py (rigid z and tilt_x, no fringe)
IMPORT_DISK = (
    'name = "disk"\ndescription = "free disk, rigid coordinates only"\n'
    + conductor("200 um", "5 um")
    + electrode("bot", "below", "3 um", "200 um", 2, 'sector_start = "0 deg"\nslot = "10 um"\n')
    + """[coordinates]
rigid = ["z", "tilt_x"]
[sampling]
levels = 3
range = 0.3
[fit]
holdout = 50
[electrostatics]
fringe = "none"
[fem]
refine = 3
"""
)


def reference_layout(gap: float, radius: float = 100e-6):
    """The reference disk's electrode layout (examples/levitated_disk.toml: rings 20-230 and
    240-473 um, four quadrants each, 10 um slots) scaled to `radius`, every electrode above at
    `gap`, under a thin disk plate: (DiskPlate, electrodes). The multipole extractor's tests and
    bench/fastcap_dense_bem.py compare it with the dense BEM."""
    import math

    from netgen.geometry.shapes import AnnularSector, DiskPlate, Electrode

    f = radius / 473e-6
    rings = [(20e-6 * f, 230e-6 * f), (240e-6 * f, radius)]
    els = [
        Electrode(
            AnnularSector(
                f"r{i}s{k}", lo, hi, -math.pi / 4 + k * math.pi / 2, math.pi / 4 + k * math.pi / 2, 10e-6 * f
            ),
            "above",
            gap,
        )
        for i, (lo, hi) in enumerate(rings)
        for k in range(4)
    ]
    return DiskPlate(radius), els
