#!/usr/bin/env bash
# Gesture evaluation experiment: train the motion feature extractor M (tiny) on the default synthetic corpus and
# score the ground truth and the built-in baselines on held-out texts (paper Table 1 layout).
# Writes experiments/gesture_model/reports/gesture_eval/gesture_test.{json,md} and confusion PNGs.
# Usage: experiments/gesture_model/gesture_evaluation.sh [STEPS]   (default 600)
set -euo pipefail
cd "$(dirname "$0")/../.."
STEPS=${1:-600}
source experiments/common.sh
start=$(date +%s)
$EG train extractor --data "$CACHE" --out "$WORK/extractor" --steps "$STEPS" --checkpoint-every 100 --quiet
echo "extractor training wall time: $(( $(date +%s) - start )) s" | tee "$WORK/extractor.time"
$EG evaluate gesture --data "$CACHE" --extractor "$WORK/extractor" --split test \
    --out experiments/gesture_model/reports/gesture_eval --overwrite
