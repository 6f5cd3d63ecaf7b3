#!/usr/bin/env bash
# The bundled recipe's speech model, read on val before its gesture model is trained on it: make model's
# calibrated speech model (recipe.sh's steps 1 and 4, $WORK/bundled/speech_calibrated; made here when missing,
# with the same command) beside BASE (the previously bundled speech model, calibrated the same way, into
# $WORK/bundled/base_means) and beside the same second speech stage trained with seed 1 from the same first
# stage (into $WORK/bundled_seed1; how far two runs of the stage lie apart):
#   - perception_shift.py on val (the val speakers' voices, never trained on, through changed recordings);
#   - real_perception.py and real_voice_emotions.py: the real recordings (never trained on: other people).
# Reports in experiments/bundled_model/reports/bundled_speech_val/ (val only). About 40 min on 2 CPU cores once make model's
# speech stages are trained; every step resumes.
# Usage: experiments/bundled_model/bundled_speech_val.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/bundled_model/bundled_speech_val.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/../.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/bundled
REPORT=experiments/bundled_model/reports/bundled_speech_val
mkdir -p "$REPORT"
grep -qs '"step": 700' "$RUN/speech_tuned/model.json" || { echo "train make model's speech stages first" >&2; exit 1; }
speech_calibrated speech_calibrated "$RUN/speech_tuned" --real-voices "$REAL_VOICES"
speech_calibrated base_means "$BASE" --real-voices "$REAL_VOICES"
SEED1=$WORK/bundled_seed1
mkdir -p "$SEED1"
speech_second_stage "$SEED1/speech_tuned" "$RUN/speech" "$CACHE" "$SEED1/times.txt" --seed 1
speech_calibrated seed1_calibrated "$SEED1/speech_tuned" --real-voices "$REAL_VOICES"
perception_val base_means speech_calibrated seed1_calibrated
real_reports base_means="$RUN/base_means" bundled="$RUN/speech_calibrated" seed1="$RUN/seed1_calibrated"
