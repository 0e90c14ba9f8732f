"""The beam conductors under the lateral etch (netgen.model.process.etched_beam), shared by
tests/model/test_process_etch_beams.py, tests/emit/test_process_etch_beams_forms.py and
bench/process_etch_beams.py: examples/cantilever.toml and examples/cc_beam.toml with the electrode
drawn past the beam (x to 160 um on the 150 um cantilever, y +-30 um on the 50 um width), so that
with fringe "none" the facing area is the etched beam's whole area at every etch of the range, and
the a_in port; the same text rewritten at an etch (a rebuild) and the Euler-Bernoulli closed forms;
and examples/cantilever.toml as drawn (drawn_text: the electrode's edges on the beam's)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
ETCHES = (-0.2e-6, 0.1e-6, 0.3e-6)  # the range's ends and a point between (m)
RANGE = 'etch_range = ["-0.2 um", "0.3 um"]\n'
PROCESS = '[process]\nparameters = ["etch"]\n' + RANGE
WIDTH = {"cantilever": 50e-6, "cc_beam": 50e-6}
LENGTH = {"cantilever": 150e-6, "cc_beam": 300e-6}


def beam_text(name: str, etch: float = 0.0, process: str = PROCESS, electrode_x: float | None = None) -> str:
    """examples/<name>.toml (cantilever or cc_beam) with the electrode past the beam, a_in, and
    [process] `process` (""  for a rebuild); at `etch` (m) the file rewritten with the etched width
    w - 2 etch and, for the cantilever, its tip back by etch (length L - etch). `electrode_x`: the
    electrode's far end along x in um (default: 160 um for the cantilever, the beam's length for
    the clamped-clamped beam)."""
    text = (ROOT / "examples" / f"{name}.toml").read_text()
    length_um = LENGTH[name] * 1e6
    far = electrode_x if electrode_x is not None else (160.0 if name == "cantilever" else length_um)
    edits = [
        (f'x = ["0 um", "{length_um:g} um"]', f'x = ["0 um", "{far!r} um"]\ny = ["-30 um", "30 um"]'),
        ("modes = 3 ", "acceleration_port = true\nmodes = 3 "),
    ]
    if etch:
        width = (WIDTH[name] - 2 * etch) * 1e6
        length = (LENGTH[name] - (etch if name == "cantilever" else 0.0)) * 1e6
        edits += [
            ('width = "50 um"', f'width = "{width!r} um"'),
            (f'length = "{length_um:g} um"', f'length = "{length!r} um"'),
        ]
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    return text + ("\n" + process if process else "")


def width_ratio(name: str, etch: float) -> float:
    """(w - 2 etch) / w."""
    return (WIDTH[name] - 2 * etch) / WIDTH[name]


def length_ratio(name: str, etch: float) -> float:
    """L(etch) / L: the cantilever's tip recedes by etch, the clamped-clamped beam's length stays."""
    return (LENGTH[name] - etch) / LENGTH[name] if name == "cantilever" else 1.0


def modal_ratios(name: str, etch: float) -> tuple[float, float, float]:
    """Euler-Bernoulli (mass, stiffness, frequency) of every peak-normalised bending mode at `etch` over
    the drawn beam's: the mode shapes are functions of x / L alone, so the modal mass is rho w t L times
    a constant, the modal stiffness E w t^3 / 12 / L^3 times a constant and f ~ (t / L^2) sqrt(E / rho):
    m ~ w L, k ~ w / L^3, f ~ 1 / L^2 (independent of the width)."""
    w, ell = width_ratio(name, etch), length_ratio(name, etch)
    return w * ell, w / ell**3, 1.0 / ell**2


def drawn_text(etch: float = 0.0, process: str = PROCESS) -> str:
    """examples/cantilever.toml as drawn (electrode x 0..150 um, y the drawn width: its edges on the
    beam's, so an under-etched beam overhangs it), [process] `process` ("" for a rebuild); at `etch`
    (m) the file rewritten at the etched width and length with the electrode where it was drawn."""
    text = (ROOT / "examples" / "cantilever.toml").read_text()
    text = text.replace('x = ["0 um", "150 um"]', 'x = ["0 um", "150 um"]\ny = ["-25 um", "25 um"]')
    if etch:
        text = text.replace('width = "50 um"', f'width = "{50 - 2e6 * etch!r} um"')
        text = text.replace('length = "150 um"', f'length = "{150 - 1e6 * etch!r} um"')
    return text + ("\n" + process if process else "")
