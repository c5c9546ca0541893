#!/usr/bin/env python3
"""Summary tables from `rsasim evaluate`'s report.csv (issue 33).

report.csv holds every cell at full precision, one row per table, group, parameter and level
(`table, group, parameter, unit, noise_level, n, trueness, precision, sd, tau, rms,
significance, exposure_factor`; docs/src/guide/scoring.md). The book's accuracy tables summarise
a group of those cells: the largest |trueness| and the largest precision P over some columns
(which may come from different columns), either per level (one column per exposure or noise
level) or over all levels (one column per report, i.e. per method).

A row of a summary is chosen by a selector `TABLE:GROUP:PARAMS`: a regular expression matched
against the whole `table` field, one against the whole `group` field (empty: any), and a
comma-separated list of parameters (empty: any). Examples:
`sources::r,c` (every source's r and c), `detector-.*:position:s`, `phantom-femur:orientation:`,
`mtpm:femur:`.

Layouts (cells: two significant digits, as the reports print them):

    bench/report_table.py by-level --report m=A/report.csv --report s=B/report.csv \\
        --row "sources r, c (mm)=m:sources::r,c" --row "femur by silhouette, position (mm)=s:phantom-femur:position:"

      | quantity | ×2 | ×1 | … |   cells "max|T| ± max P" at each level

    bench/report_table.py by-report --report dlt=A/report.csv --report selvik=B/report.csv \\
        --column "DLT + LM=dlt" --column "Selvik=selvik" --constant "paper=…" \\
        --row "source position r, c=sources::r,c"

      | quantity | DLT + LM | Selvik |  cells "|T| ≤ a mm, P ≤ b mm" over all levels

A row whose selector starts with `mean:` summarises the trueness alone ("mean ≤ a mm", for the
MTPM table, whose trueness is the mean MTPM). The generators (bench/accuracy.py) import
`read`, `worst`, `by_level` and `by_report`; the command line prints the table to stdout.
Standard library only.
"""

import argparse
import csv
import math
import re
import sys


def num(text):
    if text is None or text == "":
        return None
    x = float(text)
    return None if math.isnan(x) else x


def read(path):
    """The rows of a report.csv as dicts, numbers parsed (None where empty or NaN), each with a
    `level` key: the exposure factor in attenuation mode, else the noise level."""
    rows = []
    with open(path, newline="", encoding="utf-8") as f:
        for r in csv.DictReader(f):
            for k in ("noise_level", "trueness", "precision", "sd", "tau", "rms", "exposure_factor"):
                r[k] = num(r.get(k))
            r["n"] = int(r["n"]) if r.get("n") else 0
            r["level"] = r["exposure_factor"] if r["exposure_factor"] is not None else r["noise_level"]
            rows.append(r)
    return rows


def levels(rows):
    """The levels in the report's order (the order of its first table's rows)."""
    out = []
    for r in rows:
        if r["level"] not in out:
            out.append(r["level"])
    return out


def level_label(rows, level):
    """`×2` for an exposure factor, the noise level as it is otherwise."""
    attenuation = any(r["exposure_factor"] is not None for r in rows)
    return f"×{level:g}" if attenuation else f"{level:g}"


def parse_selector(text):
    mode = "tp"
    if text.startswith("mean:"):
        mode, text = "mean", text[len("mean:"):]
    table, group, params = (text.split(":") + ["", ""])[:3]
    return mode, table, group, [p.strip() for p in params.split(",") if p.strip()]


def select(rows, selector, level=None):
    """The rows a selector (string or parsed tuple) picks, at one level or at all."""
    _, table, group, params = parse_selector(selector) if isinstance(selector, str) else selector
    return [
        r for r in rows
        if re.fullmatch(table, r["table"])
        and (not group or re.fullmatch(group, r["group"]))
        and (not params or r["parameter"] in params)
        and (level is None or r["level"] == level)
    ]


def worst(rows):
    """(max |trueness|, max precision, unit, cells counted) over rows with a value."""
    cells = [r for r in rows if r["trueness"] is not None]
    if not cells:
        return None, None, "", 0
    t = max(abs(r["trueness"]) for r in cells)
    ps = [r["precision"] for r in cells if r["precision"] is not None]
    units = {r["unit"] for r in cells}
    return t, (max(ps) if ps else None), "/".join(sorted(units)), len(cells)


def fmt(x, digits=2):
    """Two significant digits as the reports print them, plain decimals, a real minus sign."""
    if x is None:
        return "—"
    if x == 0:
        return "0"
    e = math.floor(math.log10(abs(x)))
    decimals = max(0, digits - 1 - e)
    text = f"{round(x, decimals):.{decimals}f}"
    if abs(float(text)) >= 10 ** (e + 1) and decimals > 0:  # 0.0996 → 0.10, one decimal less
        text = f"{round(x, decimals - 1):.{decimals - 1}f}"
    return text.replace("-", "−")


UNIT = {"deg": "°", "mm": " mm", "px": " px"}


def unit_text(unit):
    return UNIT.get(unit, f" {unit}" if unit else "")


def by_level(reports, rows_spec, level_order=None):
    """Markdown: one row per (label, report key, selector), one column per level; cells
    `max|T| ± max P` over the selected cells at that level."""
    first = next(iter(reports.values()))
    lv = level_order or levels(first)
    out = ["| quantity (max \\|T\\| ± max P over the columns) | "
           + " | ".join(level_label(first, l) for l in lv) + " |",
           "|---|" + "---:|" * len(lv)]
    for label, key, selector in rows_spec:
        sel = parse_selector(selector)
        cells = []
        for l in lv:
            t, p, _, n = worst(select(reports[key], sel, l))
            if n == 0:
                cells.append("—")
            elif sel[0] == "mean":
                cells.append(fmt(t))
            else:
                cells.append(f"{fmt(t)} ± {fmt(p)}")
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def by_report(reports, columns, rows_spec, constants=None, header="quantity"):
    """Markdown: one row per (label, selector, {constant column: text}), one column per
    (header, report key) or constant column; cells `|T| ≤ a, P ≤ b` over every level."""
    constants = constants or []
    out = [f"| {header} | " + " | ".join([h for h, _ in columns] + constants) + " |",
           "|---|" + "---|" * (len(columns) + len(constants))]
    for label, selector, const in rows_spec:
        sel = parse_selector(selector)
        cells = []
        for _, key in columns:
            if key is None:
                cells.append("—")
                continue
            t, p, unit, n = worst(select(reports[key], sel))
            u = unit_text(unit)
            if n == 0:
                cells.append("—")
            elif sel[0] == "mean":
                cells.append(f"mean ≤ {fmt(t)}{u}")
            else:
                cells.append(f"\\|T\\| ≤ {fmt(t)}{u}, P ≤ {fmt(p)}{u}")
        cells += [const.get(c, "—") for c in constants]
        out.append(f"| {label} | " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("layout", choices=["by-level", "by-report"])
    ap.add_argument("--report", action="append", required=True, metavar="KEY=PATH")
    ap.add_argument("--row", action="append", required=True,
                    metavar="LABEL=[KEY:]TABLE:GROUP:PARAMS (by-level: KEY: first)")
    ap.add_argument("--column", action="append", default=[], metavar="HEADER=KEY (by-report)")
    args = ap.parse_args()
    reports = {}
    for spec in args.report:
        key, path = spec.split("=", 1)
        reports[key] = read(path)
    if args.layout == "by-level":
        rows = []
        for spec in args.row:
            label, rest = spec.rsplit("=", 1)
            key, selector = rest.split(":", 1)
            if key == "mean":
                key, selector = selector.split(":", 1)
                selector = "mean:" + selector
            rows.append((label, key, selector))
        sys.stdout.write(by_level(reports, rows))
    else:
        columns = [tuple(c.rsplit("=", 1)) for c in args.column] or [(k, k) for k in reports]
        rows = [(*spec.rsplit("=", 1), {}) for spec in args.row]
        sys.stdout.write(by_report(reports, columns, rows))


if __name__ == "__main__":
    main()
