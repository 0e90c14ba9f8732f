"""The plates under the lateral etch (netgen.model.etch_geometry.etched_plate), shared by
tests/model/test_process_etch_plates.py and tests/emit/test_process_etch_plates_forms.py: the piston
of examples/piston.toml (200 um square, a 2 N/m spring, fringe "none", its electrode "under the whole
plate", so it recedes with the plate) with the etch declared, and the same text rewritten at an etch
(a rebuild: length and width - 2 etch, the electrode again the whole plate); a rigid free disk (z and
both tilts) between two ring electrodes reaching its rim, with its squeeze film, and its rebuilds
(radius - etch, the rims' rings with it)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ETCHES = (-0.5e-6, 0.4e-6, 1.0e-6)  # the range's ends and a point between (m)
PROCESS = '[process]\nparameters = ["etch"]\netch_range = ["-0.5 um", "1 um"]\n'
SIDE = 200e-6  # m: the piston's length and width
GAP = 2e-6  # m: the piston's gap
STIFFNESS = 2.0  # N/m: the piston's spring
RADIUS = 300e-6  # m: the disk's radius


def piston_text(etch: float = 0.0, process: str = PROCESS) -> str:
    """examples/piston.toml with [process] `process` ("" for a rebuild), rewritten at `etch` (m):
    length and width SIDE - 2 etch, the electrode under the whole (etched) plate."""
    text = (ROOT / "examples" / "piston.toml").read_text()
    if etch:
        side = (SIDE - 2 * etch) * 1e6
        for key in ("length", "width"):
            old = f'{key} = "200 um"'
            assert old in text, old
            text = text.replace(old, f'{key} = "{side!r} um"', 1)
    return text + ("\n" + process if process else "")


def area_ratio(etch: float) -> float:
    """The etched piston's area over the drawn one: (L - 2 etch)(W - 2 etch) / (L W)."""
    return ((SIDE - 2 * etch) / SIDE) ** 2


def disk_text(etch: float = 0.0, process: str = PROCESS) -> str:
    """A rigid free disk (RADIUS - etch, 5 um thick) 3 um between two one-ring electrodes of four
    sectors reaching its rim (they recede with it), coordinates z, tilt_x, tilt_y, fringe "plate_between",
    the incompressible squeeze film on a coarse Reynolds mesh (fem_refine 3: the laws are checked
    against rebuilds on the same mesh, scaled), [process] `process` ("" for a rebuild)."""
    rim = f"{(RADIUS - etch) * 1e6!r} um"
    sets = "".join(
        f'[[electrodes]]\nname = "{n}"\nside = "{side}"\ngap = "3 um"\nrings = [["20 um", "{rim}"]]\n'
        'sectors = 4\nslot = "10 um"\n'
        for n, side in (("top", "above"), ("bot", "below"))
    )
    head = (
        'name = "etched_disk"\ndescription = "rigid disk under etch"\n[conductor]\nkind = "free_disk"\n'
        f'radius = "{rim}"\nthickness = "5 um"\nyoungs_modulus = "160 GPa"\npoisson_ratio = 0.22\n'
        'density = "2330 kg/m^3"\n'
    )
    tail = (
        '[coordinates]\nrigid = ["z", "tilt_x", "tilt_y"]\n[sampling]\nlevels = 5\nrange = 0.3\n[fit]\n'
        'tolerance = 0.0002\n[electrostatics]\nfringe = "plate_between"\n'
        "[damping]\nsqueeze_film = true\nfem_refine = 3\n"
    )
    return head + sets + tail + ("\n" + process if process else "")


def modal_disk_text(etch: float = 0.0, process: str = PROCESS) -> str:
    """disk_text with the rigid z and the (2,0) eigenmode (Morley plate, [fem] refine 4), no squeeze
    film (Q = 50: the compressible solve at each mode's frequency would dominate the cost)."""
    text = disk_text(etch, process="").replace('rigid = ["z", "tilt_x", "tilt_y"]', 'rigid = ["z"]\nmodes = ["2,0c"]')
    old = "squeeze_film = true\nfem_refine = 3\n"
    assert old in text
    text = text.replace(old, 'q_factor = { "*" = 50 }\n') + "[fem]\nrefine = 4\n"
    return text + ("\n" + process if process else "")


def tilted_piston_text(etch: float = 0.0, process: str = PROCESS) -> str:
    """piston_text with the tilts (examples/piston.toml's commented tilt spring, 1e-7 N m / rad) and
    the fit box at 0.3 of the touching amplitudes (at 0.6 three coordinates reach within 0.1 g of
    touching at the box's corners, where the fit itself is 5.8e-2 off)."""
    text = piston_text(etch, process)
    for old, new in (
        ("# tilt_stiffness = 1e-7", "tilt_stiffness = 1e-7"),
        ('rigid = ["z"]', 'rigid = ["z", "tilt_x", "tilt_y"]'),
        ("range = 0.6 ", "range = 0.3 "),
    ):
        assert old in text, old
        text = text.replace(old, new, 1)
    return text
