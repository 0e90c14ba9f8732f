"""The build report <name>_report.html (netgen.emit.report) and a sigma-delta run's report.html
(netgen.testbench.sigma_delta.report): their numbers are the JSON's, they are self-contained,
and a real browser (Debian's chromium, headless, installed by .ci/setup) renders them with no
console error into a screenshot that is not blank. Build pages: one written by `netgen build` of
the one-coordinate accelerometer, one rendered from the committed levitated disk (31 ports,
modes) with its committed figures; run page: a 64-period run of the disk's loop (ngspice)."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import numpy as np
import pytest
from matplotlib import image

from netgen.cli import commands as cli
from netgen.emit import report
from netgen.model import MacroModel
from tests.fixtures import ROOT

NETLISTS = ROOT / "netlists"


class Tables(HTMLParser):
    """Every <table id=...>: its own rows (not those of tables nested in it) as lists of (text,
    data-value or None) cells; every src/href attribute; the SVG <path d=...> attributes."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[tuple[str, str | None]]]] = {}
        self.links: list[str] = []
        self.paths: list[str] = []
        self._open: list[str | None] = []  # the table ids from the outermost to the innermost
        self._cell: list | None = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        self.links += [v for k, v in attrs if k in ("src", "href")]
        table = self._open[-1] if self._open else None
        if tag == "path":
            self.paths.append(a["d"])
        if tag == "table":
            self._open.append(a.get("id"))
            if a.get("id"):
                self.tables[a["id"]] = []
        elif tag == "tr" and table:
            self.tables[table].append([])
        elif tag == "td" and table:
            self._cell = ["", a.get("data-value")]

    def handle_data(self, data):
        if self._cell is not None:
            self._cell[0] += data

    def handle_endtag(self, tag):
        if tag == "td" and self._cell is not None and self._open and self._open[-1]:
            self.tables[self._open[-1]][-1].append((self._cell[0].strip(), self._cell[1]))
            self._cell = None
        elif tag == "table":
            self._open.pop()


@pytest.fixture(scope="module")
def run_page(tmp_path_factory) -> tuple[Path, dict]:
    """A 64-period sigma-delta run of the committed disk model: (report.html, summary.json)."""
    out = tmp_path_factory.mktemp("sd") / "run"
    (out / "model").mkdir(parents=True)
    for suffix in (".json", ".lib"):
        shutil.copy(NETLISTS / f"levitated_disk{suffix}", out / "model")
    args = ["sigma-delta", str(ROOT / "examples" / "levitated_disk.toml"), "--cycles", "64", "-q", "-o", str(out)]
    assert cli.main([*args, "--model", str(out / "model" / "levitated_disk.json")]) == 0
    return out / "report.html", json.loads((out / "summary.json").read_text())


def test_run_report_numbers_equal_the_summary(run_page):
    """Held or not as the summary says; every channel's scalar entries are summary.json's."""
    page, summary = run_page
    t = parsed(page)
    text = page.read_text(encoding="utf-8")
    assert ("The loop held the plate" in text) == summary["levitation"]["held"]
    assert all(link.startswith("data:") for link in t.links) and len(t.links) == 2  # spectra, coordinates
    rows = t.tables["channels"]
    for (name, entries), row in zip(summary["channels"].items(), [r for r in rows if r]):
        assert row[0][0] == name
        shown = [float(v) for _, v in row[1:] if v is not None]
        assert shown == [v for v in entries.values() if isinstance(v, (int, float)) and not isinstance(v, bool)]


def test_run_report_renders_in_chromium(run_page, tmp_path):
    """As the build reports: no console message, a screenshot that is not blank."""
    shot, console = chromium(run_page[0], tmp_path)
    assert console == [] and shot[..., :3].mean(axis=-1).std() > 0.05


@pytest.fixture(scope="module")
def pages(tmp_path_factory) -> dict[str, tuple[Path, dict]]:
    """name -> (report page, model JSON dict): a CLI build and the committed disk's page."""
    out = tmp_path_factory.mktemp("report")
    code = cli.main(["build", str(ROOT / "examples" / "accelerometer_z.toml"), "-o", str(out / "az"), "-q"])
    assert code == 0
    az = out / "az" / "accelerometer_z_report.html"
    model = MacroModel.load_json(NETLISTS / "levitated_disk.json")
    written = sorted(p for p in NETLISTS.glob("levitated_disk*") if p.is_file() and "manifest" not in p.name)
    disk = out / "levitated_disk_report.html"
    disk.write_text(
        report.page(model, [p.name for p in written], {p.name: p.read_bytes() for p in written if p.suffix == ".png"})
    )
    return {
        "accelerometer_z": (az, json.loads((out / "az" / "accelerometer_z.json").read_text())),
        "levitated_disk": (disk, json.loads((NETLISTS / "levitated_disk.json").read_text())),
    }


def parsed(page: Path) -> Tables:
    t = Tables()
    t.feed(page.read_text(encoding="utf-8"))
    return t


def numbers(rows: list[list[tuple[str, str | None]]]) -> list[list[float]]:
    """The data-value numbers of each row, checked against their shown text (6 digits: 5e-6
    relative at most; 4 digits for the fit errors)."""
    out = []
    for row in rows:
        values = []
        for text, value in row:
            if value is None:
                continue
            v = float(value)
            assert float(text) == pytest.approx(v, rel=5e-4 if "e-" in text and len(text) < 10 else 5e-6, abs=1e-300)
            values.append(v)
        if values:
            out.append(values)
    return out


@pytest.mark.parametrize("name", ["accelerometer_z", "levitated_disk"])
def test_report_numbers_equal_the_json(pages, name):
    """Coordinates (scale, mass, stiffness, damping, frequency), electrodes (gap, area), fits
    (c_ref, held-out max and rms error) and contact values are the JSON's, bit for bit."""
    page, d = pages[name]
    t = parsed(page)
    keys = ("scale", "mass", "stiffness", "damping", "frequency_hz")
    assert numbers(t.tables["coordinates"]) == [[c[k] for k in keys] for c in d["coordinates"]]
    assert numbers(t.tables["electrodes"]) == [[e["gap"], e["area"]] for e in d["electrodes"]]
    fits = [[f["c_ref"], f["max_rel_error"], f["rms_rel_error"]] for f in d["capacitances"]]
    assert numbers(t.tables["fits"]) == fits
    contact = [[v] for v in d["contact"].values() if isinstance(v, float)]
    assert numbers(t.tables["contact"]) == contact
    ports = [[cell for cell, _ in row] for row in t.tables["ports"] if row]
    assert [(r[1], r[3]) for r in ports] == [(p["name"], p["unit"]) for p in d["ports"]]


@pytest.mark.parametrize("name", ["accelerometer_z", "levitated_disk"])
def test_report_is_self_contained_and_draws_the_layout_to_scale(pages, name):
    """Every src/href is inline data; the SVG's conductor outline is the JSON's layout (in um,
    written with 4 digits: 5e-4 of the outline's size), one label per electrode."""
    page, d = pages[name]
    t = parsed(page)
    assert t.links and all(link.startswith("data:") for link in t.links)
    text = page.read_text(encoding="utf-8")
    assert "<link" not in text and "<script" not in text and "url(" not in text
    pts = np.array([[float(v) for v in p.split(",")] for p in re.findall(r"[-\d.e]+,[-\d.e]+", t.paths[0])])
    x, y = np.array(d["layout"]["conductor"]) * 1e6
    size = np.ptp(x)
    assert np.max(np.abs(pts[:, 0] - x)) <= 5e-4 * size and np.max(np.abs(pts[:, 1] + y)) <= 5e-4 * size
    labels = re.findall(r'text-anchor="middle">([^<]+)</text>', text)
    assert labels == [e["name"] for e in d["electrodes"]]


def chromium(page: Path, tmp: Path) -> tuple[np.ndarray, list[str]]:
    """Headless chromium's screenshot (1200 x 2000) of `page` and its console lines (logged on
    stderr as ':CONSOLE' with --enable-logging=stderr --v=0)."""
    exe = shutil.which("chromium")
    if exe is None:
        pytest.fail("chromium is not installed: run `bash .ci/setup` (it installs Debian's chromium)")
    shot = tmp / f"{page.stem}.png"
    done = subprocess.run(
        [exe, "--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", f"--user-data-dir={tmp / 'profile'}",
         "--enable-logging=stderr", "--v=0", f"--screenshot={shot}", "--window-size=1200,2000", page.as_uri()],
        capture_output=True, text=True, timeout=180, stdin=subprocess.DEVNULL,
    )  # fmt: skip
    assert done.returncode == 0 and shot.exists(), done.stderr[-2000:]
    return image.imread(shot), [line for line in done.stderr.splitlines() if ":CONSOLE" in line]


def test_console_check_sees_errors(tmp_path):
    """The control: a page with a console.error and an uncaught exception logs two console lines."""
    bad = tmp_path / "bad.html"
    bad.write_text('<!DOCTYPE html><p>x</p><script>console.error("boom"); undefined_fn();</script>')
    _, console = chromium(bad, tmp_path)
    assert len(console) == 2


@pytest.mark.parametrize("name", ["accelerometer_z", "levitated_disk"])
def test_report_renders_in_chromium(pages, name, tmp_path):
    """No console message, and a screenshot that is not blank: its grey levels vary (a blank page's
    standard deviation is 0; text, tables and figures on white give well over 0.05)."""
    shot, console = chromium(pages[name][0], tmp_path)
    assert console == []
    grey = shot[..., :3].mean(axis=-1)
    assert grey.std() > 0.05
