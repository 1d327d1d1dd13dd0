#!/usr/bin/env bash
# Compare hocurve's ILE curving with gmsh's elastic analogy on one geometry:
# --case sphere (default), a spherical cavity (r = 0.5) in the box [-2, 2]^3
# (bench/sphere.geo; about 2,700 tetrahedra, 32,000 nodes at order 4), or
# --case torus, a toroidal cavity (radii 1 and 0.35) in [-2, 2]^2 x [-1, 1]
# (bench/torus.geo; about 5,300 tetrahedra, 66,000 nodes at order 4).
#
#   bench/compare_gmsh.sh [--case sphere|torus] [--order P] [--increments "1 10"] [--out DIR]
#
# 1. gmsh (Debian's package) meshes the .geo at order 1         -> DIR/linear.msh
# 2. hocurve curve curves that mesh (ILE), once per increment count
#                                                                -> DIR/hocurve-pP-incN.msh
#    and once more with one increment and --optimize off: the elastic stage
#    alone, as gmsh's HighOrderOptimize 3 is               -> DIR/hocurve-pP-elastic.msh
# 3. gmsh meshes and curves the same geometry itself at order P with its
#    elastic analogy: -order P -setnumber Mesh.HighOrderOptimize 3
#                                                                -> DIR/gmsh-pP.msh
# 4. hocurve quality measures every high-order output the same way.
# Wall time and peak RSS come from /usr/bin/time -f "%e %M"; the table goes to
# stdout and DIR/compare.txt.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(dirname "$here")"
order=4
increments="1 10"
out="$root/bench/out"
case_name=sphere
while [ $# -gt 0 ]; do
    case "$1" in
        --case) case_name="$2"; shift 2 ;;
        --order) order="$2"; shift 2 ;;
        --increments) increments="$2"; shift 2 ;;
        --out) out="$2"; shift 2 ;;
        -h|--help) sed -n '2,21p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
        *) echo "compare_gmsh: unknown argument '$1'" >&2; exit 2 ;;
    esac
done

# --- tools -----------------------------------------------------------------
need_apt=()
command -v gmsh >/dev/null || need_apt+=(gmsh)
[ -x /usr/bin/time ] || need_apt+=(time)
if [ ${#need_apt[@]} -gt 0 ]; then
    if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
        echo "compare_gmsh: installing ${need_apt[*]} (apt-get)" >&2
        apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need_apt[@]}" >/dev/null
    else
        echo "compare_gmsh: missing ${need_apt[*]}; install with: sudo apt-get install -y ${need_apt[*]}" >&2
        exit 1
    fi
fi
echo "compare_gmsh: $(gmsh --version 2>&1 | head -1 | sed 's/^/gmsh /') at $(command -v gmsh)" >&2
(cd "$root" && cargo build --release --quiet --bin hocurve)
hocurve="$root/target/release/hocurve"

case "$case_name" in
    sphere) shape="sphere:0,0,0,0.5"; title="sphere cavity in a box" ;;
    torus) shape="torus:0,0,0,1,0.35"; title="torus cavity in a box" ;;
    *) echo "compare_gmsh: unknown case '$case_name' (sphere or torus)" >&2; exit 2 ;;
esac
geo="$here/$case_name.geo"
mkdir -p "$out"
cd "$out"

# timed LABEL CMD...: run CMD with its output in LABEL.log, wall seconds and
# peak RSS (MB) in LABEL.time as "seconds MB".
timed() {
    local label="$1"; shift
    if ! /usr/bin/time -f "%e %M" -o "$label.rawtime" "$@" >"$label.log" 2>&1; then
        echo "compare_gmsh: '$*' failed; see $out/$label.log" >&2
        tail -5 "$label.log" >&2
        exit 1
    fi
    awk '{printf "%s %.0f\n", $1, $2 / 1024}' "$label.rawtime" >"$label.time"
}
# min_q3 FILE.msh: min scaled Jacobian measured by hocurve quality.
quality() {
    "$hocurve" quality "$1" >"$1.quality.json"
    grep -E '"(min_q3|cells|nodes)"' "$1.quality.json" | tr -d ' ,"' | tr '\n' ' '
}
field() { # field KEY "k:v k:v ..."
    echo "$2" | tr ' ' '\n' | sed -n "s/^$1://p"
}
describe() { # describe RUN: what a run of step 2 is
    case "$1" in
        elastic) echo "elastic stage only" ;;
        *) echo "${1#inc} increment(s)" ;;
    esac
}

# 1. gmsh at order 1.
echo "compare_gmsh: gmsh order 1" >&2
timed gmsh-p1 gmsh "$geo" -3 -format msh41 -o linear.msh
tag=$(sed -n "s/.*$case_name surface tag = \([0-9]*\).*/\1/p" gmsh-p1.log | head -1)
[ -n "$tag" ] || { echo "compare_gmsh: $case_name.geo did not print the cavity's surface tag" >&2; exit 1; }

# 2. hocurve on that mesh: RUN is incN (N increments, the whole default run)
# or elastic (one increment, the elastic stage alone).
runs=""
for n in $increments; do runs="$runs inc$n"; done
runs="$runs elastic"
for run in $runs; do
    case "$run" in
        elastic) n=1; extra=(--optimize off); label="hocurve curve, ILE, elastic stage only" ;;
        *) n="${run#inc}"; extra=(); label="hocurve curve, ILE, $n increment(s)" ;;
    esac
    echo "compare_gmsh: $label, order $order" >&2
    timed "hocurve-$run" "$hocurve" curve linear.msh --order "$order" --geometry "$tag=$shape" \
        --formulation ile --increments "$n" "${extra[@]}" --output "hocurve-p$order-$run.msh" \
        --report "hocurve-p$order-$run.json"
done

# 3. gmsh's own high-order mesh, elastic analogy.
echo "compare_gmsh: gmsh order $order, Mesh.HighOrderOptimize 3 (elastic analogy)" >&2
timed gmsh-elastic gmsh "$geo" -3 -order "$order" -setnumber Mesh.HighOrderOptimize 3 -format msh41 \
    -o "gmsh-p$order.msh"

# 4. Table.
read -r g1_s g1_mb <gmsh-p1.time
read -r ge_s ge_mb <gmsh-elastic.time
gq=$(quality "gmsh-p$order.msh")
{
    echo "$title, order $order; cavity = gmsh surface $tag; $(nproc) cores; $(date -u +%Y-%m-%d)"
    echo "gmsh: $(gmsh --version 2>&1 | head -1); hocurve $("$hocurve" --version | cut -d' ' -f2)"
    echo
    printf "%-44s %9s %8s %8s %7s %8s\n" run wall_s peak_MB min_Q3 cells nodes
    printf "%-44s %9s %8s %8s %7s %8s\n" "gmsh -3 (order 1 meshing only)" "$g1_s" "$g1_mb" - - -
    for run in $runs; do
        read -r h_s h_mb <"hocurve-$run.time"
        hq=$(quality "hocurve-p$order-$run.msh")
        printf "%-44s %9s %8s %8.4f %7s %8s\n" "hocurve curve, ILE, $(describe "$run")" "$h_s" "$h_mb" \
            "$(field min_q3 "$hq")" "$(field cells "$hq")" "$(field nodes "$hq")"
    done
    printf "%-44s %9s %8s %8.4f %7s %8s\n" "gmsh -3 -order $order HighOrderOptimize 3 (whole)" "$ge_s" "$ge_mb" \
        "$(field min_q3 "$gq")" "$(field cells "$gq")" "$(field nodes "$gq")"
    echo
    echo "speed ratios (> 1: hocurve faster). 'gmsh whole - gmsh order 1' is what gmsh spends making"
    echo "the mesh high order; 'hocurve' is the whole 'hocurve curve' run (read, elevate, project,"
    echo "solve, quality, write), without the order-1 meshing it starts from:"
    for run in $runs; do
        read -r h_s _ <"hocurve-$run.time"
        awk -v d="$(describe "$run")" -v g1="$g1_s" -v ge="$ge_s" -v h="$h_s" 'BEGIN {
            printf "  %-20s (gmsh whole - gmsh order 1) / hocurve = %6.2f   gmsh whole / hocurve = %6.2f   gmsh whole / (gmsh order 1 + hocurve) = %6.2f\n",
                d ":", (ge - g1) / h, ge / h, ge / (g1 + h) }'
    done
    echo
    echo "hocurve's own phase timings (seconds, from its report):"
    for run in $runs; do
        printf "  %-20s %s\n" "$(describe "$run"):" \
            "$(sed -n 's/.*"seconds": {\(.*\)}.*/\1/p' "hocurve-p$order-$run.json" | tr -d '"')"
    done
} | tee compare.txt
