"""The XSPICE code-model libraries (netgen.sim.codemodel; netgen_es beside it) from their sources.

- a cold build into an empty cache (the ngspice source package as `.ci/setup` fetched it):
  cmpp is built, the model preprocessed and compiled, and Debian's ngspice loads the result;
- one electrode with two plate terms, one of them below its contact knee, at a DC point with
  the plate at 0.7 V: the capacitance node and the generalized force equal the closed forms with
  netgen.model.contact's clamp (an independent Python implementation), the force's AC gain equals
  dF/dx, and its gain from the plate voltage is -2F/(V_e - V_p);
- without the ngspice sources the build stops with the fix, and `netgen codemodel` exits 3;
- the target is the ngspice that runs (its own release and switches, both releases), recorded
  beside the .cm; a source tree of another release, and ngspice 46 (whose source is not
  reachable), are refused with exit 3 even where a 39 build is cached; a code model is refused,
  before ngspice starts, by an ngspice it was not built for; the .ifs files pass cmpp 43's rule.
The testbench's own library (netgen_sdloop): tests/testbench/test_sdloop.py.
"""

from __future__ import annotations

import shutil
import tarfile

import numpy as np
import pytest

from netgen.cli import commands as cli
from netgen.model import contact
from netgen.sim import codemodel
from netgen.sim.ngspice import ENV, build_record, identity, run_ngspice
from netgen.testbench.sigma_delta.ngspice import LOOP_LIBRARY
from tests.fixtures import NGSPICE

X, V, FGAIN, CREF, C0, VP = 0.2, 2.0, 0.7, 1.5, 0.25, 0.7  # VP: the plate's potential
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
        assert codemodel.build(progress=lambda m: pytest.fail("rebuilt")) == cm  # cached
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
    card = (
        f".model es netgen_es (term_elec=[0 0] mono_term=[0 0 0 1 1 1] "
        f"mono_coef=[{' '.join(str(a) for t in TERMS for a in t[0])}] mono_exp=[{mono_exp}] "
        f"knee=[{TERMS[0][1]} {TERMS[1][1]}] floor=[{TERMS[0][2]} {TERMS[1][2]}] fgain=[{FGAIN}] "
        f"cref=[{CREF}] c0=[{C0}] stop_a=[0] stop_rate=[0] stop_gain=[0])"
    )
    netlist = "\n".join(
        [
            "netgen_es: one electrode, two plate terms",
            f"Vx xs 0 DC {X} AC 1",
            "Vu us 0 0",
            f"Ve e 0 {V + VP}",
            f"Vp p 0 {VP}",
            "Rf f 0 1",
            "Rc c 0 1",
            "A1 [xs] [%vd(e p)] [us] [f] NULL es",
            "A2 [xs] NULL NULL NULL [c] es",
            card,
            ".control",
            *codemodel.control_lines(cold_build),
            ".endc",
            ".ac lin 1 1k 1k",
            ".end",
            "",
        ]
    )
    plot = run_ngspice(netlist, tmp_path)[0]
    op = run_ngspice(netlist.replace(".ac lin 1 1k 1k", ".op"), tmp_path, name="op")[0]
    plate = run_ngspice(
        netlist.replace(f"DC {X} AC 1", f"DC {X}").replace(f"Vp p 0 {VP}", f"Vp p 0 DC {VP} AC 1"),
        tmp_path,
        name="plate",
    )[0]
    c, f, dfdx = _reference()
    assert TERMS[1][0][0] - 0.4 * X + 0.1 * X * X < TERMS[1][1]  # the second term is clamped
    assert op["v(c)"][0] == pytest.approx(c, rel=1e-9)
    assert op["v(f)"][0] == pytest.approx(f, rel=1e-9)  # with V = V_e - V_plate
    assert plot["v(f)"][0].real == pytest.approx(dfdx, rel=1e-5)  # AC gain = the partial
    assert plate["v(f)"][0].real == pytest.approx(-2 * f / V, rel=1e-9)  # F ~ (V_e - V_p)^2


def test_missing_sources_stop_with_the_fix(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("NETGEN_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("NETGEN_NGSPICE_SOURCE", str(tmp_path / "nowhere"))
    with pytest.raises(codemodel.CodeModelError, match="is not an ngspice source tree"):
        codemodel.build(progress=lambda m: None)
    assert cli.main(["codemodel"]) == 3
    assert "netgen: code model: NETGEN_NGSPICE_SOURCE=" in capsys.readouterr().err
    assert not list((tmp_path / "cache" / "codemodel").glob("*.cm"))


# what each release's binary is, from its banner (ngspice --version: "ngspice-46 ... Compiled with
# KLU") and its commands (39: "osdi: no such command available in ngspice")
BUILDS = {
    "39": {"version": "ngspice-39", "major": 39, "minor": 0, "klu": False, "osdi": False},
    "46": {"version": "ngspice-46", "major": 46, "minor": 0, "klu": True, "osdi": True},
}


def test_target_is_the_binarys_own_release_and_switches(ngspice_version):
    """identity() of each release: its own banner's release, KLU and OSDI (not dpkg's version)."""
    who = identity()
    assert {k: who[k] for k in BUILDS["39"]} == BUILDS[str(ngspice_version.major)]
    assert who["path"] == shutil.which(NGSPICE[str(ngspice_version.major)])


def test_build_record_names_the_ngspice_it_was_built_for(cold_build):
    """Beside the .cm: the target (Debian's 39: no KLU, no OSDI, so neither is defined), the
    source it was built from, the compile's switches."""
    rec = codemodel.record(cold_build)
    assert build_record(cold_build).exists()
    assert {k: rec["ngspice"][k] for k in BUILDS["39"]} == BUILDS["39"]
    assert rec["source"].startswith("Debian source package ngspice 39.3")
    assert rec["defines"] == ["XSPICE", "CIDER", "WITH_PSS", "SIMULATOR"]


def _tree_39(tmp_path):
    """Debian's ngspice 39 source tree (configure.ac and the code-model preprocessor), unpacked."""
    tarball = sorted((codemodel.cache_dir() / "ngspice-source").glob("ngspice_*.orig.tar.*"))[0]
    with tarfile.open(tarball) as tar:
        members = [m for m in tar.getmembers() if m.name.endswith(("/configure.ac", "/src/xspice/cmpp/main.c"))]
        tar.extractall(tmp_path / "src", members=members, filter="data")
    return next((tmp_path / "src").iterdir())


def test_a_source_tree_of_another_release_is_refused(tmp_path, monkeypatch, capsys):
    """NETGEN_NGSPICE_SOURCE at 39's tree for ngspice 46: refused naming both releases, although
    the real cache holds 39's builds (which the cache key on dpkg's version used to return); then
    `netgen codemodel` exits 3 and the cache gains no .cm."""
    tree = _tree_39(tmp_path)
    assert codemodel.build(progress=lambda m: None).exists()  # the cached 39 build
    monkeypatch.setenv(ENV, NGSPICE["46"])
    monkeypatch.setenv("NETGEN_NGSPICE_SOURCE", str(tree))
    with pytest.raises(
        codemodel.CodeModelError,
        match="is the source of ngspice-39 and the target ngspice .* is "
        "ngspice-46: a code model built from another release crashes ngspice",
    ):
        codemodel.build(progress=lambda m: pytest.fail("built"))
    monkeypatch.setenv("NETGEN_CACHE", str(tmp_path / "cache"))
    assert cli.main(["codemodel"]) == 3
    assert "ngspice-39" in capsys.readouterr().err
    assert not list((tmp_path / "cache").rglob("*.cm"))


def test_ngspice_46_without_its_source_exits_3_naming_osdi(tmp_path, monkeypatch, capsys):
    """No source of ngspice 46 is reachable (not a Debian package here): exit 3, OSDI named as
    the fast path there, nothing built."""
    monkeypatch.setenv("NETGEN_CACHE", str(tmp_path / "cache"))
    monkeypatch.delenv("NETGEN_NGSPICE_SOURCE", raising=False)
    assert cli.main(["--ngspice", NGSPICE["46"], "codemodel"]) == 3
    err = capsys.readouterr().err
    assert "no source of ngspice-46" in err and "netgen build --format osdi" in err
    assert not list((tmp_path / "cache").rglob("*.cm"))


def test_loading_into_another_ngspice_is_refused_before_it_starts(cold_build, tmp_path, capsys):
    """A netlist that loads the 39 build, run by `netgen --ngspice <46> simulate`: exit 3 naming
    both releases and the alternative, no run folder (ngspice never started); on 39 it runs. A
    netgen code model without its build record is refused too."""
    netlist = tmp_path / "load.cir"
    netlist.write_text(f"load\nR1 a 0 1\nV1 a 0 1\n.control\npre_codemodel {cold_build}\n.endc\n.op\n.end\n")
    assert cli.main(["--ngspice", NGSPICE["46"], "simulate", str(netlist), "-o", str(tmp_path / "run46")]) == 3
    err = capsys.readouterr().err
    assert "built for ngspice-39" in err and "this run uses ngspice-46" in err and "--format osdi" in err
    assert not (tmp_path / "run46").exists()
    assert cli.main(["simulate", str(netlist), "-o", str(tmp_path / "run39"), "-q"]) == 0
    assert (tmp_path / "run39" / "load.log").read_text().startswith("netgen: ran ngspice-39 (")
    bare = tmp_path / "netgen_es-copy.cm"
    shutil.copy(cold_build, bare)
    netlist.write_text(netlist.read_text().replace(str(cold_build), str(bare)))
    assert cli.main(["simulate", str(netlist), "-o", str(tmp_path / "bare"), "-q"]) == 3
    assert "has no build record" in capsys.readouterr().err


def test_ifs_files_pass_the_rule_of_cmpp_43_and_later():
    """cmpp 43+ rejects a parameter with a default and Null_Allowed: no (writ_ifs.c: "Default value
    given for parameter ... but the user must set instance value"); 39 accepts it. Both libraries
    are clean, and the rule catches such a table."""
    for lib in (codemodel.MODEL, LOOP_LIBRARY):
        assert codemodel.ifs_problems((lib.sources / lib.name / "ifspec.ifs").read_text()) == [], lib.name
    table = "PARAMETER_TABLE:\nParameter_Name: a b c\nDefault_Value: 0 - 1.0\nNull_Allowed: no no yes\n"
    assert codemodel.ifs_problems(table) == ["a"]
