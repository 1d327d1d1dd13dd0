#!/usr/bin/env python3
"""hocurve-occt against gmsh 4.8's optimiser on one part, in interleaved rounds.

    bench/ratio_series.py --model screw --order 2 [--rounds 10]
                          [--library NAME=DIR[,BINARY] ...] [--cad DIR] [--out DIR]

On a machine whose speed drifts by 20-30 % within minutes, a ratio of two
times measured an hour apart says little. Each round here runs, back to
back, gmsh's optimiser (`Mesh.HighOrderOptimize 2`), gmsh's linear meshing
alone, and hocurve-occt once per library, the libraries in an order that
rotates from one round to the next. gmsh's curving time is its optimiser
run less its linear meshing (both whole runs, wall seconds); hocurve's is
the "curve" seconds of its report (its linear meshing excluded), as in
bench/compare_parts.py, whose models, mesh sizes and gmsh options this
uses.

--library NAME=DIR runs hocurve-occt with LD_LIBRARY_PATH=DIR, i.e. with
the libhocurve.so.0.4 in DIR instead of the installed one; without any,
the installed library alone ("installed"). Use it to compare two builds:
copy target/release/libhocurve.so to DIR/libhocurve.so.0.4. With
NAME=DIR,BINARY that variant runs the hocurve-occt BINARY instead of
--hocurve-occt's (to compare two builds of the host program too). The table
gives per tool the median and range of its curving seconds, hocurve's min
Q3 (scaled Jacobian, from its report), the ratio of gmsh's median to each
library's, and whether the libraries wrote byte-identical meshes in every
round.
"""

import argparse
import filecmp
import json
import os
import statistics
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_parts import CURVATURE, MODELS, ROOT  # noqa: E402


def wall(cmd, output, env=None):
    """Run cmd quietly; return its wall seconds. Exits if it wrote no `output`
    (gmsh's optimiser may log an error, "Failed to reach critical value",
    and exit 1 with its mesh written, which is then timed like any other)."""
    if os.path.exists(output):
        os.remove(output)
    t0 = time.monotonic()
    rc = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env).returncode
    seconds = time.monotonic() - t0
    if not os.path.exists(output):
        sys.exit(f"exit status {rc} and no {output}: {' '.join(cmd)}")
    return seconds


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--model", required=True, help="one of: " + ", ".join(m[0] for m in MODELS))
    ap.add_argument("--order", type=int, required=True)
    ap.add_argument("--rounds", type=int, default=10)
    ap.add_argument("--library", action="append", default=[], metavar="NAME=DIR[,BINARY]")
    ap.add_argument("--cad", default=os.environ.get("HOCURVE_CAD", "/work/shared/cad"))
    ap.add_argument("--hocurve-occt", default=os.path.join(ROOT, "build-occt", "hocurve-occt"))
    ap.add_argument("--gmsh", default="gmsh")
    ap.add_argument("--out", default=os.path.join(ROOT, "bench", "out", "ratio"))
    args = ap.parse_args()

    found = [m for m in MODELS if m[0] == args.model]
    if not found:
        sys.exit(f"unknown model {args.model!r}; known: {', '.join(m[0] for m in MODELS)}")
    _, step, h = found[0]
    path = os.path.join(args.cad, step)
    if not os.path.exists(path):
        sys.exit(f"no {path} (set --cad or HOCURVE_CAD)")
    libraries = []
    for spec in args.library:
        name, sep, where = spec.partition("=")
        where, _, binary = where.partition(",")
        if not sep or not name or not os.path.isfile(os.path.join(where, "libhocurve.so.0.4")):
            sys.exit(f"--library {spec!r}: expected NAME=DIR[,BINARY] with DIR/libhocurve.so.0.4")
        if binary and not os.access(binary, os.X_OK):
            sys.exit(f"--library {spec!r}: {binary} is not an executable")
        libraries.append((name, os.path.abspath(where), binary or args.hocurve_occt))
    if not libraries:
        libraries = [("installed", None, args.hocurve_occt)]
    os.makedirs(args.out, exist_ok=True)

    sizes = ["-setnumber", "Mesh.MeshSizeMax", str(h), "-setnumber", "Mesh.MeshSizeMin", str(0.1 * h),
             "-setnumber", "Mesh.MeshSizeFromCurvature", str(CURVATURE), "-format", "msh41"]
    opt_msh, lin_msh = os.path.join(args.out, "gmsh.msh"), os.path.join(args.out, "gmsh-linear.msh")
    gmsh_opt = [args.gmsh, path, "-3", "-order", str(args.order), *sizes,
                "-setnumber", "Mesh.HighOrderOptimize", "2", "-o", opt_msh]
    gmsh_lin = [args.gmsh, path, "-3", "-order", "1", *sizes, "-o", lin_msh]

    seconds = {"gmsh": []}
    q3 = {}
    identical = True
    for name, _, _ in libraries:
        seconds[name], q3[name] = [], []
    for r in range(args.rounds):
        seconds["gmsh"].append(wall(gmsh_opt, opt_msh) - wall(gmsh_lin, lin_msh))
        k = r % len(libraries)
        for name, where, binary in libraries[k:] + libraries[:k]:
            env = dict(os.environ)
            if where:
                env["LD_LIBRARY_PATH"] = where
            base = os.path.join(args.out, name)
            wall([binary, path, "--order", str(args.order), "--mesh-size", str(h),
                  "--output", base + ".msh", "--report", base + ".json"], base + ".json", env)
            with open(base + ".json") as f:
                report = json.load(f)
            seconds[name].append(report["seconds"]["curve"])
            q3[name].append(report["min_q3"] if report["invalid_elements"] == 0 else float("nan"))
        first = os.path.join(args.out, libraries[0][0] + ".msh")
        for name, _, _ in libraries[1:]:
            identical &= filecmp.cmp(first, os.path.join(args.out, name + ".msh"), shallow=False)
        print(f"round {r + 1}: " + ", ".join(f"{t} {s[-1]:.3f}" for t, s in seconds.items()), file=sys.stderr)

    gmsh = statistics.median(seconds["gmsh"])
    print(f"{args.model} at p = {args.order}, mesh size {h}, {args.rounds} rounds (curving seconds)\n")
    print("| tool | median | range | min Q3 | gmsh / it |")
    print("|---|---|---|---|---|")
    for tool, s in seconds.items():
        med = statistics.median(s)
        # (nan: a run left invalid cells; its mesh is written all the same)
        quality = "" if tool == "gmsh" else f"{min(q3[tool], key=lambda q: (q == q, q)):.4f}"
        ratio = "" if tool == "gmsh" else f"{gmsh / med:.1f}"
        label = "gmsh optimiser" if tool == "gmsh" else f"hocurve ({tool})"
        print(f"| {label} | {med:.3f} | {min(s):.3f}–{max(s):.3f} | {quality} | {ratio} |")
    if len(libraries) > 1:
        print("\nmeshes byte-identical between the libraries in every round: " + ("yes" if identical else "no"))


if __name__ == "__main__":
    main()
