#!/usr/bin/env bash
# Condition means in the perception's read-out: the bundled model's networks (the run of bundled_model.sh,
# $WORK/bundled), calibrated anew as the recipe does (configs/bundled.yaml, perception.condition_means: each
# emotion's mean of the train takes heard through a telephone band, 6-14 dB quieter and in white noise at 8-16 dB
# SNR), the front end's read-out fitted again on RAVDESS's train actors (RAVDESS=... required); then, beside BASE
# (the bundle calibrated with the telephone band's means only):
#   - perception_shift.py on val (the val speakers' voices, never trained on, through changed recordings);
#   - RAVDESS's val actors (perception_val.py, calm counted as neutral).
# Reports in experiments/perception/reports/condition_means/ (val only). About 35 min on 2 CPU cores; every step
# resumes.
# Usage: RAVDESS=.../audio_speech_actors_01-24 experiments/perception/condition_means.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: RAVDESS=... experiments/perception/condition_means.sh BASE_SPEECH_MODEL}
: "${RAVDESS:?give RAVDESS=.../audio_speech_actors_01-24}"
cd "$(dirname "$0")/../.."
source experiments/common.sh
source experiments/recipe.sh
BUILT=$WORK/bundled
RUN=$WORK/condition_means
REPORT=experiments/perception/reports/condition_means
mkdir -p "$RUN" "$REPORT"
for stage in speech speech_tuned extractor gesture gesture_styled; do  # the networks as trained, not again
    ln -sfn "$PWD/$BUILT/$stage" "$RUN/$stage"
done
train_bundle "$RUN" "$CACHE"
ravdess_scoring_manifest "$WORK/ravdess_scored.csv"
for model in "base=$BASE" "condition_means=$RUN/bundle/speech.json"; do
    name=${model%%=*} path=${model#*=}
    [ -f "$REPORT/perception_$name/perception_shift.md" ] || \
        .venv/bin/python experiments/perception_shift.py "$path" "$CACHE" "$REPORT/perception_$name" val
    [ -f "$REPORT/ravdess_val_$name.json" ] || \
        .venv/bin/python experiments/ravdess/perception_val.py "$path" "$WORK/ravdess_scored.csv" val \
            "$REPORT/ravdess_val_$name.json"
done
