#!/usr/bin/env python3
"""Two-dimensional sweep: gmsh's triangle meshes of a plate with a hole and
of NACA aerofoils in a box, curved at p = 2..10 with the defaults.

    python3 bench/sweep_2d.py [--out DIR] [--orders 2,3,4,6,8,10] [--only SUBSTR ...]

The robustness corpus (bench/corpus.py) is tetrahedral; this sweep covers
the triangle meshes and the high orders. Cases (26 meshes):

* `plate-rR-hH-aA`: the rectangle [0, 2] x [0, 1] less a circle of radius
  R in {0.1, 0.3, 0.45} at (1, 0.5), element size H in {0.25, 0.1} (0.25
  and 0.05 on the circle), gmsh algorithm A in {1 MeshAdapt, 5 Delaunay,
  6 Frontal-Delaunay}; the circle is `5=circle:1,0.5,R`.
* `nacaCODE-nN-aA`: a NACA 0012 or 4412 section of unit chord (leading
  edge at the origin) in the box [-1, 2] x [-1, 1], a closed spline through
  2N points of its closed-trailing-edge formula, meshed at size 1/N on it
  and 0.3 on the box, N in {12, 30}, algorithm A in {5, 6}; the section is
  `5=naca4:CODE,1,0,0`. At N = 12 the leading edge is not a vertex.

Each mesh is made with gmsh (`gmsh` on the PATH) into DIR/meshes and
curved with `hocurve curve MESH --order P --geometry ... --output ...
--report ...` (nothing else: the defaults). A run passes when hocurve hands
back a mesh with no certified-invalid and no uncertain cell. Prints one
line per run (case, p, cells, status, min Q3, certified min Q3, edges
placed along the curve, seconds), writes DIR/results.json, and exits 1 if
any run failed.

The binary is HOCURVE_BIN or target/release/hocurve.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def plate(r, h, hc, alg):
    geo = f"""h={h}; hc={hc}; r={r};
Point(1)={{0,0,0,h}}; Point(2)={{2,0,0,h}}; Point(3)={{2,1,0,h}}; Point(4)={{0,1,0,h}};
Line(1)={{1,2}}; Line(2)={{2,3}}; Line(3)={{3,4}}; Line(4)={{4,1}};
Point(5)={{1,0.5,0,hc}}; Point(6)={{1+r,0.5,0,hc}}; Point(7)={{1,0.5+r,0,hc}};
Point(8)={{1-r,0.5,0,hc}}; Point(9)={{1,0.5-r,0,hc}};
Circle(5)={{6,5,7}}; Circle(6)={{7,5,8}}; Circle(7)={{8,5,9}}; Circle(8)={{9,5,6}};
Curve Loop(1)={{1,2,3,4}}; Curve Loop(2)={{5,6,7,8}};
Plane Surface(1)={{1,2}};
Physical Curve(5)={{5,6,7,8}}; Physical Curve(1)={{1,2,3,4}}; Physical Surface(1)={{1}};
Mesh.Algorithm={alg};
"""
    return geo, f"5=circle:1,0.5,{r}"


def naca_points(code, n):
    """2n points of the closed-trailing-edge NACA 4-digit section `code`
    (unit chord, leading edge at the origin), from the trailing edge along
    the lower surface, round the nose and back along the upper one: the
    parameter q in [-1, 1) (x = q^2 before the camber) spaced like sin(q pi / 2)."""
    m, p, t = int(code[0]) / 100, int(code[1]) / 10, int(code[2:]) / 100
    a = [0.2969, -0.1260, -0.3516, 0.2843, -0.1036]

    def half_thickness(x):
        return 5 * t * (a[0] * math.sqrt(x) + a[1] * x + a[2] * x * x + a[3] * x ** 3 + a[4] * x ** 4)

    def camber(x):
        if m == 0:
            return 0.0, 0.0
        if x < p:
            return m / p ** 2 * (2 * p * x - x * x), 2 * m / p ** 2 * (p - x)
        return m / (1 - p) ** 2 * ((1 - 2 * p) + 2 * p * x - x * x), 2 * m / (1 - p) ** 2 * (p - x)

    pts = []
    for i in range(2 * n):
        q = math.sin((-1 + i / n) * math.pi / 2)
        xi = q * q
        y = math.copysign(half_thickness(xi), q) if q != 0 else 0.0
        yc, slope = camber(xi)
        theta = math.atan(slope)
        pts.append((xi - y * math.sin(theta), yc + y * math.cos(theta)))
    return pts


def aerofoil(code, n, alg):
    pts = naca_points(code, n)
    lines = [
        "h=0.3;",
        "Point(1)={-1,-1,0,h}; Point(2)={2,-1,0,h}; Point(3)={2,1,0,h}; Point(4)={-1,1,0,h};",
        "Line(1)={1,2}; Line(2)={2,3}; Line(3)={3,4}; Line(4)={4,1};",
    ]
    for i, (x, y) in enumerate(pts):
        lines.append(f"Point({10 + i})={{{x:.15g},{y:.15g},0,{1.0 / n:.6g}}};")
    lines.append("Spline(5)={%s,10};" % ",".join(str(10 + i) for i in range(len(pts))))
    lines.append("Curve Loop(1)={1,2,3,4}; Curve Loop(2)={5};")
    lines.append("Plane Surface(1)={1,2};")
    lines.append("Physical Curve(5)={5}; Physical Curve(1)={1,2,3,4}; Physical Surface(1)={1};")
    lines.append(f"Mesh.Algorithm={alg};")
    return "\n".join(lines) + "\n", f"5=naca4:{code},1,0,0"


def cases():
    out = []
    for r in (0.1, 0.3, 0.45):
        for h, hc in ((0.25, 0.25), (0.1, 0.05)):
            for alg in (1, 5, 6):
                out.append((f"plate-r{r}-h{h}-a{alg}",) + plate(r, h, hc, alg))
    for code in ("0012", "4412"):
        for n in (12, 30):
            for alg in (5, 6):
                out.append((f"naca{code}-n{n}-a{alg}",) + aerofoil(code, n, alg))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="sweep-2d")
    ap.add_argument("--orders", default="2,3,4,6,8,10")
    ap.add_argument("--only", nargs="*", default=[])
    args = ap.parse_args()
    binary = os.environ.get("HOCURVE_BIN", str(REPO / "target" / "release" / "hocurve"))
    out = Path(args.out)
    meshes, runs = out / "meshes", out / "runs"
    meshes.mkdir(parents=True, exist_ok=True)
    runs.mkdir(parents=True, exist_ok=True)
    orders = [int(p) for p in args.orders.split(",")]
    rows = []
    for name, geo, geometry in cases():
        if args.only and not any(o in name for o in args.only):
            continue
        msh = meshes / f"{name}.msh"
        if not msh.exists():
            (meshes / f"{name}.geo").write_text(geo)
            made = subprocess.run(["gmsh", str(meshes / f"{name}.geo"), "-2", "-format", "msh41", "-o", str(msh)],
                                  capture_output=True, text=True)
            if made.returncode != 0:
                sys.exit(f"gmsh failed on {name}: {made.stderr.strip()}")
        for p in orders:
            report = runs / f"{name}-p{p}.json"
            report.unlink(missing_ok=True)
            start = time.time()
            run = subprocess.run([binary, "curve", str(msh), "--order", str(p), "--geometry", geometry,
                                  "--output", str(runs / f"{name}-p{p}.msh"), "--report", str(report)],
                                 capture_output=True, text=True)
            seconds = time.time() - start
            row = {"case": name, "order": p, "seconds": round(seconds, 2)}
            if run.returncode != 0:
                lines = run.stderr.strip().splitlines() or ["(no message)"]
                row.update(status="error: " + lines[-1], cells=0)
            else:
                r = json.loads(report.read_text())
                bad = r["certified_invalid_elements"] + r["uncertain_elements"]
                row.update(status="ok" if bad == 0 else f"invalid {bad}", cells=r["cells"], min_q3=r["min_q3"],
                           certified_min_q3=r["certified_min_q3"], edges_along_curves=r["edges_along_curves"])
            rows.append(row)
            print(f"{name:24s} p={p:2d} cells={row['cells']:5d} {row['status'][:80]:12s} "
                  f"min_Q3={row.get('min_q3', float('nan')):.3f} cert={row.get('certified_min_q3', float('nan')):.3f} "
                  f"along={row.get('edges_along_curves', '-')} {seconds:.1f} s", flush=True)
    (out / "results.json").write_text(json.dumps(rows, indent=1))
    failed = [r for r in rows if r["status"] != "ok"]
    print(f"{len(rows) - len(failed)} of {len(rows)} runs valid")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
