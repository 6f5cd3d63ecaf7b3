#!/usr/bin/env bash
# Rebuilds the model bundled with the package (src/emogesture/assets/model/) from scratch, with the
# project's own recipe, on the experiments' synthetic corpus (common.sh: 30 voices, split by text and by
# speaker); `make model` runs it. Every step resumes when re-run (finished trainings are not redone).
# About 110 min on 2 CPU cores (the second speech stage measured whole with its data workers, the first
# on an 80-step run; the bundled model's own build, before them, took about 135 min, its trainings in
# reports/bundled_model/training_time.txt).
#   1.–5. recipe.sh: the speech model in two stages, the extractor M and the gesture model, trained on the
#      train texts of the train speakers only; the emotion perception and the fallback style calibrated on
#      val; the bundle (float16 weights) with the tiny preset's generation settings;
#   6. the bundle scored on the test split (speech and gesture reports, --emotion auto vs own, real
#      recorded speech against the test takes of the same emotion: `evaluate real`), and
#      the model card written from those numbers; then the bundle is copied into the package.
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
