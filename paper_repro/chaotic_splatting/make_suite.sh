#!/usr/bin/env bash
# The random test suites of Table 3 and Table 4 (§5 of the paper): 100 Anderson–Farrell codes,
# N uniform in 3..=10, each with its ground truth at the full view and six zoomed-in patches
# (2× to 8×). Deterministic from the seed; not committed (suite/ is regenerated in minutes).
#   paper_repro/chaotic_splatting/make_suite.sh [TIER ...]     (default: smoke medium)
# smoke: 64², 1 M points a view (seconds); medium: 256², 10 M (about 7 min on 2 cores);
# full: the paper's 1024², 50 M points (for a bigger machine).
set -euo pipefail
cd "$(dirname "$0")"
bin=${IFSLAB:-../../target/release/ifslab}
[ -x "$bin" ] || bin=ifslab
tiers=("$@")
[ ${#tiers[@]} -gt 0 ] || tiers=(smoke medium)
for tier in "${tiers[@]}"; do
    case $tier in
        smoke) codes=10 ;;
        *) codes=100 ;;
    esac
    "$bin" suite make --codes "$codes" --seed 2025 --tier "$tier" -o "suite/$tier"
done
