#!/usr/bin/env bash
# Real voices' own emotion means in the perception (`calibrate speech --real-voices`): each emotion gets a
# second mean, of real training voices given that emotion's corpus prosody, beside the corpus's. Compared on
# val (the val speakers' voices, never trained on) with the recording changes of perception_shift.py, and on
# the real recordings (never trained on: other people) at three gains (real_perception.py) and given each
# emotion's prosody (real_voice_emotions.py), for:
#   - BASE (the bundled speech model), calibrated with the corpus's means only, with the three studio voices' means
#     (fr_june, it_carlo, ru_ivr; recipe.sh: REAL_VOICES) and with the three 8-kHz telephone voices' means.
# The report also holds two trained arms, not adopted and removed with their options (`git log --follow -- experiments/perception/real_voice_means.sh`): the
# studio voices given random emotions in training (real_emotion_share), and all six real voices taught as
# neutral (real_neutral).
# Reports in experiments/perception/reports/real_voice_means/ (val only). Nothing is trained; every step resumes.
# Usage: experiments/perception/real_voice_means.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/perception/real_voice_means.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/../.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/real_voice_means
REPORT=experiments/perception/reports/real_voice_means
TELEPHONE_VOICES="es_co, fr_armelle, it_menardi"
mkdir -p "$RUN" "$REPORT"
speech_calibrated base "$BASE"  # the corpus's means only, whatever calibration BASE carries
speech_calibrated base_means "$BASE" --real-voices "$REAL_VOICES"
speech_calibrated base_means_telephone "$BASE" --real-voices "$TELEPHONE_VOICES"
perception_val base_means base_means_telephone
MODELS=(base="$RUN/base" base_means="$RUN/base_means" base_means_telephone="$RUN/base_means_telephone")
.venv/bin/python experiments/real_perception.py "$REPORT/real" "${MODELS[@]}"
.venv/bin/python experiments/real_voice_emotions.py "$REPORT/real_voice_emotions" "${MODELS[@]}"
