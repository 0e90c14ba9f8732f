"""The XSPICE code-model libraries (netgen.sim.codemodel; netgen_es beside it) from their sources.

- a cold build into an empty cache (the ngspice source package as `.ci/setup` fetched it):
  cmpp is built, the model preprocessed and compiled, and Debian's ngspice loads the result;
- one electrode with two plate terms, one of them below its contact knee, at a DC point with
  the plate at 0.7 V: the capacitance node and the generalized force equal the closed forms with
  netgen.model.contact's clamp (an independent Python implementation), the force's AC gain equals
  dF/dx, and its gain from the plate voltage is -2F/(V_e - V_p);
- without the ngspice sources the build stops with the fix, and `netgen codemodel` exits 3.
The testbench's own library (netgen_sdloop): tests/testbench/test_sdloop.py.
"""

from __future__ import annotations

import numpy as np
import pytest

from netgen import cli
from netgen.model import contact
from netgen.sim import codemodel
from netgen.sim.ngspice import run_ngspice

X, V, FGAIN, CREF, C0, VP = 0.2, 2.0, 0.7, 1.5, 0.25, 0.7     # VP: the plate's potential
# P_1 = 1 + 0.5 x (above its knee), P_2 = 0.3 - 0.4 x + 0.1 x^2 (= 0.224 at x = 0.2, below its knee 0.25)
TERMS = [([1.0, 0.5, 0.0], 0.1, 0.04), ([0.3, -0.4, 0.1], 0.25, 0.1)]


@pytest.fixture(scope="module")
def cold_build(tmp_path_factory):
    """A build into an empty cache; the source tarball is the one the real cache holds (no network)."""
    cached = sorted((codemodel.cache_dir() / "ngspice-source").glob("ngspice_*.orig.tar.*"))
    assert cached, "run .ci/setup first: it fetches the ngspice source package and builds the code model"
    cache = tmp_path_factory.mktemp("cache")
    src = cache / "codemodel" / "ngspice-source"
    src.mkdir(parents=True)
    (src / cached[0].name).symlink_to(cached[0])
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("NETGEN_CACHE", str(cache))
        mp.delenv("NETGEN_NGSPICE_SOURCE", raising=False)
        cm = codemodel.build(progress=lambda m: None)
        assert cm.parent == cache / "codemodel" and cm.exists()
        assert codemodel.build(progress=lambda m: pytest.fail("rebuilt")) == cm        # cached
    return cm


def _reference() -> tuple[float, float, float]:
    """c = sum g - c0, F = -fgain cref V^2 sum g^2 s dP/dx, dF/dx, from netgen.model.contact.clamp."""
    def parts(x):
        c, f = -C0, 0.0
        for (a0, a1, a2), knee, floor in TERMS:
            p, dp = a0 + a1 * x + a2 * x * x, a1 + 2 * a2 * x
            pe, s = contact.clamp(np.array(p), np.array(knee), np.array(floor))
            c += 1 / pe
            f -= FGAIN * CREF * V * V * s / pe**2 * dp
        return float(c), float(f)
    c, f = parts(X)
    h = 1e-6
    return c, f, (parts(X + h)[1] - parts(X - h)[1]) / (2 * h)


def test_cold_build_evaluates_clamped_plate_terms(cold_build, tmp_path):
    mono_exp = "0 1 2 0 1 2"
    card = (f".model es netgen_es (term_elec=[0 0] mono_term=[0 0 0 1 1 1] "
            f"mono_coef=[{' '.join(str(a) for t in TERMS for a in t[0])}] mono_exp=[{mono_exp}] "
            f"knee=[{TERMS[0][1]} {TERMS[1][1]}] floor=[{TERMS[0][2]} {TERMS[1][2]}] fgain=[{FGAIN}] "
            f"cref=[{CREF}] c0=[{C0}] stop_a=[0] stop_rate=[0] stop_gain=[0])")
    netlist = "\n".join([
        "netgen_es: one electrode, two plate terms", f"Vx xs 0 DC {X} AC 1", "Vu us 0 0", f"Ve e 0 {V + VP}",
        f"Vp p 0 {VP}", "Rf f 0 1", "Rc c 0 1", "A1 [xs] [%vd(e p)] [us] [f] NULL es", "A2 [xs] NULL NULL NULL [c] es",
        card,
        ".control", *codemodel.control_lines(cold_build), ".endc", ".ac lin 1 1k 1k", ".end", ""])
    plot = run_ngspice(netlist, tmp_path)[0]
    op = run_ngspice(netlist.replace(".ac lin 1 1k 1k", ".op"), tmp_path, name="op")[0]
    plate = run_ngspice(netlist.replace(f"DC {X} AC 1", f"DC {X}").replace(f"Vp p 0 {VP}", f"Vp p 0 DC {VP} AC 1"),
                        tmp_path, name="plate")[0]
    c, f, dfdx = _reference()
    assert TERMS[1][0][0] - 0.4 * X + 0.1 * X * X < TERMS[1][1]           # the second term is clamped
    assert op["v(c)"][0] == pytest.approx(c, rel=1e-9)
    assert op["v(f)"][0] == pytest.approx(f, rel=1e-9)                     # with V = V_e - V_plate
    assert plot["v(f)"][0].real == pytest.approx(dfdx, rel=1e-5)              # AC gain = the partial
    assert plate["v(f)"][0].real == pytest.approx(-2 * f / V, rel=1e-9)       # F ~ (V_e - V_p)^2


def test_missing_sources_stop_with_the_fix(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("NETGEN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("NETGEN_NGSPICE_SOURCE", str(tmp_path / "nowhere"))
    with pytest.raises(codemodel.CodeModelError, match="is not an ngspice source tree"):
        codemodel.build(progress=lambda m: None)
    assert cli.main(["codemodel"]) == 3
    assert "netgen: code model: NETGEN_NGSPICE_SOURCE=" in capsys.readouterr().err
    assert not list((tmp_path / "cache" / "codemodel").glob("*.cm"))
