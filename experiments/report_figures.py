"""The report's figures as print sees them: each figure's PDF page size (inches, from its
MediaBox) and the eight-line figures as readers with a colour-vision deficiency see them
(deuteranopia, protanopia, tritanopia at full severity: Machado, Oliveira and Fernandes 2009,
through the ``colorspacious`` package; ``pip install colorspacious``), side by side with the
original, into one PNG.

    python experiments/report_figures.py experiments/results/operator_suite --cvd docs/report_cvd.png

prints a Markdown table of the PDF sizes."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import numpy as np

EIGHT_LINES = ("convergence_by_configuration", "ecdf_evals_to_target", "fig2_convergence")
DEFICIENCIES = (("deuteranomaly", "deuteranopia"), ("protanomaly", "protanopia"), ("tritanomaly", "tritanopia"))


def pdf_size(path: Path) -> tuple[float, float]:
    """The first page's width and height in inches, from the PDF's MediaBox (points / 72)."""
    box = re.search(rb"/MediaBox\s*\[\s*([-0-9.]+)\s+([-0-9.]+)\s+([-0-9.]+)\s+([-0-9.]+)\s*\]", path.read_bytes())
    if box is None:
        raise ValueError(f"{path}: no MediaBox")
    x0, y0, x1, y1 = (float(v) for v in box.groups())
    return (x1 - x0) / 72.0, (y1 - y0) / 72.0


def simulate(rgb: np.ndarray, deficiency: str) -> np.ndarray:
    """``rgb`` (H, W, 3) in [0, 1] as seen with ``deficiency`` at severity 100."""
    from colorspacious import cspace_convert

    space = {"name": "sRGB1+CVD", "cvd_type": deficiency, "severity": 100}
    return np.clip(cspace_convert(rgb, space, "sRGB1"), 0.0, 1.0)


def cvd_sheet(report: Path, out: Path) -> None:
    """The eight-line figures (rows) as drawn and under each deficiency (columns), in one PNG."""
    from matplotlib.figure import Figure
    from matplotlib.image import imread

    names = [n for n in EIGHT_LINES if (report / f"{n}.png").exists()]
    fig = Figure(figsize=(4 * (1 + len(DEFICIENCIES)), 4.6 * len(names)), layout="constrained")
    axes = fig.subplots(len(names), 1 + len(DEFICIENCIES), squeeze=False)
    for row, name in zip(axes, names):
        rgb = imread(report / f"{name}.png")[..., :3]
        for ax, (label, image) in zip(row, [("as drawn", rgb)] + [(d, simulate(rgb, k)) for k, d in DEFICIENCIES]):
            ax.imshow(image)
            ax.set_title(f"{name}: {label}", fontsize=9)
            ax.axis("off")
    fig.savefig(out, dpi=110)


def main(argv: list[str] | None = None) -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("report", type=Path, help="a report's folder (its PDF and PNG figures)")
    p.add_argument("--cvd", type=Path, default=None, help="write the colour-vision sheet of the eight-line figures here")
    args = p.parse_args(argv)
    print("| figure | PDF width x height, in |\n| --- | --- |")
    for pdf in sorted(args.report.glob("*.pdf")):
        w, h = pdf_size(pdf)
        print(f"| {pdf.stem} | {w:.2f} x {h:.2f} |")
    if args.cvd:
        cvd_sheet(args.report, args.cvd)


if __name__ == "__main__":
    main()
