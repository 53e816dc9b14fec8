"""What ``zrp-ga-report`` costs on a folder of runs, and whether a change keeps what it says.

    python experiments/bench_report.py FOLDER [--repeats 3] [--before REV] [--formats none] [--out DIR] [--write FILE]
    python experiments/bench_report.py --compare REPORT_A REPORT_B

Runs ``python -m zrp_ga.cli.report FOLDER --out OUT`` (OUT: one new folder per variant and repeat,
siblings, so that the runs' paths relative to them are the same) with the code of this tree and,
with ``--before REV``, with the code of git revision REV too (each tree first on ``PYTHONPATH``,
run from the reports' folder, so that neither picks up the other's code), the variants in turn so that a shared machine's load falls on both. For each:
the wall time and the CPU time of every process of the command, user + system, the drawing
pool's children included (``resource.getrusage(RUSAGE_CHILDREN)`` of this script, which counts a
finished child and every descendant it waited for); the load average before and after.

Then the outputs of the first repeat of each variant are compared file by file: every .csv,
.md, .json and IOH file byte for byte; ``index.html`` byte for byte but for the line saying when
it was made and the code's commit; each PNG pixel for pixel; each PDF byte for byte but for at most 16 bytes in one
stretch (the font subset's tag and date that fontTools writes afresh). Nothing is written into
FOLDER. ``--write FILE``: the results as Markdown too.
"""

from __future__ import annotations

import argparse
import datetime
import os
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from bench_sweep import tree  # a git revision's code, importable from PYTHONPATH

HERE = Path(__file__).resolve().parents[1]


def _run(folder: str, out: Path, code: Path | None, extra: tuple[str, ...] = ()) -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(code or HERE), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    load = os.getloadavg()[0]
    start = time.perf_counter()
    # run from the reports' folder: ``python -m`` puts its working directory first on the path,
    # which would be this tree's code whatever PYTHONPATH says when run from the repository
    done = subprocess.run([sys.executable, "-m", "zrp_ga.cli.report", str(Path(folder).resolve()), "--out", str(out), *extra],
                          env=env, cwd=out.parent, capture_output=True, text=True)  # fmt: skip
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode:
        raise SystemExit(f"zrp-ga-report failed ({done.returncode}): {done.stderr.strip()[-2000:]}")
    user, system = after.ru_utime - before.ru_utime, after.ru_stime - before.ru_stime
    return dict(wall=wall, user=user, sys=system, cpu=user + system, load=(load, os.getloadavg()[0]))


def _png_pixels(path: Path):
    from PIL import Image

    with Image.open(path) as im:
        return im.size, im.mode, im.tobytes()


def _pdf_same(a: bytes, b: bytes) -> bool:
    if len(a) != len(b):
        return False
    diff = [k for k in range(len(a)) if a[k] != b[k]] if a != b else []
    return not diff or diff[-1] - diff[0] < 16


MADE = re.compile(rb"Made \d{4}-\d\d-\d\d \d\d:\d\d UTC| \(commit [0-9a-f]+(, modified)?\)")  # (a copy of a tree has no commit)


def _page(text: bytes) -> bytes:
    return MADE.sub(lambda m: b"Made" if m.group(0).startswith(b"Made") else b"", text)


def compare(ref: Path, new: Path) -> list[str]:
    """The files of report ``new`` that do not say what ``ref``'s say (one line each)."""
    problems = []
    names = {p.relative_to(ref) for p in ref.rglob("*") if p.is_file()}
    others = {p.relative_to(new) for p in new.rglob("*") if p.is_file()}
    problems += [f"{n}: only in {ref}" for n in sorted(names - others)]
    problems += [f"{n}: only in {new}" for n in sorted(others - names)]
    for n in sorted(names & others):
        a, b = (ref / n).read_bytes(), (new / n).read_bytes()
        if n.suffix == ".png":
            same = a == b or _png_pixels(ref / n) == _png_pixels(new / n)
        elif n.suffix == ".pdf":
            same = _pdf_same(a, b)
        elif n.name == "index.html":
            same = _page(a) == _page(b)
        else:
            same = a == b
        if not same:
            problems.append(f"{n}: differs")
    return problems


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("folder", nargs="?", help="runs or sweeps (read only)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--before", default=None, metavar="REV", help="also time the code of this git revision (e.g. main)")
    p.add_argument("--out", default=None, help="where the reports go (default: a new temporary folder)")
    p.add_argument("--write", default=None, metavar="FILE", help="the results as Markdown into FILE")
    p.add_argument("--formats", default=None, help="passed to zrp-ga-report (none: the tables alone, no drawing processes)")
    p.add_argument("--compare", nargs=2, default=None, metavar=("REF", "NEW"), help="only compare two reports' outputs")
    args = p.parse_args()
    if args.compare:
        problems = compare(Path(args.compare[0]), Path(args.compare[1]))
        print("\n".join(problems) or "every file says the same")
        raise SystemExit(1 if problems else 0)
    out = Path(args.out or tempfile.mkdtemp(prefix="bench_report.")).resolve()
    out.mkdir(parents=True, exist_ok=True)
    variants: dict[str, Path | None] = {}
    if args.before:
        variants[f"{args.before}"] = tree(args.before, out / "tree_before")
    variants["this tree"] = None
    for v, code in variants.items():  # which code each variant runs, as it will run it
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(code or HERE), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep))
        where = subprocess.run([sys.executable, "-c", "import zrp_ga.report.write as w; print(w.__file__)"], env=env, cwd=out,
                               capture_output=True, text=True, check=True).stdout.strip()  # fmt: skip
        print(f"{v}: {where}")
    uptime = subprocess.run(["uptime"], capture_output=True, text=True).stdout.strip()
    results: dict[str, list[dict]] = {v: [] for v in variants}
    for k in range(args.repeats):
        for v, code in variants.items():
            extra = ("--formats", args.formats) if args.formats else ()
            r = _run(args.folder, out / f"report_{list(variants).index(v)}_{k}", code, extra)
            results[v].append(r)
            print(f"{v} #{k + 1}: {r['cpu']:.1f} CPU-s ({r['user']:.1f} user + {r['sys']:.1f} sys), wall {r['wall']:.1f} s, "
                  f"load {r['load'][0]:.2f} -> {r['load'][1]:.2f}", flush=True)  # fmt: skip
    lines = [f"`python experiments/bench_report.py {args.folder} --repeats {args.repeats}"
             + (f" --before {args.before}" if args.before else "") + (f" --formats {args.formats}" if args.formats else "") + "`",
             f"on {datetime.datetime.now(datetime.UTC):%Y-%m-%d %H:%M} UTC; `uptime` before: {uptime}", "",
             "| code | CPU-s, median (min-max) | user / sys, median | wall s, median (min-max) | load 1-min, runs |",
             "|---|---|---|---|---|"]  # fmt: skip
    for v, rs in results.items():
        cpu, wall = [r["cpu"] for r in rs], [r["wall"] for r in rs]
        lines.append(f"| {v} | {statistics.median(cpu):.1f} ({min(cpu):.1f}-{max(cpu):.1f}) | "
                     f"{statistics.median(r['user'] for r in rs):.1f} / {statistics.median(r['sys'] for r in rs):.1f} | "
                     f"{statistics.median(wall):.1f} ({min(wall):.1f}-{max(wall):.1f}) | "
                     f"{', '.join(format(r['load'][0], '.1f') for r in rs)} |")  # fmt: skip
    if len(variants) == 2:
        first = [out / f"report_{i}_0" for i in range(2)]
        problems = compare(*first)
        files = sum(1 for f in first[0].rglob("*") if f.is_file())
        lines += ["", f"Outputs compared ({files} files): " + ("every file says the same." if not problems else
                  f"{len(problems)} differ: " + "; ".join(problems[:20]))]  # fmt: skip
    text = "\n".join(lines) + "\n"
    print(text)
    if args.write:
        Path(args.write).write_text(text)


if __name__ == "__main__":
    main()
