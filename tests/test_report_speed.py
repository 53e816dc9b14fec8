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


@pytest.mark.parametrize(("text", "said"), [
    ("gen,nevals,best\n0,1,2.0\n\n1,2,1.0\n", "convergence.csv line 3 is truncated (0 of 3 fields)"),  # a blank line: no field
    ("gen,nevals,best\n0,1,2.0\n1,2\n", "convergence.csv line 3 is truncated (2 of 3 fields)"),
    ("gen,nevals,best\n0,1,2.0\n1,2,1.0", "convergence.csv line 3 is truncated (no line end)"),
    ("gen,nevals,best\n0,1,2.0\n1,2,1.0\n\n", "convergence.csv line 4 is truncated (0 of 3 fields)"),
    ("gen,nevals,best\n", "convergence.csv has no rows"),
    ("", "convergence.csv is empty"),
    ("gen,nevals,best\n0,1,2.0,\n", "convergence.csv line 2 is truncated (4 of 3 fields)"),
])  # fmt: skip
def test_convergence_files_split_as_the_csv_module_splits_them(tmp_path, text, said):
    from zrp_ga.report.runs import LeftOut, read_convergence

    (tmp_path / "convergence.csv").write_text(text)
    with pytest.raises(LeftOut) as caught:
        read_convergence(tmp_path)
    assert str(caught.value) == said


@pytest.mark.parametrize("text", ['gen,nevals,"best"\n0,1,2.0\n1,"3",1.5\n', "gen,nevals,best\r\n0,1,2.0\r\n1,3,1.5\r\n",
                                  "gen,nevals,best\n0,1,2.0\n1,3,1.5\n"])  # fmt: skip
def test_convergence_files_read_whatever_their_quotes_and_line_ends(tmp_path, text):
    from zrp_ga.report.runs import read_convergence

    (tmp_path / "convergence.csv").write_text(text, newline="")
    columns = read_convergence(tmp_path)
    assert list(columns) == ["gen", "nevals", "best"]
    np.testing.assert_array_equal(columns["nevals"], [1.0, 3.0])
    np.testing.assert_array_equal(columns["best"], [2.0, 1.5])


def _hits(seed: int = 3) -> pd.DataFrame:
    """Hits of runs of three configurations on two instances (the second configuration on one,
    with more runs), at three levels; some never hit."""
    rng = np.random.default_rng(seed)
    rows = []
    for c, instances, runs in (("c1", ("i1", "i2"), 3), ("c2", ("i2",), 5), ("c3", ("i1", "i2"), 2)):
        for i in instances:
            for r in range(runs):
                nevals = int(rng.integers(50, 400))
                for level in ("1.5", "1.1", "1.01"):
                    hit = float(rng.integers(1, nevals + 1)) if rng.random() < 0.6 else math.inf
                    rows.append(dict(run=f"{c}/{i}/{r}", configuration=c, instance=i, level=level, target=1.0, hit=hit, nevals=nevals))
    rows.append(dict(run="c4/i1/0", configuration="c4", instance="i1", level="1.5", target=1.0, hit=math.inf, nevals=100))
    return pd.DataFrame(rows)


def test_ert_per_group_as_its_definition_says():
    from zrp_ga.report.targets import ert

    h = _hits()
    got = ert(h, ["configuration", "instance"])
    keys = list(dict.fromkeys(zip(h["configuration"], h["instance"])))
    assert list(zip(got["configuration"], got["instance"])) == keys  # in the order the groups first appear
    for (c, i), row in zip(keys, got.itertuples()):
        g = [r for r in h.itertuples() if r.configuration == c and r.instance == i]
        wins = [r for r in g if math.isfinite(r.hit)]
        spent = sum(r.hit if math.isfinite(r.hit) else r.nevals for r in g)
        assert (row.runs, row.successes) == (len(g), len(wins))
        assert row.success_rate == len(wins) / len(g)
        assert row.ert == (spent / len(wins) if wins else math.inf)


def test_ecdf_steps_weigh_each_instance_and_level_the_same():
    from zrp_ga.report.targets import ecdf

    h = _hits()
    got = ecdf(h, start=1.0)
    assert list(dict.fromkeys(got["configuration"])) == ["c1", "c2", "c3", "c4"]
    for c, g in got.groupby("configuration", sort=False):
        mine = h[h["configuration"] == c]
        pairs = {(i, lev): int(((mine["instance"] == i) & (mine["level"] == lev)).sum()) for i, lev in zip(mine["instance"], mine["level"])}
        steps: dict[float, float] = {}
        for r in mine.itertuples():
            if math.isfinite(r.hit):
                steps[r.hit] = steps.get(r.hit, 0.0) + 1.0 / (len(pairs) * pairs[(r.instance, r.level)])
        x = sorted(steps)
        want_x = [1.0, *x] if not x or x[0] != 1.0 else x
        want_y = np.cumsum([steps[v] for v in x])
        want_y = np.r_[0.0, want_y] if not x or x[0] != 1.0 else want_y
        np.testing.assert_array_equal(g["evaluations"].to_numpy(), want_x)
        np.testing.assert_allclose(g["fraction"].to_numpy(), want_y, rtol=1e-13)
    assert got.loc[got["configuration"] == "c4", "fraction"].tolist() == [0.0]  # never hit: the starting point alone


def test_drawing_processes_leave_the_collector_as_they_found_it(monkeypatch):
    """While the figures are drawn the collector leaves the existing objects alone (frozen, so
    that no process walks them again); afterwards they are collectable again."""
    import gc
    import os

    from zrp_ga.report import drawing

    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: {0, 1}, raising=False)
    seen = []
    got = drawing._each(lambda spec: f"{spec['name']} {gc.get_freeze_count() > 0}", [{"name": "a"}, {"name": "b"}],
                        meanwhile=lambda: seen.append(gc.get_freeze_count() > 0))  # fmt: skip
    assert got == ["a True", "b True"] and seen == [True]  # frozen in the drawing processes and here meanwhile
    assert gc.get_freeze_count() == 0


def _box(tmp_path, name: str, formats: tuple[str, ...]) -> str:
    from zrp_ga.report import figures

    with figures.style("paper"):
        return figures.boxplot({"a long configuration name": np.array([1.0, 2.0, 4.0]), "b": np.array([3.0, 5.0])}, "error, mm",
                               2.5, "LM", "a title", name, tmp_path, formats, page=True)  # fmt: skip


def test_each_figure_is_laid_out_once_and_drawn_once_per_format(tmp_path, monkeypatch):
    """The constrained layout runs once per figure, not at every savefig, and the figure is
    drawn once per format (no dry draw besides); what each format shows is what matplotlib's own
    route (``draw_without_rendering``, then each savefig with the layout kept) shows."""
    from matplotlib.figure import Figure
    from matplotlib.layout_engine import ConstrainedLayoutEngine
    from PIL import Image

    from zrp_ga.report import figures

    counts = {"layout": 0, "draw": 0}
    layout, draw = ConstrainedLayoutEngine.execute, Figure.draw

    def counted_layout(self, fig):
        counts["layout"] += 1
        return layout(self, fig)

    def counted_draw(self, renderer):
        counts["draw"] += 1
        return draw(self, renderer)

    monkeypatch.setattr(ConstrainedLayoutEngine, "execute", counted_layout)
    monkeypatch.setattr(Figure, "draw", counted_draw)
    svg = _box(tmp_path, "fast", ("png", "pdf", "svg"))
    assert counts == {"layout": 1, "draw": 4}  # png, pdf, svg and the page's svg
    monkeypatch.undo()

    def by_matplotlib(fig, out, name, formats, page=False):
        fig.draw_without_rendering()
        fig.set_layout_engine("none")
        for ext in formats:
            fig.savefig(out / f"{name}.{ext}", dpi=200, metadata={"Date": None} if ext in ("svg", "pdf") else None)
        return ""

    monkeypatch.setattr(figures, "save", by_matplotlib)
    _box(tmp_path, "plain", ("png", "svg"))
    with Image.open(tmp_path / "fast.png") as a, Image.open(tmp_path / "plain.png") as b:
        assert a.size == b.size and a.tobytes() == b.tobytes()
    assert (tmp_path / "fast.svg").read_bytes() == (tmp_path / "plain.svg").read_bytes().replace(b"plain", b"fast")
    assert "a long configuration name" in svg


def test_conclusions_are_put_into_sentences_once(tmp_path, monkeypatch):
    """The page and the console say the same sentences, made once."""
    from report_fakes import fake_run

    from zrp_ga import report
    from zrp_ga.report import conclusions, write

    for i, cost in enumerate([3.0, 2.0, 1.5, 1.2]):
        fake_run(tmp_path / "runs" / f"r{i}", "I", "ga", [(10, 5.0), (20, cost)], floor=1.0, seed=i)
    made = []
    sentences = conclusions.sentences
    monkeypatch.setattr(conclusions, "sentences", lambda t: made.append(1) or sentences(t))
    t = report.write_report([tmp_path / "runs"], tmp_path / "out", formats=())
    said = write.console(t)
    assert len(made) == 1
    page = (tmp_path / "out" / "index.html").read_text()
    for lines in sentences(t).values():
        for line in lines:
            assert f"- {line}" in said and line.split(" ")[0] in page
