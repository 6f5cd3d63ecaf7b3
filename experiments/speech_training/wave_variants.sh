#!/usr/bin/env bash
# The speech model of the recipe with its augmented windows made once, before training (`--set wave_variants=K`:
# K draws of the recording conditions per training window, kept in memory), instead of afresh in the data
# workers at every step: both stages of recipe.sh's speech training (1300 steps with half of the windows
# augmented, then 700 with the harder second-stage conditions), one process with both cores, each stage timed;
# calibrated as the recipe does (studio voices' means); for each K asked (default 8 and 16). Beside BASE (the
# bundled speech model, trained with the augmentation drawn afresh; calibrated the same way), on val:
#   - perception_shift.py (the val speakers' voices, never trained on, through changed recordings; BASE's is
#     real_voice_means.sh's base_means);
#   - real_perception.py and real_voice_emotions.py: the real recordings (never trained on: other people).
# Reports in experiments/speech_training/reports/wave_variants/ (val only). About 45 min per K on 2 CPU cores; every step resumes.
# Usage: experiments/speech_training/wave_variants.sh BASE_SPEECH_MODEL [K ...]
set -euo pipefail
BASE=${1:?usage: experiments/speech_training/wave_variants.sh BASE_SPEECH_MODEL [K ...]}
shift
COUNTS=("$@")
[ ${#COUNTS[@]} -gt 0 ] || COUNTS=(8 16)
cd "$(dirname "$0")/../.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/wave_variants
REPORT=experiments/speech_training/reports/wave_variants
mkdir -p "$RUN" "$REPORT"
speech_calibrated base_means "$BASE" --real-voices "$REAL_VOICES"
MODELS=(base_means="$RUN/base_means")
for k in "${COUNTS[@]}"; do
    run=$RUN/k$k
    variants=(--set "wave_variants=$k")
    grep -qs '"step": 1300' "$run/speech/model.json" || timed "$RUN/times.txt" "k$k speech" $EG train speech \
        --data "$CACHE" --out "$run/speech" --losses adversarial --steps 1300 --checkpoint-every 100 \
        --set wave_augment=0.5 "${variants[@]}" --quiet
    grep -qs '"step": 700' "$run/speech_tuned/model.json" || timed "$RUN/times.txt" "k$k speech_tuned" $EG train \
        speech --data "$CACHE" --init-from "$run/speech" --out "$run/speech_tuned" --losses adversarial --steps 700 \
        --checkpoint-every 100 "${SPEECH_HARD[@]}" "${variants[@]}" --quiet
    speech_calibrated "variants${k}_means" "$run/speech_tuned" --real-voices "$REAL_VOICES"
    perception_val "variants${k}_means"
    MODELS+=("variants${k}_means=$RUN/variants${k}_means")
done
real_reports "${MODELS[@]}"
