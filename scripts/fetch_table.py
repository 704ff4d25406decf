"""Print the fetch-count table of docs/performance.md, generated from `pyramid plan --json`.

    python scripts/fetch_table.py            # markdown table on stdout
    python scripts/fetch_table.py --check    # exit 1 if docs/performance.md's table differs
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

ROWS = [("box↘ ⊗", "box * g"), ("box↖ ⊗", "box^nw * g"), ("Bartlett ⊗", "bartlett * g"),
        ("Gauss 5×5 ⊗", "gauss5 * g"), ("Gauss 7×7 ⊗", "gauss7 * g"), ("quasi ⊗", "quasi * g"),
        ("box ⊗↓", "box *v g"), ("box4 ⊗↓", "box4 *v g"), ("quadratic ⊗↓", "quadratic *v g"),
        ("cubic ⊗↓", "cubic *v g"), ("nearest ⊗↑", "nearest *^ g"), ("midpoint ⊗↑", "midpoint *^ g"),
        ("Doo-Sabin ⊗↑", "doosabin *^ g"), ("cubic ⊗↑", "cubic *^ g"), ("four-point ⊗↑", "fourpoint *^ g")]
SIZE = "1920x1080"
BEGIN, END = "<!-- fetch-table:begin -->", "<!-- fetch-table:end -->"


def table() -> str:
    exe = os.path.join(os.path.dirname(sys.executable), "pyramid")
    lines = ["| filter | expression | paper's count | passes | fetches | fetches per output pixel | estimate | "
             "cost model: passes | fetches | per output pixel | estimate |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, expr in ROWS:
        d, c = (json.loads(subprocess.run([exe, "plan", "--json", "--strategy", strategy, expr, "--size", SIZE],
                                          check=True, capture_output=True, text=True).stdout)
                for strategy in ("paper", "cost"))
        paper = "–" if d["paper_fetches"] is None else f"{d['paper_fetches']:g}"
        lines.append(f"| {name} | `{expr}` | {paper} | {len(d['passes'])} | {d['fetches']:g} | "
                     f"{d['fetches_per_output_pixel']:.2f} | {d['estimate_s'] * 1e3:.1f} ms | {len(c['passes'])} | "
                     f"{c['fetches']:g} | {c['fetches_per_output_pixel']:.2f} | {c['estimate_s'] * 1e3:.1f} ms |")
    return "\n".join(lines)


def main() -> int:
    text = table()
    if "--check" not in sys.argv:
        print(text)
        return 0
    readme = open(os.path.join(os.path.dirname(__file__), "..", "docs", "performance.md"), encoding="utf-8").read()
    current = readme.split(BEGIN)[1].split(END)[0].strip()
    if current != text:
        print("docs/performance.md's fetch table is out of date: run python scripts/fetch_table.py", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
