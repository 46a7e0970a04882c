#!/usr/bin/env bash
# Stage what a patched clone has made: its golden flights, every evidence set it no longer
# lists as stale, and, until the fidelity set is made, the fidelity flights of the windows
# it has begun (with their lead-in); until moving_levers is made, its groups saved whole
# (results/levers, read back by benchmarks/moving_levers.py).
#   bash .staging/stage.sh /tmp/next      (run from this repository's root)
set -euo pipefail
clone=$(cd "$1" && pwd)
staging=$(cd "$(dirname "$0")" && pwd)
cd "$clone"
PYTHONPATH=$clone PAPER_REPRO_ROOT=$clone STAGING=$staging python - <<'PY'
import os, shutil, pathlib
from paper_repro.evidence.golden import stale_evidence
from paper_repro.evidence.sets import SETS
stale, out = set(stale_evidence()), pathlib.Path(os.environ["STAGING"]) / "figures"
for s in SETS:
    src = pathlib.Path("figures") / s.folder
    if not s.folder or s.folder in stale or not (src / "evidence.json").is_file():
        continue  # the root set (the paper mission) is staged by hand: its files are loose
    shutil.rmtree(out / s.folder, ignore_errors=True)
    shutil.copytree(src, out / s.folder)
    print("staged", s.folder)
shutil.rmtree(out / "golden", ignore_errors=True)
shutil.copytree("figures/golden", out / "golden")
print("staged golden")
PY
if [ -d results/fidelity ] && [ ! -f "$staging/figures/fidelity/evidence.json" ]; then
  mkdir -p "$staging/results/fidelity"
  for w in results/fidelity/*/; do
    n=$(ls "$w" | grep -vc '^lead-in$' || true)
    if [ "$n" -gt 0 ]; then
      rm -rf "$staging/results/fidelity/$(basename "$w")"
      cp -r "$w" "$staging/results/fidelity/"
      echo "staged fidelity $(basename "$w") ($n flights)"
    fi
  done
fi
if [ -d results/levers ] && [ ! -f "$staging/figures/studies/moving_levers/evidence.json" ]; then
  rm -rf "$staging/results/levers" && mkdir -p "$staging/results"
  cp -r results/levers "$staging/results/levers"
  echo "staged levers ($(ls results/levers | wc -l) groups)"
fi
