#!/usr/bin/env bash
# Fuzz hocurve for a bounded time: builds the cargo-fuzz targets in fuzz/
# (AddressSanitizer + LeakSanitizer, debug assertions and overflow checks on)
# and runs each for SECONDS (default 60). Fails if any target finds a crash,
# a panic, a leak, a timeout or an out-of-memory; the input that did it is in
# fuzz/artifacts/TARGET/ (reproduce: cargo fuzz run TARGET THAT_FILE, with
# RUSTC_BOOTSTRAP=1 on a stable toolchain).
#
#   msh_reader  bytes -> the .msh reader, the mesh checks, a small run, quality
#   c_abi       bytes -> a sequence of hoc_* calls with arbitrary arguments
#
# Usage: scripts/fuzz.sh [SECONDS] [TARGET...]
#   scripts/fuzz.sh            60 s each (what CI runs)
#   scripts/fuzz.sh 3600       an hour each
#   scripts/fuzz.sh 600 c_abi  one target
#
# The corpora grow in fuzz/corpus/TARGET (not committed); each run starts from
# them plus fuzz/seeds/TARGET (committed) and, for msh_reader, the fixture
# meshes tests/data/*.msh. cargo-fuzz needs nightly-only flags (-Zsanitizer);
# on a stable toolchain RUSTC_BOOTSTRAP=1 unlocks them, so stable 1.95 works.
# cargo-fuzz itself is installed with `cargo install` if it is missing.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
seconds=${1:-60}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(msh_reader c_abi)
case $seconds in
  '' | *[!0-9]*) echo "usage: $0 [SECONDS] [TARGET...]" >&2; exit 2 ;;
esac

if ! cargo fuzz --version >/dev/null 2>&1; then
  echo "fuzz: installing cargo-fuzz"
  cargo install --locked cargo-fuzz@0.13.2
fi
# Nightly-only -Z flags on a stable compiler (a nightly one does not need it).
if ! rustc --version | grep -q nightly; then
  export RUSTC_BOOTSTRAP=1
fi

cd "$root/fuzz"
echo "fuzz: building ${targets[*]} ($(rustc --version))"
for t in "${targets[@]}"; do
  cargo fuzz build "$t"
done

status=0
for t in "${targets[@]}"; do
  corpus=corpus/$t
  mkdir -p "$corpus" "artifacts/$t"
  extra=()
  [ -d "seeds/$t" ] && extra+=("seeds/$t")
  if [ "$t" = msh_reader ]; then
    cp -n "$root"/tests/data/*.msh "$corpus"/
  fi
  echo "fuzz: $t for ${seconds} s"
  # -timeout: one input taking longer is a bug (the harnesses bound their work);
  # generous because CI machines are shared (a c_abi input with a p = 7..10
  # run took 35 s under ASan on a machine loaded 3x).
  if ! cargo fuzz run "$t" "$corpus" "${extra[@]}" -- \
      -max_total_time="$seconds" -timeout=120 -rss_limit_mb=4096 -print_final_stats=1 \
      -artifact_prefix="artifacts/$t/"; then
    echo "fuzz: $t FAILED; the input is in fuzz/artifacts/$t/:" >&2
    ls -t "artifacts/$t" | head -n 3 >&2
    status=1
  fi
done
exit $status
