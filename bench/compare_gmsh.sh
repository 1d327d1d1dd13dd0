#!/usr/bin/env bash
# Compare hocurve's ILE curving with gmsh's elastic analogy on one geometry:
# a spherical cavity (r = 0.5) in the box [-2, 2]^3 (bench/sphere.geo; about
# 2,700 tetrahedra, 32,000 nodes at order 4).
#
#   bench/compare_gmsh.sh [--order P] [--increments "1 10"] [--out DIR]
#
# 1. gmsh (Debian's package) meshes sphere.geo at order 1       -> DIR/linear.msh
# 2. hocurve curve curves that mesh (ILE), once per increment count
#                                                                -> DIR/hocurve-pP-incN.msh
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
while [ $# -gt 0 ]; do
    case "$1" in
        --order) order="$2"; shift 2 ;;
        --increments) increments="$2"; shift 2 ;;
        --out) out="$2"; shift 2 ;;
        -h|--help) sed -n '2,16p' "${BASH_SOURCE[0]}" | sed 's/^# \{0,1\}//'; exit 0 ;;
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

mkdir -p "$out"
cd "$out"
geo="$here/sphere.geo"

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

# 1. gmsh at order 1.
echo "compare_gmsh: gmsh order 1" >&2
timed gmsh-p1 gmsh "$geo" -3 -format msh41 -o linear.msh
tag=$(sed -n 's/.*sphere surface tag = \([0-9]*\).*/\1/p' gmsh-p1.log | head -1)
[ -n "$tag" ] || { echo "compare_gmsh: sphere.geo did not print the sphere's surface tag" >&2; exit 1; }

# 2. hocurve on that mesh.
for n in $increments; do
    echo "compare_gmsh: hocurve curve, order $order, $n increment(s)" >&2
    timed "hocurve-inc$n" "$hocurve" curve linear.msh --order "$order" --geometry "$tag=sphere:0,0,0,0.5" \
        --formulation ile --increments "$n" --output "hocurve-p$order-inc$n.msh" --report "hocurve-p$order-inc$n.json"
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
    echo "sphere cavity in a box, order $order; sphere = gmsh surface $tag; $(nproc) cores; $(date -u +%Y-%m-%d)"
    echo "gmsh: $(gmsh --version 2>&1 | head -1); hocurve $("$hocurve" --version | cut -d' ' -f2)"
    echo
    printf "%-44s %9s %8s %8s %7s %8s\n" run wall_s peak_MB min_Q3 cells nodes
    printf "%-44s %9s %8s %8s %7s %8s\n" "gmsh -3 (order 1 meshing only)" "$g1_s" "$g1_mb" - - -
    for n in $increments; do
        read -r h_s h_mb <"hocurve-inc$n.time"
        hq=$(quality "hocurve-p$order-inc$n.msh")
        printf "%-44s %9s %8s %8.4f %7s %8s\n" "hocurve curve, ILE, $n increment(s)" "$h_s" "$h_mb" \
            "$(field min_q3 "$hq")" "$(field cells "$hq")" "$(field nodes "$hq")"
    done
    printf "%-44s %9s %8s %8.4f %7s %8s\n" "gmsh -3 -order $order HighOrderOptimize 3 (whole)" "$ge_s" "$ge_mb" \
        "$(field min_q3 "$gq")" "$(field cells "$gq")" "$(field nodes "$gq")"
    echo
    echo "speed ratios (> 1: hocurve faster). 'gmsh whole - gmsh order 1' is what gmsh spends making"
    echo "the mesh high order; 'hocurve' is the whole 'hocurve curve' run (read, elevate, project,"
    echo "solve, quality, write), without the order-1 meshing it starts from:"
    for n in $increments; do
        read -r h_s _ <"hocurve-inc$n.time"
        awk -v n="$n" -v g1="$g1_s" -v ge="$ge_s" -v h="$h_s" 'BEGIN {
            printf "  %2d increment(s): (gmsh whole - gmsh order 1) / hocurve = %6.2f   gmsh whole / hocurve = %6.2f   gmsh whole / (gmsh order 1 + hocurve) = %6.2f\n",
                n, (ge - g1) / h, ge / h, ge / (g1 + h) }'
    done
    echo
    echo "hocurve's own phase timings (seconds, from its report):"
    for n in $increments; do
        printf "  %2d increment(s): %s\n" "$n" \
            "$(sed -n 's/.*"seconds": {\(.*\)}.*/\1/p' "hocurve-p$order-inc$n.json" | tr -d '"')"
    done
} | tee compare.txt
