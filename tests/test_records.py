"""The records table (tests/records.py): fails on drift either way, at rounding level only upwards."""

import json

import pytest

from records import BETTER, PATH, WORSE, Records, floor_of


@pytest.fixture
def table(tmp_path):
    path = tmp_path / "records.json"
    path.write_text(json.dumps({"case": {"@": "abc on cpu", "mean": 0.2, "d1_deg": 1e-3, "tiny": 2e-8}}))
    return path


def test_a_value_near_its_record_passes(table):
    Records(False, table).check("case", mean=0.21, d1_deg=0.9e-3, tiny=1e-9)


@pytest.mark.parametrize(
    "values, message",
    [
        ({"mean": 0.2 * WORSE * 1.01, "d1_deg": 1e-3, "tiny": 2e-8}, "mean worse"),
        ({"mean": 0.2 / BETTER * 0.99, "d1_deg": 1e-3, "tiny": 2e-8}, "mean better"),
        ({"mean": 0.2, "d1_deg": 1e-3, "tiny": WORSE * floor_of("tiny") * 1.01}, "tiny worse"),
        ({"mean": -0.31, "d1_deg": 1e-3, "tiny": 2e-8}, "mean worse"),  # signed errors by magnitude
        ({"mean": 0.2, "d1_deg": 1e-3}, "the record has"),
        ({"mean": 0.2, "d1_deg": float("nan"), "tiny": 0.0}, "d1_deg is nan"),
    ],
)
def test_drift_either_way_fails(table, values, message):
    with pytest.raises(AssertionError, match=message):
        Records(False, table).check("case", **values)


def test_an_unknown_case_fails(table):
    with pytest.raises(AssertionError, match="no record for 'other'"):
        Records(False, table).check("other", mean=0.2)


def test_update_mode_merges_and_keeps_the_rest(table):
    records = Records(True, table)
    records.check("new", mean=0.123456, k1_deg=2e-5)
    records.check("case", mean=0.5, d1_deg=1e-3, tiny=0.0)  # no assertion in update mode
    records.write()
    written = json.loads(table.read_text())
    assert written["new"]["mean"] == 0.1235 and written["new"]["k1_deg"] == 2e-5 and " on " in written["new"]["@"]
    assert written["case"]["mean"] == 0.5 and list(written) == ["case", "new"]


def test_the_table_is_well_formed():
    table = json.loads(PATH.read_text())
    assert list(table) == sorted(table) and len(table) > 20
    for key, record in table.items():
        assert " on " in record["@"], key
        values = [v for m, v in record.items() if m != "@"]
        assert values and all(isinstance(v, float) and v == v for v in values), key
