#!/usr/bin/env bash
# More telephone-band windows in the second speech stage: the recipe's second stage (recipe.sh,
# speech_second_stage: 700 steps from make model's first stage) trained once with 0.35 of its augmented
# windows heard through a telephone band (`--set wave.telephone=0.35`; the recipe: 0.15) and once as the
# recipe has it (the control, the same first stage), each calibrated with the studio voices' means (the recipe's
# calibration before its telephone-band means: telephone_means.sh); then
# perception_shift.py on val (the val speakers' voices, never trained on, through changed recordings) for
# both and for BASE (the shipped speech model, as calibrated).
# Reports in experiments/reports/telephone_share/ (val only). About 50 min on 2 CPU cores once make model's
# first speech stage is trained; every step resumes.
# Usage: experiments/telephone_share.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/telephone_share.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
FIRST=$WORK/bundled/speech
RUN=$WORK/telephone_share
REPORT=experiments/reports/telephone_share
mkdir -p "$RUN" "$REPORT"
grep -qs '"step": 1300' "$FIRST/model.json" || { echo "train make model's first speech stage first" >&2; exit 1; }
speech_second_stage "$RUN/telephone" "$FIRST" "$CACHE" "$RUN/times.txt" --set wave.telephone=0.35
speech_second_stage "$RUN/control" "$FIRST" "$CACHE" "$RUN/times.txt"
for name in telephone control; do
    speech_calibrated "${name}_calibrated" "$RUN/$name" --real-voices "$REAL_VOICES"  # as the shipped model was
done
perception_val telephone_calibrated control_calibrated
[ -f "$REPORT/perception_base/perception_shift.md" ] || \
    .venv/bin/python experiments/perception_shift.py "$BASE" "$CACHE" "$REPORT/perception_base" val
cp "$RUN/times.txt" "$REPORT/training_time.txt"
