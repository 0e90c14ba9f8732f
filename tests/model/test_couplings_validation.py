"""A model JSON's couplings and calibration record are checked on load (netgen.model.validate):
each bad entry is a ModelError naming the entry and the fix, never a netlist with it."""

from __future__ import annotations

import copy

import pytest

from netgen.core.errors import ModelError
from netgen.model import MacroModel
from tests.fixtures import ROOT

JSON = ROOT / "netlists" / "levitated_disk.json"


@pytest.fixture(scope="module")
def doc() -> dict:
    """The reference model's JSON with one coupling and a calibration record."""
    d = MacroModel.load_json(JSON).to_dict()
    a, b = d["electrodes"][0]["name"], d["electrodes"][1]["name"]
    d["coupling"] = [{"pair": [a, b], "capacitance": 1e-14}]
    d["calibration"] = {
        "source": "test",
        "points": 3,
        "fringe": [{"electrode": a, "a": 0.4, "b": 0.06, "length": 4.73e-4}],
    }
    return d


def test_good_record_loads_and_round_trips(doc):
    """The couplings become the symmetric matrix; the record survives to_dict."""
    m = MacroModel.from_dict(copy.deepcopy(doc))
    assert m.coupling[0, 1] == m.coupling[1, 0] == 1e-14
    assert m.to_dict()["calibration"] == doc["calibration"]


def _set(path, value):
    def change(d):
        *head, last = path
        for k in head:
            d = d[k]
        d[last] = value

    return change


BAD = {
    "negative": (_set(["coupling", 0, "capacitance"], -1e-15), "coupling[0].capacitance", "negative"),
    "self": (
        lambda d: d["coupling"][0]["pair"].__setitem__(1, d["coupling"][0]["pair"][0]),
        "coupling[0].pair",
        "to itself",
    ),
    "twice": (
        lambda d: d["coupling"].append({"pair": d["coupling"][0]["pair"][::-1], "capacitance": 1e-14}),
        "coupling[1].pair",
        "given twice",
    ),
    "string value": (_set(["coupling", 0, "capacitance"], "1e-14"), "coupling[0].capacitance", "not a finite number"),
    "unknown electrode": (_set(["coupling", 0, "pair", 1], "nowhere"), "coupling[0].pair[1]", "not one of"),
    "fringe electrode": (
        _set(["calibration", "fringe", 0, "electrode"], "nowhere"),
        "calibration.fringe[0].electrode",
        "not one of",
    ),
    "fringe length": (
        _set(["calibration", "fringe", 0, "length"], 0.0),
        "calibration.fringe[0].length",
        "not a positive",
    ),
    "fringe b": (_set(["calibration", "fringe", 0, "b"], None), "calibration.fringe[0].b", "not a finite number"),
    "record": (_set(["calibration"], []), "calibration", "must be an object"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_bad_entries_are_model_errors(doc, case):
    """Each corruption: a ModelError naming the entry, with the fix."""
    change, where, problem = BAD[case]
    d = copy.deepcopy(doc)
    change(d)
    with pytest.raises(ModelError) as info:
        MacroModel.from_dict(d, "model.json")
    assert info.value.where == where and problem in info.value.problem and info.value.fix
