#!/usr/bin/env bash
# The two second-stage candidates together: the pitch moved alone (pitch_alone.sh) and the studio voices given
# the corpus's emotions (real_emotions.sh), each of which helped on its own somewhere on val. A trained speech
# model (BASE; for the report, the bundled one, the recipe's second stage) is trained on for 500 steps with that
# stage's settings (recipe.sh), half of its augmented windows also given a pitch moved alone by up to 3
# semitones, and one window of the studio voices in every quadruple, seven in eight of them given a random
# non-neutral emotion's corpus prosody and taught as it; calibrated on val with the studio voices' means
# (`--real-voices`, as the recipe does). Beside BASE, pitch_alone.sh's and real_emotions.sh's models, each
# calibrated the same way:
#   - perception_shift.py on val (the val speakers' voices, never trained on, through changed recordings);
#   - real_perception.py and real_voice_emotions.py: the real recordings (never trained on: other people).
# Reports in experiments/reports/pitch_real_emotions/ (val only). About 60 min on 2 CPU cores; every step resumes.
# Usage: experiments/pitch_real_emotions.sh BASE_SPEECH_MODEL
set -euo pipefail
BASE=${1:?usage: experiments/pitch_real_emotions.sh BASE_SPEECH_MODEL}
cd "$(dirname "$0")/.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/pitch_real_emotions
REPORT=experiments/reports/pitch_real_emotions
PITCH=$WORK/pitch_alone/pitch
EMOTIONS=$WORK/real_emotions/emotions
mkdir -p "$RUN" "$REPORT"
for model in "$PITCH" "$EMOTIONS"; do
    [ -f "$model/model.json" ] || { echo "run experiments/pitch_alone.sh and experiments/real_emotions.sh first" >&2; exit 1; }
done
STAGE=(--data "$CACHE" --init-from "$BASE" --losses adversarial --steps 500 --checkpoint-every 100 "${SPEECH_HARD[@]}"
       --set num_workers=2 --quiet)
speech_more both 1 --set wave.pitch=0.5 --set wave.pitch_semitones=3 --set "real_neutral=[$REAL_VOICES]" \
    --set real_emotion_share=0.875
speech_calibrated base_means "$BASE" --real-voices "$REAL_VOICES"
speech_calibrated pitch_means "$PITCH" --real-voices "$REAL_VOICES"
speech_calibrated emotions_means "$EMOTIONS" --real-voices "$REAL_VOICES"
speech_calibrated both_means "$RUN/both" --real-voices "$REAL_VOICES"
perception_val pitch_means both_means
MODELS=(base_means="$RUN/base_means" pitch_means="$RUN/pitch_means" emotions_means="$RUN/emotions_means"
        both_means="$RUN/both_means")
real_reports "${MODELS[@]}"
