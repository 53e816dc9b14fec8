"""``zrp-ga-report``: tables, statistics, figures and an IOHprofiler export of finished zrp-ga
runs (:func:`zrp_ga.report.write.write_report`). The paths are checked before pandas, scipy and
matplotlib are imported, so that a mistyped path is reported at once."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import NoReturn

from zrp_ga.report.common import LEVELS, ROUND_OFF, ReportError
from zrp_ga.report.write import FORMATS, console, write_report


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> NoReturn:  # one line, like every other error of the command
        self.exit(2, f"{self.prog}: error: {message}\n")


def _numbers(kind: type):
    def parse(text: str) -> tuple:
        try:
            values = tuple(kind(v) for v in text.split(",") if v.strip())
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a comma-separated list of numbers: {text!r}") from None
        if not values or any(v <= 0 for v in values):
            raise argparse.ArgumentTypeError(f"needs positive numbers: {text!r}")
        return values

    return parse


def main(argv: list[str] | None = None) -> None:
    p = _Parser(prog="zrp-ga-report", description="Tables, statistics, figures and an IOHprofiler export of finished zrp-ga runs.")
    p.add_argument("dirs", nargs="+", help="run directories, sweep directories, or folders holding them")
    p.add_argument("--out", default=None, help="report directory (default: DIR/report of the first DIR)")
    p.add_argument("--ioh", default=None, metavar="DIR", help="where the IOHprofiler export goes (default: OUT/ioh)")
    p.add_argument("--levels", type=_numbers(float), default=LEVELS, metavar="C,...",
                   help="target levels c: targets c x f_ref (default 1.5,1.1,1.05,1.01)")
    p.add_argument("--target", type=float, default=None, help="one absolute target cost for every instance instead of the levels")
    p.add_argument("--round-off", type=float, default=ROUND_OFF, metavar="EPS",
                   help="a floor below EPS x nominal cost is round-off: f_ref = EPS x nominal cost (default 1e-9)")
    p.add_argument("--budgets", type=_numbers(int), default=None, metavar="N,...",
                   help="fixed budgets in evaluations (default: 100, 1000, ... up to the runs' largest, and that)")
    p.add_argument("--tolerance", type=float, default=None, metavar="REL",
                   help="final costs closer than REL x f_ref are the same result (default: the targets' resolution, the tightest "
                        "level - 1: 0.01; never below the round-off floor)")
    p.add_argument("--latex", action="store_true", help="also write the headline tables as booktabs .tex files")
    p.add_argument("--only", action="append", default=[], metavar="KEY=VALUE",
                   help="keep only the runs given this setting (repeatable), e.g. --only refine=none")
    p.add_argument("--formats", default=",".join(FORMATS), help="figure formats of the files (default png,pdf; svg too if wanted; none: no figures)")
    p.add_argument("--style", default="paper", choices=("paper", "screen"),
                   help="figure files for a paper (3.5 in a column, 7.16 in a page, 8-9 pt; the default) or for a screen "
                        "(7 in, 10 pt); the page always shows screen-sized figures")
    args = p.parse_args(argv)
    import shlex
    import sys

    command = shlex.join(["zrp-ga-report", *(sys.argv[1:] if argv is None else argv)])
    try:
        t = write_report(args.dirs, args.out, args.target, args.only, args.levels, args.budgets, args.round_off, args.ioh,
                         tuple(f for f in args.formats.split(",") if f and f != "none"), args.style, command, args.tolerance,
                         args.latex)  # fmt: skip
    except ReportError as exc:
        p.exit(2, f"zrp-ga-report: error: {exc}\n")
    print(console(t))
    from zrp_ga.report import tuning

    found = tuning.write(args.dirs, Path(args.out) if args.out else Path(args.dirs[0]) / "report")
    if found is not None:
        print(f"tuning studies (best settings, importance): {found}")


if __name__ == "__main__":
    main()
