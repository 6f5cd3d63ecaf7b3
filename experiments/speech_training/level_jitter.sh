#!/usr/bin/env bash
# Every training window heard at its own level (`--set level_jitter_db=10`): two fine-tunes of the bundled speech
# model, 300 steps each with the recipe's second-stage settings (wave banks of 4 variants), alike but for the
# jitter; each calibrated as the recipe calibrates, given the bundle's front-end read-out (the same for both), and
# scored on val: held-out voices under changed recordings (perception_shift.py), RAVDESS's val actors
# (../ravdess/perception_val.py; RAVDESS=.../audio_speech_actors_01-24) and the real read speech at three gains.
# Usage: RAVDESS=... experiments/speech_training/level_jitter.sh
set -euo pipefail
cd "$(dirname "$0")/../.."
source experiments/common.sh
source experiments/recipe.sh
RUN=$WORK/level_jitter
REPORT=experiments/speech_training/reports/level_jitter
BUNDLED=src/emogesture/assets/model/speech.json
mkdir -p "$RUN" "$REPORT"
ravdess_scoring_manifest "$RUN/ravdess_scored.csv"
for name in control jitter10; do
    extra=()
    [ "$name" = jitter10 ] && extra=(--set level_jitter_db=10)
    grep -qs '"step": 300' "$RUN/$name/model.json" || $EG train speech --data "$CACHE" --init-from "$BUNDLED" \
        --out "$RUN/$name" --losses adversarial --steps 300 --checkpoint-every 100 "${SPEECH_HARD[@]}" \
        --set lr=2.5e-4 "${SPEECH_PITCH[@]}" "${SPEECH_BAND[@]}" --set wave_variants=4 "${extra[@]}" --quiet
    speech_calibrated "${name}_calibrated" "$RUN/$name" "${PERCEPTION[@]}"
    [ -f "$RUN/${name}_heard/model.json" ] || .venv/bin/python - "$BUNDLED" "$RUN/${name}_calibrated" "$RUN/${name}_heard" <<'PY'
import sys
from emogesture.checkpoints import load_model, save_model, stored_weights_dtype
from emogesture.models.perception import EmotionPerception
bundled, calibrated = load_model(sys.argv[1], "speech"), load_model(sys.argv[2], "speech")
perception = EmotionPerception.from_state(calibrated.metadata.emotion_perception, calibrated.tensors)
perception.heard = EmotionPerception.from_state(bundled.metadata.emotion_perception, bundled.tensors).heard
record, tensors = perception.to_state()
keep = {k: v for k, v in calibrated.tensors.items() if not k.startswith("emotion_perception.")}
save_model(sys.argv[3], "speech", calibrated.model, calibrated.config,
           calibrated.metadata.replace(emotion_perception=record), weights_dtype=stored_weights_dtype(calibrated),
           tensors={**keep, **tensors})
PY
    [ -f "$REPORT/perception_val_$name.md" ] || { .venv/bin/python experiments/perception_shift.py "$RUN/${name}_heard" \
        "$CACHE" "$RUN/shift_$name" val && cp "$RUN/shift_$name/perception_shift.md" "$REPORT/perception_val_$name.md"; }
    [ -f "$REPORT/ravdess_val_$name.json" ] || .venv/bin/python experiments/ravdess/perception_val.py \
        "$RUN/${name}_heard" "$RUN/ravdess_scored.csv" val "$REPORT/ravdess_val_$name.json"
done
.venv/bin/python experiments/real_perception.py "$REPORT" control="$RUN/control_heard" jitter10="$RUN/jitter10_heard"
