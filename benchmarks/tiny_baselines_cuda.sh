#!/usr/bin/env bash
# Train the synthetic track's tiny baselines on one CUDA device at once, then sample them.
#
#   bash benchmarks/tiny_baselines_cuda.sh STORE OUT [TRAIN_SECONDS]
#
# STORE: the README store (demo-out/data). OUT: where run folders, submissions and logs go.
# Runs ChainHOI tiny (paper and released masks), CATMO tiny, EJIM tiny and EJIM micro as
# five concurrent processes on the one GPU (default configs and seeds, --device cuda). A
# baseline whose CUDA start fails is retried on the CPU with 3 threads. A training still
# running after TRAIN_SECONDS (default 420) gets SIGINT, which writes its checkpoint
# (resume with the same `hoibench baseline train` command). Finished runs are sampled on
# the device: K = 1 for each (first caption, seed 0), K = 30 for CATMO tiny. Runs with no
# CUDA device take the CPU path throughout (slow: the tiny schedules take about an hour each).
set -u
STORE=$1; OUT=$2; BUDGET=${3:-420}
mkdir -p "$OUT/runs" "$OUT/subs" "$OUT/logs"
HB="${PYTHON:-python3} -m hoibench.cli"
train() {  # name baseline args...
  local name=$1 base=$2; shift 2
  local t0=$SECONDS
  timeout -s INT "$BUDGET" $HB baseline train "$base" "$STORE" --out "$OUT/runs/$name" --device cuda "$@" \
    > "$OUT/logs/$name.train.log" 2>&1
  local rc=$?
  if [ $rc -ne 0 ] && [ $((SECONDS - t0)) -lt 60 ]; then
    echo "cuda start failed (rc $rc); CPU, 3 threads" >> "$OUT/logs/$name.train.log"
    timeout -s INT $((BUDGET - SECONDS + t0)) $HB baseline train "$base" "$STORE" --out "$OUT/runs/$name" \
      --device cpu --threads 3 "$@" >> "$OUT/logs/$name.train.log" 2>&1
    rc=$?
  fi
  echo "$name train rc $rc in $((SECONDS - t0)) s" >> "$OUT/logs/summary.log"
}
train chainhoi-tiny chainhoi --config tiny &
train chainhoi-tiny-released chainhoi --config tiny --mask released &
train catmo-tiny catmo --config tiny &
train ejim-tiny ejim --config tiny &
train ejim-micro ejim --config micro &
wait
sample() {  # name baseline k
  local name=$1 base=$2 k=$3
  [ -f "$OUT/runs/$name/card.json" ] || { echo "$name: no finished run, not sampled" >> "$OUT/logs/summary.log"; return; }
  local t0=$SECONDS
  timeout -s INT "${SAMPLE_SECONDS:-120}" $HB baseline sample "$base" "$OUT/runs/$name" --data "$STORE" --out "$OUT/subs/$name-k$k.zip" --zip -k "$k" \
    --device cuda > "$OUT/logs/$name.sample-k$k.log" 2>&1
  echo "$name sample K=$k rc $? in $((SECONDS - t0)) s" >> "$OUT/logs/summary.log"
}
sample chainhoi-tiny chainhoi 1 &
sample chainhoi-tiny-released chainhoi 1 &
sample catmo-tiny catmo 1 &
sample catmo-tiny catmo 30 &
sample ejim-tiny ejim 1 &
sample ejim-micro ejim 1 &
wait
cat "$OUT/logs/summary.log"
