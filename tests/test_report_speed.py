"""The report's faster paths say what the slower ones said: its tables written by
``zrp_ga.report.common.write_csv`` are pandas' ``to_csv`` byte for byte, and the tables built
with whole-array operations are the ones the per-group loops built."""

import math

import numpy as np
import pandas as pd
import pytest

from zrp_ga.report.common import write_csv

AWKWARD = ["plain", "a, comma", 'a "quote"', "a\nline break", "", "  spaced  ", "ü, non-ascii", "a\r\nwindows line"]


def _frame(rows: int, seed: int = 0) -> pd.DataFrame:
    rng = np.random.default_rng(seed)
    floats = rng.standard_normal(rows) * 10.0 ** rng.integers(-30, 30, rows)
    floats[::7] = np.nan
    floats[1::11] = np.inf
    special = [1e16, 9999999999999998.0, 1e-4, 9.9999e-5, 1e-5, 0.0, -0.0, 5e-324, 1.7976931348623157e308, -np.inf, 0.1, 50.0]
    floats[: len(special)] = special[:rows]
    words = pd.Series([AWKWARD[k % len(AWKWARD)] for k in range(rows)], dtype="str")
    words[::5] = None
    return pd.DataFrame({
        "run": words, "x": floats, "n": rng.integers(-5, 10**12, rows), "ok": rng.random(rows) < 0.5,
        "objects": pd.Series([AWKWARD[k % 3] if k % 4 else np.nan for k in range(rows)], dtype=object),
        "a, b": np.round(floats, 3), 'say "x"': words,
    })  # fmt: skip


@pytest.mark.parametrize("rows", [1, 3, 40, 500])
def test_write_csv_is_pandas_to_csv_byte_for_byte(tmp_path, rows):
    df = _frame(rows, seed=rows)
    write_csv(df, tmp_path / "fast.csv")
    df.to_csv(tmp_path / "pandas.csv", index=False)
    assert (tmp_path / "fast.csv").read_bytes() == (tmp_path / "pandas.csv").read_bytes()
    back = pd.read_csv(tmp_path / "fast.csv")
    np.testing.assert_array_equal(back["x"].to_numpy(), df["x"].to_numpy())  # every float reads back the same


@pytest.mark.parametrize("df", [
    pd.DataFrame(columns=["a", "b"]),  # no rows: pandas writes the header
    pd.DataFrame({"when": pd.to_datetime(["2026-01-01", "2026-02-03"]), "v": [1.5, math.nan]}),  # a column pandas formats
    pd.DataFrame({"mixed": [1.5, "x", None], "v": [1, 2, 3]}),  # numbers among words: pandas decides
    pd.DataFrame({"f32": np.array([0.1, 1e-7], dtype=np.float32), "cat": pd.Categorical(["a", "b"])}),
])  # fmt: skip
def test_write_csv_leaves_other_tables_to_pandas(tmp_path, df):
    write_csv(df, tmp_path / "fast.csv")
    df.to_csv(tmp_path / "pandas.csv", index=False)
    assert (tmp_path / "fast.csv").read_bytes() == (tmp_path / "pandas.csv").read_bytes()
