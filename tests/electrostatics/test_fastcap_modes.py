"""The multipole extractor (netgen.electrostatics.fastcap) at a non-zero mode-shape amplitude: a
free disk (100 um radius, 2 um thick) under four quadrant electrodes (centred on +x, +y, -x, -y,
10 um gap), its (2,0)c mode deflecting the rim by 30 % of the gap (no rigid motion), against the
dense BEM (netgen.electrostatics.bem), which moves its own mesh by the same basis.

Tolerance: each solver's extrapolated value carries its own error bar e (Richardson correction
plus, for FastCap, the expansion-order change); with the order assumed, not observed, each is
allowed 2 e (coverage factor 2, as tests/electrostatics/test_fastcap.py::test_against_dense_bem),
so the two agree within 2 (e_fastcap + e_bem). The check is not vacuous: the mode moves every
quadrant's C by 8-12 %, several times that bound, so a solve that missed the mode's motion fails.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("fastcap2")
pytest.importorskip("bempp_cl")

from netgen.core.constants import EPS0  # noqa: E402
from netgen.electrostatics import bem, fastcap  # noqa: E402
from netgen.geometry.layout import electrodes, plate_outline  # noqa: E402
from netgen.mechanics import mechanics  # noqa: E402
from netgen.structure import parse_structure  # noqa: E402
from tests.oracles.small_disk import MODE_DISK, MODE_GAP  # noqa: E402

GAP = MODE_GAP
DISK = MODE_DISK


@pytest.fixture(scope="module")
def disk():
    """(FastCap prepared, dense BEM prepared, q: the (2,0)c mode at 30 % of the gap at its largest)."""
    s = parse_structure(DISK, "disk_mode.toml")
    m, plate, els = mechanics(s), plate_outline(s), electrodes(s)
    pf = fastcap.from_structure(s, plate).prepare(els, plate, m.basis)
    pb = bem.BemExtractor(eps=EPS0, settings=bem.BemSettings(tolerance=1.0, max_levels=2)).prepare(els, plate, m.basis)
    k = m.names.index("m2_0c")
    q = np.zeros(len(m.names))
    q[k] = 0.3 * GAP / np.abs(pf.geometry.probe.phi[:, k]).max()
    return pf, pb, q


@pytest.mark.slow
def test_mode_shape_against_dense_bem(disk):
    """At the mode's amplitude every quadrant's C from FastCap is within 2 (e_f + e_b) of the
    dense BEM's; the quadrants on +-x (the mode's crests, lifted towards the electrodes) gain C
    and those on +-y lose it, each by more than twice that bound (module docstring)."""
    pf, pb, q = disk
    mf, mb = pf.maxwell(q), pb.maxwell(q)
    bound = 2.0 * (mf.error + mb.error)
    assert np.abs(mf.plate_electrode / mb.plate_electrode - 1.0).max() <= bound
    change = mf.plate_electrode / pf.maxwell(np.zeros_like(q)).plate_electrode - 1.0
    assert (change[[0, 2]] > 2.0 * bound).all() and (change[[1, 3]] < -2.0 * bound).all()
