"""The lab's human motion data CSV (the utility set import) reads plain decimals only:
what Python's `int` and `float` also accept (`1_0` as 10, other scripts' digits, `inf`,
`nan`, padding inside a number) is refused with the row and the column."""

from __future__ import annotations

import math

import pytest
from fastapi.testclient import TestClient
from hypothesis import given
from hypothesis import strategies as st

from backend.analysis.human_data_csv import CsvError, parse_human_data
from controller.human_data import HUMAN_MOTIONS, LEGS, N_PROGRESS

HEADER = "motion,leg,n,theta_rad,tau_nm"


def _rows(theta: str = "0.5", tau: str = "-12.25") -> list[str]:
    return [f"{m},{leg},{n},{theta},{tau}" for m in HUMAN_MOTIONS for leg in LEGS
            for n in range(N_PROGRESS)]


def _csv(rows: list[str]) -> str:
    return "\n".join([HEADER, *rows]) + "\n"


def test_a_complete_file_of_plain_decimals_is_read() -> None:
    data = parse_human_data(_csv(_rows("+1.5e-1", "-.25")), "lab")
    assert data.theta[0, 0, 0] == 0.15 and data.tau[3, 1, 100] == -0.25


@pytest.mark.parametrize(("column", "cell"), [
    ("n", "1_0"), ("theta_rad", "1_0"), ("tau_nm", "1_000.5"), ("theta_rad", "٠.٥"),
    ("n", "١٠"), ("tau_nm", "inf"), ("theta_rad", "nan"), ("tau_nm", "1e5_0"),
    ("n", "+3"), ("n", "3.0"), ("theta_rad", "0x1"), ("tau_nm", '"1,5"'), ("tau_nm", "- 1"),
    ("theta_rad", "١e1"), ("n", "²")])
def test_what_is_not_a_plain_decimal_is_refused_naming_row_and_column(
        column: str, cell: str) -> None:
    rows = _rows()
    motion, leg, n, theta, tau = rows[4].split(",")
    cells = {"n": n, "theta_rad": theta, "tau_nm": tau} | {column: cell}
    rows[4] = ",".join([motion, leg, cells["n"], cells["theta_rad"], cells["tau_nm"]])
    with pytest.raises(CsvError) as refused:
        parse_human_data(_csv(rows), "lab")
    assert (refused.value.row, refused.value.column) == (6, column)
    assert str(refused.value).startswith(f"row 6, column {column}: not a plain ")


@given(st.floats(min_value=-6.0, max_value=6.0, allow_nan=False),
       st.sampled_from(["{!r}", "{:.3e}", "{:.6f}", "{:g}", "{:E}"]))
def test_every_decimal_a_program_writes_is_read_as_written(value: float, form: str) -> None:
    text = form.format(value)
    rows = _rows()
    motion, leg, n, _, tau = rows[0].split(",")
    rows[0] = ",".join([motion, leg, n, text, tau])
    data = parse_human_data(_csv(rows), "lab")
    assert math.isclose(data.theta[0, 0, 0], float(text), rel_tol=0, abs_tol=0)


def test_the_import_answers_422_with_the_row_and_column(client: TestClient) -> None:
    assert client.post("/api/studies", json={"name": "s"}).status_code == 201
    rows = _rows()
    rows[0] = rows[0].replace(",0.5,", ",1_0,")
    r = client.post("/api/studies/1/utility-sets/import",
                    data={"name": "lab data", "precompression_pct": "25"},
                    files={"file": ("data.csv", _csv(rows).encode(), "text/csv")})
    assert r.status_code == 422, r.text
    detail = r.json()["detail"][0]
    assert detail["loc"] == ["body", "file", "row 2", "theta_rad"]
    assert detail["msg"].startswith("not a plain decimal number") and "'1_0'" in detail["msg"]


@pytest.mark.parametrize("cell", ["9" * 5001, "1" + "0" * 4400, "0" * 5000 + "101", "1000"])
def test_an_n_of_thousands_of_digits_is_out_of_range_naming_row_and_column(cell: str) -> None:
    # int() raises ValueError (not CsvError) beyond 4,300 digits: the length is bounded first.
    rows = _rows()
    rows[4] = ",".join([*rows[4].split(",")[:2], cell, *rows[4].split(",")[3:]])
    with pytest.raises(CsvError) as refused:
        parse_human_data(_csv(rows), "lab")
    assert (refused.value.row, refused.value.column) == (6, "n")
    assert "outside 0..100" in refused.value.problem and len(refused.value.problem) < 80


def test_leading_zeros_in_n_are_read_as_the_number_however_many() -> None:
    rows = _rows()
    rows[4] = rows[4].replace(",4,", "," + "0" * 5000 + "4,")
    assert parse_human_data(_csv(rows), "lab").theta[0, 0, 4] == 0.5


def test_an_n_of_5001_digits_answers_422_not_500(client: TestClient) -> None:
    assert client.post("/api/studies", json={"name": "s"}).status_code == 201
    rows = _rows()
    rows[0] = rows[0].replace(",0,", "," + "9" * 5001 + ",")
    r = client.post("/api/studies/1/utility-sets/import",
                    data={"name": "lab data", "precompression_pct": "25"},
                    files={"file": ("data.csv", _csv(rows).encode(), "text/csv")})
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"] == ["body", "file", "row 2", "n"]
