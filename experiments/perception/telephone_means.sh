#!/usr/bin/env bash
# Telephone-band means in the perception's read-out: a speech model (BASE; for the report, the shipped one)
# calibrated with the studio voices' means (recipe.sh, REAL_VOICES) and `--condition-means telephone`, each
# emotion's mean of the train takes heard through a telephone band, its weights unchanged; then, beside BASE
# as calibrated before:
#   - perception_shift.py on val (the val speakers' voices, never trained on, through changed recordings);
#   - real_perception.py: the real recordings (never trained or calibrated on) at three gains.
# Reports in experiments/perception/reports/telephone_means/ (val only). About 25 min on 2 CPU cores; every step resumes.
# BASE is a model calibrated without telephone-band means (for the report, the bundle shipped before them).
# Usage: experiments/perception/telephone_means.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/perception/telephone_means.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/../.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/telephone_means
REPORT=experiments/perception/reports/telephone_means
mkdir -p "$RUN" "$REPORT"
speech_calibrated speech_calibrated "$BASE" --real-voices "$REAL_VOICES" --condition-means telephone
[ -f "$REPORT/perception_base/perception_shift.md" ] || \
    .venv/bin/python experiments/perception_shift.py "$BASE" "$CACHE" "$REPORT/perception_base" val
[ -f "$REPORT/perception_telephone_means/perception_shift.md" ] || \
    .venv/bin/python experiments/perception_shift.py "$RUN/speech_calibrated" "$CACHE" \
        "$REPORT/perception_telephone_means" val
.venv/bin/python experiments/real_perception.py "$REPORT/real" base="$BASE" telephone_means="$RUN/speech_calibrated"
