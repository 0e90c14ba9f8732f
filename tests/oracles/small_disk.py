"""Small free disks the extractor tests and their benches share (tests/fixtures.py re-exports
SMALL_BEM_DISK; bench scripts load this module through bench/support.py)."""

from __future__ import annotations

# the 100 um, 2 um polysilicon free disk both structures move
CONDUCTOR = """[conductor]
kind = "free_disk"
radius = "100 um"
thickness = "2 um"
youngs_modulus = "160 GPa"
poisson_ratio = 0.22
density = "2330 kg/m^3"
"""

# a 100 um disk between two full-disk electrodes at 20 um, a few hundred BEM elements per level
# (format with extractor= and extra=)
SMALL_BEM_DISK = (
    'name = "small_bem"\n'
    + CONDUCTOR
    + """[[electrodes]]
name = "top"
side = "above"
gap = "20 um"
rings = [["0 um", "100 um"]]
sectors = 1
[[electrodes]]
name = "bot"
side = "below"
gap = "20 um"
rings = [["0 um", "100 um"]]
sectors = 1
[coordinates]
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
    + """[[electrodes]]
name = "top"
side = "above"
gap = "10 um"
rings = [["0 um", "100 um"]]
sectors = 4
sector_start = "-45 deg"
[coordinates]
modes = ["2,0c"]
[electrostatics]
extractor = "fastcap"
"""
)

# the 200 um free disk over two mirror-image sectors of tests/pipeline/test_import_validation.py and
# bench/import_ulp_sensitivity.py (rigid z and tilt_x, no fringe)
IMPORT_DISK = """name = "disk"
description = "free disk, rigid coordinates only"
[conductor]
kind = "free_disk"
radius = "200 um"
thickness = "5 um"
youngs_modulus = "160 GPa"
poisson_ratio = 0.22
density = "2330 kg/m^3"
[[electrodes]]
name = "bot"
side = "below"
gap = "3 um"
rings = [["0 um", "200 um"]]
sectors = 2
sector_start = "0 deg"
slot = "10 um"
[coordinates]
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
