#!/usr/bin/env bash
# Real voices' own emotion means in the perception (`calibrate speech --real-voices`): each emotion gets a
# second mean, of real training voices given that emotion's corpus prosody, beside the corpus's. Compared on
# val (the val speakers' voices, never trained on) with the recording changes of perception_shift.py, and on
# the real recordings (never trained on: other people) at three gains (real_perception.py) and given each
# emotion's prosody (real_voice_emotions.py), for:
#   - BASE (the bundled speech model), calibrated with the corpus's means only, with the three studio voices' means
#     (fr_june, it_carlo, ru_ivr; recipe.sh: REAL_VOICES) and with the three 8-kHz telephone voices' means;
#   - real_emotions.sh's model (the studio voices given random emotions in training) with the studio means;
#   - BASE trained on for 500 steps with the second stage's settings and all six real voices taught as
#     neutral (`real_neutral=[...]`, trained here), calibrated as before and with the studio means.
# Reports in experiments/reports/real_voice_means/ (val only). About 60 min on 2 CPU cores when nothing is
# trained yet; every step resumes. Needs experiments/real_emotions.sh to have run.
# Usage: experiments/real_voice_means.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/real_voice_means.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/real_voice_means
REPORT=experiments/reports/real_voice_means
EMOTIONS=$WORK/real_emotions/emotions
TELEPHONE_VOICES="es_co, fr_armelle, it_menardi"
mkdir -p "$RUN" "$REPORT"
[ -f "$EMOTIONS/model.json" ] || { echo "run experiments/real_emotions.sh first (its model)" >&2; exit 1; }
STAGE=(--data "$CACHE" --init-from "$BASE" --losses adversarial --steps 500 --checkpoint-every 100 "${SPEECH_HARD[@]}"
       --set num_workers=2 --quiet)
speech_more anchored6 1 --set "real_neutral=[$REAL_VOICES, $TELEPHONE_VOICES]"
speech_calibrated base "$BASE"  # the corpus's means only, whatever calibration BASE carries
speech_calibrated base_means "$BASE" --real-voices "$REAL_VOICES"
speech_calibrated base_means_telephone "$BASE" --real-voices "$TELEPHONE_VOICES"
speech_calibrated emotions_means "$EMOTIONS" --real-voices "$REAL_VOICES"
speech_calibrated anchored6_calibrated "$RUN/anchored6"
speech_calibrated anchored6_means "$RUN/anchored6" --real-voices "$REAL_VOICES"
perception_val base_means base_means_telephone emotions_means anchored6_calibrated anchored6_means
MODELS=(base="$RUN/base" base_means="$RUN/base_means" base_means_telephone="$RUN/base_means_telephone"
        emotions="$WORK/real_emotions/emotions_calibrated" emotions_means="$RUN/emotions_means"
        anchored6="$RUN/anchored6_calibrated" anchored6_means="$RUN/anchored6_means")
real_reports "${MODELS[@]}"
