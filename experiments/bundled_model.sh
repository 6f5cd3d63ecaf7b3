#!/usr/bin/env bash
# Rebuilds the model bundled with the package (src/emogesture/assets/model/) from scratch, with the
# project's own recipe (configs/bundled.yaml), on the experiments' synthetic corpus (common.sh: 30 voices,
# split by text and by speaker); `make model` runs it, `make model RAVDESS=.../audio_speech_actors_01-24`
# with RAVDESS (CC BY-NC-SA 4.0: the weights are then for non-commercial use). Every step resumes when re-run
# (finished trainings are not redone). About 80 min of training on 2 CPU cores (the speech stages about 21 and
# 18 min with their banks of augmented windows, the front end's read-out with RAVDESS 5 min, the extractor 6 min,
# the gesture model 32 min), then calibration and scoring; the bundled model's own build is in
# reports/bundled_model/training_time.txt.
#   1.-5. `emogesture train bundle --recipe configs/bundled.yaml` (recipe.sh's train_bundle): the speech model
#      in two stages, the extractor M and the gesture model, trained on the train texts
#      of the train speakers only; the emotion perception and the fallback style calibrated on val; the
#      bundle (float16 weights) with the recipe's generation settings;
#   6. the bundle scored on the test split (speech and gesture reports, --emotion auto vs own, real
#      recorded speech against the test takes of the same emotion: `evaluate real`; with RAVDESS, its test
#      actors, once), the model card written from those numbers; then the bundle is copied into the package.
# Usage: experiments/bundled_model.sh
set -euo pipefail
cd "$(dirname "$0")/.."
source experiments/common.sh
RUN=$WORK/bundled
REPORT=experiments/reports/bundled_model
mkdir -p "$REPORT"

source experiments/recipe.sh
train_bundle "$RUN" "$CACHE"

# 6. the bundle, as shipped (float16), scored once on the test texts; the card; into the package
ship_bundle "$RUN/bundle" "$REPORT" "$RUN/times.txt"
