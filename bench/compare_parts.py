#!/usr/bin/env python3
"""Compare hocurve-occt with gmsh 4.8's own high-order curving on real CAD parts.

    bench/compare_parts.py [--models screw,wrenchnut] [--orders 2,3,4] [--tools hocurve,elastic,optimiser]
                           [--timeout 1800] [--out DIR] [--cad DIR] [--force] [--markdown FILE]

For each model (STEP file in --cad, default /work/shared/cad or $HOCURVE_CAD)
at each order p and the model's mesh size H (table MODELS below, from the
cad folder's README), three runs, each timed as a whole (wall seconds):

  hocurve    build-occt/hocurve-occt MODEL --order P --mesh-size H   (its defaults:
             ILE, 1 increment, 12 elements per 2π of curvature, parametric placement).
             When it stops on an inverted cell it writes no mesh; it is then run
             again with --adaptive off (the step is kept, the mesh written with its
             invalid cells) so that the table can say how many cells are invalid
             ("fails; min Q3"); that run's time is shown in brackets. "N caps, M
             edges split" in the cells column: cells hocurve removed as boundary
             caps, and interior edges its repair split (each cell around one
             into two), so the measured mesh has other cells than gmsh's.
  elastic    gmsh MODEL -3 -order P -setnumber Mesh.HighOrderOptimize 3   (elastic analogy)
  optimiser  the same with Mesh.HighOrderOptimize 2   (elastic analogy, then the optimiser)
  linear     gmsh MODEL -3 -order 1   (the linear meshing alone, for the curving-only table:
             hocurve-occt's own curving time against gmsh's optimiser run less this)

The gmsh runs get the same linear-mesh options hocurve-occt sets through the
API (Mesh.MeshSizeMax H, Mesh.MeshSizeMin 0.1 H, Mesh.MeshSizeFromCurvature 12),
so both start from the same linear mesh (the cells column says so, or shows
both counts). gmsh is Debian's 4.8.4 binary (`apt-get install -y gmsh`), the
same version as the libgmsh hocurve-occt is built on.

Every output is measured by the same tool, `target/release/hocurve quality
OUT.msh --report R.json`: min Q3 (scaled Jacobian), invalid cells (sampled) and
certified invalid cells (det J bounds; shown when they differ). "‡": gmsh
logged an error (its optimiser: "Failed to reach critical value") but wrote
its mesh, which is measured. Results are kept per run in
DIR/results/*.json; a later call reuses them unless --force, so a filter
(--models/--orders/--tools) re-runs only part of the table. Runs not in DIR
are taken from --reuse (default bench/parts-results.json, the committed rows
of the last full run), so e.g. `--tools hocurve` re-measures hocurve and
keeps gmsh's rows without the hour gmsh takes; --save FILE writes the
table's rows (to update bench/parts-results.json). The markdown table
(all results in DIR for the models and orders asked) goes to stdout and, with
--markdown, to a file. A run longer than --timeout seconds is killed and shown
as "timeout".
"""

import argparse
import datetime
import json
import os
import shutil
import signal
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# model name -> (file, gmsh Mesh.MeshSizeMax), from the cad folder's README.
MODELS = [
    ("screw", "screw.step", 1.5),
    ("wrenchnut", "wrenchnut.stp", 10.0),
    ("component8", "component8.step", 2.5),
    ("U_Joint_2", "U_Joint_2.stp", 25.0),
    ("SampleCrankshaft4A", "SampleCrankshaft4A.stp", 80.0),
]
TOOLS = ["hocurve", "elastic", "optimiser", "linear"]
# The tools of the main table; "linear" (gmsh's linear meshing alone) is what
# the curving-only table subtracts from gmsh's whole runs.
TABLE_TOOLS = TOOLS[:3]
CURVATURE = 12  # hocurve-occt's default --curvature


def run_timed(cmd, log, timeout):
    """Run cmd with stdout+stderr into log; return (exit status or None on timeout, wall seconds)."""
    t0 = time.monotonic()
    with open(log, "w") as f:
        f.write("$ " + " ".join(cmd) + "\n")
        f.flush()
        proc = subprocess.Popen(cmd, stdout=f, stderr=subprocess.STDOUT, start_new_session=True)
        try:
            rc = proc.wait(timeout=timeout)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)  # its own session: only this run
            proc.wait()
            rc = None
    return rc, time.monotonic() - t0


def quality(hocurve, msh, report, timeout):
    """hocurve quality of msh as a dict, or None."""
    if not os.path.exists(msh):
        return None
    rc, _ = run_timed([hocurve, "quality", msh, "--report", report], report + ".log", timeout)
    if rc != 0 or not os.path.exists(report):
        return None
    with open(report) as f:
        return json.load(f)


def first_error(log):
    """First line of a gmsh log that starts with "Error", or ""."""
    try:
        with open(log) as f:
            for l in f:
                if l.startswith("Error"):
                    return l.strip()[:300]
    except OSError:
        pass
    return ""


def last_line(log):
    try:
        with open(log) as f:
            lines = [l.strip() for l in f if l.strip()]
        return lines[-1][:300] if lines else ""
    except OSError:
        return ""


def run_one(args, name, path, h, p, tool):
    work = os.path.join(args.out, "runs")
    os.makedirs(work, exist_ok=True)
    base = os.path.join(work, f"{name}-p{p}-{tool}")
    msh = base + ".msh"
    for f in (msh, base + ".q.json", base + ".report.json"):
        if os.path.exists(f):
            os.remove(f)
    row = {"model": name, "p": p, "tool": tool, "h": h, "date": datetime.date.today().isoformat()}
    if tool == "hocurve":
        cmd = [args.hocurve_occt, path, "--order", str(p), "--mesh-size", str(h), "--output", msh,
               "--report", base + ".report.json"]
    else:
        order = ["-order", "1"] if tool == "linear" else ["-order", str(p)]
        curving = [] if tool == "linear" else ["-setnumber", "Mesh.HighOrderOptimize", "3" if tool == "elastic" else "2"]
        cmd = [args.gmsh, path, "-3", *order, "-format", "msh41",
               "-setnumber", "Mesh.MeshSizeMax", str(h), "-setnumber", "Mesh.MeshSizeMin", str(0.1 * h),
               "-setnumber", "Mesh.MeshSizeFromCurvature", str(CURVATURE), *curving, "-o", msh]
    rc, secs = run_timed(cmd, base + ".log", args.timeout)
    row.update(command=" ".join(cmd), exit=rc, seconds=round(secs, 2))
    if rc is None:
        row["status"] = "timeout"
    elif tool == "hocurve" and rc not in (0, 3):
        row["status"] = "failed"
        row["message"] = last_line(base + ".log")
        if os.path.exists(base + ".report.json"):
            os.remove(base + ".report.json")
        # Again with adaptive stepping off, so the mesh is written with its invalid cells.
        cmd2 = [args.hocurve_occt, path, "--order", str(p), "--mesh-size", str(h), "--adaptive", "off",
                "--output", msh, "--report", base + ".report.json"]
        rc2, secs2 = run_timed(cmd2, base + ".noadapt.log", args.timeout)
        row.update(retry_command=" ".join(cmd2), retry_exit=rc2, retry_seconds=round(secs2, 2))
    else:
        # hocurve-occt: 3 = written with invalid cells. gmsh: nonzero when it logged an
        # error (its optimiser: "Failed to reach critical value"), the mesh written all the same.
        row["status"] = "ok" if rc == 0 else ("invalid" if tool == "hocurve" else "error")
        if tool != "hocurve" and rc != 0:
            row["message"] = first_error(base + ".log") or last_line(base + ".log")
    q = quality(args.hocurve, msh, base + ".q.json", args.timeout) if tool != "linear" else None
    if q:
        row.update(cells=q.get("cells"), nodes=q.get("nodes"), min_q3=q.get("min_q3"),
                   invalid=q.get("invalid_elements"), certified_invalid=q.get("certified_invalid_elements"),
                   certified_min_q3=q.get("certified_min_q3"))
    if tool == "hocurve" and os.path.exists(base + ".report.json"):
        with open(base + ".report.json") as f:
            rep = json.load(f)
        for k in ("cells_given", "placement_fallbacks", "placement_projected", "distorted_facets", "repair"):
            if k in rep:
                row[k] = rep[k]
        # Its own split of the wall time: STEP import and linear meshing, then curving.
        row.update(mesh_seconds=rep["seconds"]["mesh"], curve_seconds=rep["seconds"]["curve"],
                   solves=len(rep.get("solves", [])))
    if not args.keep_meshes and os.path.exists(msh):
        os.remove(msh)
    return row


def fmt_q(row):
    if row is None:
        return "–", "–", "–"
    q = row.get("min_q3")
    inv = row.get("invalid")
    cert = row.get("certified_invalid")
    qs = "–" if q is None else (f"{q:.3f}" if abs(q) >= 0.001 or q == 0 else f"{q:.1e}")
    invs = "–" if inv is None else (f"{inv}" if cert in (None, inv) else f"{inv} ({cert} cert.)")
    secs = f"{row['seconds']:.1f}"
    st = row["status"]
    if st == "timeout":
        return "timeout", "–", f"> {row['seconds']:.0f}"
    if st == "failed" and row["tool"] == "hocurve":
        # Stopped on an inverted cell; the figures are from the run with adaptive stepping off.
        qs = f"fails; {qs}" if q is not None else "fails"
        if row.get("retry_seconds") is not None:
            secs += f" [{row['retry_seconds']:.1f}]"
    elif st == "failed" or (st == "error" and q is None):
        qs = "fails" if q is None else f"fails; {qs}"
    elif st == "error":
        qs += " ‡"  # gmsh logged an error but wrote the mesh
    return qs, invs, secs


def model_orders(models, orders):
    """(model, p) in the table's order: MODELS, then orders, for the models asked."""
    return [(name, p) for name, _, _ in MODELS if name in models for p in orders]


def table(rows, models, orders):
    by = {(r["model"], r["p"], r["tool"]): r for r in rows}
    out = ["| model | p | cells | hocurve min Q3 | inv | s | gmsh elastic min Q3 | inv | s "
           "| gmsh optimiser min Q3 | inv | s |",
           "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for name, p in model_orders(models, orders):
        rs = [by.get((name, p, t)) for t in TABLE_TOOLS]
        if not any(rs):
            continue
        # Cells of the linear mesh: gmsh's, and hocurve-occt's before its cap removal.
        cells = sorted({r.get("cells_given", r.get("cells")) for r in rs if r and r.get("cells")})
        cs = " / ".join(str(c) for c in cells) if cells else "–"
        h = rs[0]
        if h and h.get("cells_given") and h.get("cells") and h["cells"] != h["cells_given"]:
            rep = h.get("repair", {})
            caps = rep.get("removed_caps", h["cells_given"] - h["cells"])
            notes = [f"{caps} caps"] if caps else []
            if rep.get("edge_splits"):
                notes.append(f"{rep['edge_splits']} edges split")
            if rep.get("surface_flips"):
                notes.append(f"{rep['surface_flips']} surface edges flipped")
            cs += f" ({', '.join(notes)})" if notes else ""
        line = [name, str(p), cs]
        for r in rs:
            line += list(fmt_q(r))
        out.append("| " + " | ".join(line) + " |")
    return "\n".join(out)


def curving_table(rows, models, orders):
    """Curving against curving: hocurve-occt's own curving time (its report), and
    gmsh's optimiser run less gmsh's linear meshing of the same model and size."""
    by = {(r["model"], r["p"], r["tool"]): r for r in rows}
    out = ["| model | p | hocurve curving s | elastic solves | gmsh linear meshing s | gmsh optimiser s "
           "| gmsh valid | gmsh curving s | ratio |",
           "|---|---|---|---|---|---|---|---|---|"]
    for name, p in model_orders(models, orders):
        hoc, lin, opt = (by.get((name, p, t)) for t in ("hocurve", "linear", "optimiser"))
        if not (hoc and hoc.get("curve_seconds") is not None and hoc["status"] == "ok" and lin and opt):
            continue
        if lin["status"] != "ok" or opt["status"] not in ("ok", "error") or opt.get("min_q3") is None:
            continue
        gmsh_curving = opt["seconds"] - lin["seconds"]
        valid = "yes" if opt.get("certified_invalid", opt.get("invalid")) == 0 else "no"
        out.append(f"| {name} | {p} | {hoc['curve_seconds']:.1f} | {hoc.get('solves', '–')} | {lin['seconds']:.1f} "
                   f"| {opt['seconds']:.1f} | {valid} | {gmsh_curving:.1f} | {gmsh_curving / hoc['curve_seconds']:.1f} |")
    return "\n".join(out)


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--models", default=",".join(m[0] for m in MODELS))
    ap.add_argument("--orders", default="2,3,4")
    ap.add_argument("--tools", default=",".join(TOOLS))
    ap.add_argument("--timeout", type=float, default=1800, help="seconds per run (default 1800)")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "out", "parts"))
    ap.add_argument("--cad", default=os.environ.get("HOCURVE_CAD", "/work/shared/cad"))
    ap.add_argument("--hocurve-occt", default=os.path.join(ROOT, "build-occt", "hocurve-occt"))
    ap.add_argument("--hocurve", default=os.path.join(ROOT, "target", "release", "hocurve"))
    ap.add_argument("--gmsh", default=shutil.which("gmsh") or "gmsh")
    ap.add_argument("--force", action="store_true", help="run again even where a result is kept")
    ap.add_argument("--keep-meshes", action="store_true", help="keep the curved .msh files (large)")
    ap.add_argument("--table-only", action="store_true", help="print the table of the kept results, run nothing")
    ap.add_argument("--markdown", help="also write the table to this file")
    ap.add_argument("--reuse", default=os.path.join(ROOT, "bench", "parts-results.json"),
                    help="rows for runs not in DIR (default bench/parts-results.json)")
    ap.add_argument("--save", help="write the rows of the table (JSON) to this file")
    args = ap.parse_args()

    models = args.models.split(",")
    known = [m[0] for m in MODELS]
    for m in models:
        if m not in known:
            ap.error(f"unknown model {m} (known: {', '.join(known)})")
    orders = [int(p) for p in args.orders.split(",")]
    tools = args.tools.split(",")
    for t in tools:
        if t not in TOOLS:
            ap.error(f"unknown tool {t} (known: {', '.join(TOOLS)})")
    resdir = os.path.join(args.out, "results")
    os.makedirs(resdir, exist_ok=True)

    if not args.table_only:
        for exe in ([args.hocurve_occt] if "hocurve" in tools else []) + [args.hocurve]:
            if not os.access(exe, os.X_OK):
                sys.exit(f"compare_parts: {exe} not found (build it: see examples/occt/README.md)")
        if any(t != "hocurve" for t in tools):
            try:
                v = subprocess.run([args.gmsh, "--version"], capture_output=True, text=True).stderr.strip() or \
                    subprocess.run([args.gmsh, "--version"], capture_output=True, text=True).stdout.strip()
            except OSError:
                sys.exit("compare_parts: no gmsh binary (apt-get install -y gmsh)")
            print(f"compare_parts: gmsh {v} ({args.gmsh})", file=sys.stderr)
        for name, fname, h in MODELS:
            if name not in models:
                continue
            path = os.path.join(args.cad, fname)
            if not os.path.exists(path):
                sys.exit(f"compare_parts: {path} not found (--cad)")
            for p in orders:
                for tool in tools:
                    res = os.path.join(resdir, f"{name}-p{p}-{tool}.json")
                    if os.path.exists(res) and not args.force:
                        continue
                    print(f"compare_parts: {name} p = {p} {tool} ...", file=sys.stderr, flush=True)
                    row = run_one(args, name, path, h, p, tool)
                    with open(res, "w") as f:
                        json.dump(row, f, indent=1)
                    print(f"compare_parts:   {row['status']}, {row['seconds']} s, min Q3 {row.get('min_q3')}, "
                          f"invalid {row.get('invalid')}", file=sys.stderr, flush=True)

    rows = {}
    for fn in sorted(os.listdir(resdir)):
        if fn.endswith(".json"):
            with open(os.path.join(resdir, fn)) as f:
                r = json.load(f)
            rows[(r["model"], r["p"], r["tool"])] = r
    if args.reuse and os.path.exists(args.reuse):
        with open(args.reuse) as f:
            for r in json.load(f):
                rows.setdefault((r["model"], r["p"], r["tool"]), r)
    rows = [rows[k] for k in sorted(rows) if k[0] in models and k[1] in orders]
    md = table(rows, models, orders) + "\n\nCurving alone:\n\n" + curving_table(rows, models, orders)
    if args.save:
        with open(args.save, "w") as f:
            json.dump(rows, f, indent=1)
            f.write("\n")
    print(md)
    if args.markdown:
        with open(args.markdown, "w") as f:
            f.write(md + "\n")


if __name__ == "__main__":
    main()
