"""The summary table: one Parquet type per column, whatever values a parameter takes."""

from __future__ import annotations

from pathlib import Path

import pytest

pd = pytest.importorskip("pandas")
pytest.importorskip("pyarrow")

from elastoflow.sweep._results import write_summary  # noqa: E402


def _row(point: int, parameters: dict, status: str = "done") -> dict:
    return {"point": point, "parameters": parameters, "status": status, "message": "",
            "steps": 10, "attempts": 1, "resumed_from_step": 0, "results": {"e_final [J]": 1.0}}


def test_a_parameter_of_text_and_numbers_is_written_as_text(tmp_path: Path) -> None:
    # time.substeps is "auto" or a count: the table was not written at all (pyarrow refused
    # the column), after every point had run.
    rows = [_row(0, {"time.substeps": "auto", "fluid.gravity": [0.0, -9.81], "v": 1}),
            _row(1, {"time.substeps": 10, "fluid.gravity": [0.0, 0.0], "v": 2.5}),
            _row(2, {}, "pending")]
    path = write_summary(tmp_path / "summary.parquet", rows,
                         ["time.substeps", "fluid.gravity", "v"])
    table = pd.read_parquet(path)
    assert table["time.substeps"].tolist()[:2] == ["auto", "10"]
    assert pd.isna(table["time.substeps"][2])
    assert table["fluid.gravity"].tolist()[:2] == ["[0.0, -9.81]", "[0.0, 0.0]"]
    # Numbers stay numbers (ints and floats together as floats).
    assert table["v"].dtype == "float64" and table["v"].tolist()[:2] == [1.0, 2.5]
    assert table["status"].tolist() == ["done", "done", "pending"]


def test_parameters_of_one_kind_keep_their_type(tmp_path: Path) -> None:
    rows = [_row(0, {"coupling.scheme": "explicit", "flag": True, "n": 32}),
            _row(1, {"coupling.scheme": "monolithic", "flag": False, "n": 64})]
    table = pd.read_parquet(write_summary(tmp_path / "s.parquet", rows,
                                          ["coupling.scheme", "flag", "n"]))
    assert table["coupling.scheme"].tolist() == ["explicit", "monolithic"]
    assert table["flag"].tolist() == [True, False]
    assert table["n"].tolist() == [32, 64]
