"""Regenerate the pkm5 fixture CSVs from shared/reference/pkm5.md (run from the repository root).

The CSVs are committed so the tests do not depend on shared/; this script documents where every number came from:
000 Tables A.8-A.10 (IK simulations, §6.3-6.5 of the reference, with its [reconstructed] length columns) and
Tables A.15-A.17 (FK simulations, §6.6). Values are copied exactly as printed.
"""

import csv
import re
import sys
from pathlib import Path

REFERENCE = Path(sys.argv[1] if len(sys.argv) > 1 else "../shared/reference/pkm5.md")
OUT = Path(__file__).parent


def section(text, title):
    start = text.index(title)
    end = text.index("\n### ", start + 1)
    return text[start:end]


def rows(block):
    for line in block.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) > 3 and re.match(r"^-?\d", cells[0]):
            yield cells


def write(name, header, data):
    with open(OUT / name, "w", newline="") as fh:
        writer = csv.writer(fh)
        writer.writerow(header)
        writer.writerows(data)


def main():
    text = REFERENCE.read_text()
    lengths = [f"L{i}_mm" for i in range(1, 7)]
    for title, name, angle in (
        ("### 6.3 000 Table A.8", "table_a8_translation.csv", None),
        ("### 6.4 000 Table A.9", "table_a9_alpha.csv", "alpha_deg"),
        ("### 6.5 000 Table A.10", "table_a10_beta.csv", "beta_deg"),
    ):
        data = []
        for cells in rows(section(text, title)):
            pose = cells[1:5] if angle else cells[1:4]
            data.append([cells[0], *pose, *cells[-1].split()])
        write(name, ["region", "x_mm", "y_mm", "z_mm"] + ([angle] if angle else []) + lengths, data)
    for title, name, mode in (
        ("**Table A.15", "table_a15_fk_translation.csv", "translation"),
        ("**Table A.16", "table_a16_fk_alpha.csv", "alpha"),
        ("**Table A.17", "table_a17_fk_beta.csv", "beta"),
    ):
        start = text.index(title)
        block = text[start : text.index("\n**Table", start + 1) if mode != "beta" else text.index("\n### ", start)]
        cols = (
            ["x_mm", "y_mm", "z_mm"]
            + ([f"{mode}_deg"] if mode != "translation" else [])
            + ["theta1_deg", "theta3_deg", "theta5_deg"]
        )
        header = (
            ["row", "region"]
            + [f"true_{c}" for c in cols]
            + [f"guess_{c}" for c in cols]
            + [f"converged_{c}" for c in cols]
            + ["iterations"]
            + lengths
            + ["rerun"]
        )
        data = []
        for cells in rows(block):
            data.append(
                [
                    cells[0],
                    cells[1],
                    *cells[2].split(),
                    *cells[3].split(),
                    *cells[4].split(),
                    cells[6],
                    *cells[7].split(),
                    cells[8],
                ]
            )
        write(name, header, data)


if __name__ == "__main__":
    main()
