#!/usr/bin/env bash
# Record the outputs of every command on fixed seeds into OUTDIR, for checking that a refactor
# changes no number: run it on two commits, then benchmarks/compare_outputs.sh A B.
#   BIN=path/to/bayes-mpem benchmarks/record_outputs.sh OUTDIR
# (with PYTHONPATH=<checkout>/src to run another checkout's code with the same venv).
set -u
OUT=$1
BIN=${BIN:-$(command -v bayes-mpem)}
D=${DATA:-$(cd "$(dirname "$0")/.." && pwd)/data}
rm -rf "$OUT"; mkdir -p "$OUT"; cd "$OUT" || exit 1
export MPLBACKEND=Agg
run() { local name=$1; shift; "$BIN" "$@" > "log_$name.txt" 2>&1; echo "$name $?"; }
run simulate simulate --preset abe58 --out sim --seed 3
run simulater simulate --preset random --out simr --seed 5 --effect range_bias=4
run demo demo --out demo --seed 1
run fit fit sim/pings.csv --beacons sim/beacons.csv --out fit --seed 2
run fitp fit sim/pings.csv --beacons sim/beacons.csv --out fitp --method paper --seed 2
run fitd fit sim/pings.csv --beacons sim/beacons.csv --out fitd --path double --seed 2
run sample sample sim/pings.csv --beacons sim/beacons.csv --out sample --seed 4 --no-progress
run compare compare sim/pings.csv --beacons sim/beacons.csv --out compare --seed 4 --no-progress
run diagnose diagnose simr/pings.csv --beacons simr/beacons.csv --out diagnose --seed 1 --no-progress
run loc1 locate "$D/obsrange/SIO_CC03.txt" --format obsrange --out loc_cc03
run loc2 locate "$D/obsrange/WHOI_S05.txt" --format obsrange --out loc_whoi --fit-lag \
    --outliers first_arrival
run loc3 locate "$D/obsrange/SIO_CC03.txt" --format obsrange --out loc_cc03s --sample --seed 3 \
    --no-progress --ssp woa09
run loc4 locate "$D/seagap/obsdata.inp" --format seagap --out loc_seagap --ssp survey \
    --speed-intervals 5
run simnav simulate --navigation --preset abe58 --seed 2 --out dive
run nav navigate dive/pings.csv --beacons dive/beacons.csv --out nav
run navo navigate dive/pings.csv --beacons dive/beacons.csv --out navo --multipath outlier
"$BIN" stream --beacons dive/beacons.csv --replay dive/pings.csv --speed max --seed 1 \
    > stream.jsonl 2> log_stream.txt; echo "stream $?"
run simgnssa simulate --gnssa --format garpos --seed 5 --out gnssa
run garpos locate gnssa/SIM.0000.sim-initcfg.ini --out loc_garpos
