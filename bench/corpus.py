#!/usr/bin/env python3
"""Robustness corpus runner: curve every mesh of the corpus at p = 2..6 with
the defaults and say which runs fail.

    .venv/bin/python bench/corpus.py [--quick] [--orders 2,3,4,5,6] [--out DIR]
                                     [--only SUBSTR ...] [--report-only] [--timeout S] [--resume]

Generates the corpus into DIR/meshes with scripts/gen_corpus.py (unless
DIR/meshes/manifest.json is already there for the same --quick), runs
`hocurve curve CASE.msh --order P --geometry ... --output OUT.msh --report R.json`
for every case and order (nothing else on the command line: the defaults),
reads each JSON report, and prints a table

    case  generator  cells  p  status  min_Q3  cert_min_Q3  time_s

(status: `ok`, `invalid N` = N certified-invalid or uncertain cells in a mesh
that was handed back, or `error: <hocurve's message>` when it refused to
return a mesh, e.g. at the limit of adaptive stepping), then the
distribution of min Q3 over all runs (quantiles, histogram), and a summary.
The table also goes to DIR/results.csv and DIR/results.json; each run's
result is kept in DIR/runs/CASE-pP.result.json (with its hocurve report
CASE-pP.json) and --resume reuses them. Runs go order by order (p = 2 for
every case first), so an interrupted long run has the cheap orders complete.

Exit status: 1 if any run has certified-invalid or uncertain cells or an
error, 0 otherwise; --report-only always exits 0.

The binary is HOCURVE_BIN or target/release/hocurve. Runs go one after the
other (hocurve uses the cores itself).
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))

import gen_corpus  # noqa: E402

ORDERS = (2, 3, 4, 5, 6)


def hocurve_bin():
    return Path(os.environ.get("HOCURVE_BIN", REPO / "target" / "release" / "hocurve"))


def ensure_corpus(mesh_dir, quick=False, only=None, log=sys.stderr):
    """The manifest of mesh_dir, generating the corpus there first if needed."""
    mesh_dir = Path(mesh_dir)
    m = mesh_dir / "manifest.json"
    if m.exists():
        manifest = json.loads(m.read_text())
        names = {c["name"] for c in manifest["cases"]}
        wanted = {c["name"] for c in gen_corpus.cases() if (c["quick"] or not quick)
                  and (not only or any(o in c["name"] for o in only))}
        if wanted <= names:
            return manifest
    # In a child process: gmsh is initialised and finalised there.
    cmd = [sys.executable, str(REPO / "scripts" / "gen_corpus.py"), "--out", str(mesh_dir)]
    if quick:
        cmd.append("--quick")
    if only:
        cmd += ["--only", *only]
    print(f"corpus: generating into {mesh_dir}", file=log, flush=True)
    subprocess.run(cmd, check=True)
    return json.loads(m.read_text())


def error_line(stderr):
    """hocurve's `hocurve: error: ...` message, shortened to its first clause."""
    for line in stderr.splitlines():
        if line.startswith("hocurve: error:"):
            return line[len("hocurve: error:"):].strip()
    tail = [l for l in stderr.splitlines() if l.strip()]
    return tail[-1].strip() if tail else "no message"


def short_error(msg):
    """The error without its advice: 'invalid element: cell 10 is inverted (certified ...) in increment 7 of 10'."""
    for cut in ("; try ", " (load "):
        if cut in msg:
            msg = msg.split(cut)[0]
    return msg


def run_case(case, order, mesh_dir, work_dir, timeout=900, binary=None):
    """Curve one case at one order; returns a result dict (never raises on hocurve failures)."""
    binary = binary or hocurve_bin()
    work_dir = Path(work_dir)
    work_dir.mkdir(parents=True, exist_ok=True)
    stem = f"{case['name']}-p{order}"
    out = work_dir / f"{stem}.msh"
    rep = work_dir / f"{stem}.json"
    for f in (out, rep):
        if f.exists():
            f.unlink()
    args = [str(binary), "curve", str(Path(mesh_dir) / case["file"]), "--order", str(order)]
    for g in case["geometry"]:
        args += ["--geometry", g]
    args += ["--output", str(out), "--report", str(rep)]
    res = {"case": case["name"], "generator": case["generator"], "shape": case["shape"],
           "cells": case["cells"], "p": order, "status": None, "error": None, "min_q3": None,
           "certified_min_q3": None, "invalid": None, "certified_invalid": None, "uncertain": None,
           "removed_caps": None, "increments_taken": None, "step_backs": None, "time_s": None}
    t0 = time.monotonic()
    try:
        r = subprocess.run(args, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        res["time_s"] = time.monotonic() - t0
        res["status"] = f"error: timeout after {timeout} s"
        res["error"] = res["status"][7:]
        return res
    res["time_s"] = time.monotonic() - t0
    if r.returncode != 0 or not rep.exists():
        res["error"] = error_line(r.stderr)
        res["status"] = "error: " + short_error(res["error"])
        return res
    j = json.loads(rep.read_text())
    res.update(min_q3=j.get("min_q3"), certified_min_q3=j.get("certified_min_q3"),
               invalid=j.get("invalid_elements"), certified_invalid=j.get("certified_invalid_elements"),
               uncertain=j.get("uncertain_elements"), removed_caps=j.get("removed_caps"),
               increments_taken=j.get("increments_taken"), step_backs=len(j.get("step_backs") or []))
    bad = (res["certified_invalid"] or 0) + (res["uncertain"] or 0)
    res["status"] = "ok" if bad == 0 and not res["invalid"] else f"invalid {max(bad, res['invalid'] or 0)}"
    out.unlink(missing_ok=True)  # keep the reports, not the (large) meshes
    return res


def failed(res):
    return res["status"] != "ok"


def num(x, nd=3):
    return "-" if x is None else f"{x:.{nd}f}"


def table(results):
    w = max([len("case")] + [len(r["case"]) for r in results])
    lines = [f"{'case':<{w}}  {'generator':<9} {'cells':>6} {'p':>2}  {'min_Q3':>7} {'cert_Q3':>7} "
             f"{'time_s':>7}  status"]
    for r in results:
        lines.append(f"{r['case']:<{w}}  {r['generator']:<9} {r['cells']:>6} {r['p']:>2}  {num(r['min_q3']):>7} "
                     f"{num(r['certified_min_q3']):>7} {r['time_s']:>7.2f}  {r['status']}")
    return "\n".join(lines)


def markdown(results):
    """A case x order matrix for docs/validation.md: min Q3 / certified min Q3, or the failure."""
    orders = sorted({r["p"] for r in results})
    by = {(r["case"], r["p"]): r for r in results}
    cases = list(dict.fromkeys(r["case"] for r in results))
    lines = ["| case | generator | tets | " + " | ".join(f"p = {p}" for p in orders) + " |",
             "|---|---|---:|" + "---|" * len(orders)]
    for c in cases:
        first = next(r for r in results if r["case"] == c)
        cells = []
        for p in orders:
            r = by.get((c, p))
            if r is None:
                cells.append("")
            elif r["status"] == "ok":
                cells.append(f"{r['min_q3']:.2f} / {r['certified_min_q3']:.2f}")
            elif r["status"].startswith("invalid"):
                cells.append(f"**{r['status']}**")
            else:
                msg = r["error"] or ""
                if msg.startswith("invalid element: cell") and " in increment " in msg:
                    where = msg.split(" in increment ")[1].split(" ")[0]
                    cells.append(f"**fails** (incr. {where})")
                else:
                    cells.append(f"**error**: {short_error(msg)}")
        lines.append(f"| `{c}` | {first['generator']} | {first['cells']} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def quantile(xs, q):
    xs = sorted(xs)
    if not xs:
        return float("nan")
    k = (len(xs) - 1) * q
    lo, hi = math.floor(k), math.ceil(k)
    return xs[lo] + (xs[hi] - xs[lo]) * (k - lo)


def distribution(results):
    """Quantiles and a histogram of min Q3 over the runs that returned a mesh."""
    q3 = [r["min_q3"] for r in results if r["min_q3"] is not None]
    lines = [f"min Q3 over {len(q3)} runs that returned a mesh (of {len(results)}):"]
    if not q3:
        return "\n".join(lines)
    lines.append("  " + "  ".join(f"{name} {quantile(q3, q):.3f}" for name, q in
                                  (("min", 0), ("q10", 0.1), ("q25", 0.25), ("median", 0.5), ("q75", 0.75),
                                   ("max", 1))))
    labels = ["<= 0"] + [f"{k / 10:.1f}-{(k + 1) / 10:.1f}" for k in range(10)]
    counts = [0] * len(labels)
    for x in q3:
        counts[0 if x <= 0 else min(10, math.ceil(x * 10))] += 1
    top = max(counts) or 1
    for lab, n in zip(labels, counts):
        lines.append(f"  {lab:>8} {n:4d} {'#' * round(40 * n / top)}")
    return "\n".join(lines)


def summary(results):
    bad = [r for r in results if failed(r)]
    errors = [r for r in bad if r["status"].startswith("error")]
    cases = sorted({r["case"] for r in bad})
    return (f"{len(results)} runs, {len(results) - len(bad)} ok, {len(bad)} failed "
            f"({len(errors)} errors, {len(bad) - len(errors)} with invalid cells) in {len(cases)} of "
            f"{len({r['case'] for r in results})} cases; {sum(r['time_s'] for r in results):.0f} s of hocurve")


def error_kinds(results):
    """{message with its numbers replaced by N: (count, one full message)}, most frequent first."""
    import re

    kinds = {}
    for r in results:
        if r["error"]:
            key = re.sub(r"\d+(\.\d+)?(e-?\d+)?", "N", short_error(r["error"]))
            n, ex = kinds.get(key, (0, r["error"]))
            kinds[key] = (n + 1, ex)
    return dict(sorted(kinds.items(), key=lambda kv: -kv[1][0]))


def write_results(out_dir, results):
    out_dir = Path(out_dir)
    (out_dir / "results.json").write_text(json.dumps(results, indent=1) + "\n")
    with open(out_dir / "results.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(results[0].keys()))
        w.writeheader()
        w.writerows(results)


def main(argv=None):
    ap = argparse.ArgumentParser(description="Curve the robustness corpus at p = 2..6 and report the failures.")
    ap.add_argument("--quick", action="store_true", help="only the CI subset")
    ap.add_argument("--orders", default=",".join(map(str, ORDERS)), help="comma-separated orders (default 2..6)")
    ap.add_argument("--out", default=str(REPO / "bench" / "out" / "corpus"), help="output directory")
    ap.add_argument("--only", nargs="*", help="only cases whose name contains one of these")
    ap.add_argument("--report-only", action="store_true", help="exit 0 even if runs fail")
    ap.add_argument("--timeout", type=float, default=1800, help="seconds per run (default 1800)")
    ap.add_argument("--markdown", action="store_true", help="also print the case x order matrix in Markdown")
    ap.add_argument("--resume", action="store_true",
                    help="reuse the results of runs already done in DIR/runs (an interrupted long run)")
    a = ap.parse_args(argv)
    orders = [int(x) for x in a.orders.split(",") if x.strip()]
    binary = hocurve_bin()
    if not binary.is_file():
        print(f"corpus: {binary} not found: run `cargo build --release` or set HOCURVE_BIN", file=sys.stderr)
        return 2
    out = Path(a.out)
    manifest = ensure_corpus(out / "meshes", a.quick, a.only)
    cases = [c for c in manifest["cases"] if (c["quick"] or not a.quick)
             and (not a.only or any(o in c["name"] for o in a.only))]
    # Order by order: the low orders of every case (cheap) come first.
    done = {}
    runs = out / "runs"
    runs.mkdir(parents=True, exist_ok=True)
    for p in orders:
        for c in cases:
            saved = runs / f"{c['name']}-p{p}.result.json"
            if a.resume and saved.exists():
                r = json.loads(saved.read_text())
            else:
                r = run_case(c, p, out / "meshes", runs, timeout=a.timeout, binary=binary)
                saved.write_text(json.dumps(r) + "\n")
            done[(c["name"], p)] = r
            print(f"corpus: {c['name']} p={p}: {r['status']} ({r['time_s']:.1f} s)", file=sys.stderr, flush=True)
    results = [done[(c["name"], p)] for c in cases for p in orders]
    if not results:
        print("corpus: no cases selected", file=sys.stderr)
        return 2
    write_results(out, results)
    print(f"hocurve robustness corpus: {len(cases)} cases x p = {','.join(map(str, orders))} "
          f"(gmsh {manifest.get('gmsh')}, {manifest.get('tetgen') or 'no tetgen'})")
    print(table(results))
    print()
    print(distribution(results))
    print()
    kinds = error_kinds(results)
    if kinds:
        print("errors (numbers replaced by N; one full message each):")
        for pattern, (k, example) in kinds.items():
            print(f"  {k:3d} x {pattern}")
            print(f"        e.g. {example}")
        print()
    print(summary(results))
    if a.markdown:
        print()
        print(markdown(results))
    if a.report_only:
        return 0
    return 1 if any(failed(r) for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
