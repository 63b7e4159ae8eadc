#!/usr/bin/env bash
# Compare two folders written by benchmarks/record_outputs.sh: the same files, JSON/CSV/Markdown
# byte for byte (wall-clock "seconds" and the data path masked), posterior files as data (their
# created_at stamps masked), and the logs without timing lines. Exit 1 on any difference.
#   PYTHON=.venv/bin/python benchmarks/compare_outputs.sh BEFORE AFTER
A=$1; B=$2; rc=0
diff <(cd $A && find . -type f | sort) <(cd $B && find . -type f | sort) && echo "same file list" || rc=1
for f in $(cd $A && find . -type f \( -name "*.json" -o -name "*.csv" -o -name "*.md" \) | sort); do
  if ! cmp -s <(sed -E 's/"(seconds|sampling_seconds|elapsed)": [0-9.eE+-]+/"\1": X/g; s#"source": "[^"]*/data/#"source": "data/#g' "$A/$f") <(sed -E 's/"(seconds|sampling_seconds|elapsed)": [0-9.eE+-]+/"\1": X/g; s#"source": "[^"]*/data/#"source": "data/#g' "$B/$f"); then echo "DIFFERS: $f"; rc=1; fi
done
for f in $(cd $A && find . -name "*.nc" | sort); do
  [ -f "$B/$f" ] || continue  # the file lists above already differ
  ${PYTHON:-python3} - "$A/$f" "$B/$f" <<'PY' || rc=1
import sys, xarray as xr
a = xr.open_datatree(sys.argv[1]); b = xr.open_datatree(sys.argv[2])
for t in (a, b):
    for node in t.subtree:
        node.attrs.pop("created_at", None)
try:
    xr.testing.assert_identical(a, b); print("nc identical:", sys.argv[1].split("/", 4)[-1])
except AssertionError as e:
    print("DIFFERS nc:", sys.argv[1], str(e)[:500]); sys.exit(1)
PY
done
for f in $(cd $A && ls log_*.txt); do
  if ! diff -q <(grep -v -E "[0-9.]+ s\b|elapsed|it/s|s/it" $A/$f) <(grep -v -E "[0-9.]+ s\b|elapsed|it/s|s/it" $B/$f) >/dev/null; then echo "log differs: $f"; diff <(grep -v -E "[0-9.]+ s\b|elapsed|it/s|s/it" $A/$f) <(grep -v -E "[0-9.]+ s\b|elapsed|it/s|s/it" $B/$f) | head -10; fi
done
exit $rc
