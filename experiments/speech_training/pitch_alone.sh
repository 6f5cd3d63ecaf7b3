#!/usr/bin/env bash
# The pitch alone moved in training: a trained speech model (BASE; for the report, the bundled one, the
# recipe's second stage) trained on for 500 steps with that stage's settings (recipe.sh), half of its
# augmented windows also given a pitch moved alone by up to 3 semitones (`--set wave.pitch=0.5`; PSOLA, the
# formants kept), as people's pitch differs around their vocal tracts more than the corpus's speakers' does;
# calibrated on val; then, beside BASE and the control (the same 500 steps without it, trained here):
#   - perception_shift.py on val (the val speakers' voices, never trained on, through changed recordings);
#   - real_perception.py and real_voice_emotions.py: the real recordings (never trained on).
# Reports in experiments/speech_training/reports/pitch_alone/ (val only). About 60 min on 2 CPU cores; every step resumes.
# Usage: experiments/speech_training/pitch_alone.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/speech_training/pitch_alone.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/../.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/pitch_alone
CONTROL=$RUN/control_calibrated
REPORT=experiments/speech_training/reports/pitch_alone
mkdir -p "$RUN" "$REPORT"
STAGE=(--data "$CACHE" --init-from "$BASE" --losses adversarial --steps 500 --checkpoint-every 100 "${SPEECH_HARD[@]}"
       --quiet)
speech_more control 2 --set num_workers=2
speech_more pitch 2 --set wave.pitch=0.5 --set wave.pitch_semitones=3 --set num_workers=2
speech_calibrated control_calibrated "$RUN/control"
speech_calibrated pitch_calibrated "$RUN/pitch"
MODELS=(base="$BASE" control="$CONTROL" pitch="$RUN/pitch_calibrated")
.venv/bin/python experiments/perception_shift.py "$RUN/pitch_calibrated" "$CACHE" "$REPORT/perception_pitch" val
real_reports "${MODELS[@]}"
